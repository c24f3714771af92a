"""MEGNO and the fast Lyapunov indicators FLI and OFLI, accumulated by the
compiled tangent-map stepper after every step.

With one deviation vector normalised every step τ and r_i its stretching in
step i (ending at t_i = iτ):

* MEGNO (Cincotta & Simó 2000): Y(t) = (2/t) ∫₀ᵗ s δ̇/δ ds, discretely
  Y(t_n) = (2/t_n) Σ_{i≤n} t_i ln r_i, and its mean Ȳ(t_n) = (1/n) Σ Y(t_i).
  On quasi-periodic orbits Ȳ → 2 (Y oscillates about 2, → 0 on stable
  periodic ones); on chaotic orbits Ȳ ≈ χ₁ t / 2.
* FLI (Froeschlé, Lega & Gonczi 1997): sup_{s≤t} ln‖w(s)‖ of the never
  renormalised vector — grows like ln t on regular orbits, like χ₁ t on
  chaotic ones.
* OFLI (Fouchard, Lega, Froeschlé & Froeschlé 2002): the same for the part
  of w orthogonal to the flow, which removes the linear shear along the
  flow and separates periodic from quasi-periodic orbits.

All three need the stretching of every step, so they are computed inside the
stepper (``fast_indicators`` of :class:`varint.tangent_map.TangentMapPropagator`),
for ``method="tm"``.
"""

from __future__ import annotations

from . import _kernels as K
from .indicators import _with_scheme
from .results import MEGNOResult
from .runs import Run

__all__ = ["megno"]


def megno(model, x0, t_end, tau=0.05, method="tm", scheme=None, seed=0, deviations=None,
          t_out=None, progress=None, errors="raise", escape_radius=None, checkpoint=None,
          checkpoint_interval=60.0, **method_options):
    """MEGNO Y(t), its mean Ȳ(t), FLI and OFLI of one or many orbits.

    Parameters are as in :func:`varint.lyapunov_spectrum`; one deviation
    vector (``deviations`` of shape ([M,] 2N) or ([M,] 2N, 1), normalised
    before use; seeded random by default).

    Returns
    -------
    MEGNOResult
        ``t``, ``megno``, ``mean_megno``, ``fli``, ``ofli`` ([M,] n_out).

    Raises
    ------
    ValueError
        For a method other than "tm" (the indicators need the stretching of
        every step, which only the compiled TM stepper accumulates).
    """
    if str(method).lower() != "tm":
        raise ValueError(f"megno is computed by method='tm' only (it needs the stretching of "
                         f"every step inside the compiled stepper), got method={method!r}")
    run = Run("megno", model, x0, t_end, tau, method=method, k=1, renorm="normalize",
              deviations=deviations, seed=seed, t_out=t_out, progress=progress, errors=errors,
              require="unit",
              method_options=dict(_with_scheme(scheme, method_options), fast_indicators=True),
              escape_radius=escape_radius, checkpoint=checkpoint,
              checkpoint_interval=checkpoint_interval)
    if run.W0.shape[2] != 1:
        raise ValueError(f"megno follows one deviation vector, {run.W0.shape[2]} were given")

    def record(state):
        aux = state.extra["fast_indicators"][:, 0]  # (M, N_AUX) of the one vector
        t = state.step * run.tau
        return {"megno": 2.0 * aux[:, K.AUX_WEIGHTED] / t,
                "mean_megno": aux[:, K.AUX_MEGNO_SUM] / state.step,
                "fli": aux[:, K.AUX_FLI].copy(), "ofli": aux[:, K.AUX_OFLI].copy()}

    def build(t, fields, common):
        return MEGNOResult(**common, megno=fields.get("megno"),
                           mean_megno=fields.get("mean_megno"), fli=fields.get("fli"),
                           ofli=fields.get("ofli"), deviations=run._squeeze(run.state.W))

    return run.execute(record, build)

"""Chaos indicators built on deviation vectors: the Lyapunov spectrum, GALI
and SALI.

Each indicator is a short function over the propagator protocol of
:mod:`varint.methods`: it chooses how the vectors are renormalised every τ
and what to read off them at the output times, and knows nothing about the
integrator underneath. So ``method=`` switches between the tangent map
method, the TDH methods and the reference integrators without touching this
code.

References
----------
Ch. Skokos & E. Gerlach, Phys. Rev. E 82, 036704 (2010) — the paper.
G. Benettin, L. Galgani, A. Giorgilli & J.-M. Strelcyn, Meccanica 15, 9 and
21 (1980) — the standard method for the spectrum.
Ch. Skokos, T. Bountis & Ch. Antonopoulos, Physica D 231, 30 (2007) and
Eur. Phys. J. ST 165, 5 (2008) — GALI.
Ch. Skokos, J. Phys. A 34, 10029 (2001) — SALI.
"""

from __future__ import annotations

import numbers

import numpy as np

from . import _validate as check
from .results import GALIResult, LyapunovResult, SALIResult
from .runs import Run

__all__ = ["lyapunov_spectrum", "gali", "sali"]


def _with_scheme(scheme, options):
    # Only methods built on a splitting scheme take one; None means the
    # method's default (SBAB2C for "tm", as in the paper).
    return options if scheme is None else dict(options, scheme=scheme)


def lyapunov_spectrum(model, x0, t_end, tau=0.05, method="tm", scheme=None,
                      n_exponents=None, seed=0, deviations=None, t_out=None, progress=None,
                      errors="raise", escape_radius=None, checkpoint=None,
                      checkpoint_interval=60.0, **method_options):
    """Finite-time Lyapunov exponents X_1(t), …, X_k(t) of one or many orbits.

    Every τ the deviation vectors are re-orthonormalised by QR
    decomposition and the logarithms of the diagonal of R are accumulated:
    X_i(t) = (1/t) Σ log R_ii (the discrete QR technique; paper Sect. III,
    eq. 10). For regular orbits X_1 ∝ 1/t (eq. 12); for autonomous
    Hamiltonians X_i + X_{2N−i+1} → 0 (eq. 13).

    Parameters
    ----------
    model : Model
    x0 : array_like, shape (2N,) or (M, 2N)
        Initial state(s); several orbits run in one call.
    t_end : float
        Final time (rounded to a multiple of τ).
    tau : float, default 0.05
        Renormalisation interval (= integration step for ``"tm"``).
    method : str, default "tm"
        Integration method (see :data:`varint.METHODS`).
    scheme : str or SplittingScheme, optional
        Splitting scheme of the symplectic methods ("tm" and the TDH
        methods); the paper's "SBAB2C" by default.
    n_exponents : int, optional
        How many exponents (k ≤ 2N deviation vectors); all 2N by default.
    seed : int or None, default 0
        Seed of the random orthonormal initial deviation vectors; None draws
        one (recorded in the provenance, and reused when resuming).
    deviations : array_like, shape ([M,] 2N, k), optional
        Orthonormal initial deviation vectors instead of random ones.
    t_out : None, int or array_like
        Output times (see :func:`varint.state.output_steps`); log-spaced by
        default.
    progress : bool, optional
        Progress bar on stderr; by default only when stderr is a terminal;
        False: never.
    errors : {"raise", "flag"}
        A failing orbit (non-finite, escaped, degenerate vectors) raises
        :class:`IntegrationError`, whose message gives the time and step and
        which carries the partial result; with "flag" it is frozen, its
        ``status`` is non-zero and its later exponents are NaN (a warning
        says how many failed).
    escape_radius : float, optional
        Stop an orbit as escaped once |q| exceeds this (overrides the
        model's ``escape_radius`` for this call).
    checkpoint : str or os.PathLike, optional
        Save the run to this file every ``checkpoint_interval`` seconds and
        when it stops (finished, failed or interrupted by Ctrl-C). If the
        file exists, the run resumes from it; the result is then bitwise
        identical to an uninterrupted run. A checkpoint written with other
        arguments is refused with a :class:`CheckpointError` naming them
        (see :mod:`varint.checkpoint`).
    checkpoint_interval : float, default 60
        Seconds of wall time between checkpoint writes.
    **method_options
        Passed to the method (e.g. ``rtol`` for the reference integrators).

    Returns
    -------
    LyapunovResult
        ``t`` (n_out,), ``exponents`` ([M,] n_out, k), ``energy_error``.
        After Ctrl-C: the outputs recorded so far, with ``interrupted=True``
        (and a warning); a second Ctrl-C stops at once.
    """
    dim = model.dim
    if n_exponents is not None:
        k = check.n_vectors(n_exponents, dim, "n_exponents")
    elif deviations is not None:
        W = check.real_array(deviations, "deviations")
        k = W.shape[-1] if W.ndim > 1 else 1
    else:
        k = dim
    run = Run("lyapunov_spectrum", model, x0, t_end, tau, method=method, k=k, renorm="qr",
              deviations=deviations, seed=seed, t_out=t_out, progress=progress, errors=errors,
              require="orthonormal", method_options=_with_scheme(scheme, method_options),
              options={"n_exponents": k}, escape_radius=escape_radius, checkpoint=checkpoint,
              checkpoint_interval=checkpoint_interval)
    if run.W0.shape[2] != k:
        raise ValueError(f"n_exponents = {k} but {run.W0.shape[2]} deviation vectors were given")

    def record(state):
        t = state.step * run.tau
        return {"exponents": state.log_growth() / t}

    def build(t, fields, common):
        return LyapunovResult(**common, exponents=fields.get("exponents"),
                              deviations=run._squeeze(run.state.W))

    return run.execute(record, build)


def _gali_orders(k, dim):
    orders = (k,) if isinstance(k, numbers.Integral) and not isinstance(k, bool) else tuple(k)
    if not orders:
        raise ValueError("k must name at least one GALI order")
    orders = tuple(check.n_vectors(o, dim, "GALI order k", minimum=2) for o in orders)
    if len(set(orders)) != len(orders):
        raise ValueError(f"GALI orders must be distinct, got {orders}")
    return tuple(sorted(orders))


def gali_from_vectors(W, orders):
    """GALI_k of the first k columns of unit vectors ``W`` (M, 2N, K), for
    each k in ``orders``: the product of the singular values (paper eq. 18).

    Returns a dict k -> ndarray of shape (M,).
    """
    return {k: np.prod(np.linalg.svd(W[:, :, :k], compute_uv=False), axis=-1) for k in orders}


def sali_from_vectors(W):
    """SALI = min(‖ŵ₁ + ŵ₂‖, ‖ŵ₁ − ŵ₂‖) of the first two columns of unit
    vectors ``W`` (M, 2N, K), shape (M,)."""
    w1, w2 = W[:, :, 0], W[:, :, 1]
    return np.minimum(np.linalg.norm(w1 + w2, axis=1), np.linalg.norm(w1 - w2, axis=1))


def gali(model, x0, t_end, tau=0.05, k=(2, 3, 4), method="tm", scheme=None, seed=0,
         deviations=None, t_out=None, progress=None, errors="raise", escape_radius=None,
         checkpoint=None, checkpoint_interval=60.0, **method_options):
    """Generalised alignment indices GALI_k(t) (paper Sect. IV, eqs. 15–18).

    max(k) deviation vectors are evolved and normalised to unit length every
    τ; GALI_k is the volume spanned by the first k of them, computed at the
    output times from the singular values. Regular motion on an N-torus:
    GALI_k ≈ const for k ≤ N and ∝ t^{−2(k−N)} for k > N (eq. 17); chaotic
    motion: exponential decay (eq. 16).

    Parameters
    ----------
    k : int or sequence of int, default (2, 3, 4)
        GALI orders, each in 2..2N.
    deviations : array_like, shape ([M,] 2N, max k), optional
        Linearly independent initial vectors (normalised before use);
        seeded random orthonormal ones by default.

    Other parameters are as in :func:`lyapunov_spectrum`.

    Returns
    -------
    GALIResult
        ``t``, ``gali`` (dict k -> ([M,] n_out)), ``energy_error``.
    """
    orders = _gali_orders(k, model.dim)
    run = Run("gali", model, x0, t_end, tau, method=method, k=orders[-1], renorm="normalize",
              deviations=deviations, seed=seed, t_out=t_out, progress=progress, errors=errors,
              require="unit", method_options=_with_scheme(scheme, method_options),
              options={"k": list(orders)}, escape_radius=escape_radius, checkpoint=checkpoint,
              checkpoint_interval=checkpoint_interval)
    if run.W0.shape[2] < orders[-1]:
        raise ValueError(f"GALI_{orders[-1]} needs {orders[-1]} deviation vectors, "
                         f"{run.W0.shape[2]} were given")

    def record(state):
        return {f"gali_{o}": v for o, v in gali_from_vectors(state.W, orders).items()}

    def build(t, fields, common):
        return GALIResult(**common, gali={o: fields.get(f"gali_{o}") for o in orders},
                          deviations=run._squeeze(run.state.W))

    return run.execute(record, build)


def sali(model, x0, t_end, tau=0.05, method="tm", scheme=None, seed=0, deviations=None,
         t_out=None, progress=None, errors="raise", escape_radius=None, checkpoint=None,
         checkpoint_interval=60.0, **method_options):
    """Smaller alignment index SALI(t) = min(‖ŵ₁ + ŵ₂‖, ‖ŵ₁ − ŵ₂‖).

    Two deviation vectors normalised every τ. SALI → 0 exponentially for
    chaotic orbits and stays away from 0 for regular ones in 2-dof systems
    (Skokos 2001). Parameters as in :func:`gali`.

    Returns
    -------
    SALIResult
    """
    run = Run("sali", model, x0, t_end, tau, method=method, k=2, renorm="normalize",
              deviations=deviations, seed=seed, t_out=t_out, progress=progress, errors=errors,
              require="unit", method_options=_with_scheme(scheme, method_options),
              escape_radius=escape_radius, checkpoint=checkpoint,
              checkpoint_interval=checkpoint_interval)
    if run.W0.shape[2] != 2:
        raise ValueError(f"SALI needs exactly 2 deviation vectors, {run.W0.shape[2]} were given")

    def record(state):
        return {"sali": sali_from_vectors(state.W)}

    def build(t, fields, common):
        return SALIResult(**common, sali=fields.get("sali"), deviations=run._squeeze(run.state.W))

    return run.execute(record, build)

"""Plain integration of orbits and (optionally) their deviation vectors."""

from __future__ import annotations

import numpy as np

from .indicators import _with_scheme
from .results import IntegrationResult
from .runs import Run

__all__ = ["integrate"]


def integrate(model, x0, t_end, tau=0.05, method="tm", scheme=None, deviations=None,
              t_out=None, progress=None, errors="raise", escape_radius=None, checkpoint=None,
              checkpoint_interval=60.0, **method_options):
    """Integrate orbits, and deviation vectors if given, from 0 to ``t_end``.

    The deviation vectors are never renormalised: ``deviations`` of the
    result is the numerical tangent map of the whole run applied to the
    initial vectors (for ``"tm"``, exactly the derivative of the numerical
    orbit map; paper Sect. V.C). Without ``deviations`` no tangent work is
    done at all.

    Parameters
    ----------
    model : Model
    x0 : array_like, shape (2N,) or (M, 2N)
    t_end : float
    tau : float, default 0.05
        Integration step (``"tm"``) or output grid spacing.
    method, scheme : str
        As in :func:`varint.lyapunov_spectrum`.
    deviations : array_like, shape ([M,] 2N, k), optional
        Initial deviation vectors to carry along.
    t_out : None, int or array_like
        Times at which to store the orbit; only t_end by default.
    progress, errors, escape_radius, checkpoint, checkpoint_interval
        As in :func:`varint.lyapunov_spectrum`: progress bar, failure
        handling, escape radius, and the checkpoint file to save to and
        resume from (bitwise).

    Returns
    -------
    IntegrationResult
        ``state`` ([M,] 2N), ``deviations`` ([M,] 2N, k), ``states`` at the
        output times, ``energy_error``.

    Raises
    ------
    IntegrationError
        If an orbit becomes non-finite or escapes, or the deviation vectors
        overflow (it says at what time; the partial result is attached).
        The raw deviation vectors are checked for overflow every 16 steps.
    """
    run = Run("integrate", model, x0, t_end, tau, method=method, k=0, renorm="none",
              deviations=np.zeros((model.dim, 0)) if deviations is None else deviations,
              t_out=1 if t_out is None else t_out, progress=progress, errors=errors,
              method_options=_with_scheme(scheme, method_options), escape_radius=escape_radius,
              checkpoint=checkpoint, checkpoint_interval=checkpoint_interval)

    def record(state):
        return {"states": state.x.copy()}

    def build(t, fields, common):
        return IntegrationResult(**common, states=fields.get("states"),
                                 deviations=run._squeeze(run.state.W))

    return run.execute(record, build)

"""The tangent map (TM) method: ``method="tm"``.

Any registered splitting scheme integrates the orbit and, through the tangent
maps of its drift, kick and corrector flows, the deviation vectors (Skokos &
Gerlach 2010, Sect. V.C, eqs. 46–47 and 53). One step of length τ is one
renormalisation interval.
"""

from __future__ import annotations

import numpy as np
import numba

from . import _kernels as K
from .schemes import get_scheme, stage_arrays

__all__ = ["TangentMapPropagator", "tangent_map_steps"]

_RENORM = {"none": K.RENORM_NONE, "normalize": K.RENORM_NORMALIZE, "qr": K.RENORM_QR}


class TangentMapPropagator:
    """Advance orbits and deviation vectors with the TM method.

    Parameters
    ----------
    model : Model
    tau : float
        Integration step, which is also the renormalisation interval.
    renorm : {"qr", "normalize", "none"}
    scheme : str or SplittingScheme, default "SBAB2C"
        The paper's S_B2^c by default.
    parallel : bool, optional
        Run the orbits of a batch on all cores (numba ``prange``). By
        default, when there is more than one orbit and more than one thread.
    fast_indicators : bool, default False
        Also accumulate MEGNO, FLI and OFLI of every vector after every step
        into ``state.extra["fast_indicators"]`` (shape (M, k, 5), columns as
        :data:`varint._kernels.AUX_LOG` …); needs ``renorm="normalize"``.
    """

    method = "tm"

    def __init__(self, model, tau, renorm, scheme="SBAB2C", parallel=None,
                 fast_indicators=False):
        self.model = model
        self.tau = float(tau)
        self.scheme = get_scheme(scheme)
        self.renorm = renorm
        self.parallel = parallel
        self.fast_indicators = bool(fast_indicators)
        if self.fast_indicators and renorm != "normalize":
            raise ValueError(f"fast_indicators need renorm='normalize', got {renorm!r}")
        self._kinds, self._h, self._hc = stage_arrays(self.scheme, self.tau)
        r = model.escape_radius
        self._escape_r2 = np.inf if r is None else float(r) ** 2

    def describe(self):
        return {"scheme": self.scheme.describe()}

    def _aux(self, state):
        if not self.fast_indicators:
            return np.empty((state.n_orbits, 0, 0))
        if "fast_indicators" not in state.extra:
            # At t = 0: S = 0, so FLI = 0; OFLI is a maximum over steps ≥ 1.
            aux = np.zeros((state.n_orbits, state.k, K.N_AUX))
            aux[:, :, K.AUX_OFLI] = -np.inf
            state.extra["fast_indicators"] = aux
        return state.extra["fast_indicators"]

    def versions(self):
        return {"numba": numba.__version__}

    def advance(self, state, n):
        """Advance every active orbit of ``state`` by ``n`` steps."""
        m = state.n_orbits
        parallel = K.use_parallel(self.parallel, m)
        model = self.model
        kernel = K.batch_kernel(model.n_dof, state.k, model.bandwidth, parallel,
                                self.fast_indicators)
        counters = np.zeros((m, len(K.COUNTERS)), dtype=np.int64)
        done = np.zeros(m, dtype=np.int64)
        was_active = state.status == K.OK
        kernel(state.x, state.W, state.acc_m, state.acc_e, int(n), self._kinds, self._h,
               self._hc, model.inverse_mass, model.params, model.bandwidth,
               model.grad_kernel, model.hess_kernel, model.third_kernel,
               _RENORM[self.renorm], self._escape_r2, counters, state.status, done,
               self._aux(state), state.step * self.tau, self.tau)
        state.after_kernel(n, was_active, done, counters, K.COUNTERS)


def tangent_map_steps(model, x, W=None, tau=0.05, n_steps=1, scheme="SBAB2C"):
    """Low-level: ``n_steps`` steps of the numerical map S and its tangent
    map TS, without renormalisation; τ may be negative (S(−τ) is the inverse
    of S(τ) for the symmetric schemes).

    Parameters
    ----------
    model : Model
    x : array_like, shape (2N,)
    W : array_like, shape (2N, k), optional
        Deviation vectors; none by default.
    tau : float
        Non-zero step.
    n_steps : int
    scheme : str or SplittingScheme

    Returns
    -------
    x : ndarray, shape (2N,)
    W : ndarray, shape (2N, k)
    """
    x = np.array(x, dtype=np.float64).reshape(1, -1)
    if x.shape[1] != model.dim or not np.isfinite(x).all():
        raise ValueError(f"x must be a finite state of length {model.dim}")
    if not (np.isfinite(tau) and tau != 0):
        raise ValueError(f"tau must be finite and non-zero, got {tau!r}")
    W = np.zeros((model.dim, 0)) if W is None else np.array(W, dtype=np.float64)
    W = W.reshape(model.dim, -1)[None].copy()
    k = W.shape[2]
    kinds, h, hc = stage_arrays(get_scheme(scheme), float(tau))
    status = np.zeros(1, dtype=np.int64)
    done = np.zeros(1, dtype=np.int64)
    r = model.escape_radius
    kernel = K.batch_kernel(model.n_dof, k, model.bandwidth, False)
    kernel(x, W, np.ones((1, k)), np.zeros((1, k), dtype=np.int64), int(n_steps), kinds, h,
           hc, model.inverse_mass, model.params, model.bandwidth, model.grad_kernel,
           model.hess_kernel, model.third_kernel, K.RENORM_NONE,
           np.inf if r is None else float(r) ** 2,
           np.zeros((1, len(K.COUNTERS)), dtype=np.int64), status, done,
           np.empty((1, 0, 0)), 0.0, float(tau))
    if status[0] != K.OK:
        raise FloatingPointError(f"the map failed after {done[0]} steps (status {status[0]})")
    return x[0], W[0]

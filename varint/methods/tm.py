"""The tangent map (TM) method: ``method="tm"``.

Any registered splitting scheme integrates the orbit and, through the tangent
maps of its drift, kick and corrector flows, the deviation vectors (Skokos &
Gerlach 2010, Sect. V.C, eqs. 46–47 and 53). One step of length τ is one
renormalisation interval.
"""

from __future__ import annotations

import numpy as np
import numba

from ..kernels import tm as K
from ..protocol import COUNTERS, Renorm, Status
from ..schemes import get_scheme, stage_arrays, stage_times
from . import method_options

__all__ = ["TangentMapPropagator", "tangent_map_steps"]


class TangentMapPropagator:
    """Advance orbits and deviation vectors with the TM method.

    Parameters
    ----------
    model : Model
    tau : float
        Integration step, which is also the renormalisation interval.
    renorm : Renorm
    accumulator : Accumulator, optional
        Updated after every step (see :class:`varint.protocol.Accumulator`).
    scheme : str or SplittingScheme, default "SBAB2C"
        The paper's S_B2^c by default.
    parallel : bool, optional
        Run the orbits of a batch on all cores (numba ``prange``). By
        default, when there is more than one orbit and more than one thread.
    """

    method = "tm"
    OPTIONS = ("scheme", "parallel")

    def __init__(self, model, tau, renorm, accumulator=None, **options):
        opts = method_options(self.method, options, self.OPTIONS)
        self.model = model
        self.tau = float(tau)
        self.scheme = get_scheme(opts.get("scheme", "SBAB2C"))
        self.renorm = Renorm.parse(renorm)
        self.parallel = opts.get("parallel")
        self.accumulator = accumulator
        self._kinds, self._h, self._hc = stage_arrays(self.scheme, self.tau)
        # A time-dependent V: the stage times and ∂_tV kernel (kernels/tm.py).
        self._time = (stage_times(self.scheme), model.time_kernel) if model.time_dependent else ()
        r = model.escape_radius
        self._escape_r2 = np.inf if r is None else float(r) ** 2

    def describe(self):
        return {"scheme": self.scheme.describe()}

    def versions(self):
        return {"numba": numba.__version__}

    def _accumulator(self, state):
        acc = self.accumulator
        if acc is None:
            return K.no_accumulator, np.empty((state.n_orbits, 0, 0)), False
        return acc.update, state.extra[acc.key], acc.needs_flow

    def advance(self, state, n):
        """Advance every active orbit of ``state`` by ``n`` steps."""
        m = state.n_orbits
        model = self.model
        update, aux, flow = self._accumulator(state)
        kernel = K.batch_kernel(model.n_dof, state.k, model.bandwidth,
                                K.use_parallel(self.parallel, m), flow, model.time_dependent)
        time = self._time + (state.time_momentum(),) if self._time else ()
        counters = np.zeros((m, len(COUNTERS)), dtype=np.int64)
        done = np.zeros(m, dtype=np.int64)
        was_active = state.status == Status.OK
        kernel(state.x, state.W, state.acc_m, state.acc_e, int(n), self._kinds, self._h,
               self._hc, model.inverse_mass, model.params, model.bandwidth,
               model.grad_kernel, model.hess_kernel, model.third_kernel, int(self.renorm),
               self._escape_r2, counters, state.status, done, update, aux,
               state.step, self.tau, *time)
        state.after_kernel(n, was_active, done, counters, COUNTERS)


def tangent_map_steps(model, x, W=None, tau=0.05, n_steps=1, scheme="SBAB2C"):
    """Low-level: ``n_steps`` steps of the numerical map S and its tangent
    map TS, without renormalisation; τ may be negative (S(−τ) is the inverse
    of S(τ) for the symmetric schemes). A time-dependent V starts at t = 0.

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

    Raises
    ------
    FloatingPointError
        If the map fails (the message gives the step and the reason).
    """
    from ..protocol import REASONS

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
    time = ((stage_times(get_scheme(scheme)), model.time_kernel, np.zeros(1))
            if model.time_dependent else ())
    kernel = K.batch_kernel(model.n_dof, k, model.bandwidth, False, False, bool(time))
    kernel(x, W, np.ones((1, k)), np.zeros((1, k), dtype=np.int64), int(n_steps), kinds, h,
           hc, model.inverse_mass, model.params, model.bandwidth, model.grad_kernel,
           model.hess_kernel, model.third_kernel, int(Renorm.NONE),
           np.inf if r is None else float(r) ** 2,
           np.zeros((1, len(COUNTERS)), dtype=np.int64), status, done,
           K.no_accumulator, np.empty((1, 0, 0)), 0, float(tau), *time)
    if status[0] != Status.OK:
        raise FloatingPointError(f"the map failed after {done[0]} steps: "
                                 f"{REASONS.get(Status(status[0]), status[0])}")
    return x[0], W[0]

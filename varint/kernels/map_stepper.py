"""The compiled stepper of map models (:mod:`varint.models.maps`): orbits
and deviation vectors advanced by the map x' = F(x) and its tangent map
w' = DF(x) w, with the end-of-interval checks and renormalisation every
stepper shares (:mod:`varint.kernels.checks`).

One interval τ is ``iters`` iterations (τ = 1 by default); after it the
state is checked (:func:`~varint.kernels.checks.state_status`: a map's
components need not split into q and p), the vectors are renormalised and
the indicator's accumulator is updated at t = (step + 1)·τ, exactly as the
TM stepper does for flows, so every indicator reads the same run state.
The model's kernels are numba dispatchers passed as arguments and compiled
into the stepper; small sizes are compile-time constants
(:func:`varint.kernels.tm.specialised_sizes`' rule).
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
from numba import njit, prange

from ..protocol import Renorm, Status
from .checks import CHECK_EVERY, renormalize, state_status, tangent_overflow

__all__ = ["map_batch", "batch_kernel", "advance_map", "COUNTERS"]

_OK = int(Status.OK)
_OVERFLOW = int(Status.TANGENT_OVERFLOW)
_NONE = int(Renorm.NONE)

#: Work counted per orbit: evaluations of F, of DF, and products DF·W.
COUNTERS = ("map_evaluations", "jacobians", "tangent_products")

#: Largest dimension and k for which sizes are compile-time constants.
SPECIALISE_D, SPECIALISE_K = 16, 32


@njit(inline="always")
def advance_map(x, xn, par, periods, iterate, d):
    """One iteration x ← F(x) in place (``xn`` is work space), each
    component of positive period P reduced into [0, P)."""
    iterate(x, par, xn)
    for i in range(d):
        v = xn[i]
        p = periods[i]
        if p > 0.0:
            v -= p * math.floor(v / p)
        x[i] = v


def _make_map_orbit(D_C, K_C):
    """The one-orbit map stepper; sizes are constants when ≥ 0, else read
    from the arrays."""

    @njit
    def map_orbit(x, W, acc_m, acc_e, n_steps, iters, par, periods, iterate, jacobian, renorm,
                  escape_r2, counters, accumulate, aux, step0, tau):
        d = D_C if D_C >= 0 else x.shape[0]
        k = K_C if K_C >= 0 else W.shape[1]
        xn = np.empty(d)
        J = np.zeros((d, d))
        col = np.empty(d)
        r = np.empty(k if aux.shape[0] > 0 else 0)   # stretching, for the accumulator
        no_flow = np.empty(0)                        # a map has no phase-space velocity
        tangent = k > 0
        for s in range(n_steps):
            for _ in range(iters):
                if tangent:
                    # w' = DF(x) w at the point before the iteration.
                    jacobian(x, par, J)
                    counters[1] += 1
                    counters[2] += 1
                    for j in range(k):
                        for i in range(d):
                            col[i] = W[i, j]
                        for i in range(d):
                            acc = 0.0
                            for m in range(d):
                                acc += J[i, m] * col[m]
                            W[i, j] = acc
                advance_map(x, xn, par, periods, iterate, d)
                counters[0] += 1
            status = state_status(x, d, escape_r2)
            if status != _OK:
                return status, s
            if renorm != _NONE:
                status = renormalize(W, renorm, acc_m, acc_e, r, d, k)
                if status != _OK:
                    return status, s
                if aux.shape[0] > 0:
                    # The time from the integer step, so it does not depend on chunking.
                    accumulate(aux, r, x, W, no_flow, (step0 + s + 1) * tau)
            elif tangent and s % CHECK_EVERY == CHECK_EVERY - 1:
                if tangent_overflow(W):
                    return _OVERFLOW, s
        if renorm == _NONE and tangent and tangent_overflow(W):
            return _OVERFLOW, n_steps - 1
        return _OK, n_steps

    return map_orbit


@lru_cache(maxsize=None)
def map_batch(d, k, parallel):
    """The batch stepper for dimension ``d`` and ``k`` vectors (−1 for
    both: sizes read at run time): advances every orbit of ``X`` (M, d)
    whose ``status`` is OK by ``n_steps`` intervals of ``iters``
    iterations, in parallel over orbits if ``parallel``; ``done[m]``
    receives the intervals orbit m completed and ``status[m]`` its status.
    A failed orbit is left as it was when the failure was detected."""
    map_orbit = _make_map_orbit(d, k)

    @njit(parallel=parallel)
    def batch(X, W, acc_m, acc_e, n_steps, iters, par, periods, iterate, jacobian, renorm,
              escape_r2, counters, status, done, accumulate, aux, step0, tau):
        for m in prange(X.shape[0]):
            if status[m] != _OK:
                done[m] = 0
                continue
            st, steps = map_orbit(X[m], W[m], acc_m[m], acc_e[m], n_steps, iters, par, periods,
                                  iterate, jacobian, renorm, escape_r2, counters[m],
                                  accumulate, aux[m], step0, tau)
            status[m] = st
            done[m] = steps

    return batch


def batch_kernel(d, k, parallel):
    """:func:`map_batch` with the sizes as constants when they are small."""
    if d <= SPECIALISE_D and k <= SPECIALISE_K:
        return map_batch(d, k, parallel)
    return map_batch(-1, -1, parallel)

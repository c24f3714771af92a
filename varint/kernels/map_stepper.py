"""The step body of map models (:mod:`varint.models.maps`): orbits and
deviation vectors advanced by the map x' = F(x) and its tangent map
w' = DF(x) w.

One interval τ is ``iters`` iterations (τ = 1 by default); the end of the
interval is the stepping skeleton's (:mod:`varint.kernels.interval`),
exactly as for flows, with the state checked by
:func:`~varint.kernels.checks.state_status` (a map's components need not
split into q and p), so every indicator reads the same run state. The
model's kernels are compiled into the stepper; small sizes are
compile-time constants.
"""

from __future__ import annotations

import math
from collections import namedtuple
from functools import cache

import numpy as np
from numba import njit

from .checks import state_status
from .inlining import into_kernels
from .interval import StepBody, batch_loop, no_accumulator, orbit_record

__all__ = ["map_body", "map_batch", "batch_kernel", "advance_map", "MapOrbit", "MapSetup",
           "COUNTERS"]

#: Work counted per orbit: evaluations of F, of DF, and products DF·W.
COUNTERS = ("map_evaluations", "jacobians", "tangent_products")

#: Largest dimension and k for which sizes are compile-time constants.
SPECIALISE_D, SPECIALISE_K = 16, 32

#: One orbit's record (:mod:`varint.kernels.interval`).
MapOrbit = orbit_record("MapOrbit")

#: What a call reads: iterations per interval, the map's parameters and the
#: period of each component (0: none).
MapSetup = namedtuple("MapSetup", ("iters", "par", "periods"))

_Work = namedtuple("_Work", ("d", "k", "xe", "xn", "J", "col"))


@njit(inline=into_kernels)
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


@cache
def map_body(D_C, K_C, iterate, jacobian):
    """The step body of the map ``iterate`` with tangent map ``jacobian``;
    sizes are constants when ≥ 0, else read from the arrays. An interval is
    ``setup.iters`` iterations, each w' = DF(x) w at the point before it,
    then x' = F(x)."""

    @njit(inline="always")
    def begin(state, setup, call):
        d = D_C if D_C >= 0 else state.x.shape[0]
        k = K_C if K_C >= 0 else state.W.shape[1]
        return _Work(d, k, state.x, np.empty(d), np.zeros((d, d)), np.empty(d)), 0

    @njit(inline="always")
    def step(state, setup, ws, carry, s, call):
        x, W, counters = state.x, state.W, state.counters
        d, k, xn, J, col = ws.d, ws.k, ws.xn, ws.J, ws.col
        for _ in range(setup.iters):
            if k > 0:
                jacobian(x, setup.par, J)
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
            advance_map(x, xn, setup.par, setup.periods, iterate, d)
            counters[0] += 1
        return 0, carry

    @njit(inline="always")
    def check(state, setup, ws, xe, call):
        return state_status(xe, ws.d, call.escape_r2)

    # A map has no phase-space velocity: the accumulator gets an empty flow.
    return StepBody(begin=begin, step=step, check=check)


@cache
def map_batch(d, k, parallel, iterate, jacobian, accumulate=no_accumulator):
    """The batch stepper of the map ``iterate``/``jacobian`` for dimension
    ``d`` and ``k`` vectors (−1 for both: read at run time):
    ``batch(states, setup, call, status, done)``
    (:func:`varint.kernels.interval.batch_loop`) with a batch of
    :class:`MapOrbit` and a :class:`MapSetup`; ``done[m]`` receives the
    intervals orbit m completed. A failed orbit is left as it was when the
    failure was detected."""
    return batch_loop(map_body(d, k, iterate, jacobian), parallel, accumulate)


def batch_kernel(d, k, parallel, iterate, jacobian, accumulate=no_accumulator):
    """:func:`map_batch` with the sizes as constants when they are small."""
    if d <= SPECIALISE_D and k <= SPECIALISE_K:
        return map_batch(d, k, parallel, iterate, jacobian, accumulate)
    return map_batch(-1, -1, parallel, iterate, jacobian, accumulate)

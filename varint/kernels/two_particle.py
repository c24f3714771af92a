"""Compiled steppers of the two-particle method (:mod:`varint.methods.two_particle`):
deviation vectors estimated from the separations of k neighbouring orbits
instead of the variational equations (Benettin, Galgani & Strelcyn 1976).

Every interval τ the reference orbit x and its neighbours y_j are advanced
by the same integrator — one step of a splitting scheme for a flow (the TM
method's own stepper without vectors), or ``iters`` iterations of a map —
and the separations D_j = y_j − x (reduced modulo a map's periods) become
the deviation vectors,

    w_j ← D_j · c_j / s_j,

with s_j = |y_j − x| at the interval's start and c_j the vector's length
there (1 for renormalised vectors; the raw length when nothing is
renormalised). They are then renormalised, their stretching accumulated and
the indicator's accumulator updated exactly as by every other stepper (the
stepping skeleton's end of an interval, :mod:`varint.kernels.interval`),
and a neighbour is put back at distance d0 along its vector,
y_j = x + d0 ŵ_j, every interval or, with a threshold ``d_max`` > 0, only
once s_j exceeds it.

For a flow the reference orbit of a block of intervals is integrated first,
in one call of the TM stepper that records it after every step (as the TDH
methods do, :mod:`varint.tdh`), so it reuses its forces between steps as the
TM method does; the neighbours, reset every interval, take one step at a
time.
"""

from __future__ import annotations

import math
from collections import namedtuple
from functools import cache

import numpy as np
from numba import njit

from ..protocol import Renorm, Status
from . import tm as K
from .checks import state_status
from .inlining import into_kernels
from .interval import Call, StepBody, batch_loop, no_accumulator, orbit_record
from .map_stepper import advance_map

__all__ = ["flow_body", "map_body", "flow_batch", "map_batch", "TPOrbit", "TPFlowSetup",
           "TPMapSetup"]

_OK = int(Status.OK)
_NONE = int(Renorm.NONE)
#: Size (in float64 values) of the record of the reference orbit per block.
_BLOCK_VALUES = 1 << 16


@njit(inline=into_kernels, error_model="numpy")
def _place(x, Y, W, d0, periods, d, k, raw, reset, d_max):
    """Put neighbour j back at x + d0 ŵ_j where it must be (every interval,
    or once its separation, modulo the periods, exceeds ``d_max`` > 0).
    ``raw``: the vectors are not renormalised, ŵ_j = w_j / |w_j|."""
    for j in range(k):
        if not reset:
            s = 0.0
            for i in range(d):
                v = Y[j, i] - x[i]
                p = periods[i]
                if p > 0.0:
                    v -= p * math.floor(v / p + 0.5)
                s += v * v
            if math.sqrt(s) <= d_max:
                continue
        c = 1.0
        if raw:
            c = 0.0
            for i in range(d):
                c += W[i, j] * W[i, j]
            c = math.sqrt(c)
        for i in range(d):
            Y[j, i] = x[i] + d0 * W[i, j] / c


@njit(inline=into_kernels, error_model="numpy")
def _separations(x, Y, W, start, scale, periods, d, k):
    """w_j ← D_j · scale_j / start_j with D_j = y_j − x, each component of
    positive period P reduced into [−P/2, P/2)."""
    for j in range(k):
        f = scale[j] / start[j]
        for i in range(d):
            v = Y[j, i] - x[i]
            p = periods[i]
            if p > 0.0:
                v -= p * math.floor(v / p + 0.5)
            W[i, j] = v * f


@njit(inline=into_kernels, error_model="numpy")
def _starts(x, Y, W, start, scale, periods, d, k, raw):
    """|y_j − x| (modulo the periods) and the vectors' lengths (1 unless
    ``raw``) at the start of an interval."""
    for j in range(k):
        s = 0.0
        for i in range(d):
            v = Y[j, i] - x[i]
            p = periods[i]
            if p > 0.0:
                v -= p * math.floor(v / p + 0.5)
            s += v * v
        start[j] = math.sqrt(s)
        c = 1.0
        if raw:
            c = 0.0
            for i in range(d):
                c += W[i, j] * W[i, j]
            c = math.sqrt(c)
        scale[j] = c


#: One orbit's record (:mod:`varint.kernels.interval`): ``Y`` (k, 2N), the
#: neighbours; ``pt`` (1,), the orbit's momentum conjugate to time (a
#: time-dependent V; (0,) otherwise).
TPOrbit = orbit_record("TPOrbit", ("Y", "pt"))

#: What a call of the flow stepper reads: the TM stepper's tables
#: (:class:`varint.kernels.tm.TMSetup`), the neighbours' distance d0 and the
#: threshold d_max (≤ 0: reset every interval).
TPFlowSetup = namedtuple("TPFlowSetup", ("kinds", "h", "hc", "minv", "par", "bw", "ctime", "d0",
                                         "d_max"))

#: What a call of the map stepper reads: iterations per interval, the map's
#: parameters and periods, d0 and d_max.
TPMapSetup = namedtuple("TPMapSetup", ("iters", "par", "periods", "d0", "d_max"))

_FlowWork = namedtuple("_FlowWork", ("n", "k", "d", "xe", "block", "rec", "x0", "orbit_setup",
                                     "no_W", "no_m", "no_e", "no_aux", "one_rec", "no_periods",
                                     "start", "scale", "flow", "q", "g", "pl", "pt_y"))
_MapWork = namedtuple("_MapWork", ("d", "k", "xe", "xn", "start", "scale"))


@cache
def flow_body(N_C, BW_C, kernels, FLOW, TIME):
    """The two-particle step body of a flow (N and the bandwidth constants
    when ≥ 0) with the model ``kernels`` (:func:`varint.kernels.tm.model_kernels`);
    ``FLOW``: the accumulator reads the phase-space velocity; ``TIME``: a
    time-dependent V (see :func:`varint.kernels.tm.tm_body`)."""
    record = K.orbit_kernel(N_C, BW_C, kernels, TIME)
    grad = kernels[0]

    @njit(inline="always", error_model="numpy")
    def begin(state, setup, call):
        n = state.x.shape[0] // 2
        d = 2 * n
        k = state.W.shape[1]
        block = max(1, min(call.n_steps, _BLOCK_VALUES // d))
        orbit_setup = K.TMSetup(setup.kinds, setup.h, setup.hc, setup.minv, setup.par,
                                setup.bw, setup.ctime)
        ws = _FlowWork(n, k, d, np.empty(d), block,
                       np.empty((block, d)),     # the reference orbit through a block
                       np.empty(d),              # ... and at its start
                       orbit_setup,
                       np.empty((d, 0)), np.ones(0), np.zeros(0, dtype=np.int64),
                       np.empty((0, 0)),
                       np.empty((1, d)),         # a neighbour's one step, recorded and unused
                       np.zeros(d),
                       np.empty(k), np.empty(k), np.empty(d if FLOW else 0),
                       np.empty(n), np.empty(n), setup.par.copy(),
                       np.zeros(1))              # the neighbours' p_t, which nothing needs
        # The block: its first interval, the next block's, the intervals the
        # reference orbit completed and its status.
        return ws, (0, 0, 0, _OK)

    @njit(inline="always", error_model="numpy")
    def step(state, setup, ws, carry, s, call):
        x, W, Y, counters = state.x, state.W, state.Y, state.counters
        n, k, d, rec, x0 = ws.n, ws.k, ws.d, ws.rec, ws.x0
        first, following, complete, orbit_status = carry
        raw = call.renorm == _NONE
        if s == following:
            # The reference through the next block, recorded after every step.
            nb = min(ws.block, call.n_steps - s)
            for i in range(d):
                x0[i] = x[i]
            orbit_status, steps = record(
                K.TMOrbit(x, ws.no_W, ws.no_m, ws.no_e, ws.no_aux, counters, state.pt, rec),
                ws.orbit_setup, Call(nb, call.step0 + s, call.tau, _NONE, call.escape_r2))
            complete = steps if orbit_status != _OK else nb
            first, following = s, s + nb
        i_block = s - first
        if i_block == complete:
            return orbit_status, (first, following, complete, orbit_status)
        xa = x0 if i_block == 0 else rec[i_block - 1]
        _starts(xa, Y, W, ws.start, ws.scale, ws.no_periods, d, k, raw)
        for j in range(k):
            st, _ = record(
                K.TMOrbit(Y[j], ws.no_W, ws.no_m, ws.no_e, ws.no_aux, counters, ws.pt_y,
                          ws.one_rec),
                ws.orbit_setup, Call(1, call.step0 + s, call.tau, _NONE, call.escape_r2))
            if st != _OK:
                for i in range(d):
                    x[i] = xa[i]
                return st, (first, following, complete, orbit_status)
        xe = ws.xe
        for i in range(d):
            xe[i] = rec[i_block, i]
        if FLOW:
            q, g = ws.q, ws.g
            for i in range(n):
                q[i] = xe[i]
            if TIME:
                ws.pl[ws.pl.shape[0] - 1] = float(call.step0 + s + 1) * call.tau
            grad(q, ws.pl, g)
            counters[0] += 1
            for i in range(n):
                ws.flow[i] = setup.minv[i] * xe[n + i]
                ws.flow[n + i] = -g[i]
        _separations(xe, Y, W, ws.start, ws.scale, ws.no_periods, d, k)
        return _OK, (first, following, complete, orbit_status)

    @njit(inline="always")
    def flow(state, setup, ws, carry, xe, s, call, out):
        for i in range(ws.d):
            out[i] = ws.flow[i]
        return carry

    @njit(inline="always", error_model="numpy")
    def after(state, setup, ws, s, call):
        raw = call.renorm == _NONE
        _place(ws.xe, state.Y, state.W, setup.d0, ws.no_periods, ws.d, ws.k, raw,
               setup.d_max <= 0.0, setup.d_max)
        return _OK

    # No end-of-interval check: the reference and the neighbours were checked
    # as they were advanced.
    return StepBody(begin=begin, step=step, flow=flow, after=after, error_model="numpy")


@cache
def map_body(iterate):
    """The two-particle step body of the map ``iterate``."""

    @njit(inline="always", error_model="numpy")
    def begin(state, setup, call):
        d = state.x.shape[0]
        k = state.W.shape[1]
        return _MapWork(d, k, state.x, np.empty(d), np.empty(k), np.empty(k)), 0

    @njit(inline="always", error_model="numpy")
    def step(state, setup, ws, carry, s, call):
        x, W, Y, counters = state.x, state.W, state.Y, state.counters
        d, k, xn, periods = ws.d, ws.k, ws.xn, setup.periods
        _starts(x, Y, W, ws.start, ws.scale, periods, d, k, call.renorm == _NONE)
        for _ in range(setup.iters):
            advance_map(x, xn, setup.par, periods, iterate, d)
            counters[0] += 1
            for j in range(k):
                advance_map(Y[j], xn, setup.par, periods, iterate, d)
                counters[0] += 1
        # The orbit and its neighbours are checked before they become vectors.
        status = state_status(x, d, call.escape_r2)
        for j in range(k):
            if status == _OK:
                status = state_status(Y[j], d, call.escape_r2)
        if status == _OK:
            _separations(x, Y, W, ws.start, ws.scale, periods, d, k)
        return status, carry

    @njit(inline="always", error_model="numpy")
    def after(state, setup, ws, s, call):
        raw = call.renorm == _NONE
        _place(state.x, state.Y, state.W, setup.d0, setup.periods, ws.d, ws.k, raw,
               setup.d_max <= 0.0, setup.d_max)
        return _OK

    return StepBody(begin=begin, step=step, after=after, error_model="numpy")


@cache
def flow_batch(n, bw, parallel, kernels, accumulate=no_accumulator, flow=False, time=False):
    """The batch two-particle stepper of a flow for N = ``n`` and bandwidth
    ``bw`` (−1 for both: read at run time) with the model ``kernels``:
    ``batch(states, setup, call, status, done)``
    (:func:`varint.kernels.interval.batch_loop`) with a batch of
    :class:`TPOrbit` and a :class:`TPFlowSetup`."""
    body = flow_body(n, bw, kernels, bool(flow), bool(time))
    return batch_loop(body, parallel, accumulate, flow)


@cache
def map_batch(parallel, iterate, accumulate=no_accumulator):
    """The batch two-particle stepper of a map (as :func:`flow_batch`, with
    a :class:`TPMapSetup`)."""
    return batch_loop(map_body(iterate), parallel, accumulate)

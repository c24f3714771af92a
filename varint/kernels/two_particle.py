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
the indicator's accumulator updated exactly as by every other stepper
(:mod:`varint.kernels.checks`), and a neighbour is put back at distance d0
along its vector, y_j = x + d0 ŵ_j, every interval or, with a threshold
``d_max`` > 0, only once s_j exceeds it.

For a flow the reference orbit of a block of intervals is integrated first,
in one call of the TM stepper that records it after every step (as the TDH
methods do, :mod:`varint.tdh`), so it reuses its forces between steps as the
TM method does; the neighbours, reset every interval, take one step at a
time.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
from numba import njit, prange

from ..protocol import Renorm, Status
from . import tm as K
from .checks import CHECK_EVERY, renormalize, state_status, tangent_overflow
from .map_stepper import advance_map

__all__ = ["flow_batch", "map_batch"]

_OK = int(Status.OK)
_OVERFLOW = int(Status.TANGENT_OVERFLOW)
_NONE = int(Renorm.NONE)
#: Size (in float64 values) of the record of the reference orbit per block.
_BLOCK_VALUES = 1 << 16


@njit(inline="always", error_model="numpy")
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


@njit(inline="always", error_model="numpy")
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


@njit(inline="always", error_model="numpy")
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


@njit(inline="always", error_model="numpy")
def _end_of_interval(x, Y, W, acc_m, acc_e, start, scale, periods, d, k, renorm, r, aux,
                     accumulate, flow, t, d0, d_max, s):
    """The separations as vectors, their renormalisation and accumulator,
    and the neighbours put back; returns a status."""
    _separations(x, Y, W, start, scale, periods, d, k)
    raw = renorm == _NONE
    if not raw:
        status = renormalize(W, renorm, acc_m, acc_e, r, d, k)
        if status != _OK:
            return status
        if aux.shape[0] > 0:
            accumulate(aux, r, x, W, flow, t)
    elif k > 0 and s % CHECK_EVERY == CHECK_EVERY - 1 and tangent_overflow(W):
        return _OVERFLOW
    _place(x, Y, W, d0, periods, d, k, raw, d_max <= 0.0, d_max)
    return _OK


def _make_flow_orbit(N_C, BW_C, FLOW, TIME):
    """The one-orbit two-particle stepper of a flow (N and the bandwidth
    constants when ≥ 0); ``FLOW``: the accumulator reads the phase-space
    velocity; ``TIME``: a time-dependent V (arguments as for
    :func:`varint.kernels.tm.tm_batch`)."""
    record = K.orbit_kernel(N_C, BW_C, TIME)

    @njit(error_model="numpy")
    def tp_orbit(x, W, acc_m, acc_e, Y, n_steps, kinds, h, hc, minv, par, bw_rt, grad, hess,
                 third, renorm, escape_r2, d0, d_max, counters, accumulate, aux, step0, tau,
                 ctime=None, dtime=None, pt=None):
        n = x.shape[0] // 2
        d = 2 * n
        k = W.shape[1]
        block = max(1, min(n_steps, _BLOCK_VALUES // d))
        rec = np.empty((block, d))
        x0 = np.empty(d)
        no_W, no_m, no_e = np.empty((d, 0)), np.ones(0), np.zeros(0, dtype=np.int64)
        no_aux = np.empty((0, 0))
        one_rec = np.empty((1, d))   # a neighbour's one step, recorded and unused
        no_periods = np.zeros(d)
        start = np.empty(k)
        scale = np.empty(k)
        r = np.empty(k if aux.shape[0] > 0 else 0)
        flow = np.empty(d if FLOW else 0)
        q = np.empty(n)
        g = np.empty(n)
        pl = par.copy()
        pt_y = np.zeros(1)        # the neighbours' p_t, which nothing needs
        raw = renorm == _NONE
        done = 0
        while done < n_steps:
            nb = min(block, n_steps - done)
            for i in range(d):
                x0[i] = x[i]
            # The reference through the block, recorded after every step.
            if TIME:
                status, steps = record(x, no_W, no_m, no_e, nb, kinds, h, hc, minv, par, bw_rt,
                                       grad, hess, third, _NONE, escape_r2, counters, rec,
                                       K.no_accumulator, no_aux, step0 + done, tau, ctime,
                                       dtime, pt)
            else:
                status, steps = record(x, no_W, no_m, no_e, nb, kinds, h, hc, minv, par, bw_rt,
                                       grad, hess, third, _NONE, escape_r2, counters, rec,
                                       K.no_accumulator, no_aux, step0 + done, tau)
            complete = steps if status != _OK else nb
            for s in range(complete):
                xa = x0 if s == 0 else rec[s - 1]
                xe = rec[s]
                _starts(xa, Y, W, start, scale, no_periods, d, k, raw)
                for j in range(k):
                    if TIME:
                        st, _ = record(Y[j], no_W, no_m, no_e, 1, kinds, h, hc, minv, par,
                                       bw_rt, grad, hess, third, _NONE, escape_r2, counters,
                                       one_rec, K.no_accumulator, no_aux, step0 + done + s, tau,
                                       ctime, dtime, pt_y)
                    else:
                        st, _ = record(Y[j], no_W, no_m, no_e, 1, kinds, h, hc, minv, par,
                                       bw_rt, grad, hess, third, _NONE, escape_r2, counters,
                                       one_rec, K.no_accumulator, no_aux, step0 + done + s, tau)
                    if st != _OK:
                        for i in range(d):
                            x[i] = xa[i]
                        return st, done + s
                if FLOW:
                    for i in range(n):
                        q[i] = xe[i]
                    if TIME:
                        pl[pl.shape[0] - 1] = float(step0 + done + s + 1) * tau
                    grad(q, pl, g)
                    counters[0] += 1
                    for i in range(n):
                        flow[i] = minv[i] * xe[n + i]
                        flow[n + i] = -g[i]
                st = _end_of_interval(xe, Y, W, acc_m, acc_e, start, scale, no_periods, d, k,
                                      renorm, r, aux, accumulate, flow,
                                      (step0 + done + s + 1) * tau, d0, d_max, done + s)
                if st != _OK:
                    for i in range(d):
                        x[i] = xe[i]
                    return st, done + s
            if status != _OK:
                return status, done + complete
            done += nb
        if raw and k > 0 and tangent_overflow(W):
            return _OVERFLOW, n_steps - 1
        return _OK, n_steps

    return tp_orbit


@lru_cache(maxsize=None)
def flow_batch(n, bw, parallel, flow=False, time=False):
    """The batch two-particle stepper of a flow for N = ``n`` and bandwidth
    ``bw`` (−1 for both: read at run time): advances every orbit of ``X``
    (M, 2N) whose ``status`` is OK, with its neighbours ``Y`` (M, k, 2N) and
    vectors ``W`` (M, 2N, k), by ``n_steps`` intervals; ``done`` and
    ``status`` as for :func:`varint.kernels.tm.tm_batch`, and the same
    ``ctime``, ``dtime``, ``pt`` after ``tau`` with ``time``."""
    tp_orbit = _make_flow_orbit(n, bw, flow, time)

    @njit(parallel=parallel, error_model="numpy")
    def batch(X, W, acc_m, acc_e, Y, n_steps, kinds, h, hc, minv, par, bw_rt, grad, hess, third,
              renorm, escape_r2, d0, d_max, counters, status, done, accumulate, aux, step0, tau,
              ctime=None, dtime=None, pt=None):
        for m in prange(X.shape[0]):
            if status[m] != _OK:
                done[m] = 0
                continue
            if time:
                st, steps = tp_orbit(X[m], W[m], acc_m[m], acc_e[m], Y[m], n_steps, kinds, h, hc,
                                     minv, par, bw_rt, grad, hess, third, renorm, escape_r2, d0,
                                     d_max, counters[m], accumulate, aux[m], step0, tau, ctime,
                                     dtime, pt[m:m + 1])
            else:
                st, steps = tp_orbit(X[m], W[m], acc_m[m], acc_e[m], Y[m], n_steps, kinds, h, hc,
                                     minv, par, bw_rt, grad, hess, third, renorm, escape_r2, d0,
                                     d_max, counters[m], accumulate, aux[m], step0, tau)
            status[m] = st
            done[m] = steps

    return batch


def _make_map_orbit():
    @njit(error_model="numpy")
    def tp_map_orbit(x, W, acc_m, acc_e, Y, n_steps, iters, par, periods, iterate, renorm,
                     escape_r2, d0, d_max, counters, accumulate, aux, step0, tau):
        d = x.shape[0]
        k = W.shape[1]
        xn = np.empty(d)
        start = np.empty(k)
        scale = np.empty(k)
        r = np.empty(k if aux.shape[0] > 0 else 0)
        no_flow = np.empty(0)
        raw = renorm == _NONE
        for s in range(n_steps):
            _starts(x, Y, W, start, scale, periods, d, k, raw)
            for _ in range(iters):
                advance_map(x, xn, par, periods, iterate, d)
                counters[0] += 1
                for j in range(k):
                    advance_map(Y[j], xn, par, periods, iterate, d)
                    counters[0] += 1
            status = state_status(x, d, escape_r2)
            for j in range(k):
                if status == _OK:
                    status = state_status(Y[j], d, escape_r2)
            if status != _OK:
                return status, s
            status = _end_of_interval(x, Y, W, acc_m, acc_e, start, scale, periods, d, k, renorm,
                                      r, aux, accumulate, no_flow, (step0 + s + 1) * tau, d0,
                                      d_max, s)
            if status != _OK:
                return status, s
        if raw and k > 0 and tangent_overflow(W):
            return _OVERFLOW, n_steps - 1
        return _OK, n_steps

    return tp_map_orbit


@lru_cache(maxsize=None)
def map_batch(parallel):
    """The batch two-particle stepper of a map (as :func:`flow_batch`, with
    ``iters`` iterations per interval and the map's ``periods``)."""
    tp_map_orbit = _make_map_orbit()

    @njit(parallel=parallel, error_model="numpy")
    def batch(X, W, acc_m, acc_e, Y, n_steps, iters, par, periods, iterate, renorm, escape_r2,
              d0, d_max, counters, status, done, accumulate, aux, step0, tau):
        for m in prange(X.shape[0]):
            if status[m] != _OK:
                done[m] = 0
                continue
            st, steps = tp_map_orbit(X[m], W[m], acc_m[m], acc_e[m], Y[m], n_steps, iters, par,
                                     periods, iterate, renorm, escape_r2, d0, d_max, counters[m],
                                     accumulate, aux[m], step0, tau)
            status[m] = st
            done[m] = steps

    return batch

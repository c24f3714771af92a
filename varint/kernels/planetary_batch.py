"""The part stepper's batch kernel for planetary systems over SIMD lanes:
what a map of a planetary system runs (:class:`varint.methods.planetary.PlanetaryPropagator`).

The orbits of a call are stepped ``width`` at a time as the lanes of
:func:`varint.kernels.planetary_lanes.lane_word`, one interval τ (the
scheme's word of flows) after the other; at the end of every interval each
lane's orbit goes through the end-of-interval contract of the stepping
skeleton (:func:`varint.kernels.interval.orbit_loop`: the check, the
renormalisation and the indicator's update at t = (step0 + s + 1)·τ, or
the overflow check of raw vectors) on its own record. An orbit that stops
(a failure, or the call's last interval) leaves its lane, and the next
orbit of the call takes it (its own interval count s from 0): an orbit
decided early frees its lane at once, and a lane idles only once no orbit
is left to take it (it then steps a copy of a finite state, discarded).

Every lane's arithmetic is its orbit's alone and the one-orbit part
stepper's (the lanes are bit for bit the one-orbit flows, the contract is
the same functions in the same order), so an orbit's result does not
depend on which lane, block, chunk or thread stepped it (tests).
"""

from __future__ import annotations

from functools import cache

import numpy as np
from numba import njit

from ..protocol import Renorm, Status
from .checks import CHECK_EVERY, orbit_status, renormalize, tangent_overflow
from ..threads import in_threads
from .closures import cache_on_disk
from .planetary_lanes import _FIELDS, lane_word

__all__ = ["lane_batch", "LANES"]

#: Orbits per block of lanes: four AVX-512 vectors of doubles (measured at
#: 64 in studies/planetary_lanes.py; a narrower block idles less at the end
#: of a call).
LANES = 32

_OK = int(Status.OK)
_OVERFLOW = int(Status.TANGENT_OVERFLOW)
_NONE = int(Renorm.NONE)


@cache
def lane_batch(n, k, apply, field, accumulate, flow, parallel, width=LANES):
    """``batch(x, W, acc_m, acc_e, aux, counters, parts, h, par, n_work,
    call, status, done, order, groups)``: the orbits ``order[groups[g]:
    groups[g + 1]]`` (active ones, of the batch's M) advanced by
    ``call.n_steps`` intervals, one block of ``width`` lanes per group (in
    parallel over groups if ``parallel``). ``x`` (M, 6n), ``W`` (M, 6n,
    k), ``acc_m``, ``acc_e`` (M, k), ``aux`` (M, k, columns) or (M, 0, 0),
    ``counters`` (M, parts) as the part stepper's records; ``status[m]``
    and ``done[m]`` as :func:`varint.kernels.interval.batch_loop` sets
    them. ``accumulate`` and ``flow`` as there; ``field`` the model's phase-
    space velocity. Jacobi coordinates only (the lanes'). In parallel, the
    serial kernel on threads, one group at a time
    (:func:`varint.threads.in_threads`): one kernel compiled for both."""
    batch = serial_lane_batch(n, k, apply, field, accumulate, flow, width)
    if not parallel:
        return batch

    def threaded(x, Wst, acc_m, acc_e, aux, counters, parts, h, par, n_work, call, status,
                 done, order, groups):
        def work(lo, hi):
            batch(x, Wst, acc_m, acc_e, aux, counters, parts, h, par, n_work, call, status,
                  done, order, groups[lo:hi + 1])

        in_threads(work, groups.shape[0] - 1, slice_size=1)

    return threaded


@cache
def serial_lane_batch(n, k, apply, field, accumulate, flow, width=LANES):
    """:func:`lane_batch`'s kernel, its groups one after the other,
    compiled with ``nogil=True`` (threads run it side by side on other
    groups: each orbit is in one group)."""
    block = lane_block(n, k, apply, field, accumulate, flow, width)

    @njit(error_model="numpy", nogil=True)
    def batch(x, Wst, acc_m, acc_e, aux, counters, parts, h, par, n_work, call, status, done,
              order, groups):
        # The flows of each part in one interval, counted per orbit as the
        # one-orbit stepper counts them.
        per_part = np.zeros(counters.shape[1], dtype=np.int64)
        for st in range(parts.shape[0]):
            per_part[parts[st]] += 1
        for g in range(groups.shape[0] - 1):
            block(x, Wst, acc_m, acc_e, aux, counters, parts, h, par, n_work, call, status,
                  done, order, groups[g], groups[g + 1], per_part)

    return cache_on_disk(batch)


@cache
def lane_block(n, k, apply, field, accumulate, flow, width=LANES):
    """``block(x, W, acc_m, acc_e, aux, counters, parts, h, par, n_work,
    call, status, done, order, lo, hi, per_part)``: the orbits
    ``order[lo:hi]`` advanced by one block of ``width`` lanes, as
    :func:`lane_batch` describes, ``per_part[j]`` the flows of part j in one
    interval. Made apart from the batch and not per ``parallel``: the
    serial and the parallel batch call the same block, so a run of both
    compiles it once (8 s of the 13 s of a serial batch of two planets)."""
    word = lane_word(n, True, k, apply, width)
    dim = 6 * n
    half = dim // 2                 # the degrees of freedom, as orbit_status reads them
    FLOW = bool(flow)
    EVERY = CHECK_EVERY

    @njit(error_model="numpy")
    def load(X, V, lane, xm, Wm):
        for i in range(dim):
            X[i, lane] = xm[i]
        for c in range(k):
            for i in range(dim):
                V[c, i, lane] = Wm[i, c]

    @njit(error_model="numpy")
    def block(x, Wst, acc_m, acc_e, aux, counters, parts, h, par, n_work, call, status, done,
              order, lo, hi, per_part):
        X = np.empty((dim, width))
        V = np.zeros((k, dim, width))
        Xf, Vf = X.reshape(dim * width), V.reshape(k * dim * width)
        S = np.empty(n * _FIELDS * width)
        bad = np.zeros(width, dtype=np.bool_)
        met = np.zeros(width, dtype=np.int64)
        xs, Ws, work = np.empty(dim), np.empty((k, dim)), np.empty(n_work)
        rows = aux.shape[1] > 0
        r = np.empty(k if rows else 0)
        out = np.empty(dim if FLOW else 0)
        park = x[order[lo]].copy()        # what an idle lane steps: a finite state
        idle = np.zeros((dim, k))
        orbit = np.full(width, -1, dtype=np.int64)
        s_lane = np.zeros(width, dtype=np.int64)
        nxt, live = lo, 0
        for lane in range(width):
            if nxt < hi:
                orbit[lane] = order[nxt]
                load(X, V, lane, x[order[nxt]], Wst[order[nxt]])
                nxt += 1
                live += 1
            else:
                load(X, V, lane, park, idle)
        renorm = call.renorm
        while live > 0:
            word(X, V, Xf, Vf, parts, h, par, S, bad, met, xs, Ws, work)
            for lane in range(width):
                m = orbit[lane]
                if m < 0:
                    continue
                s = s_lane[lane]
                for j in range(per_part.shape[0]):
                    counters[m, j] += per_part[j]
                xm, Wm = x[m], Wst[m]
                for i in range(dim):
                    xm[i] = X[i, lane]
                for c in range(k):
                    for i in range(dim):
                        Wm[i, c] = V[c, i, lane]
                # The end-of-interval contract (interval.orbit_loop), in its order.
                st = orbit_status(xm, half, call.escape_r2)
                if st == _OK:
                    if renorm != _NONE:
                        st = renormalize(Wm, renorm, acc_m[m], acc_e[m], r, dim, k)
                        if st == _OK and rows:
                            if FLOW:
                                field(xm, par, out)
                            accumulate(aux[m], r, xm, Wm, out, (call.step0 + s + 1) * call.tau)
                    elif k > 0 and s % EVERY == EVERY - 1 and tangent_overflow(Wm):
                        st = _OVERFLOW
                finished = True
                if st != _OK:
                    status[m], done[m] = st, s
                elif s + 1 == call.n_steps:
                    if EVERY > 1 and renorm == _NONE and k > 0 and tangent_overflow(Wm):
                        status[m], done[m] = _OVERFLOW, call.n_steps - 1
                    else:
                        status[m], done[m] = _OK, call.n_steps
                else:
                    finished = False
                    s_lane[lane] = s + 1
                    if renorm != _NONE:
                        for c in range(k):
                            for i in range(dim):
                                V[c, i, lane] = Wm[i, c]
                if finished:
                    s_lane[lane] = 0
                    if nxt < hi:
                        orbit[lane] = order[nxt]
                        load(X, V, lane, x[order[nxt]], Wst[order[nxt]])
                        nxt += 1
                    else:
                        orbit[lane] = -1
                        live -= 1
                        load(X, V, lane, park, idle)

    return block

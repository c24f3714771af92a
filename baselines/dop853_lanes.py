"""DOP853 over many orbits at once, in SIMD lanes: ``engine="lanes"``.

The same method as :mod:`varint.baselines.dop853_kernel` — the explicit
8(5,3) pair of Dormand & Prince with Hairer's error estimate and step-size
control (Hairer, Nørsett & Wanner, *Solving ODEs I*, Sect. II.10; SciPy's
coefficients and control constants, read from SciPy) restarted every τ as
in the paper — but with L orbits integrated together: the state of lane l
is row l of arrays (L, size), and every stage of every lane is computed
in one pass before the next stage (the stage sums as plain loops over the
state's components, which LLVM vectorises, instead of a BLAS call per
stage and orbit). Each lane keeps its own time in the interval, step size,
rejections and status: lanes whose interval is done wait (masked) for the
others. The right-hand side is the model's own (the generated one where it
applies, :func:`varint.baselines.rhs.tangent_rhs`), called on each lane's
row.

What it gives up is SciPy's order of arithmetic: the stage sums are plain
loops, not SciPy's BLAS calls, so the results are the method's but not
SciPy's bits (they agree to rounding, ``tests/baselines``). A lane's
arithmetic involves no other lane, so an orbit gives the same bits alone
or in any batch, in any chunking. ``studies/bench_baselines.py`` measures
both engines on one orbit and on a batch.
"""

from __future__ import annotations

import math
from functools import cache

import numpy as np
from numba import njit

from varint.protocol import Status

from varint.kernels.closures import cache_on_disk
from varint.kernels.interval import Call

from .blocks import COND_LIMIT, END_BLOCK, BlockOrbit, BlockSetup
from .dop853_kernel import (A, B, C, COUNTS, E3, E5, MAX_FACTOR, MIN_FACTOR, N_STAGES, SAFETY,
                            dop853_engine)

__all__ = ["lanes_kernel", "LANES"]

#: Orbits integrated together: a multiple of the SIMD width of doubles
#: (8 with AVX-512, 4 with AVX2).
LANES = 8

_OK = int(Status.OK)
_NONFINITE = int(Status.ORBIT_NONFINITE)
_FAILED = int(Status.INTEGRATOR_FAILED)
_BLOCKS, _NFEV, _STEPS, _REJECTED = range(len(COUNTS))


@njit
def _stage(Y, K, s, coefficients, h, out, acc):
    """out[l] = Y[l] + h_l Σ_{j<s} c_j K[j, l] for every lane: one pass per
    stage over contiguous rows (the innermost loop runs over the state's
    components, which LLVM vectorises)."""
    L, size = Y.shape
    for lane in range(L):
        for i in range(size):
            acc[i] = 0.0
        for j in range(s):
            c = coefficients[j]
            row = K[j, lane]
            for i in range(size):
                acc[i] += c * row[i]
        hl = h[lane]
        for i in range(size):
            out[lane, i] = Y[lane, i] + acc[i] * hl


@cache
def lanes_kernel(rhs, take):
    """The kernel ``advance(X, W, acc_m, acc_e, h, status, done, n, tau,
    rtol, atol, powers, mode, escape_r2, counts, aux, par, minv, step0,
    clock)`` that integrates L orbits together (documented below), for the
    right-hand side ``rhs(t, y, yp)`` (:func:`varint.baselines.rhs.tangent_rhs`)
    and ``take``, the one-orbit kernel that takes an output
    (:func:`varint.kernels.interval.orbit_loop` of
    :func:`varint.baselines.blocks.output_body`, with the indicator's
    accumulator).

    Both are compiled in, not passed as arguments (a function passed as a
    value is an address of this process, which numba never caches), so the
    kernel is cached across processes where they can be named
    (:mod:`varint.kernels.closures`).
    """
    initial_step = dop853_engine(rhs).initial_step

    @njit
    def interval(Y, h_abs, tau, rtol, atol, powers, going, counts, K, Ys, Ynew, acc, t, tt,
                 hstep, first, rejected):
        """Integrate every going lane of ``Y`` (L, size) from 0 to τ, in place;
        returns per lane whether it reached τ (a lane that fails stops: its
        ``going`` is cleared and it is not done). ``K[0]`` holds f(Y) on entry."""
        L, size = Y.shape
        done = np.zeros(L, dtype=np.bool_)
        for lane in range(L):
            t[lane] = 0.0
            first[lane] = True
            rejected[lane] = False
        while True:
            active = False
            for lane in range(L):
                hstep[lane] = 0.0
                if not going[lane]:
                    continue
                min_step = 10 * abs(np.nextafter(t[lane], np.inf) - t[lane])
                if first[lane] and h_abs[lane] < min_step:
                    h_abs[lane] = min_step
                # SciPy tests ``h_abs < min_step``, which a NaN never fails.
                if not h_abs[lane] >= min_step:
                    going[lane] = False
                    continue
                t_new = t[lane] + h_abs[lane]
                if t_new - tau > 0:
                    t_new = tau
                hstep[lane] = t_new - t[lane]
                h_abs[lane] = abs(hstep[lane])
                active = True
            if not active:
                return done
            # The 12 stages K[s] = f(y + h Σ_{j<s} a_sj K_j), then y₁ and f(y₁).
            for s in range(1, N_STAGES + 1):
                if s < N_STAGES:
                    _stage(Y, K, s, A[s], hstep, Ys, acc)
                    out, c = Ys, C[s]
                else:
                    _stage(Y, K, N_STAGES, B, hstep, Ynew, acc)
                    out, c = Ynew, 1.0
                for lane in range(L):
                    if going[lane]:
                        tt[lane] = t[lane] + c * hstep[lane]
                        rhs(tt[lane], out[lane], K[s, lane])
            for lane in range(L):
                if not going[lane]:
                    continue
                counts[lane, _NFEV] += N_STAGES
                first[lane] = False
                # DOP853's error: |h| ‖e5‖² / √(n (‖e5‖² + 0.01 ‖e3‖²)), scaled by
                # atol + rtol·max(|y|, |y_new|).
                e5 = 0.0
                e3 = 0.0
                for i in range(size):
                    y0, y1 = abs(Y[lane, i]), abs(Ynew[lane, i])
                    scale = atol + (y0 if y0 >= y1 else y1) * rtol
                    a5 = 0.0
                    a3 = 0.0
                    for j in range(N_STAGES + 1):
                        a5 += E5[j] * K[j, lane, i]
                        a3 += E3[j] * K[j, lane, i]
                    a5 /= scale
                    a3 /= scale
                    e5 += a5 * a5
                    e3 += a3 * a3
                err = 0.0 if e5 == 0 and e3 == 0 else (
                    h_abs[lane] * e5 / math.sqrt((e5 + 0.01 * e3) * size))
                if err < 1:
                    factor = MAX_FACTOR if err == 0 else min(MAX_FACTOR,
                                                             SAFETY * math.pow(err, powers[1]))
                    if rejected[lane]:
                        factor = min(1.0, factor)
                    t[lane] = t[lane] + hstep[lane]
                    h_abs[lane] *= factor
                    counts[lane, _STEPS] += 1
                    first[lane] = True
                    rejected[lane] = False
                    for i in range(size):
                        Y[lane, i] = Ynew[lane, i]
                        K[0, lane, i] = K[N_STAGES, lane, i]
                    if not t[lane] - tau < 0:
                        going[lane] = False
                        done[lane] = True
                else:
                    h_abs[lane] *= max(MIN_FACTOR, SAFETY * math.pow(err, powers[1]))
                    rejected[lane] = True
                    counts[lane, _REJECTED] += 1

    @njit
    def advance(X, W, acc_m, acc_e, h, status, done, n, tau, rtol, atol, powers, mode, escape_r2,
                    counts, aux, par, minv, step0, clock):
        """Advance L orbits (one per lane) by ``n`` intervals τ each, restarting
        DOP853 every τ from the renormalised state (the paper's scheme).

        Parameters
        ----------
        X, W : ndarray, shapes (L, 2N) and (L, 2N, k)
            Orbits and deviation vectors, advanced in place.
        acc_m, acc_e : ndarray, shape (L, k)
            Stretching accumulators (:func:`varint.kernels.checks.renormalize`).
        h : ndarray, shape (L,)
            The step each lane's DOP853 proposed at the end of its previous
            interval (NaN before the first); updated.
        status, done : ndarray of int64, shape (L,)
            Receive each lane's status and the intervals it completed (a failed
            lane stops there; the others go on).
        n : int
        tau, rtol, atol : float
        powers : tuple of float
            :data:`varint.baselines.dop853_kernel.POWERS`.
        mode : int
            A :class:`~varint.protocol.Renorm`.
        escape_r2 : float
        counts : ndarray of int64, shape (L, 4)
            :data:`~varint.baselines.dop853_kernel.COUNTS` per lane, incremented.
        aux, par, minv :
            The accumulator's arrays, one per lane, shape (L, ...); the model's
            parameters and inverse masses.
        step0 : int
            The run's interval count at the start.
        clock : ndarray, shape (L, 2) or (L, 0)
            (t, p_t) of each orbit for a time-dependent V (see
            :mod:`varint.baselines.rhs`), else empty.
        """
        L, d = X.shape
        k = W.shape[2]
        c = clock.shape[1]
        size = d * (1 + k) + c
        Y = np.empty((L, size))
        K = np.empty((N_STAGES + 1, L, size))
        Ys = np.empty((L, size))
        Ynew = np.empty((L, size))
        acc = np.empty(size)
        t, tt, hstep, h_abs = np.empty(L), np.empty(L), np.empty(L), np.empty(L)
        first = np.zeros(L, dtype=np.bool_)
        rejected = np.zeros(L, dtype=np.bool_)
        going = np.zeros(L, dtype=np.bool_)
        work = np.empty((3, size))
        yrow = np.empty((1, size))
        Cv = np.empty((k, k))
        for lane in range(L):
            status[lane] = _OK
            done[lane] = 0
        for j in range(n):
            for lane in range(L):
                going[lane] = status[lane] == _OK
                if not going[lane]:
                    continue
                for i in range(d):
                    Y[lane, i] = X[lane, i]
                    for a in range(k):
                        Y[lane, d + i * k + a] = W[lane, i, a]
                if c:
                    Y[lane, size - 2] = (step0 + j) * tau
                    Y[lane, size - 1] = clock[lane, 1]
                counts[lane, _BLOCKS] += 1
                rhs(0.0, Y[lane], K[0, lane])
                counts[lane, _NFEV] += 1
                if h[lane] != h[lane]:
                    h_abs[lane] = initial_step(Y[lane], K[0, lane], tau, rtol, atol,
                                               math.pow(size, powers[3]), powers, work[0],
                                               work[1], work[2])
                    counts[lane, _NFEV] += 1
                else:
                    h_abs[lane] = min(h[lane], tau)
            if not going.any():
                break
            reached = interval(Y, h_abs, tau, rtol, atol, powers, going, counts, K, Ys, Ynew, acc,
                               t, tt, hstep, first, rejected)
            for lane in range(L):
                if status[lane] != _OK:
                    continue
                finite = True
                for i in range(size):
                    if not np.isfinite(Y[lane, i]):
                        finite = False
                if not finite:
                    status[lane] = _NONFINITE
                    continue
                if not reached[lane]:
                    status[lane] = _FAILED
                    continue
                h[lane] = h_abs[lane]
                for i in range(size):
                    yrow[0, i] = Y[lane, i]
                for a in range(k):
                    for b in range(k):
                        Cv[a, b] = 1.0 if a == b else 0.0
                st, _ = take(BlockOrbit(X[lane], W[lane], acc_m[lane], acc_e[lane], aux[lane],
                                        np.zeros(0, dtype=np.int64), Cv),
                             BlockSetup(yrow, 0, COND_LIMIT, par, minv, c),
                             Call(1, step0 + j, tau, mode, escape_r2))
                if c:
                    clock[lane, 0] = yrow[0, size - 2]
                    clock[lane, 1] = yrow[0, size - 1]
                if st != _OK and st != END_BLOCK:
                    status[lane] = st
                    continue
                done[lane] = j + 1

    return cache_on_disk(advance)

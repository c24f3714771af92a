"""Compiled steppers of the three TDH methods (Skokos & Gerlach 2010, Sect.
V.B): one kernel, specialised at compile time to the method.

Every renormalisation interval [t_i, t_i + τ) the orbit is advanced by
``n_sub`` steps Δt of its splitting scheme, and the deviation vectors
w = (δq, δp) by an approximation of the tangent dynamics Hamiltonian (TDH,
eq. 9 of the paper's LaTeX source) built from D²V at the grid times
t_i + jΔt only. The orbit is integrated a block of intervals at a time by
the TM method's own stepper (:func:`varint.kernels.tm.orbit_kernel`, k = 0),
which records it after every step: the orbit is the TM method's, bit for
bit, and the stepper is called once per block, not once per step (a call
per step cost more than the step: numba reference-counts the arrays passed).
Then the vectors follow the recorded orbit through the block:

* ``CC`` (TDHcc): D²V frozen at q(t_i); the quadratic Hamiltonian integrated
  by the stage tables of a splitting scheme (drift δq += h M⁻¹δp, kick
  δp −= h D²V δq, corrector kick δp −= h · 2 D²V M⁻¹ D²V δq).
* ``ES`` (TDHes): D²V frozen at q(t_i); the exact flow through the
  eigen-decomposition of M^{-1/2} D²V M^{-1/2} (:mod:`varint.tdh.frozen`).
* ``EPS`` (TDHeps): the same stage tables, but the kick and corrector of
  stage s use D²V at the grid point ``tidx[s]`` reached by the drifts before
  it (time is a coordinate of the extended phase space, eqs. 30–37).

The TDH is a quadratic form of w, so its corrector term
C̃ = {B̃, {B̃, Ã}} = δqᵀ D²V M⁻¹ D²V δq (eq. 36 with a mass) needs no third
derivatives of V.

A time-dependent V(q, t) (``TIME``): the orbit is the TM stepper's in the
extended phase space (:mod:`varint.kernels.tm`), and D²V at grid point j of
interval i is evaluated at its time t = (i·m + j)·Δt, written to the last
entry of a private copy of ``par``.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from numba import njit, prange

from ..kernels import tm as K
from ..kernels.banded import band_kick_block, band_square_add
from ..kernels.checks import (CHECK_EVERY, all_finite, derivative_status, renormalize,
                              tangent_overflow)
from ..protocol import COUNTERS as TM_COUNTERS, Renorm, Status
from .frozen import _oscillator

#: The three methods (compile-time constants of the kernel).
CC, ES, EPS = 0, 1, 2

#: Counters kept per orbit: those of the TM stepper, and eigen-decompositions.
COUNTERS = TM_COUNTERS + ("eigendecompositions",)

_OK = int(Status.OK)
_DEGENERATE = int(Status.TANGENT_DEGENERATE)
_OVERFLOW = int(Status.TANGENT_OVERFLOW)
_HESS = int(Status.HESSIAN_NONFINITE)
_NONE = int(Renorm.NONE)

#: Size (in float64 values) of the record of the orbit kept per block of
#: intervals: 512 kB.
_BLOCK_VALUES = 1 << 16


@lru_cache(maxsize=None)
def generic_orbit(n, bw):
    """``run_orbit(x, n_steps, kinds, h, hc, minv, par, bw_rt, grad, hess,
    third, escape_r2, counters, rec) -> (status, steps)``: the orbit alone
    by the generic TM stepper (sizes N = ``n``, bandwidth ``bw``; −1: read
    at run time), the state after every step written to ``rec``."""
    orbit = K.orbit_kernel(n, bw)

    @njit
    def run_orbit(x, n_steps, kinds, h, hc, minv, par, bw_rt, grad, hess, third, escape_r2,
                  counters, rec):
        d = x.shape[0]
        return orbit(x, np.empty((d, 0)), np.ones(0), np.zeros(0, dtype=np.int64), n_steps,
                     kinds, h, hc, minv, par, bw_rt, grad, hess, third, _NONE, escape_r2,
                     counters, rec, K.no_accumulator, np.empty((0, 0)), 0, 0.0)

    return run_orbit


@lru_cache(maxsize=None)
def generated_orbit(module):
    """The same as :func:`generic_orbit` by a generated stepper
    (:mod:`varint.kernels.generate`, k = 0), whose snapshots at every step
    are the record: the orbit is the TM method's, bit for bit."""
    orbit = module.orbit

    @njit
    def run_orbit(x, n_steps, kinds, h, hc, minv, par, bw_rt, grad, hess, third, escape_r2,
                  counters, rec):
        d = x.shape[0]
        return orbit(x, np.empty((d, 0)), np.ones(0), np.zeros(0, dtype=np.int64), n_steps,
                     0, 0.0, h, hc, escape_r2, counters, np.empty((0, 0)),
                     np.zeros(2, dtype=np.int64), np.arange(1, n_steps + 1), rec,
                     np.empty((n_steps, d, 0)), np.ones((n_steps, 0)),
                     np.zeros((n_steps, 0), dtype=np.int64), np.empty((n_steps, 0, 0)), _NONE, 0)

    return run_orbit


def _make_tdh_orbit(N_C, K_C, BW_C, MODE, FLOW, run_orbit, TIME=False):
    """The one-orbit TDH stepper for method ``MODE``; sizes are constants
    when ≥ 0, else read from the arrays. ``FLOW``: the accumulator reads the
    phase-space velocity (see :func:`varint.kernels.tm.tm_batch`).
    ``run_orbit``: :func:`generic_orbit` or :func:`generated_orbit`.
    ``TIME``: a time-dependent V, with ``ctime``, ``dtime``, ``pt`` as for
    the TM stepper (:func:`varint.kernels.tm.tm_batch`); its orbit is the
    generic stepper's in the extended phase space."""
    time_orbit = K.orbit_kernel(N_C, BW_C, True) if TIME else run_orbit

    @njit
    def tdh_orbit(x, W, acc_m, acc_e, n_steps, kinds, h, hc, n_sub, tkinds, th, thc, tidx,
                  need, tau, minv, par, bw_rt, grad, hess, third, eig, renorm, escape_r2,
                  counters, accumulate, aux, step0, ctime=None, dtime=None, pt=None):
        n = N_C if N_C >= 0 else x.shape[0] // 2
        k = K_C if K_C >= 0 else W.shape[1]
        bw = BW_C if BW_C >= 0 else bw_rt
        d = 2 * n
        bwc = min(2 * bw, n - 1)
        tangent = k > 0
        # The orbit runs a block of intervals at a time (one call of the TM
        # stepper, which records it after every step); then the vectors
        # follow it through the block.
        block = max(1, min(n_steps, _BLOCK_VALUES // (n_sub * d)))
        rec = np.empty((block * n_sub, d))
        x0 = np.empty(n)                        # q at the start of the block
        r_acc = np.empty(k if aux.shape[0] > 0 else 0)    # stretching, for the accumulator
        flow = np.empty(d if FLOW else 0)
        gq = np.empty(n)                        # ∇V, for the accumulator's flow
        q = np.empty(n)
        H = np.zeros((bw + 1, n))
        n_grid = n_sub + 1
        Hs = np.zeros((n_grid, bw + 1, n))      # D²V at the grid points of an interval
        HCs = np.zeros((n_grid, bwc + 1, n))    # D²C̃ = 2 D²V M⁻¹ D²V there
        hc_done = np.zeros(n_grid, dtype=np.bool_)
        zero_T = np.zeros((bw + 1, n))          # the TDH has no third derivatives
        Kb = np.zeros((bwc + 1, n))
        ne = n if MODE == ES else 0
        Kd = np.zeros((ne, ne))                 # M^{-1/2} D²V M^{-1/2}
        lam = np.empty(ne)
        Qm = np.empty((ne, ne))
        q0 = np.empty(ne)                       # q(t_i), for an analytic eigensolver
        ca = np.empty(ne)                       # c and s of each mode (frozen.py)
        sa = np.empty(ne)
        u = np.empty(ne)                        # S⁻¹δq, S δp
        v = np.empty(ne)
        ma = np.empty(ne)                       # the modes after τ
        mb = np.empty(ne)
        rs = np.sqrt(minv)                      # S = M^{-1/2}
        have_end = False                        # Hs[n_sub] is D²V at the current q
        pl = par.copy()                         # with the time of a grid point (TIME)
        dt = tau / n_sub
        done = 0
        while done < n_steps:
            nb = min(block, n_steps - done)
            for i in range(n):
                x0[i] = x[i]
            if TIME:
                status, steps = time_orbit(x, np.empty((d, 0)), np.ones(0),
                                           np.zeros(0, dtype=np.int64), nb * n_sub, kinds, h,
                                           hc, minv, par, bw_rt, grad, hess, third, _NONE,
                                           escape_r2, counters, rec, K.no_accumulator,
                                           np.empty((0, 0)), (step0 + done) * n_sub, dt, ctime,
                                           dtime, pt)
            else:
                status, steps = run_orbit(x, nb * n_sub, kinds, h, hc, minv, par, bw_rt, grad,
                                          hess, third, escape_r2, counters, rec)
            complete = steps // n_sub if status != _OK else nb
            for s in range(complete):
                if tangent:
                    # D²V at the grid points t_i + jΔt the method uses.
                    for jg in range(n_grid):
                        hc_done[jg] = False
                        if not need[jg]:
                            continue
                        if jg == 0 and have_end:
                            for b in range(bw + 1):
                                for i in range(n):
                                    Hs[0, b, i] = Hs[n_sub, b, i]
                            continue
                        r = s * n_sub + jg - 1
                        for i in range(n):
                            q[i] = x0[i] if r < 0 else rec[r, i]
                        if TIME:
                            pl[pl.shape[0] - 1] = float((step0 + done + s) * n_sub + jg) * dt
                        hess(q, pl, H)
                        counters[1] += 1
                        if not all_finite(H.ravel(), (bw + 1) * n):
                            for i in range(d):
                                x[i] = rec[(s + 1) * n_sub - 1, i]
                            return derivative_status(q, n, _HESS), done + s
                        for b in range(bw + 1):
                            for i in range(n):
                                Hs[jg, b, i] = H[b, i]
                        if jg == 0:
                            for i in range(ne):
                                q0[i] = q[i]
                    have_end = need[n_sub]
                if tangent and MODE == ES:
                    # Exact flow of the frozen TDH: the modal coordinates
                    # Qᵀ S⁻¹δq and Qᵀ S δp evolve as uncoupled oscillators.
                    for i in range(n):
                        Kd[i, i] = rs[i] * Hs[0, 0, i] * rs[i]
                    for b in range(1, bw + 1):
                        for i in range(n - b):
                            Kd[i, i + b] = Kd[i + b, i] = rs[i] * Hs[0, b, i] * rs[i + b]
                    finite = True
                    for i in range(n):
                        for j in range(n):
                            finite = finite and abs(Kd[i, j]) < np.inf
                    if not finite:
                        # LAPACK would raise: fail the interval like a bad vector.
                        for i in range(d):
                            x[i] = rec[(s + 1) * n_sub - 1, i]
                        return _DEGENERATE, done + s
                    eig(q0, Kd, lam, Qm)
                    counters[4] += 1
                    for r in range(n):
                        ca[r], sa[r] = _oscillator(lam[r], tau)
                    counters[3] += 1
                    for j in range(k):
                        for i in range(n):
                            u[i] = W[i, j] / rs[i]
                            v[i] = W[n + i, j] * rs[i]
                        for r in range(n):
                            a = 0.0
                            c = 0.0
                            for i in range(n):
                                a += Qm[i, r] * u[i]
                                c += Qm[i, r] * v[i]
                            ma[r] = ca[r] * a + sa[r] * c
                            mb[r] = -lam[r] * sa[r] * a + ca[r] * c
                        for i in range(n):
                            a = 0.0
                            c = 0.0
                            for r in range(n):
                                a += Qm[i, r] * ma[r]
                                c += Qm[i, r] * mb[r]
                            W[i, j] = rs[i] * a
                            W[n + i, j] = c / rs[i]
                elif tangent:
                    # The TDH's splitting flows; kicks use D²V at their grid point.
                    for st in range(tkinds.shape[0]):
                        hs = th[st]
                        if tkinds[st] == 0:
                            for i in range(n):
                                a = hs * minv[i]
                                for j in range(k):
                                    W[i, j] += a * W[n + i, j]
                            continue
                        g = tidx[st]
                        hcs = thc[st]
                        counters[3] += 1
                        if hcs == 0.0:
                            for b in range(bw + 1):
                                for i in range(n):
                                    Kb[b, i] = hs * Hs[g, b, i]
                            band_kick_block(Kb, W, n, k, bw)
                            continue
                        if not hc_done[g]:
                            for b in range(bw + 1):
                                for i in range(n):
                                    H[b, i] = Hs[g, b, i]
                            band_square_add(H, minv, zero_T, HCs[g], n, bw, bwc)
                            hc_done[g] = True
                        for b in range(bwc + 1):
                            for i in range(n):
                                Kb[b, i] = hcs * HCs[g, b, i]
                        for b in range(bw + 1):
                            for i in range(n):
                                Kb[b, i] += hs * Hs[g, b, i]
                        band_kick_block(Kb, W, n, k, bwc)
                # The vectors are at the end of interval s, and so is the orbit.
                r = (s + 1) * n_sub - 1
                if renorm != _NONE:
                    if renormalize(W, renorm, acc_m, acc_e, r_acc, d, k) != _OK:
                        for i in range(d):
                            x[i] = rec[r, i]
                        return _DEGENERATE, done + s
                    if aux.shape[0] > 0:
                        if FLOW:
                            for i in range(n):
                                q[i] = rec[r, i]
                            if TIME:
                                pl[pl.shape[0] - 1] = float((step0 + done + s + 1) * n_sub) * dt
                            grad(q, pl, gq)
                            counters[0] += 1
                            for i in range(n):
                                flow[i] = minv[i] * rec[r, n + i]
                                flow[n + i] = -gq[i]
                        accumulate(aux, r_acc, rec[r], W, flow, (step0 + done + s + 1) * tau)
                elif tangent and (done + s) % CHECK_EVERY == CHECK_EVERY - 1 and \
                        tangent_overflow(W):
                    for i in range(d):
                        x[i] = rec[r, i]
                    return _OVERFLOW, done + s
            if status != _OK:
                return status, done + complete
            done += nb
        if renorm == _NONE and tangent and tangent_overflow(W):
            return _OVERFLOW, n_steps - 1
        return _OK, n_steps

    return tdh_orbit


@lru_cache(maxsize=None)
def tdh_batch(n, k, bw, mode, parallel, flow, run_orbit, time=False):
    """The batch stepper of method ``mode`` (``CC``, ``ES`` or ``EPS``) for
    N = ``n``, ``k`` vectors and bandwidth ``bw`` (−1 for all three: sizes
    read at run time).

    The returned function advances every orbit of ``X`` (M, 2N) whose
    ``status`` is OK by ``n_steps`` renormalisation intervals, in parallel
    over orbits if ``parallel``; ``done[m]`` receives the intervals orbit m
    completed and ``status[m]`` its status (codes of :class:`varint.protocol.Status`).
    An orbit that fails is frozen as it was at the failure: the orbit at the
    end of the failed orbit step and the vectors at the start of that
    interval, or, if their renormalisation failed, both at its end.
    ``run_orbit`` integrates the orbit (:func:`generic_orbit` or
    :func:`generated_orbit`). With ``time`` (a time-dependent V) ``ctime``,
    ``dtime`` and ``pt`` (M,) follow ``step0``, as for
    :func:`varint.kernels.tm.tm_batch`.
    """
    tdh_orbit = _make_tdh_orbit(n, k, bw, mode, flow, run_orbit, time)

    @njit(parallel=parallel)
    def batch(X, W, acc_m, acc_e, n_steps, kinds, h, hc, n_sub, tkinds, th, thc, tidx, need,
              tau, minv, par, bw_rt, grad, hess, third, eig, renorm, escape_r2, counters,
              status, done, accumulate, aux, step0, ctime=None, dtime=None, pt=None):
        for m in prange(X.shape[0]):
            if status[m] != _OK:
                done[m] = 0
                continue
            if time:
                st, steps = tdh_orbit(X[m], W[m], acc_m[m], acc_e[m], n_steps, kinds, h, hc,
                                      n_sub, tkinds, th, thc, tidx, need, tau, minv, par, bw_rt,
                                      grad, hess, third, eig, renorm, escape_r2, counters[m],
                                      accumulate, aux[m], step0, ctime, dtime, pt[m:m + 1])
            else:
                st, steps = tdh_orbit(X[m], W[m], acc_m[m], acc_e[m], n_steps, kinds, h, hc,
                                      n_sub, tkinds, th, thc, tidx, need, tau, minv, par, bw_rt,
                                      grad, hess, third, eig, renorm, escape_r2, counters[m],
                                      accumulate, aux[m], step0)
            status[m] = st
            done[m] = steps

    return batch


def batch_kernel(n, k, bw, mode, parallel, flow=False, module=None, time=False):
    """:func:`tdh_batch` specialised to the sizes when they are small (the
    TM stepper's rule, :func:`varint.kernels.tm.batch_kernel`), its orbit
    by the generated stepper ``module`` if given, else the generic one."""
    sizes = K.specialised_sizes(n, k, bw)
    run_orbit = generic_orbit(sizes[0], sizes[2]) if module is None else generated_orbit(module)
    return tdh_batch(*sizes, mode, parallel, flow, run_orbit, time)

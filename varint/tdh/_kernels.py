"""The step body of the three TDH methods (Skokos & Gerlach 2010, Sect.
V.B): one body for all three, the method read from the setup at run time
(a kernel costs ~20 CPU s to compile, and a run of two methods, or of
TDHes with both eigensolvers, compiles one); the loop over intervals and
their ends are the stepping skeleton's (:mod:`varint.kernels.interval`).

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

from collections import namedtuple
from functools import cache

import numpy as np
from numba import njit

from ..codegen.interval import Outputs, StepperOrbit, StepperSetup
from ..kernels import tm as K
from ..kernels.banded import band_kick_block, band_square_add
from ..kernels.checks import all_finite, derivative_status
from ..kernels.interval import (Call, StepBody, batch_loop, no_accumulator, orbit_record)
from ..protocol import COUNTERS as TM_COUNTERS, Renorm, Status
from .frozen import _oscillator, lapack_eig

#: The three methods (the setup's ``exact`` says whether TDHes's flow runs).
CC, ES, EPS = 0, 1, 2

#: Counters kept per orbit: those of the TM stepper, and eigen-decompositions.
COUNTERS = TM_COUNTERS + ("eigendecompositions",)

_OK = int(Status.OK)
_DEGENERATE = int(Status.TANGENT_DEGENERATE)
_HESS = int(Status.HESSIAN_NONFINITE)
_NONE = int(Renorm.NONE)

#: Size (in float64 values) of the record of the orbit kept per block of
#: intervals: 512 kB.
_BLOCK_VALUES = 1 << 16

#: One orbit's record (:mod:`varint.kernels.interval`); ``pt`` (1,): its
#: momentum conjugate to time (a time-dependent V; (0,) otherwise).
TDHOrbit = orbit_record("TDHOrbit", ("pt",))

#: What a call reads: the orbit's stage tables (``kinds``, ``h``, ``hc``,
#: for the step Δt = τ/n_sub; ``ctime``: their times, for a time-dependent
#: V), orbit steps per interval, the tangent scheme's stage tables
#: (``tkinds``, ``th``, ``thc``; ``tidx``: the grid point of each stage's
#: D²V), the grid points whose D²V the method needs, the model's inverse
#: masses, parameters and bandwidth; ``exact``: TDHes's exact flow instead of
#: the stage tables, its eigen-decompositions by the kernel's closed-form
#: eigensolver where ``analytic``, else by LAPACK.
TDHSetup = namedtuple("TDHSetup", ("kinds", "h", "hc", "ctime", "n_sub", "tkinds", "th", "thc",
                                   "tidx", "need", "minv", "par", "bw", "exact", "analytic"))

_Work = namedtuple("_Work", (
    "n", "k", "d", "xe", "bw", "bwc", "block", "rec", "x0", "orbit_setup", "no_W", "no_m", "no_e",
    "no_aux", "q", "gq", "H", "Hs", "HCs", "hc_done", "zero_T", "Kb", "Kd", "lam", "Qm", "q0", "ca",
    "sa", "u", "v", "ma", "mb", "rs", "pl"))


@cache
def generic_orbit(n, bw, kernels, time=False):
    """``run_orbit(state, setup, call) -> (status, steps)``: the orbit alone
    by the generic TM stepper (:func:`varint.kernels.tm.orbit_kernel`:
    sizes N = ``n``, bandwidth ``bw``; −1: read at run time), the state
    after every step written to ``state.record``."""
    return K.orbit_kernel(n, bw, kernels, time)


@cache
def generated_orbit(module):
    """The same as :func:`generic_orbit` by a generated stepper
    (:mod:`varint.codegen`, k = 0), whose snapshots at every step are the
    record: the orbit is the TM method's, bit for bit."""
    orbit = module.orbit

    @njit
    def run_orbit(state, setup, call):
        d = state.x.shape[0]
        n_steps = call.n_steps
        return orbit(StepperOrbit(state.x, np.empty((d, 0)), np.ones(0),
                                  np.zeros(0, dtype=np.int64), np.empty((0, 0)), state.counters,
                                  np.zeros(2, dtype=np.int64)),
                     StepperSetup(setup.h, setup.hc, 0),
                     Call(n_steps, 0, 0.0, _NONE, call.escape_r2),
                     Outputs(np.arange(1, n_steps + 1), state.record, np.empty((n_steps, d, 0)),
                             np.ones((n_steps, 0)), np.zeros((n_steps, 0), dtype=np.int64),
                             np.empty((n_steps, 0, 0))))

    return run_orbit


@cache
def tdh_body(N_C, K_C, BW_C, kernels, analytic, run_orbit, TIME=False):
    """The step body of the TDH methods for the model ``kernels``
    (:func:`varint.kernels.tm.model_kernels`): with the setup's ``exact``
    TDHes's exact flow, its eigen-decompositions by LAPACK or, where the
    setup's ``analytic`` is set, by the closed-form eigensolver
    ``analytic`` (None: the model has none), else the splitting flows of
    TDHcc and TDHeps (they differ only in the setup's tables: ``n_sub``,
    ``tidx`` and ``need``). One body for the three methods: a run of
    several compiles one kernel (the bits are those of one body per method,
    the same arithmetic behind a branch taken once per interval). Sizes are
    constants when ≥ 0, else read from the arrays.
    ``run_orbit`` integrates the orbit (:func:`generic_orbit` or
    :func:`generated_orbit`); with ``TIME`` (a time-dependent V) its orbit
    is the generic stepper's in the extended phase space.

    The orbit runs a block of intervals at a time (one call of
    ``run_orbit``, which records it after every step); the vectors then
    follow it interval by interval, and the end point of each interval is
    copied from the record. An orbit that fails is frozen as it was at the
    failure: the orbit at the end of the failed orbit step and the vectors
    at the start of that interval, or, if their renormalisation failed,
    both at its end.
    """
    grad, hess = kernels[0], kernels[1]
    # Without a closed-form eigensolver both branches call LAPACK's.
    ANALYTIC = analytic is not None
    eig = lapack_eig if analytic is None else analytic

    @njit(inline="always")
    def begin(state, setup, call):
        n = N_C if N_C >= 0 else state.x.shape[0] // 2
        k = K_C if K_C >= 0 else state.W.shape[1]
        bw = BW_C if BW_C >= 0 else setup.bw
        d = 2 * n
        bwc = min(2 * bw, n - 1)
        n_sub = setup.n_sub
        n_grid = n_sub + 1
        ne = n if setup.exact else 0
        block = max(1, min(call.n_steps, _BLOCK_VALUES // (n_sub * d)))
        orbit_setup = K.TMSetup(setup.kinds, setup.h, setup.hc, setup.minv, setup.par, setup.bw,
                                setup.ctime)
        ws = _Work(n, k, d, np.empty(d), bw, bwc, block,
                   np.empty((block * n_sub, d)),      # the orbit after every step of a block
                   np.empty(n),                       # q at the start of the block
                   orbit_setup,
                   np.empty((d, 0)), np.ones(0), np.zeros(0, dtype=np.int64), np.empty((0, 0)),
                   np.empty(n),                       # q
                   np.empty(n),                       # ∇V, for the accumulator's flow
                   np.zeros((bw + 1, n)),
                   np.zeros((n_grid, bw + 1, n)),     # D²V at the grid points of an interval
                   np.zeros((n_grid, bwc + 1, n)),    # D²C̃ = 2 D²V M⁻¹ D²V there
                   np.zeros(n_grid, dtype=np.bool_),
                   np.zeros((bw + 1, n)),             # the TDH has no third derivatives
                   np.zeros((bwc + 1, n)),
                   np.zeros((ne, ne)),                # M^{-1/2} D²V M^{-1/2}
                   np.empty(ne), np.empty((ne, ne)),
                   np.empty(ne),                      # q(t_i), for an analytic eigensolver
                   np.empty(ne), np.empty(ne),        # c and s of each mode (frozen.py)
                   np.empty(ne), np.empty(ne),        # S⁻¹δq, S δp
                   np.empty(ne), np.empty(ne),        # the modes after τ
                   np.sqrt(setup.minv),               # S = M^{-1/2}
                   setup.par.copy())                  # with the time of a grid point (TIME)
        # The block: its first interval, the next block's, the intervals the
        # orbit completed and its status; whether Hs[n_sub] is D²V at the
        # current q.
        return ws, (0, 0, 0, _OK, False)

    @njit(inline="always")
    def step(state, setup, ws, carry, s, call):
        x, W, counters = state.x, state.W, state.counters
        n, k, d, bw, bwc = ws.n, ws.k, ws.d, ws.bw, ws.bwc
        rec, x0, q, H, Hs, HCs, hc_done = ws.rec, ws.x0, ws.q, ws.H, ws.Hs, ws.HCs, ws.hc_done
        minv, n_sub, need = setup.minv, setup.n_sub, setup.need
        first, following, complete, orbit_status, have_end = carry
        tau = call.tau
        dt = tau / n_sub
        if s == following:
            # The orbit through the next block, recorded after every step.
            nb = min(ws.block, call.n_steps - s)
            for i in range(n):
                x0[i] = x[i]
            orbit_status, steps = run_orbit(
                K.TMOrbit(x, ws.no_W, ws.no_m, ws.no_e, ws.no_aux, counters, state.pt, rec),
                ws.orbit_setup, Call(nb * n_sub, (call.step0 + s) * n_sub, dt, _NONE,
                                     call.escape_r2))
            complete = steps // n_sub if orbit_status != _OK else nb
            first, following = s, s + nb
        i_block = s - first
        if i_block == complete:
            # The orbit failed in this interval; it is where it failed.
            return orbit_status, (first, following, complete, orbit_status, have_end)
        end_row = (i_block + 1) * n_sub - 1
        if k > 0:
            # D²V at the grid points t_i + jΔt the method uses.
            for jg in range(n_sub + 1):
                hc_done[jg] = False
                if not need[jg]:
                    continue
                if jg == 0 and have_end:
                    for b in range(bw + 1):
                        for i in range(n):
                            Hs[0, b, i] = Hs[n_sub, b, i]
                    continue
                r = i_block * n_sub + jg - 1
                for i in range(n):
                    q[i] = x0[i] if r < 0 else rec[r, i]
                if TIME:
                    ws.pl[ws.pl.shape[0] - 1] = float((call.step0 + s) * n_sub + jg) * dt
                hess(q, ws.pl, H)
                counters[1] += 1
                if not all_finite(H.ravel(), (bw + 1) * n):
                    for i in range(d):
                        x[i] = rec[end_row, i]
                    return (derivative_status(q, n, _HESS),
                            (first, following, complete, orbit_status, have_end))
                for b in range(bw + 1):
                    for i in range(n):
                        Hs[jg, b, i] = H[b, i]
                if jg == 0:
                    for i in range(ws.q0.shape[0]):
                        ws.q0[i] = q[i]
            have_end = need[n_sub]
        if k > 0 and setup.exact:
            # Exact flow of the frozen TDH: the modal coordinates
            # Qᵀ S⁻¹δq and Qᵀ S δp evolve as uncoupled oscillators.
            Kd, lam, Qm, rs = ws.Kd, ws.lam, ws.Qm, ws.rs
            ca, sa, u, v, ma, mb = ws.ca, ws.sa, ws.u, ws.v, ws.ma, ws.mb
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
                    x[i] = rec[end_row, i]
                return _DEGENERATE, (first, following, complete, orbit_status, have_end)
            if ANALYTIC and setup.analytic:
                eig(ws.q0, Kd, lam, Qm)
            else:
                lapack_eig(ws.q0, Kd, lam, Qm)
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
        elif k > 0:
            # The TDH's splitting flows; kicks use D²V at their grid point.
            tkinds, th, thc, tidx, Kb = setup.tkinds, setup.th, setup.thc, setup.tidx, ws.Kb
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
                    band_square_add(H, minv, ws.zero_T, HCs[g], n, bw, bwc)
                    hc_done[g] = True
                for b in range(bwc + 1):
                    for i in range(n):
                        Kb[b, i] = hcs * HCs[g, b, i]
                for b in range(bw + 1):
                    for i in range(n):
                        Kb[b, i] += hs * Hs[g, b, i]
                band_kick_block(Kb, W, n, k, bwc)
        # The vectors are at the end of the interval, and so is the orbit.
        for i in range(d):
            ws.xe[i] = rec[end_row, i]
        return _OK, (first, following, complete, orbit_status, have_end)

    @njit(inline="always")
    def flow(state, setup, ws, carry, xe, s, call, out):
        n, q, gq = ws.n, ws.q, ws.gq
        for i in range(n):
            q[i] = xe[i]
        if TIME:
            ws.pl[ws.pl.shape[0] - 1] = (float((call.step0 + s + 1) * setup.n_sub)
                                         * (call.tau / setup.n_sub))
        grad(q, ws.pl, gq)
        state.counters[0] += 1
        for i in range(n):
            out[i] = setup.minv[i] * xe[n + i]
            out[n + i] = -gq[i]
        return carry

    # No end-of-interval check of the orbit: run_orbit checked it every step.
    return StepBody(begin=begin, step=step, flow=flow)


@cache
def tdh_batch(n, k, bw, parallel, kernels, analytic, run_orbit, accumulate=no_accumulator,
              flow=False, time=False):
    """The batch stepper of the TDH methods (the setup says which) for
    N = ``n``, ``k`` vectors and bandwidth ``bw`` (−1 for all three: sizes
    read at run time): ``batch(states, setup, call, status, done)``
    (:func:`varint.kernels.interval.batch_loop`) with a batch of
    :class:`TDHOrbit` and a :class:`TDHSetup`; ``call.tau`` is the
    renormalisation interval τ and ``done[m]`` receives the intervals orbit
    m completed. ``analytic``: the model's closed-form eigensolver for
    TDHes, or None. ``run_orbit`` integrates the orbit
    (:func:`generic_orbit` or :func:`generated_orbit`). With ``time`` V
    depends on t.

    TDHcc, TDHeps and TDHes (with either eigensolver) share one kernel
    (:func:`tdh_body`): a run of several compiles it once."""
    body = tdh_body(n, k, bw, kernels, analytic, run_orbit, time)
    return batch_loop(body, parallel, accumulate, flow)


def batch_kernel(n, k, bw, parallel, kernels, analytic=None, accumulate=no_accumulator,
                 flow=False, module=None, time=False):
    """:func:`tdh_batch` specialised to the sizes when they are small (the
    TM stepper's rule, :func:`varint.kernels.tm.batch_kernel`), its orbit
    by the generated stepper ``module`` if given, else the generic one."""
    sizes = K.specialised_sizes(n, k, bw)
    run_orbit = (generic_orbit(sizes[0], sizes[2], kernels, time) if module is None
                 else generated_orbit(module))
    return tdh_batch(*sizes, parallel, kernels, analytic, run_orbit, accumulate, flow, time)

"""The generic compiled tangent-map stepper: one kernel for every splitting
scheme and every model that provides the kernels of
:mod:`varint.models.base`.

The TM method (Skokos & Gerlach 2010, Sect. V.C) extends each flow of a
splitting scheme to the deviation vectors w = (δq, δp):

* drift  e^{h L_AV} (eq. 46):  q += h M⁻¹p,        δq += h M⁻¹δp
* kick   e^{h L_BV} (eq. 47):  p −= h ∇V(q),        δp −= h D²V(q) δq
* corrector e^{h L_CV} (eq. 53): p −= h ∇C(q),      δp −= h D²C(q) δq

A scheme arrives as stage tables (:func:`varint.schemes.stage_arrays`); a
kick stage carries a kick length and a corrector length, since both act on
p at the same q. Forces and Hessians are reused while q is unchanged (the
last kick of a BAB step and the first of the next), which is exact: the
same inputs give the same bits.

A potential V(q, t) that depends on time (``model.time_dependent``) is
integrated in the extended phase space, with t and its conjugate momentum
p_t as one more degree of freedom: A = ½pᵀM⁻¹p + p_t, B = V(q, t). Only
drifts advance t (by their length h), so the kicks of stage s act at the
known time t_s = (step + c_s)·τ, c_s the drift coefficients before it
(:func:`varint.schemes.stage_times`); the kernels read t from their last
parameter (a private copy per orbit, ``par[-1] = t_s``), and p_t, which
nothing else depends on, is kicked by −h ∂_tV − h_c ∂_tC for the conserved
extended energy K = H + p_t (``time=True`` steppers; see
:func:`_make_orbit_kernel`). Every scheme stays symplectic in the extended
space, and the deviation vectors, with δt = 0, follow the same formulas.

This module is the TM method's step body (:func:`tm_body`): one step of
the scheme's stages. The loop over steps and the end of every step (the
orbit's checks, renormalisation, the accumulator of an indicator) are the
stepping skeleton's (:mod:`varint.kernels.interval`). A derivative kernel
that returns a non-finite value at a finite position (a potential singular
on the orbit) stops the orbit before that kick, with the position kept.

Speed comes from two choices, both measured (studies/bench_tm.py):

* the model's kernels (:func:`model_kernels`) are compiled into the
  stepper (inlined, not called through a pointer);
* for small systems the sizes N, k and the bandwidth are compile-time
  constants of the stepper, so the many short loops unroll; large systems
  fix only k (≤ 8) and the bandwidth (:func:`specialised_sizes`).
"""

from __future__ import annotations

from collections import namedtuple
from functools import cache

import numpy as np
from numba import njit

from ..protocol import Status
from .banded import band_kick_block, band_matvec, band_square_add
from .checks import all_finite, derivative_status, orbit_status
from .drift import drift
from .interval import StepBody, batch_loop, no_accumulator, orbit_loop, orbit_record

__all__ = ["tm_body", "tm_batch", "orbit_kernel", "batch_kernel", "specialised_sizes",
           "model_kernels", "TMOrbit", "TMSetup", "SPECIALISE_N"]

_OK = int(Status.OK)
_GRAD = int(Status.GRADIENT_NONFINITE)
_HESS = int(Status.HESSIAN_NONFINITE)
_THIRD = int(Status.THIRD_NONFINITE)

#: Largest N and k for which the stepper is specialised to constant sizes,
#: and largest k specialised when N is too large to be a constant.
SPECIALISE_N, SPECIALISE_K, SPECIALISE_K_LARGE_N = 16, 32, 8

#: One orbit's record (:mod:`varint.kernels.interval`): ``pt`` (1,) its
#: momentum conjugate to time (a time-dependent V; (0,) otherwise) and
#: ``record`` (≥ n_steps, 2N), where a recording stepper writes the orbit.
TMOrbit = orbit_record("TMOrbit", ("pt", "record"))

#: What a call of the stepper reads: the stage tables of
#: :func:`varint.schemes.stage_arrays` (``kinds``, ``h``, ``hc``), the
#: inverse masses, the model's parameters, its bandwidth and, for a
#: time-dependent V, the stage times ``ctime`` (:func:`varint.schemes.stage_times`).
TMSetup = namedtuple("TMSetup", ("kinds", "h", "hc", "minv", "par", "bw", "ctime"))

# The step body's work space (sizes, derivative buffers, band matrices).
_Work = namedtuple("_Work", ("n", "k", "d", "xe", "bw", "bwc", "q", "g", "gc", "mg", "H", "T",
                             "HC", "Kb", "pl", "gt"))


def model_kernels(model):
    """The compiled kernels of ``model`` the stepper is built with:
    ``(grad, hess, third, dtime)`` (``dtime`` None unless V depends on t)."""
    dtime = model.time_kernel if model.time_dependent else None
    return model.grad_kernel, model.hess_kernel, model.third_kernel, dtime


@cache
def tm_body(N_C, K_C, BW_C, kernels, TIME=False):
    """The TM method's step body for the model ``kernels``
    (:func:`model_kernels`); sizes are constants when ≥ 0, else read from
    the arrays.

    One step applies the scheme's stages: drifts, and kicks fused with a
    corrector at the same q (see the module docstring). Forces, Hessians and
    third derivatives are reused while q (and, with ``TIME``, t) is bitwise
    unchanged: the carry holds which are valid.

    With ``TIME`` V depends on t: the kick of stage s of step ``step0 + i``
    evaluates ∇V, D²V and the third derivatives at t = (step0 + i +
    ctime[s])·τ, written to the last entry of a private copy of ``par``
    (the time depends only on the step and stage, so chunking never changes
    a bit); ``dtime(q, par, gt) -> ∂_tV`` (also writing gt = ∂_t∇V) is
    evaluated with every gradient and counted with it, and the orbit's p_t
    (``state.pt[0]``) is kicked by −h ∂_tV − h_c ∂_tC.
    """
    grad, hess, third, dtime = kernels

    @njit(inline="always")
    def begin(state, setup, call):
        n = N_C if N_C >= 0 else state.x.shape[0] // 2
        k = K_C if K_C >= 0 else state.W.shape[1]
        bw = BW_C if BW_C >= 0 else setup.bw
        bwc = min(2 * bw, n - 1)
        pl = setup.par.copy() if TIME else setup.par    # pl[-1] = t of this orbit's kicks
        ws = _Work(n, k, 2 * n, state.x, bw, bwc,
                   np.empty(n),                 # q: contiguous copy of the positions
                   np.empty(n),                 # ∇V
                   np.empty(n),                 # ∇C
                   np.empty(n),                 # M⁻¹∇V
                   np.zeros((bw + 1, n)), np.zeros((bw + 1, n)),
                   np.zeros((bwc + 1, n)), np.zeros((bwc + 1, n)),
                   pl, np.empty(n if TIME else 0))   # ∂_t∇V
        # Which of g, H, ∇C and D²C hold at the current q; the time of
        # them (NaN: none); ∂_tV.
        return ws, (False, False, False, False, np.nan, 0.0)

    @njit(inline="always")
    def step(state, setup, ws, carry, s, call):
        x, W, counters = state.x, state.W, state.counters
        kinds, h, hc, minv = setup.kinds, setup.h, setup.hc, setup.minv
        n, k, bw, bwc = ws.n, ws.k, ws.bw, ws.bwc
        q, g, gc, mg, H, T, HC, Kb, pl, gt = (ws.q, ws.g, ws.gc, ws.mg, ws.H, ws.T, ws.HC,
                                              ws.Kb, ws.pl, ws.gt)
        have_g, have_h, have_c, have_hc, t_have, dv = carry
        tangent = k > 0
        for st in range(kinds.shape[0]):
            hs = h[st]
            if kinds[st] == 0:
                # Drift e^{h L_AV}.
                drift(x, W, minv, hs, n, k)
                have_g = have_h = have_c = have_hc = False
                continue
            # Kick e^{h L_BV}, fused with a corrector e^{hc L_CV} at the same q.
            hcs = hc[st]
            if TIME:
                tk = (float(call.step0 + s) + setup.ctime[st]) * call.tau
                if tk != t_have:
                    have_g = have_h = have_c = have_hc = False
                    pl[pl.shape[0] - 1] = tk
                    t_have = tk
            if not have_g:
                for i in range(n):
                    q[i] = x[i]
                grad(q, pl, g)
                counters[0] += 1
                if TIME:
                    dv = dtime(q, pl, gt)
                    if not (all_finite(gt, n) and dv - dv == 0.0):
                        return _GRAD, (have_g, have_h, have_c, have_hc, t_have, dv)
                if not all_finite(g, n):
                    return (derivative_status(q, n, _GRAD),
                            (have_g, have_h, have_c, have_hc, t_have, dv))
                have_g = True
            if (tangent or hcs != 0.0) and not have_h:
                hess(q, pl, H)
                counters[1] += 1
                if not all_finite(H.ravel(), (bw + 1) * n):
                    return (derivative_status(q, n, _HESS),
                            (have_g, have_h, have_c, have_hc, t_have, dv))
                have_h = True
            if hcs != 0.0:
                if not have_c:
                    for i in range(n):
                        mg[i] = minv[i] * g[i]
                    band_matvec(H, mg, gc, n, bw)
                    for i in range(n):
                        gc[i] *= 2.0  # ∇C = 2 D²V M⁻¹∇V
                    have_c = True
                for i in range(n):
                    x[n + i] -= hs * g[i] + hcs * gc[i]
                if TIME:
                    # ∂_tC = 2 (M⁻¹∇V)·∂_t∇V
                    ct = 0.0
                    for i in range(n):
                        ct += minv[i] * g[i] * gt[i]
                    state.pt[0] -= hs * dv + hcs * 2.0 * ct
            else:
                for i in range(n):
                    x[n + i] -= hs * g[i]
                if TIME:
                    state.pt[0] -= hs * dv
            if not tangent:
                continue
            counters[3] += 1
            if hcs == 0.0:
                for b in range(bw + 1):
                    for i in range(n):
                        Kb[b, i] = hs * H[b, i]
                band_kick_block(Kb, W, n, k, bw)
                continue
            if not have_hc:
                third(q, pl, mg, T)
                counters[2] += 1
                if not all_finite(T.ravel(), (bw + 1) * n):
                    return (derivative_status(q, n, _THIRD),
                            (have_g, have_h, have_c, have_hc, t_have, dv))
                band_square_add(H, minv, T, HC, n, bw, bwc)
                have_hc = True
            for b in range(bwc + 1):
                for i in range(n):
                    Kb[b, i] = hcs * HC[b, i]
            for b in range(bw + 1):
                for i in range(n):
                    Kb[b, i] += hs * H[b, i]
            band_kick_block(Kb, W, n, k, bwc)
        return _OK, (have_g, have_h, have_c, have_hc, t_have, dv)

    @njit(inline="always")
    def check(state, setup, ws, xe, call):
        return orbit_status(ws.xe, ws.n, call.escape_r2)

    @njit(inline="always")
    def flow(state, setup, ws, carry, xe, s, call, out):
        """(M⁻¹p, −∇V) at the end of step s, with ∇V of the last kick if q
        (and t) did not move since."""
        n = ws.n
        have_g, have_h, have_c, have_hc, t_have, dv = carry
        if TIME:
            te = float(call.step0 + s + 1) * call.tau
            if te != t_have:
                have_g = have_h = have_c = have_hc = False
                ws.pl[ws.pl.shape[0] - 1] = te
                t_have = te
        if not have_g:
            for i in range(n):
                ws.q[i] = xe[i]
            grad(ws.q, ws.pl, ws.g)
            state.counters[0] += 1
            if TIME:
                dv = dtime(ws.q, ws.pl, ws.gt)
            have_g = True
        for i in range(n):
            out[i] = setup.minv[i] * xe[n + i]
            out[n + i] = -ws.g[i]
        return have_g, have_h, have_c, have_hc, t_have, dv

    return StepBody(begin=begin, step=step, check=check, flow=flow)


@cache
def orbit_kernel(n, bw, kernels, time=False):
    """The one-orbit stepper without deviation vectors (k = 0) for N =
    ``n`` and bandwidth ``bw`` (−1 for both: read at run time) that writes
    the orbit after every step to ``state.record``: how the TDH methods,
    the two-particle method and the section finder integrate their orbit by
    the same machinery as the TM method. ``orbit(state, setup, call) ->
    (status, steps)`` with a :class:`TMOrbit`, a :class:`TMSetup` and a
    :class:`~varint.kernels.interval.Call`."""
    return orbit_loop(tm_body(n, 0, bw, kernels, time), record=True)


@cache
def tm_batch(n, k, bw, parallel, kernels, accumulate=no_accumulator, flow=False, time=False):
    """The batch stepper for N = ``n``, ``k`` vectors and bandwidth ``bw``
    (−1 for all three: read at run time) of the model ``kernels``
    (:func:`model_kernels`): ``batch(states, setup, call, status, done)``
    (:func:`varint.kernels.interval.batch_loop`) with a batch of
    :class:`TMOrbit` (``record`` unused) and a :class:`TMSetup`.
    ``accumulate`` updates ``states.aux[m]`` after every step; with
    ``flow`` it is given the phase-space velocity. With ``time`` V depends
    on t (see :func:`tm_body`). A failed step leaves the state as it was
    when the failure was detected (for a singular kernel: before that kick).
    """
    body = tm_body(n, k, bw, kernels, time)
    return batch_loop(body, parallel, accumulate, flow)


def specialised_sizes(n, k, bw):
    """The compile-time sizes (N, k, bandwidth) of the stepper for a system,
    −1 where a size is read at run time.

    Small systems fix all three. Large systems keep N at run time but still
    fix a small k and the bandwidth: for FPU-β with n = 512 and one vector
    that halves the time per step (the k-loop of every row update
    disappears).
    """
    if n <= SPECIALISE_N and k <= SPECIALISE_K:
        return n, k, bw
    if k <= SPECIALISE_K_LARGE_N:
        return -1, k, bw
    return -1, -1, -1


def batch_kernel(n, k, bw, parallel, kernels, accumulate=no_accumulator, flow=False,
                 time=False):
    """:func:`tm_batch` for the sizes of :func:`specialised_sizes`."""
    return tm_batch(*specialised_sizes(n, k, bw), parallel, kernels, accumulate, flow, time)

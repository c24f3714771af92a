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

After every step the orbit is checked and the deviation vectors are
renormalised (:mod:`varint.kernels.checks`); an indicator's accumulator
(:class:`varint.protocol.Accumulator`) is then updated. A derivative kernel
that returns a non-finite value at a finite position (a potential singular
on the orbit) stops the orbit before that kick, with the position kept.

Speed comes from two choices, both measured (studies/bench_tm.py):

* the model's kernels are numba dispatchers passed as arguments, so numba
  compiles them into the stepper (inlined, not called through a pointer);
* for small systems the sizes N, k and the bandwidth are compile-time
  constants of a stepper built by :func:`tm_batch`, so the many short loops
  unroll; large systems fix only k (≤ 8) and the bandwidth
  (:func:`specialised_sizes`).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import numba
from numba import njit, prange

from ..protocol import Renorm, Status
from .banded import band_kick_block, band_matvec, band_square_add
from .checks import (CHECK_EVERY, all_finite, derivative_status, orbit_status, renormalize,
                     tangent_overflow)

__all__ = ["tm_batch", "orbit_kernel", "batch_kernel", "specialised_sizes", "use_parallel",
           "no_accumulator", "SPECIALISE_N"]

_OK = int(Status.OK)
_GRAD = int(Status.GRADIENT_NONFINITE)
_HESS = int(Status.HESSIAN_NONFINITE)
_THIRD = int(Status.THIRD_NONFINITE)
_OVERFLOW = int(Status.TANGENT_OVERFLOW)
_NONE = int(Renorm.NONE)

#: Largest N and k for which the stepper is specialised to constant sizes,
#: and largest k specialised when N is too large to be a constant.
SPECIALISE_N, SPECIALISE_K, SPECIALISE_K_LARGE_N = 16, 32, 8


@njit
def no_accumulator(aux, r, x, W, flow, t):
    """The accumulator of indicators that accumulate nothing."""


def _make_orbit_kernel(N_C, K_C, BW_C, RECORD=False, FLOW=False, TIME=False):
    """The one-orbit stepper; sizes are constants when ≥ 0, else read from
    the arrays.

    With ``RECORD`` (a compile-time constant, so the TM method's stepper
    has no such code) the orbit after every step is written to
    ``record[step]``, of shape (≥ n_steps, 2N): the TDH methods
    (:mod:`varint.tdh`) integrate their orbit with this stepper (k = 0) and
    read D²V at the grid points from the record.

    With ``FLOW`` (likewise) the phase-space velocity (M⁻¹p, −∇V) at the end
    of each step is passed to the accumulator.

    With ``TIME`` (likewise) V depends on t (see the module docstring), and
    three more arguments are read: ``ctime`` (n_stages,), the time of each
    stage in units of τ from the step's start (:func:`varint.schemes.stage_times`);
    ``dtime``, the model's kernel ``dtime(q, par, gt) -> ∂_tV`` that also
    writes ``gt = ∂_t∇V``; and ``pt`` (1,), the orbit's p_t, updated in
    place. The kick of stage s of step ``step0 + i`` evaluates ∇V, D²V and
    the third derivatives at t = (step0 + i + ctime[s])·τ, written to the
    last entry of a private copy of ``par``: the time depends only on the
    step and stage, so chunking never changes a bit, and forces are reused
    between stages only when both q and t are bitwise unchanged. The time
    derivatives are evaluated with every gradient (and counted with it).
    """

    @njit
    def tm_orbit(x, W, acc_m, acc_e, n_steps, kinds, h, hc, minv, par, bw_rt,
                 grad, hess, third, renorm, escape_r2, counters, record, accumulate, aux,
                 step0, tau, ctime=None, dtime=None, pt=None):
        n = N_C if N_C >= 0 else x.shape[0] // 2
        k = K_C if K_C >= 0 else W.shape[1]
        bw = BW_C if BW_C >= 0 else bw_rt
        d = 2 * n
        bwc = min(2 * bw, n - 1)
        q = np.empty(n)      # contiguous copy of the positions for the model
        g = np.empty(n)      # ∇V
        gc = np.empty(n)     # ∇C
        mg = np.empty(n)     # M⁻¹∇V
        H = np.zeros((bw + 1, n))
        T = np.zeros((bw + 1, n))
        HC = np.zeros((bwc + 1, n))
        Kb = np.zeros((bwc + 1, n))
        r = np.empty(k if aux.shape[0] > 0 else 0)   # stretching, for the accumulator
        flow = np.empty(d if FLOW else 0)
        tangent = k > 0
        have_g = have_h = have_c = have_hc = False
        if TIME:
            pl = par.copy()          # par[-1] = t of this orbit's kicks
            last = pl.shape[0] - 1
            gt = np.empty(n)         # ∂_t∇V
            dv = 0.0                 # ∂_tV
            t_have = np.nan          # the time of g, H, ∇C and D²C
        else:
            pl = par
        for s in range(n_steps):
            for st in range(kinds.shape[0]):
                hs = h[st]
                if kinds[st] == 0:
                    # Drift e^{h L_AV}.
                    for i in range(n):
                        a = hs * minv[i]
                        x[i] += a * x[n + i]
                        for j in range(k):
                            W[i, j] += a * W[n + i, j]
                    have_g = have_h = have_c = have_hc = False
                    continue
                # Kick e^{h L_BV}, fused with a corrector e^{hc L_CV} at the same q.
                hcs = hc[st]
                if TIME:
                    tk = (float(step0 + s) + ctime[st]) * tau
                    if tk != t_have:
                        have_g = have_h = have_c = have_hc = False
                        pl[last] = tk
                        t_have = tk
                if not have_g:
                    for i in range(n):
                        q[i] = x[i]
                    grad(q, pl, g)
                    counters[0] += 1
                    if TIME:
                        dv = dtime(q, pl, gt)
                        if not (all_finite(gt, n) and dv - dv == 0.0):
                            return _GRAD, s
                    if not all_finite(g, n):
                        return derivative_status(q, n, _GRAD), s
                    have_g = True
                if (tangent or hcs != 0.0) and not have_h:
                    hess(q, pl, H)
                    counters[1] += 1
                    if not all_finite(H.ravel(), (bw + 1) * n):
                        return derivative_status(q, n, _HESS), s
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
                        pt[0] -= hs * dv + hcs * 2.0 * ct
                else:
                    for i in range(n):
                        x[n + i] -= hs * g[i]
                    if TIME:
                        pt[0] -= hs * dv
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
                        return derivative_status(q, n, _THIRD), s
                    band_square_add(H, minv, T, HC, n, bw, bwc)
                    have_hc = True
                for b in range(bwc + 1):
                    for i in range(n):
                        Kb[b, i] = hcs * HC[b, i]
                for b in range(bw + 1):
                    for i in range(n):
                        Kb[b, i] += hs * H[b, i]
                band_kick_block(Kb, W, n, k, bwc)
            status = orbit_status(x, n, escape_r2)
            if status != _OK:
                return status, s
            if RECORD:
                for i in range(d):
                    record[s, i] = x[i]
            if renorm != _NONE:
                status = renormalize(W, renorm, acc_m, acc_e, r, d, k)
                if status != _OK:
                    return status, s
                if aux.shape[0] > 0:
                    if FLOW:
                        if TIME:
                            te = float(step0 + s + 1) * tau
                            if te != t_have:
                                have_g = have_h = have_c = have_hc = False
                                pl[last] = te
                                t_have = te
                        if not have_g:  # the flow at the current q needs ∇V
                            for i in range(n):
                                q[i] = x[i]
                            grad(q, pl, g)
                            counters[0] += 1
                            if TIME:
                                dv = dtime(q, pl, gt)
                            have_g = True
                        for i in range(n):
                            flow[i] = minv[i] * x[n + i]
                            flow[n + i] = -g[i]
                    # The time from the integer step, so it does not depend on chunking.
                    accumulate(aux, r, x, W, flow, (step0 + s + 1) * tau)
            elif tangent and s % CHECK_EVERY == CHECK_EVERY - 1:
                if tangent_overflow(W):
                    return _OVERFLOW, s
        if renorm == _NONE and tangent and tangent_overflow(W):
            return _OVERFLOW, n_steps - 1
        return _OK, n_steps

    return tm_orbit


@lru_cache(maxsize=None)
def orbit_kernel(n, bw, time=False):
    """The one-orbit stepper without deviation vectors (k = 0) for N = ``n``
    and bandwidth ``bw`` (−1 for both: sizes read at run time), with the
    ``record`` of :func:`_make_orbit_kernel` written: how the TDH methods
    integrate their orbit by the same machinery as the TM method. With
    ``time``, for a time-dependent V (its arguments as in
    :func:`_make_orbit_kernel`)."""
    return _make_orbit_kernel(n, 0, bw, RECORD=True, TIME=time)


@lru_cache(maxsize=None)
def tm_batch(n, k, bw, parallel, flow=False, time=False):
    """The batch stepper for N = ``n``, ``k`` vectors and bandwidth ``bw``
    (pass −1 for all three to get the run-time-sized one).

    The returned function advances every orbit of ``X`` (M, 2N) whose
    ``status`` is OK by ``n_steps`` steps, in parallel over orbits if
    ``parallel``; ``done[m]`` receives the steps orbit m completed and
    ``status[m]`` its status. A failed step leaves the state as it was when
    the failure was detected (for a singular kernel: before that kick).
    ``accumulate`` updates ``aux[m]`` (k, columns) after every step
    (``step0``: the step count at the start, ``tau``: the step); pass :func:`no_accumulator` and an
    empty ``aux`` (M, 0, 0) for none. With ``flow`` the accumulator is given
    the phase-space velocity. With ``time`` (a time-dependent V) three more
    arguments follow ``tau``: ``ctime`` (n_stages,) and the model's
    ``dtime`` kernel (see :func:`_make_orbit_kernel`) and ``pt`` (M,), the
    orbits' momenta conjugate to time, updated in place.
    """
    tm_orbit = _make_orbit_kernel(n, k, bw, FLOW=flow, TIME=time)

    @njit(parallel=parallel)
    def batch(X, W, acc_m, acc_e, n_steps, kinds, h, hc, minv, par, bw_rt,
              grad, hess, third, renorm, escape_r2, counters, status, done, accumulate, aux,
              step0, tau, ctime=None, dtime=None, pt=None):
        for m in prange(X.shape[0]):
            if status[m] != _OK:
                done[m] = 0
                continue
            if time:
                st, steps = tm_orbit(X[m], W[m], acc_m[m], acc_e[m], n_steps, kinds, h, hc,
                                     minv, par, bw_rt, grad, hess, third, renorm, escape_r2,
                                     counters[m], np.empty((0, 0)), accumulate, aux[m], step0,
                                     tau, ctime, dtime, pt[m:m + 1])
            else:
                st, steps = tm_orbit(X[m], W[m], acc_m[m], acc_e[m], n_steps, kinds, h, hc,
                                     minv, par, bw_rt, grad, hess, third, renorm, escape_r2,
                                     counters[m], np.empty((0, 0)), accumulate, aux[m], step0,
                                     tau)
            status[m] = st
            done[m] = steps

    return batch


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


def use_parallel(parallel, n_orbits):
    """Whether a batch runs its orbits on all cores: as asked, or by default
    when there is more than one orbit and more than one numba thread."""
    if parallel is None:
        return n_orbits > 1 and numba.get_num_threads() > 1
    return bool(parallel)


def batch_kernel(n, k, bw, parallel, flow=False, time=False):
    """:func:`tm_batch` for the sizes of :func:`specialised_sizes`."""
    return tm_batch(*specialised_sizes(n, k, bw), parallel, flow, time)

"""Compiled tangent-map stepper: one generic kernel for every splitting scheme.

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

After every step the deviation vectors are renormalised in place:
``RENORM_QR`` (modified Gram–Schmidt, for Lyapunov spectra: paper eq. 10),
``RENORM_NORMALIZE`` (unit columns, for GALI/SALI: paper eq. 15) or
``RENORM_NONE`` (the raw tangent map). The logarithms of the removed
stretching factors are needed only at output times, so the factors are
multiplied into a mantissa ``acc_m`` whose binary exponent is moved into the
integer ``acc_e`` with ``frexp`` (exact) whenever it leaves [2⁻⁵⁰⁰, 2⁵⁰⁰]:
no ``log`` in the hot loop, no overflow, and log(acc_m) + acc_e·ln 2 is the
sum of the logs to round-off.

Speed comes from two choices, both measured (studies/bench_tm.py):

* the model's kernels are numba dispatchers passed as arguments, so numba
  compiles them into the stepper (inlined, not called through a pointer);
* for small systems the sizes N, k and the bandwidth are compile-time
  constants of a stepper built by :func:`tm_batch`, so the many short loops
  unroll; this halves the time per step of Hénon–Heiles compared with
  run-time sizes. Each (N, k, bandwidth) costs one compilation of about a
  second or two per process; large systems fix only k (≤ 8) and the
  bandwidth (:func:`specialised_sizes`).

With ``fast_indicators`` the stepper also accumulates MEGNO, FLI and OFLI
after every step (:func:`_fast_indicators`, used by :func:`varint.megno`).
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
import numba
from numba import njit, prange

from ._banded import band_kick_block, band_matvec, band_square_add

RENORM_NONE, RENORM_NORMALIZE, RENORM_QR = 0, 1, 2

# Status codes returned per orbit (0 = fine).
OK, ORBIT_NONFINITE, ESCAPED, TANGENT_DEGENERATE, TANGENT_OVERFLOW = 0, 1, 2, 3, 4
#: Negative codes stop an orbit on purpose, not as a failure: DECIDED marks
#: an orbit frozen by early stopping once its indicator settled its nature
#: (:func:`varint.driver.drive`'s ``decide``). Every stepper skips any
#: non-zero status; only positive codes are failures.
DECIDED = -1

#: Counters kept per orbit: ∇V evaluations, D²V evaluations, third-derivative
#: contractions, kick products on the deviation vectors (D²V·W or D²C·W).
COUNTERS = ("gradient", "hessian", "third", "tangent_products")

_BIG = 2.0 ** 500
_SMALL = 2.0 ** -500
#: Unrenormalised deviation vectors larger than this are reported as overflow.
TANGENT_LIMIT = 1e300
#: Steps between the (cheap but not free) overflow checks of raw deviations.
_CHECK_EVERY = 16
#: Largest N and k for which the stepper is specialised to constant sizes,
#: and largest k specialised when N is too large to be a constant.
SPECIALISE_N, SPECIALISE_K, SPECIALISE_K_LARGE_N = 16, 32, 8


@njit(inline="always")
def _renormalize(W, mode, acc_m, acc_e, d, k):
    for j in range(k):
        if mode == RENORM_QR:
            for a in range(j):
                r = 0.0
                for i in range(d):
                    r += W[i, a] * W[i, j]
                for i in range(d):
                    W[i, j] -= r * W[i, a]
        r = 0.0
        for i in range(d):
            r += W[i, j] * W[i, j]
        r = math.sqrt(r)
        if not (r > 0.0 and r < np.inf):
            return False
        a = acc_m[j] * r
        if a > _BIG or a < _SMALL:
            m, e = math.frexp(a)
            a = m
            acc_e[j] += e
        acc_m[j] = a
        inv = 1.0 / r
        for i in range(d):
            W[i, j] *= inv
    return True


@njit(cache=True)
def renormalize(W, mode, acc_m, acc_e):
    """Renormalise the columns of ``W`` (2N, k) in place, as the TM stepper
    does after every step; for the other methods, which renormalise between
    calls of their integrator.

    ``mode`` is ``RENORM_QR`` (modified Gram–Schmidt; the positive diagonal
    of R is multiplied into the accumulators ``acc_m``/``acc_e``) or
    ``RENORM_NORMALIZE`` (each column to unit length, its norm multiplied
    in). Returns False if a column is zero or non-finite.
    """
    return _renormalize(W, mode, acc_m, acc_e, W.shape[0], W.shape[1])


@njit(cache=True)
def _tangent_overflow(W):
    # Deliberately not inlined: a compact call site keeps the hot loop small
    # (inlining this check cost ~15% per step in the Hénon–Heiles benchmark).
    for i in range(W.shape[0]):
        for j in range(W.shape[1]):
            if not (abs(W[i, j]) < TANGENT_LIMIT):
                return True
    return False


#: Columns of the per-vector accumulators of :func:`_fast_indicators`.
AUX_LOG, AUX_WEIGHTED, AUX_MEGNO_SUM, AUX_FLI, AUX_OFLI = range(5)
N_AUX = 5


@njit(inline="always")
def _fast_indicators(x, W, aux, g, minv, t, n, k):
    """Accumulate MEGNO, FLI and OFLI of each vector after a step ending at
    time ``t``, before the vectors are renormalised (so ‖w_j‖ is the
    stretching r of this step).

    With ln r_i the log-stretching of step i (time t_i), S = Σ ln r_i is
    ln‖w(t)‖ of the never-renormalised vector; the accumulators are
    S, Σ t_i ln r_i, Σ_i Y(t_i) with the MEGNO Y(t) = (2/t) Σ t_i ln r_i
    (the discrete form of (2/t) ∫ s δ̇/δ ds), FLI = max S and
    OFLI = max ln‖w_⊥‖, w_⊥ the part of w orthogonal to the flow
    f = (M⁻¹p, −∇V); ``g`` is ∇V at the current q.
    """
    ff = 0.0
    for i in range(n):
        v = minv[i] * x[n + i]
        ff += v * v + g[i] * g[i]
    for j in range(k):
        ww = 0.0
        wf = 0.0
        for i in range(n):
            ww += W[i, j] * W[i, j] + W[n + i, j] * W[n + i, j]
            wf += W[i, j] * minv[i] * x[n + i] - W[n + i, j] * g[i]
        lr = 0.5 * math.log(ww)
        s = aux[j, AUX_LOG] + lr
        aux[j, AUX_LOG] = s
        aux[j, AUX_WEIGHTED] += t * lr
        aux[j, AUX_MEGNO_SUM] += 2.0 * aux[j, AUX_WEIGHTED] / t
        if s > aux[j, AUX_FLI]:
            aux[j, AUX_FLI] = s
        perp = ww - wf * wf / ff if ff > 0.0 else ww
        if perp > 0.0:
            o = s - lr + 0.5 * math.log(perp)
            if o > aux[j, AUX_OFLI]:
                aux[j, AUX_OFLI] = o


def _make_orbit_kernel(N_C, K_C, BW_C, RECORD=False, AUX=False):
    """The one-orbit stepper; sizes are constants when ≥ 0, else read from
    the arrays.

    With ``RECORD`` (a compile-time constant, so the TM method's stepper
    has no such code) the orbit after every step is written to
    ``record[step]``, of shape (≥ n_steps, 2N): the TDH methods
    (:mod:`varint.tdh`) integrate their orbit with this stepper (k = 0) and
    read D²V at the grid points from the record.

    With ``AUX`` (likewise a compile-time constant) MEGNO, FLI and OFLI are
    accumulated into ``aux`` (k, N_AUX) after every step
    (:func:`_fast_indicators`); ``t0`` is the time at the start of the call
    and ``tau`` the step.
    """

    @njit
    def tm_orbit(x, W, acc_m, acc_e, n_steps, kinds, h, hc, minv, par, bw_rt,
                 grad, hess, third, renorm, escape_r2, counters, record, aux, t0, tau):
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
        tangent = k > 0
        have_g = have_h = have_c = have_hc = False
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
                if not have_g:
                    for i in range(n):
                        q[i] = x[i]
                    grad(q, par, g)
                    counters[0] += 1
                    have_g = True
                if (tangent or hcs != 0.0) and not have_h:
                    hess(q, par, H)
                    counters[1] += 1
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
                else:
                    for i in range(n):
                        x[n + i] -= hs * g[i]
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
                    third(q, par, mg, T)
                    counters[2] += 1
                    band_square_add(H, minv, T, HC, n, bw, bwc)
                    have_hc = True
                for b in range(bwc + 1):
                    for i in range(n):
                        Kb[b, i] = hcs * HC[b, i]
                for b in range(bw + 1):
                    for i in range(n):
                        Kb[b, i] += hs * H[b, i]
                band_kick_block(Kb, W, n, k, bwc)
            rq = 0.0
            rp = 0.0
            for i in range(n):
                rq += x[i] * x[i]
                rp += x[n + i] * x[n + i]
            if rq > escape_r2:
                return ESCAPED, s
            if not (rq + rp < np.inf):
                return ORBIT_NONFINITE, s
            if RECORD:
                for i in range(d):
                    record[s, i] = x[i]
            if AUX:
                if not have_g:  # the flow at the current q needs ∇V
                    for i in range(n):
                        q[i] = x[i]
                    grad(q, par, g)
                    counters[0] += 1
                    have_g = True
                _fast_indicators(x, W, aux, g, minv, t0 + (s + 1) * tau, n, k)
            if renorm != RENORM_NONE:
                if not _renormalize(W, renorm, acc_m, acc_e, d, k):
                    return TANGENT_DEGENERATE, s
            elif tangent and s % _CHECK_EVERY == _CHECK_EVERY - 1:
                if _tangent_overflow(W):
                    return TANGENT_OVERFLOW, s
        if renorm == RENORM_NONE and tangent and _tangent_overflow(W):
            return TANGENT_OVERFLOW, n_steps - 1
        return OK, n_steps

    return tm_orbit


@lru_cache(maxsize=None)
def orbit_kernel(n, bw):
    """The one-orbit stepper without deviation vectors (k = 0) for N = ``n``
    and bandwidth ``bw`` (−1 for both: sizes read at run time), with the
    ``record`` of :func:`_make_orbit_kernel` written: how the TDH methods
    integrate their orbit by the same machinery as the TM method."""
    return _make_orbit_kernel(n, 0, bw, RECORD=True)


@lru_cache(maxsize=None)
def tm_batch(n, k, bw, parallel, fast_indicators=False):
    """The batch stepper for N = ``n``, ``k`` vectors and bandwidth ``bw``
    (pass −1 for all three to get the run-time-sized one).

    The returned function advances every orbit of ``X`` (M, 2N) whose
    ``status`` is OK by ``n_steps`` steps, in parallel over orbits if
    ``parallel``; ``done[m]`` receives the steps orbit m completed and
    ``status[m]`` its status. A failed step leaves the state as it was at
    the end of that step. With ``fast_indicators``, MEGNO, FLI and OFLI are
    accumulated into ``aux`` (M, k, N_AUX) (``t0``: time at the start,
    ``tau``: step); otherwise those three arguments are ignored.
    """
    tm_orbit = _make_orbit_kernel(n, k, bw, AUX=fast_indicators)

    @njit(parallel=parallel)
    def batch(X, W, acc_m, acc_e, n_steps, kinds, h, hc, minv, par, bw_rt,
              grad, hess, third, renorm, escape_r2, counters, status, done, aux, t0, tau):
        for m in prange(X.shape[0]):
            if status[m] != OK:
                done[m] = 0
                continue
            st, steps = tm_orbit(X[m], W[m], acc_m[m], acc_e[m], n_steps, kinds, h, hc,
                                 minv, par, bw_rt, grad, hess, third, renorm, escape_r2,
                                 counters[m], np.empty((0, 0)), aux[m], t0, tau)
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


def batch_kernel(n, k, bw, parallel, fast_indicators=False):
    """:func:`tm_batch` for the sizes of :func:`specialised_sizes`."""
    return tm_batch(*specialised_sizes(n, k, bw), parallel, fast_indicators)

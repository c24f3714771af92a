"""The end-of-interval work every stepper shares, written once: the orbit's
checks (escape, non-finite), the renormalisation of the deviation vectors
with the bookkeeping of their stretching, and the overflow check of
unrenormalised vectors.

The TM stepper, the TDH steppers, the section finder and the baselines all
call these functions (inlined into their compiled loops), so an orbit fails
for the same reasons, with the same status codes (:class:`~varint.protocol.Status`),
whatever method advanced it.

The stretching factors are needed as logarithms only at output times, so
they are multiplied into a mantissa ``acc_m`` that is rescaled by 2^∓500
(exactly) into the integer exponent ``acc_e`` whenever it leaves
[2⁻⁵⁰⁰, 2⁵⁰⁰]: no ``log`` in the hot loop, no overflow, and
log(acc_m) + acc_e·ln 2 is the sum of the logarithms to round-off.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..protocol import Renorm, Status, TANGENT_LIMIT
from .inlining import into_kernels

__all__ = ["orbit_status", "orbit_status_wide", "square_sums", "state_status", "renormalize",
           "renormalize_block", "renormalized_rows",
           "tangent_overflow", "all_finite", "derivative_status", "ACC_BIG", "ACC_SMALL",
           "CHECK_EVERY", "HUGE_Q2"]

# Plain integers in the compiled loops (numba folds them to constants).
_OK = int(Status.OK)
_ESCAPED = int(Status.ESCAPED)
_NONFINITE = int(Status.ORBIT_NONFINITE)
_DEGENERATE = int(Status.TANGENT_DEGENERATE)
_QR = int(Renorm.QR)

#: The range of the stretching mantissa before its exponent is moved out.
ACC_BIG = 2.0 ** 500
ACC_SMALL = 2.0 ** -500
#: Steps between the (cheap but not free) overflow checks of raw deviations.
CHECK_EVERY = 16
#: A derivative kernel that is not finite where |q|² exceeds this reports
#: the orbit as running away (ORBIT_NONFINITE), not the potential as
#: singular: there the derivatives overflow before the state does.
HUGE_Q2 = 1e100


@njit(inline=into_kernels)
def orbit_status(x, n, escape_r2):
    """``Status.ESCAPED`` if |q|² > ``escape_r2``, ``ORBIT_NONFINITE`` if
    the state ``x`` (2N,) holds a NaN or infinity, else ``OK``."""
    rq = 0.0
    rp = 0.0
    for i in range(n):
        rq += x[i] * x[i]
        rp += x[n + i] * x[n + i]
    if rq > escape_r2:
        return _ESCAPED
    if not (rq + rp < np.inf):
        return _NONFINITE
    return _OK


#: Below this |q|² + |p|² the sums of :func:`orbit_status_wide` cannot have
#: overflowed in any order (2^1000: far from the largest double, 2^1024).
_WIDE_MAX = 2.0 ** 1000
#: 8u (u = 2^-53, the unit round-off) per site: four times the bound
#: 2γ_n ≈ 2nu on the difference of two summation orders of n non-negative terms
#: (Higham 2002, Accuracy and Stability of Numerical Algorithms, eq. 4.4).
_ORDER_SLACK = 2.0 ** -50


@njit(cache=True, fastmath={"reassoc"})
def square_sums(x, n):
    """|q|² and |p|² of the state ``x`` (2N,), ``n`` = N, added in whatever
    order the compiler finds fastest (``reassoc`` alone: NaN and infinity
    still propagate). Called, not inlined, so that the flag stays with it
    (numba inlines a function into its caller with the caller's flags)."""
    rq = 0.0
    rp = 0.0
    for i in range(n):
        rq += x[i] * x[i]
        rp += x[n + i] * x[n + i]
    return rq, rp


@njit(inline=into_kernels)
def orbit_status_wide(x, n, escape_r2):
    """:func:`orbit_status` of ``x``, the same status for every ``x``, in a
    fraction of its time for a long state.

    :func:`orbit_status` adds the squares in one chain, one dependent
    addition per site (3.3 µs at N = 4096, as much as a kick of FPU-β).
    Here they are added in vector lanes (:func:`square_sums`, 0.6 µs), and
    only the answer is kept: the order of a sum of n non-negative terms
    moves it by at most 2γ_n ≈ 2nu of itself (Higham 2002, Accuracy and
    Stability of Numerical Algorithms, eq. 4.4), so when these sums are
    finite, far from overflow and |q|² is below ``escape_r2`` by more than
    :data:`_ORDER_SLACK` · n · |q|², the chained sums give OK too. In any
    other case (an orbit that escaped, failed, or stands within round-off
    of the escape radius) the answer is :func:`orbit_status`'s own.
    """
    rq, rp = square_sums(x, n)
    if rq + rp < _WIDE_MAX and rq < escape_r2 - rq * (n * _ORDER_SLACK):
        return _OK
    return orbit_status(x, n, escape_r2)


@njit(inline=into_kernels)
def state_status(x, d, escape_r2):
    """:func:`orbit_status` for a map's state ``x`` (d,), whose components
    need not split into positions and momenta: ``ESCAPED`` if |x|² >
    ``escape_r2``, ``ORBIT_NONFINITE`` if it holds a NaN or infinity."""
    r = 0.0
    for i in range(d):
        r += x[i] * x[i]
    if not (r < np.inf):
        return _NONFINITE
    if r > escape_r2:
        return _ESCAPED
    return _OK


@njit(inline=into_kernels)
def all_finite(a, n):
    """Whether the first ``n`` entries of the 1-D ``a`` are finite (one sum:
    a NaN or infinity anywhere makes it non-finite)."""
    s = 0.0
    for i in range(n):
        s += a[i]
    return s - s == 0.0


@njit(inline=into_kernels)
def derivative_status(q, n, status):
    """``status`` (a derivative kernel was not finite at q), or
    ``ORBIT_NONFINITE`` if |q|² > :data:`HUGE_Q2`."""
    rq = 0.0
    for i in range(n):
        rq += q[i] * q[i]
    return status if rq < HUGE_Q2 else _NONFINITE


@njit(inline=into_kernels)
def renormalize(W, mode, acc_m, acc_e, r, d, k):
    """Renormalise the k columns of ``W`` (d, k) in place and return
    ``Status.OK``, or ``TANGENT_DEGENERATE`` if a column is zero or not
    finite.

    ``mode`` is ``Renorm.QR`` (modified Gram–Schmidt; the positive diagonal
    of R is the stretching) or ``Renorm.NORMALIZE`` (each column to unit
    length, its norm the stretching). The stretching of column j is written
    to ``r[j]`` (when ``r`` has k entries; pass an empty array otherwise) and
    multiplied into ``acc_m[j]``/``acc_e[j]``.
    """
    keep = r.shape[0] >= k
    for j in range(k):
        if mode == _QR:
            for a in range(j):
                s = 0.0
                for i in range(d):
                    s += W[i, a] * W[i, j]
                for i in range(d):
                    W[i, j] -= s * W[i, a]
        s = 0.0
        for i in range(d):
            s += W[i, j] * W[i, j]
        s = math.sqrt(s)
        if not (s > 0.0 and s < np.inf):
            return _DEGENERATE
        if keep:
            r[j] = s
        a = acc_m[j] * s
        # Exact powers of two keep the mantissa in range (no call: cheap).
        if a > ACC_BIG:
            a *= ACC_SMALL
            acc_e[j] += 500
        elif a < ACC_SMALL:
            a *= ACC_BIG
            acc_e[j] -= 500
        acc_m[j] = a
        inv = 1.0 / s
        for i in range(d):
            W[i, j] *= inv
    return _OK


@njit(cache=True)
def renormalize_block(W, mode, acc_m, acc_e, r):
    """:func:`renormalize` of every column of ``W`` (2N, k), callable from
    Python and from methods that renormalise between calls of their
    integrator."""
    return renormalize(W, mode, acc_m, acc_e, r, W.shape[0], W.shape[1])


@njit(cache=True)
def renormalized_rows(W, mode, acc_m, acc_e):
    """Renormalised copies of the vectors ``W`` (R, 2N, k) of R rows, with
    copies of their accumulators: :func:`renormalize` of each row, so a
    snapshot read between renormalisations gives what the stepper would
    have held had it renormalised there. A row whose vectors are degenerate
    (zero, not finite: a failed orbit) gets NaN vectors and mantissas."""
    W = W.copy()
    acc_m = acc_m.copy()
    acc_e = acc_e.copy()
    none = np.empty(0)
    d, k = W.shape[1], W.shape[2]
    for row in range(W.shape[0]):
        if renormalize(W[row], mode, acc_m[row], acc_e[row], none, d, k) != _OK:
            W[row] = np.nan
            acc_m[row] = np.nan
    return W, acc_m, acc_e


@njit(cache=True)
def tangent_overflow(W):
    """Whether any entry of the unrenormalised vectors ``W`` has reached
    :data:`~varint.protocol.TANGENT_LIMIT` (or is not finite)."""
    # Deliberately not inlined: a compact call site keeps the hot loop small
    # (inlining this check cost ~15% per step in the Hénon–Heiles benchmark).
    for i in range(W.shape[0]):
        for j in range(W.shape[1]):
            if not (abs(W[i, j]) < TANGENT_LIMIT):
                return True
    return False

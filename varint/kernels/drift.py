"""The drift of a kinetic energy T = ½ pᵀM⁻¹p with a diagonal mass matrix,
and its tangent: the flow e^{h L_T} moves q by h M⁻¹p and δq by h M⁻¹δp
(p and δp unchanged) — exact, the A-step of every ABA-type splitting
(Laskar & Robutel 2001). Inlined like :mod:`varint.kernels.banded`.
"""

from __future__ import annotations

from numba import njit

from .inlining import into_kernels

__all__ = ["drift"]


@njit(inline=into_kernels)
def drift(x, W, minv, h, n, k):
    """``q += h M⁻¹p`` in ``x = (q, p)`` (length 2n) and ``δq += h M⁻¹δp``
    in the k columns of ``W`` (2n × k), ``minv`` the diagonal of M⁻¹."""
    for i in range(n):
        a = h * minv[i]
        x[i] += a * x[n + i]
        for j in range(k):
            W[i, j] += a * W[n + i, j]

"""Symmetric band matrices: the storage of every Hessian in varint.

A symmetric N×N matrix of bandwidth ``bw`` is stored as ``B`` of shape
``(bw + 1, N)`` with ``B[b, i] = A[i, i + b]`` (zero where ``i + b >= N``).
A dense Hessian of a small system is the case ``bw = N − 1``; a lattice with
nearest-neighbour coupling has ``bw = 1`` and never forms an N×N matrix.

The kernels take the sizes as arguments and are inlined into their callers
(``inline="always"``): inside the tangent-map stepper the sizes are
compile-time constants for small systems, so these loops unroll completely.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .inlining import into_kernels


@njit(inline=into_kernels)
def band_matvec(B, x, y, n, bw):
    """``y = A x`` for the band-stored symmetric ``A``."""
    for i in range(n):
        y[i] = B[0, i] * x[i]
    for b in range(1, bw + 1):
        for i in range(n - b):
            y[i] += B[b, i] * x[i + b]
            y[i + b] += B[b, i] * x[i]


@njit(inline=into_kernels)
def band_kick_block(B, W, n, k, bw):
    """``δp −= A δq`` for deviation vectors ``W = (δq; δp)`` of shape
    (2N, k), in place: the tangent part of a kick with kick matrix ``A``.

    Rows of ``W`` are indexed directly rather than through views, which
    keeps the inlined loops free of stride arithmetic.
    """
    for i in range(n):
        a = B[0, i]
        for j in range(k):
            W[n + i, j] -= a * W[i, j]
    for b in range(1, bw + 1):
        for i in range(n - b):
            a = B[b, i]
            for j in range(k):
                W[n + i, j] -= a * W[i + b, j]
                W[n + i + b, j] -= a * W[i, j]


@njit(inline=into_kernels)
def band_square_add(B, d, T, S, n, bw, bws):
    """``S = 2 (A diag(d) A + T)`` for band-stored symmetric ``A`` and ``T``
    of bandwidth ``bw``; ``S`` has bandwidth ``bws = min(2 bw, N − 1)``.

    This is D²C = 2 (D²V M⁻¹ D²V + Σ_k (M⁻¹∇V)_k D²(∂_kV)) with
    ``T`` the contracted third derivatives.
    """
    for c in range(bws + 1):
        for i in range(n - c):
            j = i + c
            s = T[c, i] if c <= bw else 0.0
            # A[i, m] and A[m, j] are both inside the band for these m.
            for m in range(max(0, j - bw), min(n - 1, i + bw) + 1):
                a1 = B[m - i, i] if m >= i else B[i - m, m]
                a2 = B[j - m, m] if j >= m else B[m - j, j]
                s += a1 * d[m] * a2
            S[c, i] = 2.0 * s


def band_to_dense(B):
    """Dense symmetric matrix from band storage (for tests and small N)."""
    B = np.asarray(B)
    n = B.shape[-1]
    A = np.zeros(B.shape[:-2] + (n, n))
    for b in range(B.shape[-2]):
        idx = np.arange(n - b)
        A[..., idx, idx + b] = B[..., b, : n - b]
        A[..., idx + b, idx] = B[..., b, : n - b]
    return A

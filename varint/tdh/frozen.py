"""The exact flow of the frozen tangent dynamics Hamiltonian (TDHes).

Over one interval [t_i, t_i + Δt) the TDHes and TDHcc methods freeze the
coefficients of the TDH (Skokos & Gerlach 2010, eq. 9) at the orbit's
position q_i:

    H_V(δq, δp) = ½ δpᵀM⁻¹δp + ½ δqᵀ A δq,   A = D²V(q_i).

With S = M^{-1/2} (diagonal) the canonical change u = S⁻¹δq, v = Sδp turns
this into ½|v|² + ½ uᵀKu with K = S A S, and the eigen-decomposition
K = Q Λ Qᵀ (paper eq. 29, extended to a diagonal mass) into N uncoupled
oscillators ½(P_r² + λ_r Q_r²) (paper eq. 28, H_VQP), whose flow over h is

    Q_r(h) = c Q_r + s P_r,   P_r(h) = −λ_r s Q_r + c P_r,

with c = cos(√λ h), s = sin(√λ h)/√λ for λ > 0 (an oscillating mode),
c = cosh(√−λ h), s = sinh(√−λ h)/√−λ for λ < 0 (a hyperbolic one) and
c = 1, s = h for λ = 0 (a free one). :func:`oscillator` computes c and s as
functions of z = λh², by their Taylor series near z = 0, so they pass
through the free case continuously instead of dividing 0 by 0.

For Hénon–Heiles the eigenvectors are known in closed form (paper eq. A.10):
:func:`henon_heiles_transform`. (Equation numbers count the equations of
the paper's LaTeX source.)
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..kernels.inlining import into_kernels

__all__ = ["oscillator", "henon_heiles_transform", "lapack_eig", "henon_heiles_eig"]

#: Below this |z| = |λ|h² the series of c and s/h are used: their first
#: omitted terms, z³/720 and z³/5040, are below 1e-18 there, while the
#: closed forms are accurate to round-off above it.
_SERIES_Z = 1e-6


@njit(inline=into_kernels)
def _oscillator(lam, h):
    z = lam * h * h
    if abs(z) < _SERIES_Z:
        return 1.0 - z / 2.0 + z * z / 24.0, h * (1.0 - z / 6.0 + z * z / 120.0)
    if lam > 0.0:
        w = math.sqrt(lam)
        return math.cos(w * h), math.sin(w * h) / w
    w = math.sqrt(-lam)
    return math.cosh(w * h), math.sinh(w * h) / w


@njit(cache=True)
def oscillator(lam, h):
    """``(c, s)`` of the flow Q(h) = cQ + sP, P(h) = −λsQ + cP of the 1-dof
    Hamiltonian ½(P² + λQ²), for any real λ.

    Parameters
    ----------
    lam : float
        The eigenvalue λ: > 0 oscillating, 0 free, < 0 hyperbolic.
    h : float
        The time step.

    Returns
    -------
    c, s : float
        cos(√λ h) and sin(√λ h)/√λ, or their continuations cosh and
        sinh(√−λ h)/√−λ for λ < 0; s → h as λ → 0.
    """
    return _oscillator(lam, h)


@njit(inline="always")
def _hh_rotation(x, y):
    # The unit eigenvector (c, s) of D²V = [[1+2y, 2x], [2x, 1−2y]] for the
    # eigenvalue 1 + 2r, r = |q|: the first column of the paper's T (A.10),
    # T = [[c, −s], [s, c]] with c = √((r+y)/2r), s = x/√(2r(r+y)). For
    # y < 0, r + y cancels (and is 0/0 on the negative y axis), so there the
    # same expressions are written with r + y = x²/(r − y).
    r = math.hypot(x, y)
    if r == 0.0:
        return 1.0, 0.0, r  # D²V = I: any basis diagonalises it
    if y >= 0.0:
        return math.sqrt((r + y) / (2.0 * r)), x / math.sqrt(2.0 * r * (r + y)), r
    s = math.sqrt((r - y) / (2.0 * r))
    return abs(x) / math.sqrt(2.0 * r * (r - y)), s if x >= 0.0 else -s, r


def henon_heiles_transform(x, y):
    """The paper's analytic diagonalisation of the Hénon–Heiles TDH (A.10).

    The canonical change δq = T δQ, δp = T δP turns the TDH frozen at the
    orbit point (x, y) into the uncoupled oscillators of eq. (A.11).

    Parameters
    ----------
    x, y : float
        The orbit's position q(t_i).

    Returns
    -------
    T : ndarray, shape (2, 2)
        Orthogonal; its columns are eigenvectors of D²V(x, y) (eq. A.12).
    lam : ndarray, shape (2,)
        The eigenvalues 1 + 2√(x²+y²) and 1 − 2√(x²+y²), in T's column order.

    Notes
    -----
    The paper's expressions are used as printed where they are well
    conditioned (y ≥ 0); for y < 0 the factor r + y (r = √(x²+y²)), which
    cancels and is 0/0 on the negative y axis, is written as x²/(r − y).
    At x = y = 0, D²V = I and T = I.

    References
    ----------
    Skokos & Gerlach, Phys. Rev. E 82, 036704 (2010), Appendix A, eqs.
    (A.9)–(A.12).
    """
    x, y = float(x), float(y)
    if not (math.isfinite(x) and math.isfinite(y)):
        raise ValueError(f"x and y must be finite, got {x!r}, {y!r}")
    c, s, r = _hh_rotation(x, y)
    return np.array([[c, -s], [s, c]]), np.array([1.0 + 2.0 * r, 1.0 - 2.0 * r])


@njit
def lapack_eig(q, K, lam, Q):
    """Eigen-decomposition K = Q diag(lam) Qᵀ of the symmetric ``K`` (N, N)
    by LAPACK (``numpy.linalg.eigh``), written into ``lam`` and ``Q``; ``q``
    is not used (the signature is that of :func:`henon_heiles_eig`)."""
    w, v = np.linalg.eigh(K)
    for i in range(w.shape[0]):
        lam[i] = w[i]
        for j in range(w.shape[0]):
            Q[i, j] = v[i, j]


@njit
def henon_heiles_eig(q, K, lam, Q):
    """The same for Hénon–Heiles from the orbit point ``q`` = (x, y), by the
    paper's analytic transformation (A.10); ``K`` is not read."""
    c, s, r = _hh_rotation(q[0], q[1])
    lam[0] = 1.0 + 2.0 * r
    lam[1] = 1.0 - 2.0 * r
    Q[0, 0] = c
    Q[0, 1] = -s
    Q[1, 0] = s
    Q[1, 1] = c

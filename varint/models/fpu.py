"""The FPU-β chain with fixed ends (Skokos & Gerlach 2010, eq. 56).

    H = Σ_{i=1}^{n} p_i²/2 + Σ_{i=0}^{n} [ r_i²/2 + β r_i⁴/4 ],
    r_i = q_{i+1} − q_i,  q_0 = q_{n+1} = 0.

Every derivative is assembled bond by bond, so D²V is tridiagonal and never
formed as an n×n matrix: the kernels cost O(n) and work at n = 4096.
"""

from __future__ import annotations

import numbers

import numpy as np
from numba import njit

from .base import Model

__all__ = ["FPUBeta"]


@njit(cache=True, error_model="numpy")
def _bond(q, b):
    # Bond b joins particles b − 1 and b (0-based, walls at −1 and n).
    n = q.shape[0]
    left = q[b - 1] if b >= 1 else 0.0
    right = q[b] if b < n else 0.0
    return right - left


@njit(cache=True, error_model="numpy")
def _grad(q, par, g):
    beta = par[0]
    n = q.shape[0]
    for i in range(n):
        g[i] = 0.0
    for b in range(n + 1):
        r = _bond(q, b)
        f = r + beta * r * r * r  # φ'(r)
        if b < n:
            g[b] += f
        if b >= 1:
            g[b - 1] -= f


@njit(inline="always", error_model="numpy")
def _add_bond(B, b, k, n):
    # A bond b with stiffness k joins particles b − 1 and b: it adds
    # k e_b e_bᵀ to a symmetric tridiagonal matrix in band storage.
    if b < n:
        B[0, b] += k
    if b >= 1:
        B[0, b - 1] += k
    if 1 <= b < n:
        B[1, b - 1] = -k


@njit(cache=True, error_model="numpy")
def _hess(q, par, B):
    beta = par[0]
    n = q.shape[0]
    for i in range(n):
        B[0, i] = 0.0
        B[1, i] = 0.0
    for b in range(n + 1):
        r = _bond(q, b)
        _add_bond(B, b, 1.0 + 3.0 * beta * r * r, n)  # φ''(r)


@njit(cache=True, error_model="numpy")
def _third(q, par, v, B):
    beta = par[0]
    n = q.shape[0]
    for i in range(n):
        B[0, i] = 0.0
        B[1, i] = 0.0
    for b in range(n + 1):
        r = _bond(q, b)
        dv = (v[b] if b < n else 0.0) - (v[b - 1] if b >= 1 else 0.0)
        _add_bond(B, b, 6.0 * beta * r * dv, n)  # φ'''(r) · (e_b · v)


class FPUBeta(Model):
    """The Fermi–Pasta–Ulam–Tsingou β chain of ``n`` particles, fixed ends.

    Parameters
    ----------
    n : int
        Number of moving particles (degrees of freedom); 8 in the paper.
    beta : float
        Quartic coupling β; 1.5 in the paper.

    References
    ----------
    Skokos & Gerlach, Phys. Rev. E 82, 036704 (2010), eq. (56).
    """

    def __init__(self, n: int = 8, beta: float = 1.5) -> None:
        if (isinstance(n, (bool, np.bool_)) or not isinstance(n, numbers.Real)
                or not float(n).is_integer() or n < 2):
            raise ValueError(f"n must be an integer >= 2 (number of moving particles), got {n!r}")
        if (isinstance(beta, (bool, np.bool_)) or not isinstance(beta, numbers.Real)
                or not np.isfinite(beta)):
            raise ValueError(f"beta must be a finite real number, got {type(beta).__name__} "
                             f"{beta!r}")
        self.beta = float(beta)
        super().__init__(int(n), self._V, _grad, _hess, _third, bandwidth=1,
                         params=(self.beta,), name=f"FPUBeta(n={int(n)}, beta={self.beta:g})")

    def _V(self, q):
        pad = np.zeros(q.shape[:-1] + (1,))
        r = np.diff(np.concatenate([pad, q, pad], axis=-1), axis=-1)
        return np.sum(0.5 * r * r + 0.25 * self.beta * r ** 4, axis=-1)

    def describe(self):
        d = super().describe()
        d.update(n=self.n_dof, beta=self.beta)
        return d

    def symbolic(self):
        """The potential in SymPy, bond by bond; β enters as the exact
        binary value of the float."""
        import sympy as sp

        from .symbolic import SymbolicPotential

        n = self.n_dof
        q = sp.symbols(f"q1:{n + 1}")
        beta = sp.Rational(self.beta)
        walls = (sp.Integer(0),) + q + (sp.Integer(0),)
        r = [walls[b + 1] - walls[b] for b in range(n + 1)]
        V = sp.Add(*[ri**2 / 2 + beta * ri**4 / 4 for ri in r])
        return SymbolicPotential(V, q, (sp.Integer(1),) * n)

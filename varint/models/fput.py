"""The Fermi–Pasta–Ulam–Tsingou chain with cubic (α) and quartic (β) bonds.

    H = Σ_{i=1}^{n} p_i²/2 + Σ_bonds [ r²/2 + α r³/3 + β r⁴/4 ],  r = q_{i+1} − q_i,

with fixed ends (q_0 = q_{n+1} = 0: n + 1 bonds) or periodic ones (a ring
of n bonds). Per bond the force is φ'(r) = r + αr² + βr³ and the stiffness
φ''(r) = 1 + 2αr + 3βr², so ∂V/∂q_i = φ'(r_{i−1}) − φ'(r_i) and D²V is
tridiagonal (Skokos & Gerlach 2010, eq. 56 for α = 0; Danieli, Many Manda,
Mithun & Skokos 2019 for the α-β chain).

The chain is its stencil (:mod:`varint.models.stencil`): the bond φ and its
derivatives below; its kernels, energy densities and SymPy potential follow.
Every derivative is assembled bond by bond in O(n). The kick, fused with
its tangent map, runs the same floating-point operations in the same order
as the generic stepper with the band kernels, so for fixed ends both paths
give bitwise the same orbit and vectors (tests/models/test_lattices.py).
"""

from __future__ import annotations

import numbers

import numpy as np
from numba import njit

from .lattice import check_real
from .stencil import Potential, Stencil, StencilLattice, stencil_kernels

__all__ = ["FPUT", "STENCIL"]


@njit(cache=True, error_model="numpy")
def force(r, alpha, beta):
    """φ'(r); for α = 0 exactly the expression of the FPU-β kernels."""
    if alpha == 0.0:
        return r + beta * r * r * r
    return r + alpha * r * r + beta * r * r * r


@njit(cache=True, error_model="numpy")
def stiffness(r, alpha, beta):
    """φ''(r)."""
    if alpha == 0.0:
        return 1.0 + 3.0 * beta * r * r
    return 1.0 + 2.0 * alpha * r + 3.0 * beta * r * r


@njit(cache=True, error_model="numpy")
def third(r, alpha, beta):
    """φ'''(r)."""
    if alpha == 0.0:
        return 6.0 * beta * r
    return 2.0 * alpha + 6.0 * beta * r


# The bond of the stencil, c = (α, β); its derivatives branch on α = 0
# (FPU-β), the stencil's regime.
@njit(cache=True, error_model="numpy")
def _beta_only(c):
    return c[0] == 0.0


@njit(cache=True, error_model="numpy")
def _bond_force(r, c):
    return force(r, c[0], c[1])


@njit(cache=True, error_model="numpy")
def _bond_stiffness(r, c):
    return stiffness(r, c[0], c[1])


@njit(cache=True, error_model="numpy")
def _bond_third(r, c):
    return third(r, c[0], c[1])


#: The α-β chain as a stencil (:mod:`varint.models.stencil`): bonds only.
STENCIL = Stencil(
    "FPUT",
    bond=Potential(_bond_force, _bond_stiffness, _bond_third,
                   terms=(lambda r, c: 0.5 * r * r, lambda r, c: c[0] * r ** 3 / 3.0,
                          lambda r, c: 0.25 * c[1] * r ** 4),
                   expression=lambda r, c: r**2 / 2 + c[0] * r**3 / 3 + c[1] * r**4 / 4,
                   regime=_beta_only))

_KERNELS = stencil_kernels(STENCIL)
_apply, _field = _KERNELS.apply, _KERNELS.field



def check_size(n):
    if (isinstance(n, (bool, np.bool_)) or not isinstance(n, numbers.Real)
            or not float(n).is_integer() or n < 2):
        raise ValueError(f"n must be an integer >= 2 (number of moving particles), got {n!r}")
    return int(n)


def check_coupling(value, name):
    if (isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real)
            or not np.isfinite(value)):
        raise ValueError(f"{name} must be a finite real number, got {type(value).__name__} "
                         f"{value!r}")
    return float(value)


class FPUT(StencilLattice):
    """The α-β Fermi–Pasta–Ulam–Tsingou chain of ``n`` particles.

    Parameters
    ----------
    n : int
        Moving particles (degrees of freedom).
    alpha, beta : float
        Cubic and quartic couplings.
    boundary : {"fixed", "periodic"}
        Fixed ends (n + 1 bonds, walls at q = 0) or a ring (n bonds, n ≥ 3).

    References
    ----------
    E. Fermi, J. Pasta, S. Ulam & M. Tsingou, Los Alamos report LA-1940
    (1955); Ch. Skokos & E. Gerlach, Phys. Rev. E 82, 036704 (2010), eq. 56;
    C. Danieli, B. Many Manda, T. Mithun & Ch. Skokos, Math. Eng. 1, 447
    (2019).
    """

    density_of = "energy"

    def __init__(self, n=8, alpha=0.0, beta=1.5, boundary="fixed", name=None):
        n = check_size(n)
        self.alpha = check_coupling(alpha, "alpha")
        self.beta = check_coupling(beta, "beta")
        name = name or f"FPUT(n={n}, alpha={self.alpha:g}, beta={self.beta:g})"
        self._setup_stencil(STENCIL, n, boundary, name, bond_coeffs=(self.alpha, self.beta),
                            kernels=_KERNELS)

    def initial_block(self, width=1, density=0.1, seed=0):
        """Momenta p = ±√(2h) on a central block of ``width`` particles (q =
        0; h = ``density`` is the kinetic energy of each), signs drawn by
        ``default_rng(seed)`` (all positive for ``seed=None``)."""
        h = check_real(density, "density", positive=True)
        sites = self._block_sites(width)
        signs = (np.ones(sites.size) if seed is None
                 else np.random.default_rng(seed).choice([-1.0, 1.0], sites.size))
        x = np.zeros(2 * self.n_sites)
        x[self.n_sites + sites] = signs * np.sqrt(2.0 * h)
        return x

    def describe(self):
        d = super().describe()
        d.update(n=self.n_dof, alpha=self.alpha, beta=self.beta)
        return d

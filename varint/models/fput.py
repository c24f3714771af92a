"""The Fermi–Pasta–Ulam–Tsingou chain with cubic (α) and quartic (β) bonds.

    H = Σ_{i=1}^{n} p_i²/2 + Σ_bonds [ r²/2 + α r³/3 + β r⁴/4 ],  r = q_{i+1} − q_i,

with fixed ends (q_0 = q_{n+1} = 0: n + 1 bonds) or periodic ones (a ring
of n bonds). Per bond the force is φ'(r) = r + αr² + βr³ and the stiffness
φ''(r) = 1 + 2αr + 3βr², so ∂V/∂q_i = φ'(r_{i−1}) − φ'(r_i) and D²V is
tridiagonal (Skokos & Gerlach 2010, eq. 56 for α = 0; Danieli, Many Manda,
Mithun & Skokos 2019 for the α-β chain).

Every derivative is assembled bond by bond in O(n). The kick, fused with
its tangent map, runs the same floating-point operations in the same order
as the generic stepper with the band kernels below, so for fixed ends both
paths give bitwise the same orbit and vectors (tests/models/test_lattices.py).
"""

from __future__ import annotations

import numbers

import numpy as np
from numba import njit

from .lattice import HEADER, LatticeModel, Parts, check_real, drift, no_band_kernel, \
    no_third_kernel

__all__ = ["FPUT"]

_ALPHA, _BETA = HEADER, HEADER + 1


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


@njit(cache=True, error_model="numpy")
def bond(q, b, n, periodic):
    """r_b = q_b − q_{b−1}: bond b joins particles b − 1 and b (0-based),
    walls at −1 and n for fixed ends; on a ring bond 0 joins n − 1 and 0."""
    if periodic:
        return q[b % n] - q[(b - 1) % n]
    right = q[b] if b < n else 0.0
    left = q[b - 1] if b >= 1 else 0.0
    return right - left


# The band kernels (fixed ends; par = header, α, β). For α = 0 they are the
# FPU-β kernels of Skokos & Gerlach 2010, operation for operation.
@njit(cache=True, error_model="numpy")
def _grad(q, par, g):
    alpha, beta = par[_ALPHA], par[_BETA]
    n = q.shape[0]
    for i in range(n):
        g[i] = 0.0
    for b in range(n + 1):
        f = force(bond(q, b, n, False), alpha, beta)
        if b < n:
            g[b] += f
        if b >= 1:
            g[b - 1] -= f


@njit(cache=True, error_model="numpy")
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
    alpha, beta = par[_ALPHA], par[_BETA]
    n = q.shape[0]
    for i in range(n):
        B[0, i] = 0.0
        B[1, i] = 0.0
    for b in range(n + 1):
        _add_bond(B, b, stiffness(bond(q, b, n, False), alpha, beta), n)


@njit(cache=True, error_model="numpy")
def _third(q, par, v, B):
    alpha, beta = par[_ALPHA], par[_BETA]
    n = q.shape[0]
    for i in range(n):
        B[0, i] = 0.0
        B[1, i] = 0.0
    for b in range(n + 1):
        r = bond(q, b, n, False)
        dv = (v[b] if b < n else 0.0) - (v[b - 1] if b >= 1 else 0.0)
        _add_bond(B, b, third(r, alpha, beta) * dv, n)


@njit(cache=True, error_model="numpy")
def _kick_site(x, V, k, h, alpha, beta, i, n, periodic):
    # Particle i between bond i (left) and bond i + 1 (right). The order of
    # the operations is that of _grad, _hess and band_kick_block: ∇V_i =
    # (0 + φ'_left) − φ'_right; δp_i −= h(k_l + k_r)δq_i, then the left and
    # the right neighbour.
    rl = bond(x, i, n, periodic)
    rr = bond(x, i + 1, n, periodic)
    x[n + i] -= h * ((0.0 + force(rl, alpha, beta)) - force(rr, alpha, beta))
    kl = stiffness(rl, alpha, beta)
    kr = stiffness(rr, alpha, beta)
    a = h * ((0.0 + kl) + kr)
    al = h * (-kl)
    ar = h * (-kr)
    il = i - 1 if i >= 1 else n - 1
    ir = i + 1 if i < n - 1 else 0
    for j in range(k):
        w = V[j, n + i] - a * V[j, i]
        if i >= 1 or periodic:
            w -= al * V[j, il]
        if i < n - 1 or periodic:
            w -= ar * V[j, ir]
        V[j, n + i] = w


@njit(cache=True, error_model="numpy")
def _kick(x, V, k, h, par):
    n = x.shape[0] // 2
    alpha, beta = par[_ALPHA], par[_BETA]
    periodic = par[3] != 0.0
    _kick_site(x, V, k, h, alpha, beta, 0, n, periodic)
    # The right bond of site i is the left bond of site i + 1: its force
    # and stiffness are carried to the next site (one φ', φ'' per bond, not
    # two; the same values, the kick only moves momenta).
    rl = x[1] - x[0]
    fl = force(rl, alpha, beta)
    kl = stiffness(rl, alpha, beta)
    for i in range(1, n - 1):
        rr = x[i + 1] - x[i]
        fr = force(rr, alpha, beta)
        kr = stiffness(rr, alpha, beta)
        x[n + i] -= h * ((0.0 + fl) - fr)
        a = h * ((0.0 + kl) + kr)
        al = h * (-kl)
        ar = h * (-kr)
        for j in range(k):
            V[j, n + i] = ((V[j, n + i] - a * V[j, i]) - al * V[j, i - 1]) - ar * V[j, i + 1]
        fl, kl = fr, kr
    _kick_site(x, V, k, h, alpha, beta, n - 1, n, periodic)


@njit(cache=True, error_model="numpy")
def _apply(part, h, x, V, k, par, work):
    n = x.shape[0] // 2
    if part == 0:
        drift(x, V, h, k, n)
    else:
        _kick(x, V, k, h, par)


@njit(cache=True, error_model="numpy")
def _field(x, par, out):
    n = x.shape[0] // 2
    alpha, beta = par[_ALPHA], par[_BETA]
    periodic = par[3] != 0.0
    for i in range(n):
        out[i] = x[n + i]
        out[n + i] = -((0.0 + force(bond(x, i, n, periodic), alpha, beta))
                       - force(bond(x, i + 1, n, periodic), alpha, beta))


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


class FPUT(LatticeModel):
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
        band = boundary == "fixed"
        name = name or f"FPUT(n={n}, alpha={self.alpha:g}, beta={self.beta:g})"
        header = [1.0, 1.0, float(n), 1.0 if boundary == "periodic" else 0.0]
        self._setup(n, boundary, name, self._V, _grad, _hess if band else no_band_kernel,
                    _third if band else no_third_kernel, 1 if band else 0,
                    header + [self.alpha, self.beta], band)
        self.parts = Parts(names=("T", "V"), apply=_apply, field=_field, splits={2: ("T", "V")},
                           par=self.params, default_scheme="ABA864")

    def _potential_of_bonds(self, r):
        return 0.5 * r * r + self.alpha * r ** 3 / 3.0 + 0.25 * self.beta * r ** 4

    def _V(self, q):
        r, _ = self.bonds(q)
        return np.sum(self._potential_of_bonds(r), axis=-1)

    def densities(self, x):
        """Energy per particle: p_i²/2 plus half of each of its two bonds'
        energies (all of a bond to a wall), so that Σ_i h_i = H."""
        x = np.asarray(x, dtype=float)
        n = self.n_sites
        r, pairs = self.bonds(x[..., :n])
        return 0.5 * x[..., n:] ** 2 + self.split_bonds(self._potential_of_bonds(r), pairs)

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

    def symbolic(self):
        """The potential in SymPy, bond by bond (fixed ends); α and β enter
        as the exact binary values of the floats."""
        import sympy as sp

        from .symbolic import SymbolicPotential

        self._band()
        n = self.n_dof
        q = sp.symbols(f"q1:{n + 1}")
        alpha, beta = sp.Rational(self.alpha), sp.Rational(self.beta)
        walls = (sp.Integer(0),) + q + (sp.Integer(0),)
        r = [walls[b + 1] - walls[b] for b in range(n + 1)]
        V = sp.Add(*[ri**2 / 2 + alpha * ri**3 / 3 + beta * ri**4 / 4 for ri in r])
        return SymbolicPotential(V, q, (sp.Integer(1),) * n)

"""A lattice as one declarative stencil: what a site and a bond cost, from
which every kernel, the energy, its site distribution and SymPy follow.

A T(p) + V(q) lattice with unit masses and nearest-neighbour coupling is

    H = Σ_l [ p_l²/2 + u(q_l; a_l) ] + Σ_{⟨l,m⟩} φ(q_m − q_l),

a *site* potential u and a *bond* potential φ (either may be absent), on
the geometry of :mod:`varint.models.lattice` (chain or 2D lattice, fixed or
periodic boundaries; fixed boundaries add a bond from each edge site to a
wall at q = 0). :class:`Stencil` holds the two as :class:`Potential`: its
first three derivatives as small numba functions and its value in NumPy and
SymPy, written once. :func:`stencil_kernels` then gives the kernels the
methods run, generic over the stencil (its functions compiled in):

* the fused kick e^{h L_V} with its tangent map, p −= h ∇V, δp −= h D²V δq
  (Skokos & Gerlach 2010, eq. 47), every site once, the stencil applied on
  the fly (never a matrix), and the drift of T (eq. 46): the part flows of
  :class:`~varint.models.lattice.Parts`;
* the vector field J∇H (for OFLI and the flow accumulators);
* for fixed-end chains, the band kernels ∇V, D²V and Σ_k v_k D²(∂_kV) of
  :mod:`varint.models.base` (bandwidth 1), which every other method runs.

:class:`StencilLattice` is the model of a stencil: V, the energy densities
(each site's u and half of each of its bonds' φ, all of a bond to a wall)
and the SymPy potential follow from the same declaration. A new lattice is
its stencil (tests/models/test_stencil.py writes a φ⁴ chain and a Toda
lattice in a few lines and checks them against finite differences).

Two kinds of bond, because they are computed differently:

* ``linear`` (φ = κ r²/2, the Klein–Gordon coupling): ∂V/∂q_l gains
  z κ q_l − κ Σ_{m~l} q_m, so the kernels fold z κ into the site's
  coefficient a_l (u must enter a as a q²/2) and sum the neighbours — any
  dimension, any boundary;
* nonlinear φ (FPUT, Toda): chains only; each bond's φ' and φ'' is computed
  once and carried to the next site.

Every kernel keeps the floating-point operations, and their order, of the
hand-written kernels it replaced (the Klein–Gordon and FPUT ones), so their
results are bitwise the same.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import cache
from types import SimpleNamespace
from typing import Any

import numpy as np
from numba import njit

from .._validate import array_bytes, check_memory
from ..kernels.closures import cache_on_disk
from .lattice import (HEADER, LatticeModel, Parts, drift, neighbour_sum, neighbour_sweep,
                      no_band_kernel, no_third_kernel)

__all__ = ["Potential", "Stencil", "StencilLattice", "stencil_kernels", "N_COEFFS"]

#: Coefficients each potential reads (a tuple ``c`` of this many floats;
#: unused ones are 0).
N_COEFFS = 3

# par = header (geometry), the site's coefficients, the bond's, κ (the
# linear bond's stiffness), then a_l for every site (with z κ folded in).
SITE_C, BOND_C = HEADER, HEADER + N_COEFFS
KAPPA = HEADER + 2 * N_COEFFS
A0 = KAPPA + 1


@dataclass(frozen=True)
class Potential:
    """A potential of one variable: of a site, u(q; a, c), or of a bond,
    φ(r; c) (then without ``a``), r = q_m − q_l.

    Attributes
    ----------
    force, stiffness, third : numba dispatchers
        The first three derivatives: ``f(q, a, c)`` for a site, ``f(r, c)``
        for a bond, ``c`` a tuple of :data:`N_COEFFS` floats.
    terms : tuple of callables
        The potential in NumPy as a sum of terms, ``t(y, a, c)`` (site) or
        ``t(y, c)`` (bond), added left to right (the energy densities add
        them one by one to the kinetic energy, in this order).
    expression : callable
        The potential in SymPy, of the same arguments (SymPy numbers).
    total : callable or None
        ``total(r, c)``: Σ over the last axis of a bond's φ, where it is
        written in another order than the sum of the terms (a linear bond
        sums r² first); None sums the terms.
    linear : bool
        A bond φ = κ r²/2 whose stiffness κ = ``stiffness(0, c)`` is
        constant (the kernels then sum neighbours; module docstring).
    regime : numba dispatcher or None
        ``regime(c) -> bool``, the test on the coefficients that the
        derivatives branch on (FPUT: α = 0), if any. A chain's kick then
        runs its site loop in one of two copies, chosen once per kick, in
        which the test is known and the branch folds away: left in the
        loop, it kept the loop from vectorising.
    """

    force: Any
    stiffness: Any
    third: Any
    terms: tuple
    expression: Callable
    total: Callable | None = None
    linear: bool = False
    regime: Any = None

    def __post_init__(self):
        # A tuple, so that the potential is hashable (stencil_kernels keeps
        # one set of kernels per potential).
        object.__setattr__(self, "terms", tuple(self.terms))


@dataclass(frozen=True)
class Stencil:
    """A lattice H = Σ p²/2 + Σ_l u(q_l; a_l) + Σ_bonds φ(r) (module
    docstring): its site and bond potentials (None: absent; not both).

    Attributes
    ----------
    name : str
        For messages and the model's name.
    site, bond : Potential or None
    """

    name: str
    site: Potential | None = None
    bond: Potential | None = None

    def __post_init__(self):
        if self.site is None and self.bond is None:
            raise ValueError(f"stencil {self.name!r} needs a site or a bond potential, got "
                             "neither")


def _coefficients(values, what):
    c = [float(v) for v in values]
    if len(c) > N_COEFFS:
        raise ValueError(f"a {what} potential reads at most {N_COEFFS} coefficients, "
                         f"got {len(c)}: {c}")
    return c + [0.0] * (N_COEFFS - len(c))


# -- the kernels ------------------------------------------------------------------------

@njit(error_model="numpy")
def _one_regime(c):
    """The regime of a bond whose derivatives do not branch: always one."""
    return True


def stencil_kernels(stencil):
    """The kernels of ``stencil`` (generic over it: its functions compiled
    in, absent potentials compiled out): ``grad``, ``hess``, ``third``
    (band kernels of fixed-end chains), ``kick``, ``apply`` and ``field``
    (:class:`~varint.models.lattice.Parts`), as a namespace. All read the
    parameter array of :meth:`StencilLattice._parameters`.

    One namespace per (site, bond) pair, made once: the kernels read the
    geometry and coefficients from the parameters, so every lattice of a
    stencil (any shape, boundary or coefficients) runs the same compiled
    part stepper. Made anew per lattice, a stencil whose functions are not
    varint's (which no disk cache can name) was compiled again for each
    (4–5 s of CPU per kernel)."""
    return _kernels(stencil.site, stencil.bond)


@cache
def _kernels(site, bond):
    has_site = site is not None
    linear = bond is not None and bond.linear
    chain_bond = bond is not None and not bond.linear
    site_force = site.force if has_site else None
    site_stiff = site.stiffness if has_site else None
    site_third = site.third if has_site else None
    bond_force = bond.force if chain_bond else None
    bond_stiff = bond.stiffness if chain_bond else None
    bond_third = bond.third if chain_bond else None
    bond_regime = bond.regime if chain_bond and bond.regime is not None else _one_regime

    @njit(error_model="numpy")
    def coeffs(par, o):
        return (par[o], par[o + 1], par[o + 2])

    @njit(error_model="numpy")
    def u1(q, a, cs):
        # u'(q) (0 without a site potential: the bond chain's sums then
        # start from 0.0, as its band kernels do).
        if has_site:
            return site_force(q, a, cs)
        return 0.0

    @njit(error_model="numpy")
    def u2(q, a, cs):
        if has_site:
            return site_stiff(q, a, cs)
        return 0.0

    @njit(error_model="numpy")
    def bond_r(q, b, n, periodic):
        # r_b = q_b − q_{b−1}: bond b joins particles b − 1 and b (0-based),
        # walls at −1 and n for fixed ends; on a ring bond 0 joins n − 1 and 0.
        if periodic:
            return q[b % n] - q[(b - 1) % n]
        right = q[b] if b < n else 0.0
        left = q[b - 1] if b >= 1 else 0.0
        return right - left

    # -- band kernels (fixed-end chains) --
    @njit(error_model="numpy")
    def grad(q, par, g):
        n = q.shape[0]
        cs = coeffs(par, SITE_C)
        if linear:
            dim, nx, ny, per = int(par[0]), int(par[1]), int(par[2]), par[3] != 0.0
            kappa = par[KAPPA]
            for s in range(n):
                g[s] = u1(q[s], par[A0 + s], cs) - kappa * neighbour_sum(q, 0, s, nx, ny, dim,
                                                                          per)
            return
        cb = coeffs(par, BOND_C)
        for i in range(n):
            g[i] = u1(q[i], par[A0 + i], cs)
        for b in range(n + 1):
            f = bond_force(bond_r(q, b, n, False), cb)
            if b < n:
                g[b] += f
            if b >= 1:
                g[b - 1] -= f

    @njit(error_model="numpy")
    def add_bond(B, b, k, n):
        # A bond b of stiffness k joins particles b − 1 and b: it adds
        # k e_b e_bᵀ to a symmetric tridiagonal matrix in band storage.
        if b < n:
            B[0, b] += k
        if b >= 1:
            B[0, b - 1] += k
        if 1 <= b < n:
            B[1, b - 1] = -k

    @njit(error_model="numpy")
    def hess(q, par, B):
        n = q.shape[0]
        cs = coeffs(par, SITE_C)
        if linear:
            kappa = par[KAPPA]
            for s in range(n):
                B[0, s] = u2(q[s], par[A0 + s], cs)
                B[1, s] = -kappa if s < n - 1 else 0.0
            return
        cb = coeffs(par, BOND_C)
        for i in range(n):
            B[0, i] = u2(q[i], par[A0 + i], cs)
            B[1, i] = 0.0
        for b in range(n + 1):
            add_bond(B, b, bond_stiff(bond_r(q, b, n, False), cb), n)

    @njit(error_model="numpy")
    def third(q, par, v, B):
        # Σ_k v_k D²(∂_k V): the site's u''' on the diagonal, each bond's
        # φ''' (r) · (v_b − v_{b−1}) on its 2×2 block.
        n = q.shape[0]
        cs = coeffs(par, SITE_C)
        for i in range(n):
            B[0, i] = site_third(q[i], par[A0 + i], cs) * v[i] if has_site else 0.0
            B[1, i] = 0.0
        if chain_bond:
            cb = coeffs(par, BOND_C)
            for b in range(n + 1):
                r = bond_r(q, b, n, False)
                dv = (v[b] if b < n else 0.0) - (v[b - 1] if b >= 1 else 0.0)
                add_bond(B, b, bond_third(r, cb) * dv, n)

    # -- the kick of a linear coupling: the neighbour sweep --
    @njit(error_model="numpy")
    def linear_local(q, s, cst):
        # u'(q) and h u''(q), once per site (shared by the orbit and the vectors).
        h, _, _, cs, par = cst
        a = par[A0 + s]
        return u1(q, a, cs), h * u2(q, a, cs)

    @njit(error_model="numpy")
    def linear_site(p, g, around, cst):
        h, kappa = cst[0], cst[1]
        return p - h * (g[0] - kappa * around)

    @njit(error_model="numpy")
    def linear_vector(dp, g, dq, around, cst):
        return dp - (g[1] * dq - cst[2] * around)

    sweep = neighbour_sweep(linear_local, linear_site, linear_vector)

    # Inlined by numba (as is ``kick``): the sweep and the chain's loop then
    # sit right inside ``apply``, where the number of vectors is a constant.
    @njit(inline="always", error_model="numpy")
    def linear_kick(x, V, k, h, par):
        dim, nx, ny, per = int(par[0]), int(par[1]), int(par[2]), par[3] != 0.0
        kappa = par[KAPPA]
        cst = (h, kappa, h * kappa, coeffs(par, SITE_C), par)
        sweep(x, V, k, x.shape[0] // 2, 0, cst, nx, ny, dim, per)

    # -- the kick of a bond chain: each bond's force carried to the next site --
    @njit(inline="always", error_model="numpy")
    def chain_site(x, V, k, h, cs, a, i, n, fl, kl, fr, kr, left, il, right, ir):
        # Particle i between bond i (left: φ' = fl, φ'' = kl) and bond i + 1
        # (right: fr, kr); ``left``/``right``: whether a particle (at il/ir)
        # rather than a wall is there. The order of the operations is that
        # of grad, hess and band_kick_block: ∇V_i = (u' + φ'_left) − φ'_right;
        # δp_i −= h(u'' + k_l + k_r)δq_i, then the left and the right neighbour.
        x[n + i] -= h * ((u1(x[i], a, cs) + fl) - fr)
        c = h * ((u2(x[i], a, cs) + kl) + kr)
        al = h * (-kl)
        ar = h * (-kr)
        for j in range(k):
            w = V[j, n + i] - c * V[j, i]
            if left:
                w -= al * V[j, il]
            if right:
                w -= ar * V[j, ir]
            V[j, n + i] = w

    @njit(inline="always", error_model="numpy")
    def chain_interior(x, V, k, h, cs, cb, par, n, fl, kl):
        # Sites 1 … n − 2: the right bond of site i is the left bond of site
        # i + 1, so its force and stiffness are carried to the next site (one
        # φ', φ'' per bond; the same values, the kick only moves momenta).
        for i in range(1, n - 1):
            r = x[i + 1] - x[i]
            fr = bond_force(r, cb)
            kr = bond_stiff(r, cb)
            a = par[A0 + i]
            x[n + i] -= h * ((u1(x[i], a, cs) + fl) - fr)
            c = h * ((u2(x[i], a, cs) + kl) + kr)
            al = h * (-kl)
            ar = h * (-kr)
            for j in range(k):
                V[j, n + i] = ((V[j, n + i] - c * V[j, i]) - al * V[j, i - 1]) - ar * V[j, i + 1]
            fl = fr
            kl = kr
        return fl, kl

    # Inlined, as kick is: k is then a constant in the loops over vectors.
    # The edge sites take their bonds from the sweep too (bond 0 and bond n
    # are one bond on a ring, the walls' for fixed ends): computed anew with
    # a run-time boundary flag, they cost ~12 of FPU-beta's 75 ns kick at
    # n = 64 (measured alone).
    @njit(inline="always", error_model="numpy")
    def chain_kick(x, V, k, h, par):
        n = x.shape[0] // 2
        periodic = par[3] != 0.0
        cs, cb = coeffs(par, SITE_C), coeffs(par, BOND_C)
        r0 = bond_r(x, 0, n, True) if periodic else bond_r(x, 0, n, False)
        f0 = bond_force(r0, cb)
        k0 = bond_stiff(r0, cb)
        r = x[1] - x[0]
        fl = bond_force(r, cb)
        kl = bond_stiff(r, cb)
        chain_site(x, V, k, h, cs, par[A0], 0, n, f0, k0, fl, kl, periodic, n - 1, True, 1)
        # The same loop twice: in each copy the regime is known, so the
        # derivatives' branch on it folds away and the loop vectorises.
        if bond_regime(cb):
            fl, kl = chain_interior(x, V, k, h, cs, cb, par, n, fl, kl)
        else:
            fl, kl = chain_interior(x, V, k, h, cs, cb, par, n, fl, kl)
        if periodic:
            fr, kr = f0, k0
        else:
            r = bond_r(x, n, n, False)
            fr = bond_force(r, cb)
            kr = bond_stiff(r, cb)
        chain_site(x, V, k, h, cs, par[A0 + n - 1], n - 1, n, fl, kl, fr, kr, True, n - 2,
                   periodic, 0)

    @njit(inline="always", error_model="numpy")
    def kick(x, V, k, h, par):
        """e^{h L_V} and its tangent map: p −= h ∇V(q), δp −= h D²V(q) δq."""
        if chain_bond:
            chain_kick(x, V, k, h, par)
        else:
            linear_kick(x, V, k, h, par)

    # Inlined by numba into the part stepper's step, where the number of
    # vectors is a constant: the loops over vectors unroll and the site
    # loops vectorise (called instead, with k a run-time value, FPU-beta's
    # drift at n = 64 took twice as long: studies/fpu_gap.py).
    @njit(inline="always", error_model="numpy")
    def apply(part, h, x, V, k, par, work):
        n = x.shape[0] // 2
        if part == 0:
            drift(x, V, h, k, n)
        else:
            kick(x, V, k, h, par)

    @njit(error_model="numpy")
    def field(x, par, out):
        n = x.shape[0] // 2
        dim, nx, ny, per = int(par[0]), int(par[1]), int(par[2]), par[3] != 0.0
        cs = coeffs(par, SITE_C)
        if chain_bond:
            cb = coeffs(par, BOND_C)
            for i in range(n):
                out[i] = x[n + i]
                out[n + i] = -((u1(x[i], par[A0 + i], cs) + bond_force(bond_r(x, i, n, per), cb))
                               - bond_force(bond_r(x, i + 1, n, per), cb))
            return
        kappa = par[KAPPA]
        for s in range(n):
            q = x[s]
            out[s] = x[n + s]
            out[n + s] = -(u1(q, par[A0 + s], cs)
                           - kappa * neighbour_sum(x, 0, s, nx, ny, dim, per))

    made = dict(grad=grad, hess=hess, third=third, kick=kick, apply=apply, field=field)
    return SimpleNamespace(**{name: cache_on_disk(k) for name, k in made.items()})


# -- the model ------------------------------------------------------------------------

class StencilLattice(LatticeModel):
    """The lattice of a :class:`Stencil` (module docstring): its kernels,
    V, energy densities and SymPy potential all follow from the stencil.

    Parameters
    ----------
    stencil : Stencil
    shape : int or (int, int)
        N sites of a chain, or (nx, ny) of a 2D lattice (a nonlinear bond
        runs on chains only).
    boundary : {"fixed", "periodic"}
    a : float or array of shape (N,), default 0
        The site coefficients a_l (ignored without a site potential).
    site_coeffs, bond_coeffs : sequence of float
        At most :data:`N_COEFFS` coefficients of each potential.
    name : str, optional
    kernels : namespace, optional
        :func:`stencil_kernels` of ``stencil``, when the subclass keeps them
        at module level (then every instance shares one compiled part
        stepper).
    default_scheme : str
        The scheme ``method="tm"`` runs when none is given.
    """

    density_of = "energy"

    def __init__(self, stencil, shape, boundary="fixed", a=0.0, site_coeffs=(),
                 bond_coeffs=(), name=None, default_scheme="ABA864"):
        if not isinstance(stencil, Stencil):
            raise ValueError(f"stencil must be a varint.models.stencil.Stencil, got {stencil!r}")
        name = name or f"{stencil.name}(shape={shape!r}, boundary={boundary!r})"
        self._setup_stencil(stencil, shape, boundary, name, a, site_coeffs, bond_coeffs,
                            default_scheme=default_scheme)

    def _setup_stencil(self, stencil, shape, boundary, name, a=0.0, site_coeffs=(),
                       bond_coeffs=(), kernels=None, default_scheme="ABA864"):
        from .lattice import check_boundary, lattice_shape

        nx, ny, dim = lattice_shape(shape, check_boundary(boundary))
        n = nx * ny
        bond = stencil.bond
        if bond is not None and not bond.linear and dim != 1:
            raise ValueError(f"stencil {stencil.name!r} has a nonlinear bond, which runs on "
                             f"chains only; got shape {shape!r}")
        # Before the first array of size N (the parameters), the check of
        # Model.__init__: its inverse mass, one state, gradient and band.
        check_memory(array_bytes(n, 2 * n, n, (2, n)), f"model {name} ({n} degrees of freedom)")
        self.stencil = stencil
        self.site_coeffs = _coefficients(site_coeffs, "site")
        self.bond_coeffs = _coefficients(bond_coeffs, "bond")
        self.a = np.broadcast_to(np.asarray(a, dtype=float), (n,))
        kernels = kernels if kernels is not None else stencil_kernels(stencil)
        band = dim == 1 and boundary == "fixed"
        header = [float(dim), float(nx), float(ny), 1.0 if boundary == "periodic" else 0.0]
        kappa = (float(bond.stiffness(0.0, tuple(self.bond_coeffs)))
                 if bond is not None and bond.linear else 0.0)
        # A linear bond adds z κ q_l²/2 to each site (z neighbours, walls
        # counted): folded into a_l (module docstring).
        folded = self.a + 2 * dim * kappa if kappa else self.a
        par = np.concatenate([header, self.site_coeffs, self.bond_coeffs, [kappa], folded])
        self._setup(shape, boundary, name, self._stencil_V, kernels.grad,
                    kernels.hess if band else no_band_kernel,
                    kernels.third if band else no_third_kernel, 1 if band else 0, par, band)
        self.parts = Parts(names=("T", "V"), apply=kernels.apply, field=kernels.field,
                           splits={2: ("T", "V")}, par=self.params,
                           default_scheme=default_scheme)

    # -- what follows from the stencil in NumPy and SymPy --
    def _site_energy(self, q, into=None):
        """Σ of the site potential's terms added to ``into`` one by one
        (None: their sum alone)."""
        site = self.stencil.site
        c = tuple(self.site_coeffs)
        out = into
        for term in site.terms:
            t = term(q, self.a, c)
            out = t if out is None else out + t
        return out

    def _bond_energy(self, r):
        c = tuple(self.bond_coeffs)
        out = None
        for term in self.stencil.bond.terms:
            t = term(r, c)
            out = t if out is None else out + t
        return out

    def _stencil_V(self, q):
        q = np.asarray(q, dtype=float)
        total = None
        if self.stencil.site is not None:
            total = np.sum(self._site_energy(q), axis=-1)
        if self.stencil.bond is not None:
            r, _ = self.bonds(q)
            bond = self.stencil.bond
            b = (bond.total(r, tuple(self.bond_coeffs)) if bond.total is not None
                 else np.sum(self._bond_energy(r), axis=-1))
            total = b if total is None else total + b
        return total

    def densities(self, x):
        """Energy per site: p_l²/2, then the site potential's terms, then
        half of each of its bonds' φ (all of a bond to a wall), so that
        Σ_l h_l = H. Shape (..., N)."""
        x = np.asarray(x, dtype=float)
        n = self.n_sites
        q, p = x[..., :n], x[..., n:]
        out = 0.5 * p * p
        if self.stencil.site is not None:
            out = self._site_energy(q, out)
        if self.stencil.bond is not None:
            r, pairs = self.bonds(q)
            out = out + self.split_bonds(self._bond_energy(r), pairs)
        return out

    def symbolic(self):
        """The potential in SymPy (fixed-end chains: what ``method="taylor"``
        integrates); every coefficient enters as the exact binary value of
        its float. A linear bond's κ/2 multiplies the sum of r²."""
        import sympy as sp

        from .symbolic import SymbolicPotential

        self._band()
        n = self.n_sites
        q = sp.symbols(f"q1:{n + 1}")
        site, bond = self.stencil.site, self.stencil.bond
        V = sp.Integer(0)
        if site is not None:
            cs = tuple(sp.Rational(c) for c in self.site_coeffs)
            V = sp.Add(*[site.expression(qi, sp.Rational(a), cs)
                         for a, qi in zip(self.a, q, strict=True)])
        if bond is not None:
            walls = (sp.Integer(0),) + q + (sp.Integer(0),)
            r = [walls[b + 1] - walls[b] for b in range(n + 1)]
            cb = tuple(sp.Rational(c) for c in self.bond_coeffs)
            if bond.linear:
                kappa = sp.Rational(self.params[KAPPA])
                V += kappa / 2 * sp.Add(*[ri ** 2 for ri in r])
            else:
                V += sp.Add(*[bond.expression(ri, cb) for ri in r])
        return SymbolicPotential(V, q, (sp.Integer(1),) * n)

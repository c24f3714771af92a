"""The disordered Klein–Gordon (DKG) lattice in one and two dimensions.

    H = Σ_l [ p_l²/2 + ε̃_l q_l²/2 + q_l⁴/4 ] + (1/2W) Σ_{⟨l,m⟩} (q_m − q_l)²,

the last sum over nearest-neighbour bonds (with fixed boundaries, also the
bonds from each edge site to the wall, where q = 0). The on-site
coefficients ε̃_l are drawn uniformly from [1/2, 3/2] by
``numpy.random.default_rng(seed)``, site by site in the order l = 0 … N−1;
the same W sets the coupling 1/W (Skokos, Krimer, Komineas & Flach 2009;
Flach, Krimer & Skokos 2009 in 1D; Many Manda, Senyange & Skokos 2020 in
2D — the 1/(2W) per bond of 2D is our reading, the papers' text could not
be checked).

Writing d_l = ε̃_l + z/W (z = 2 neighbours in 1D, 4 in 2D, counting walls):

* ∂V/∂q_l = (d_l + q_l²) q_l − (1/W) Σ_{m~l} q_m,
* D²V: diagonal d_l + 3q_l², −1/W on every bond (a 3-point stencil in 1D,
  5-point in 2D; never stored).

H = T(p) + V(q), so its parts are the kinetic drift and the potential
kick, with their tangent maps (Skokos & Gerlach 2010, eqs. 46–47), fused:
one pass over the sites kicks p and every δp.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .._validate import array_bytes, check_memory
from .lattice import (HEADER, LatticeModel, Parts, check_real, check_seed, drift, edge_site,
                      n_edges, neighbour_sum, neighbour_sum_v, no_band_kernel, no_third_kernel)

__all__ = ["DisorderedKG"]

# par = header (geometry), 1/W, then d_l = ε̃_l + z/W for every site.
_C, _D0 = HEADER, HEADER + 1


@njit(cache=True, error_model="numpy")
def _grad(q, par, g):
    nx, ny, dim, per = int(par[1]), int(par[2]), int(par[0]), par[3] != 0.0
    c = par[_C]
    for s in range(q.shape[0]):
        g[s] = (par[_D0 + s] + q[s] * q[s]) * q[s] - c * neighbour_sum(q, 0, s, nx, ny, dim,
                                                                      per)


@njit(cache=True, error_model="numpy")
def _hess(q, par, B):
    # Fixed-end chains only (bandwidth 1).
    c = par[_C]
    n = q.shape[0]
    for s in range(n):
        B[0, s] = par[_D0 + s] + 3.0 * q[s] * q[s]
        B[1, s] = -c if s < n - 1 else 0.0


@njit(cache=True, error_model="numpy")
def _third(q, par, v, B):
    # Σ_k v_k D²(∂_k V): only ∂³V/∂q_l³ = 6 q_l is non-zero.
    for s in range(q.shape[0]):
        B[0, s] = 6.0 * q[s] * v[s]
        B[1, s] = 0.0


@njit(cache=True, error_model="numpy")
def _kick_site(x, V, k, h, c, d0, s, n, nx, ny, dim, per):
    q = x[s]
    x[n + s] -= h * ((d0 + q * q) * q - c * neighbour_sum(x, 0, s, nx, ny, dim, per))
    a = h * (d0 + 3.0 * q * q)
    b = h * c
    for j in range(k):
        V[j, n + s] -= a * V[j, s] - b * neighbour_sum_v(V, 0, s, j, nx, ny, dim, per)


@njit(cache=True, error_model="numpy")
def _kick(x, V, k, h, par):
    """e^{h L_V} and its tangent map: p −= h ∇V(q), δp −= h D²V(q) δq,
    every site once, the stencil applied on the fly."""
    dim, nx, ny, per = int(par[0]), int(par[1]), int(par[2]), par[3] != 0.0
    # N from the array, not from par: then the compiler can tell the q and
    # p halves of x apart and vectorise the site loops (4x faster).
    n = x.shape[0] // 2
    c = par[_C]
    b = h * c
    for e in range(n_edges(nx, ny, dim)):
        s = edge_site(e, nx, ny, dim)
        _kick_site(x, V, k, h, c, par[_D0 + s], s, n, nx, ny, dim, per)
    if dim == 1:
        for s in range(1, n - 1):
            q = x[s]
            d0 = par[_D0 + s]
            x[n + s] -= h * ((d0 + q * q) * q - c * (x[s - 1] + x[s + 1]))
            a = h * (d0 + 3.0 * q * q)
            for j in range(k):
                V[j, n + s] -= a * V[j, s] - b * (V[j, s - 1] + V[j, s + 1])
        return
    # Row by row, through slices indexed from 1: numba then needs no
    # negative-index fix-up on x[s − ny] (it cannot prove s − ny ≥ 0), and
    # the site loops vectorise (3.5x faster; the same arithmetic).
    for i in range(1, nx - 1):
        r = i * ny
        q, qu, qd, p = x[r:r + ny], x[r - ny:r], x[r + ny:r + 2 * ny], x[n + r:n + r + ny]
        d = par[_D0 + r:_D0 + r + ny]
        for j in range(1, ny - 1):
            qj = q[j]
            p[j] -= h * ((d[j] + qj * qj) * qj - c * ((q[j - 1] + q[j + 1]) + (qu[j] + qd[j])))
        for m in range(k):
            v, vu, vd = V[m, r:r + ny], V[m, r - ny:r], V[m, r + ny:r + 2 * ny]
            w = V[m, n + r:n + r + ny]
            for j in range(1, ny - 1):
                qj = q[j]
                w[j] -= h * (d[j] + 3.0 * qj * qj) * v[j] - b * ((v[j - 1] + v[j + 1])
                                                                 + (vu[j] + vd[j]))


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
    dim, nx, ny, per = int(par[0]), int(par[1]), int(par[2]), par[3] != 0.0
    c = par[_C]
    for s in range(n):
        q = x[s]
        out[s] = x[n + s]
        out[n + s] = -((par[_D0 + s] + q * q) * q - c * neighbour_sum(x, 0, s, nx, ny, dim, per))


class DisorderedKG(LatticeModel):
    """The disordered Klein–Gordon lattice (see the module docstring).

    Parameters
    ----------
    shape : int or (int, int)
        N sites of a chain, or (nx, ny) of a 2D lattice.
    W : float, default 4
        Disorder strength; also sets the coupling 1/W.
    seed : int, default 0
        Seed of the on-site coefficients ε̃_l ~ U[1/2, 3/2].
    boundary : {"fixed", "periodic"}
        Fixed: the edge sites are bound to walls at q = 0 (the papers'
        choice as we recall it; unverified). Periodic: ring or torus.

    Attributes
    ----------
    epsilon : ndarray, shape (N,)
        The drawn ε̃_l.

    References
    ----------
    Ch. Skokos, D. O. Krimer, S. Komineas & S. Flach, Phys. Rev. E 79,
    056211 (2009); S. Flach, D. O. Krimer & Ch. Skokos, Phys. Rev. Lett.
    102, 024101 (2009); B. Many Manda, B. Senyange & Ch. Skokos, Phys. Rev.
    E 101, 032206 (2020).
    """

    density_of = "energy"

    def __init__(self, shape, W=4.0, seed=0, boundary="fixed"):
        self.W = check_real(W, "W", positive=True)
        self.seed = check_seed(seed)
        from .lattice import check_boundary, lattice_shape

        nx, ny, dim = lattice_shape(shape, check_boundary(boundary))
        n = nx * ny
        name = f"DisorderedKG(shape={shape!r}, W={self.W:g}, seed={self.seed})"
        # Before the first array of size N: disorder, parameters, one state.
        check_memory(array_bytes(n, n, 2 * n, 2 * n), f"model {name} ({n} sites)")
        self.epsilon = np.random.default_rng(self.seed).uniform(0.5, 1.5, n)
        z = 2 * dim
        c = 1.0 / self.W
        self._geometry = (nx, ny, dim, boundary)
        band = dim == 1 and boundary == "fixed"
        header = [float(dim), float(nx), float(ny), 1.0 if boundary == "periodic" else 0.0]
        par = np.concatenate([header, [c], self.epsilon + z * c])
        self._setup(shape, boundary, name, self._V, _grad, _hess if band else no_band_kernel,
                    _third if band else no_third_kernel, 1 if band else 0, par, band)
        self.parts = Parts(names=("T", "V"), apply=_apply, field=_field, splits={2: ("T", "V")},
                           par=self.params, default_scheme="ABA864")

    def _V(self, q):
        dq, _ = self.bonds(q)
        return (np.sum(0.5 * self.epsilon * q * q + 0.25 * q ** 4, axis=-1)
                + np.sum(dq * dq, axis=-1) / (2.0 * self.W))

    def densities(self, x):
        """Energy per site h_l = p_l²/2 + ε̃_l q_l²/2 + q_l⁴/4 plus half of
        each of its bonds' energies (all of a bond to a wall), so that
        Σ_l h_l = H. Shape (..., N)."""
        x = np.asarray(x, dtype=float)
        n = self.n_sites
        q, p = x[..., :n], x[..., n:]
        dq, pairs = self.bonds(q)
        return (0.5 * p * p + 0.5 * self.epsilon * q * q + 0.25 * q ** 4
                + self.split_bonds(dq * dq / (2.0 * self.W), pairs))

    def initial_block(self, width=1, density=0.4, seed=0):
        """All energy in momenta: p = ±√(2h) on a central block of
        ``width`` (or width × width) sites, q = 0, so each of them holds the
        energy ``density`` = h. Signs drawn by ``default_rng(seed)``; all
        positive for ``seed=None``.

        Returns
        -------
        x0 : ndarray, shape (2N,)
        """
        h = check_real(density, "density", positive=True)
        sites = self._block_sites(width)
        signs = (np.ones(sites.size) if seed is None
                 else np.random.default_rng(check_seed(seed)).choice([-1.0, 1.0], sites.size))
        x = np.zeros(2 * self.n_sites)
        x[self.n_sites + sites] = signs * np.sqrt(2.0 * h)
        return x

    def describe(self):
        d = super().describe()
        d.update(W=self.W, seed=self.seed, disorder="uniform [1/2, 3/2]")
        return d

    def symbolic(self):
        """The potential in SymPy (fixed-end chains: what ``method="taylor"``
        integrates); the ε̃_l and 1/W enter as the exact binary values of
        the floats."""
        import sympy as sp

        from .symbolic import SymbolicPotential

        self._band()
        n = self.n_sites
        q = sp.symbols(f"q1:{n + 1}")
        c = sp.Rational(1.0 / self.W)
        walls = (sp.Integer(0),) + q + (sp.Integer(0),)
        V = sp.Add(*[sp.Rational(e) * qi ** 2 / 2 + qi ** 4 / 4 for e, qi in zip(self.epsilon, q, strict=True)])
        V += c / 2 * sp.Add(*[(walls[b + 1] - walls[b]) ** 2 for b in range(n + 1)])
        return SymbolicPotential(V, q, (sp.Integer(1),) * n)

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
one pass over the sites kicks p and every δp. The lattice is its stencil
(:mod:`varint.models.stencil`): the site potential and the linear bond
below; its kernels, energy densities and SymPy potential follow.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .._validate import array_bytes, check_memory
from .lattice import check_boundary, check_real, check_seed, lattice_shape
from .stencil import Potential, Stencil, StencilLattice, stencil_kernels

__all__ = ["DisorderedKG", "STENCIL"]


# The site: u(q; a) = a q²/2 + q⁴/4 with a = ε̃_l (the kernels add z/W).
@njit(cache=True, error_model="numpy")
def _site_force(q, a, c):
    return (a + q * q) * q


@njit(cache=True, error_model="numpy")
def _site_stiffness(q, a, c):
    return a + 3.0 * q * q


@njit(cache=True, error_model="numpy")
def _site_third(q, a, c):
    return 6.0 * q


# The bond: φ(r) = r²/(2W), c = (W,): linear, κ = 1/W.
@njit(cache=True, error_model="numpy")
def _bond_force(r, c):
    return r / c[0]


@njit(cache=True, error_model="numpy")
def _bond_stiffness(r, c):
    return 1.0 / c[0]


@njit(cache=True, error_model="numpy")
def _bond_third(r, c):
    return 0.0


#: The Klein–Gordon lattice as a stencil (:mod:`varint.models.stencil`).
STENCIL = Stencil(
    "Klein-Gordon",
    site=Potential(_site_force, _site_stiffness, _site_third,
                   terms=(lambda q, a, c: 0.5 * a * q * q, lambda q, a, c: 0.25 * q ** 4),
                   expression=lambda q, a, c: a * q ** 2 / 2 + q ** 4 / 4),
    bond=Potential(_bond_force, _bond_stiffness, _bond_third,
                   terms=(lambda r, c: r * r / (2.0 * c[0]),),
                   expression=lambda r, c: r ** 2 / (2 * c[0]),
                   total=lambda r, c: np.sum(r * r, axis=-1) / (2.0 * c[0]), linear=True))

_KERNELS = stencil_kernels(STENCIL)
_apply, _field = _KERNELS.apply, _KERNELS.field


class DisorderedKG(StencilLattice):
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
        nx, ny, _ = lattice_shape(shape, check_boundary(boundary))
        n = nx * ny
        name = f"DisorderedKG(shape={shape!r}, W={self.W:g}, seed={self.seed})"
        # Before the first array of size N: disorder, parameters, one state.
        check_memory(array_bytes(n, n, 2 * n, 2 * n), f"model {name} ({n} sites)")
        self.epsilon = np.random.default_rng(self.seed).uniform(0.5, 1.5, n)
        self._setup_stencil(STENCIL, shape, boundary, name, a=self.epsilon,
                            bond_coeffs=(self.W,), kernels=_KERNELS)

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

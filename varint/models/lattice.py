"""Many-body lattices in one and two dimensions: their geometry, the parts
their Hamiltonian splits into, and the site distributions the lattice
observables are made of.

A lattice model is a :class:`~varint.models.base.Model` (so every run,
indicator, map and checkpoint takes it) that also declares :class:`Parts`:
the integrable pieces H = P_1 + … + P_k its Hamiltonian splits into, each
with its exact flow *fused* with the flow's tangent map — one compiled pass
over the sites moves the orbit and every deviation vector (Skokos & Gerlach
2010, Sect. V.C, applied to each part). ``method="tm"`` then runs any
two-part scheme of :data:`varint.SCHEMES` or k-part composition of
:data:`varint.schemes.SCHEMES` on them (:mod:`varint.methods.parts`).

Geometry
--------
Sites are numbered row by row: site (i, j) of an ``nx × ny`` lattice is
``l = i·ny + j``; a chain of N sites is the single row ``nx = 1, ny = N``.
The state is x = (q_0 … q_{N−1}, p_0 … p_{N−1}) as everywhere in varint.
Each site couples to its 2 (1D) or 4 (2D) nearest neighbours. Boundaries:

* ``"fixed"`` — the missing neighbours are fixed at zero (a chain between
  two walls, q_0 = q_{N+1} = 0 in 1-based numbering);
* ``"periodic"`` — a ring (1D) or a torus (2D).

Hessians are never stored: the kick of a lattice multiplies the deviation
vectors by its stencil on the fly, O(N) per vector. Chains with fixed ends
also provide the band kernels of :mod:`varint.models.base` (bandwidth 1),
so every other method (TDH, DOP853, CVODE, Taylor) runs them too; 2D
lattices and ring chains have no band storage (their Hessians have entries
far from the diagonal), and run with ``method="tm"`` only.

Site distributions
------------------
:meth:`LatticeModel.densities` gives the distribution of the conserved
quantity over sites (energy for the Klein–Gordon and FPUT lattices, norm
for the DDNLS); :mod:`varint.indicators.lattice` turns it into the second
moment m₂ and the participation number P, and the deviation vectors into
their distribution over sites (the DVD).
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import njit

from ..schemes import get_scheme
from .base import Model

__all__ = ["LatticeModel", "Parts", "BOUNDARIES", "lattice_shape"]

#: Boundary conditions a lattice takes.
BOUNDARIES = ("fixed", "periodic")

# Header of every lattice parameter array ``par`` (floats): dimension,
# rows, columns, periodic flag; the model's own entries follow.
DIM, NX, NY, PERIODIC, HEADER = 0, 1, 2, 3, 4


def lattice_shape(shape, boundary):
    """``(nx, ny, dim)`` of a lattice from ``shape`` (an int N or a pair
    (nx, ny)), checked.

    Raises
    ------
    ValueError
        If the shape is not a positive int or a pair of them, or too small
        for the boundary (a periodic side needs 3 sites, a fixed one 2).
    """
    def whole(v):
        return (not isinstance(v, (bool, np.bool_)) and isinstance(v, numbers.Real)
                and float(v).is_integer())

    smallest = 3 if boundary == "periodic" else 2
    if whole(shape):
        n = int(shape)
        if n < smallest:
            raise ValueError(f"shape must be at least {smallest} sites for {boundary} ends, "
                             f"got {shape!r}")
        return 1, n, 1
    if isinstance(shape, (tuple, list)) and len(shape) == 2 and all(whole(s) for s in shape):
        nx, ny = (int(s) for s in shape)
        if min(nx, ny) < smallest:
            raise ValueError(f"each side of shape must be at least {smallest} sites for "
                             f"{boundary} boundaries, got {tuple(shape)!r}")
        return nx, ny, 2
    raise ValueError(f"shape must be a number of sites N (1D) or a pair (nx, ny) (2D), "
                     f"got {shape!r}")


def check_boundary(boundary):
    if boundary not in BOUNDARIES:
        raise ValueError(f"boundary must be one of {', '.join(BOUNDARIES)}, got {boundary!r}")
    return boundary


def check_real(value, name, positive=False):
    """A finite real number (positive if asked), as a float."""
    if (isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real)
            or not math.isfinite(value) or (positive and value <= 0)):
        what = "a positive finite number" if positive else "a finite real number"
        raise ValueError(f"{name} must be {what}, got {value!r}")
    return float(value)


def check_seed(seed):
    if isinstance(seed, (bool, np.bool_)) or not isinstance(seed, numbers.Integral) or seed < 0:
        raise ValueError(f"seed must be a non-negative integer (it draws the disorder), "
                         f"got {seed!r}")
    return int(seed)


@njit(cache=True, error_model="numpy")
def no_band_kernel(q, par, B):
    """The ``hess`` (and ``third``) kernel of a lattice without band storage."""
    raise ValueError("this lattice has no band-stored Hessian (2D lattice, ring, or not "
                     "T(p) + V(q)); run it with method='tm'")


@njit(cache=True, error_model="numpy")
def no_third_kernel(q, par, v, B):
    raise ValueError("this lattice has no band-stored Hessian (2D lattice, ring, or not "
                     "T(p) + V(q)); run it with method='tm'")


@njit(cache=True, error_model="numpy")
def no_gradient_kernel(q, par, g):
    raise ValueError("this lattice is not of the form H = T(p) + V(q); run it with "
                     "method='tm'")


@njit(cache=True, error_model="numpy")
def neighbour_sum(a, base, s, nx, ny, dim, periodic):
    """Σ a[base + m] over the nearest neighbours m of site s (missing
    neighbours of fixed boundaries count as zero). For the sites on the
    edges; the interior loops of the kernels index their neighbours
    directly."""
    n = nx * ny
    i = s // ny
    j = s - i * ny
    acc = 0.0
    if j > 0:
        acc += a[base + s - 1]
    elif periodic:
        acc += a[base + s + ny - 1]
    if j < ny - 1:
        acc += a[base + s + 1]
    elif periodic:
        acc += a[base + s - ny + 1]
    if dim == 2:
        if i > 0:
            acc += a[base + s - ny]
        elif periodic:
            acc += a[base + s + n - ny]
        if i < nx - 1:
            acc += a[base + s + ny]
        elif periodic:
            acc += a[base + s - n + ny]
    return acc


@njit(cache=True, error_model="numpy")
def neighbour_sum_v(V, base, s, c, nx, ny, dim, periodic):
    """:func:`neighbour_sum` of deviation vector ``c``, row ``c`` of V."""
    n = nx * ny
    i = s // ny
    j = s - i * ny
    acc = 0.0
    if j > 0:
        acc += V[c, base + s - 1]
    elif periodic:
        acc += V[c, base + s + ny - 1]
    if j < ny - 1:
        acc += V[c, base + s + 1]
    elif periodic:
        acc += V[c, base + s - ny + 1]
    if dim == 2:
        if i > 0:
            acc += V[c, base + s - ny]
        elif periodic:
            acc += V[c, base + s + n - ny]
        if i < nx - 1:
            acc += V[c, base + s + ny]
        elif periodic:
            acc += V[c, base + s - n + ny]
    return acc


@njit(cache=True, error_model="numpy")
def n_edges(nx, ny, dim):
    """How many boundary sites :func:`edge_site` enumerates."""
    return 2 if dim == 1 else 2 * ny + 2 * (nx - 2)


@njit(cache=True, error_model="numpy")
def edge_site(e, nx, ny, dim):
    """The ``e``-th boundary site, each once: both ends of a chain; the
    first and last rows and the first and last column of a 2D lattice.
    Their neighbours need :func:`neighbour_sum`; the interior loops of the
    kernels index neighbours directly, with no test."""
    if dim == 1:
        return 0 if e == 0 else ny - 1
    if e < 2 * ny:
        j = e >> 1
        return j if e & 1 == 0 else (nx - 1) * ny + j
    e -= 2 * ny
    i = 1 + (e >> 1)
    return i * ny if e & 1 == 0 else i * ny + ny - 1


def neighbour_sweep(local, site, vector):
    """The one pass over the sites of an update that reads each site's
    value and the sum of its nearest neighbours' — the stencil of every
    linear coupling (the Klein–Gordon kick, the DDNLS hopping):
    ``sweep(x, V, k, dst, src, cst, nx, ny, dim, periodic)`` computes at
    every site s ``g = local(x[src + s], s, cst)`` (what the site's updates
    share, once per site where it can) and sets

        x[dst + s] = site(x[dst + s], g, Σ_{m~s} x[src + m], cst)

    and, on every deviation vector (row c of V), ``V[c, dst + s] =
    vector(V[c, dst + s], g, V[c, src + s], Σ_{m~s} V[c, src + m], cst)``.
    ``dst`` and ``src`` are the offsets of the two halves of the state (0
    for q, N for p); they differ, so the update never reads what it wrote.
    ``local``, ``site`` and ``vector`` are numba functions (compiled in);
    ``cst``, a tuple, carries what they read.

    The edge sites go through :func:`neighbour_sum`; the interior is
    indexed directly — a chain site by site, a 2D lattice row by row
    through slices indexed from 1, so that numba needs no negative-index
    fix-up on x[s − ny] (it cannot prove s − ny ≥ 0) and the site loops
    vectorise (3.5× faster than through :func:`neighbour_sum`; the same
    arithmetic).
    """

    # Inlined by numba where it is called: the offsets and the number of
    # vectors are then constants of the caller's loops.
    @njit(inline="always", error_model="numpy")
    def sweep(x, V, k, dst, src, cst, nx, ny, dim, per):
        # N from the array, not from par: then the compiler can tell the q
        # and p halves of x apart and vectorise the site loops (4x faster).
        n = x.shape[0] // 2
        for e in range(n_edges(nx, ny, dim)):
            s = edge_site(e, nx, ny, dim)
            g = local(x[src + s], s, cst)
            x[dst + s] = site(x[dst + s], g, neighbour_sum(x, src, s, nx, ny, dim, per), cst)
            for c in range(k):
                V[c, dst + s] = vector(V[c, dst + s], g, V[c, src + s],
                                       neighbour_sum_v(V, src, s, c, nx, ny, dim, per), cst)
        if dim == 1:
            for s in range(1, n - 1):
                g = local(x[src + s], s, cst)
                x[dst + s] = site(x[dst + s], g, x[src + s - 1] + x[src + s + 1], cst)
                for c in range(k):
                    V[c, dst + s] = vector(V[c, dst + s], g, V[c, src + s],
                                           V[c, src + s - 1] + V[c, src + s + 1], cst)
            return
        for i in range(1, nx - 1):
            r = i * ny
            r0 = src + r
            a, au, ad = x[r0:r0 + ny], x[r0 - ny:r0], x[r0 + ny:r0 + 2 * ny]
            out = x[dst + r:dst + r + ny]
            for j in range(1, ny - 1):
                out[j] = site(out[j], local(a[j], r + j, cst),
                              (a[j - 1] + a[j + 1]) + (au[j] + ad[j]), cst)
            for c in range(k):
                v, vu, vd = V[c, r0:r0 + ny], V[c, r0 - ny:r0], V[c, r0 + ny:r0 + 2 * ny]
                w = V[c, dst + r:dst + r + ny]
                for j in range(1, ny - 1):
                    w[j] = vector(w[j], local(a[j], r + j, cst), v[j],
                                  (v[j - 1] + v[j + 1]) + (vu[j] + vd[j]), cst)

    return sweep


@njit(cache=True, error_model="numpy")
def _hop_local(own, s, cst):
    return 0.0


@njit(cache=True, error_model="numpy")
def _hop_site(old, g, around, cst):
    return old + cst[0] * around


@njit(cache=True, error_model="numpy")
def _hop_vector(old, g, v, around, cst):
    return old + cst[0] * around


_hop_sweep = neighbour_sweep(_hop_local, _hop_site, _hop_vector)


@njit(cache=True, error_model="numpy")
def hop(x, V, k, dst, src, coef, nx, ny, dim, periodic):
    """x[dst + s] += coef · Σ_{m ~ s} x[src + m] for every site s, and the same on every
    deviation vector: the exact flow of a quadratic hopping part whose
    equations of motion are linear (so its tangent map is itself)."""
    _hop_sweep(x, V, k, dst, src, (coef,), nx, ny, dim, periodic)


@njit(inline="always", error_model="numpy")
def drift(x, V, h, k, n):
    """The kinetic flow e^{h L_T} of T = ½|p|² and its tangent map:
    q += h p, δq += h δp (Skokos & Gerlach 2010, eq. 46, unit masses).

    Through slices, each loop reading one half of a row and writing the
    other, so that it vectorises. Every entry gets the same operation, so
    the loops' shape leaves the bits alone: one loop per row for several
    vectors (one site loop over the orbit and k vectors at once, k a
    constant, took 1.9 times as long for k = 4 at N = 1024,
    studies/bench_stencil.py), the orbit's and the one vector's together
    for k = 1 (FPU-β's drift at n = 64 then took a third less time, measured
    alone), and inlined into the part stepper, where k is a constant."""
    q, p = x[:n], x[n:2 * n]
    if k == 1:
        dq, dp = V[0, :n], V[0, n:2 * n]
        for s in range(n):
            q[s] += h * p[s]
            dq[s] += h * dp[s]
        return
    for s in range(n):
        q[s] += h * p[s]
    for c in range(k):
        dq, dp = V[c, :n], V[c, n:2 * n]
        for s in range(n):
            dq[s] += h * dp[s]


@dataclass(frozen=True)
class Parts:
    """The parts a lattice's Hamiltonian splits into, as the part stepper
    (:mod:`varint.kernels.parts`) runs them.

    Attributes
    ----------
    names : tuple of str
        Every part the model can flow exactly, by index.
    apply : numba dispatcher
        ``apply(part, h, x, V, k, par, work)``: the exact flow of part
        ``part`` (an index into ``names``) for time ``h`` applied in place
        to the orbit ``x`` (2N,) and, fused in the same pass over the sites,
        its tangent map to the ``k`` deviation vectors, the rows of ``V``
        (k, 2N) (one contiguous row per vector: the stepper transposes the
        run's (2N, k) block, so that the site loops vectorise). ``k`` is a
        compile-time constant for small k. ``work`` is scratch of
        ``n_work`` floats.
    field : numba dispatcher
        ``field(x, par, out)``: the Hamiltonian vector field ẋ = J∇H at x
        (for accumulators that need the flow, e.g. OFLI).
    splits : dict of int -> tuple of str
        The parts (in scheme order) a k-part scheme runs on: e.g.
        ``{2: ("T", "V")}`` for H = T + V, where a two-part scheme's drift is
        the first and its kick the second.
    par : ndarray of float64
        The parameters ``apply`` and ``field`` read.
    n_work : int
        Scratch size per orbit.
    default_scheme : str or None
        The model's preferred scheme of ``method="tm"`` when none is given,
        run on its fused part stepper (or on the stepper generated for a
        small chain, :func:`varint.methods.parts.runs_parts`); None keeps
        :data:`varint.schemes.DEFAULT_SCHEME` on the generic stepper
        (:func:`varint.schemes.default_for` reads it).
    extend : callable or None
        ``extend(n_parts) -> (par, n_work)`` for splits whose flows need
        more data than ``par`` (built only when such a scheme is run).
    schemes : dict or None
        The model's own schemes by upper-cased name (those of a general
        H(q, p), :data:`varint.flows.general.GENERAL_SCHEMES`): when given,
        ``method="tm"`` takes only these.
    timed : bool
        A time-dependent H whose flows each integrate the whole H over
        their time h: ``apply`` reads the flow's start time from the last
        entry of ``par`` and advances the momentum conjugate to time, held
        in the last float of ``work`` (:func:`varint.kernels.parts.parts_body`).
    apply_only : callable or None
        ``apply_only(used) -> apply`` for a frozenset of part indices: the
        same flows compiled for those parts only, the others doing nothing
        (a general H's scheme runs one of its three Gauss–Legendre steps:
        compiling the other two took half of a GL8 run's 30 s compile,
        ``studies/compile_cost.py --cases general``); None: :attr:`apply`
        serves every scheme.
    """

    names: tuple
    apply: Any
    field: Any
    splits: dict
    par: np.ndarray
    n_work: int = 0
    default_scheme: str | None = None
    extend: Callable | None = None
    schemes: dict | None = None
    timed: bool = False
    apply_only: Callable | None = None

    def index(self, name):
        return self.names.index(name)

    def applying(self, used):
        """The ``apply`` of a scheme whose stages run the parts ``used``
        (part indices): :attr:`apply_only`'s, or :attr:`apply`."""
        if self.apply_only is None:
            return self.apply
        return self.apply_only(frozenset(int(i) for i in used))

    def slots(self, n_parts):
        """Slot of a ``n_parts``-part scheme → part index.

        Raises
        ------
        ValueError
            If the model has no split into that many parts.
        """
        if n_parts not in self.splits:
            have = ", ".join(f"{k} parts ({' + '.join(v)})" for k, v in sorted(self.splits.items()))
            raise ValueError(f"this model splits into {have}; a scheme over {n_parts} parts "
                             "does not fit it")
        return {slot: self.index(name) for slot, name in enumerate(self.splits[n_parts])}

    def resolve(self, scheme, owner="this model"):
        """The scheme ``scheme`` (name or object; None: the default) as the
        part stepper runs it on ``owner`` (its name, for the error).

        Raises
        ------
        ValueError
            For an unknown name, or for a model with :attr:`schemes` a
            scheme not among them.
        """
        chosen = scheme if scheme is not None else self.default_scheme
        if self.schemes is None:
            return get_scheme(chosen)
        # A model with schemes of its own (a general H(q, p)) takes only those.
        key = chosen.upper() if isinstance(chosen, str) else getattr(chosen, "name", "").upper()
        if key not in self.schemes:
            raise ValueError(f"{owner} is integrated by its own schemes "
                             f"({', '.join(s.name for s in self.schemes.values())}); "
                             f"got {chosen!r}")
        return self.schemes[key]

    def params(self, n_parts):
        """``(par, n_work)`` for a scheme over ``n_parts`` parts."""
        if self.extend is not None:
            return self.extend(n_parts)
        return self.par, self.n_work


class LatticeModel(Model):
    """Base of the lattice models: geometry, parts and site distributions.

    Subclasses call :meth:`_setup` with their potential, kernels and
    :class:`Parts`, and implement :meth:`densities` (and :meth:`energy`
    when H is not T(p) + V(q)).

    Attributes
    ----------
    shape : tuple of int
        ``(N,)`` for a chain, ``(nx, ny)`` for a 2D lattice.
    dim : int
        Phase-space dimension 2N (as every model).
    n_sites : int
    boundary : {"fixed", "periodic"}
    parts : Parts
    band_kernels : bool
        Whether the band kernels of :mod:`varint.models.base` are real (so
        methods other than the part stepper run the model).
    """

    band_kernels = True

    def _setup(self, shape, boundary, name, potential, grad, hess, third, bandwidth, params,
               band_kernels):
        self.boundary = check_boundary(boundary)
        nx, ny, d = lattice_shape(shape, boundary)
        self.nx, self.ny, self.lattice_dim = nx, ny, d
        self.shape = (ny,) if d == 1 else (nx, ny)
        self.n_sites = nx * ny
        self.band_kernels = bool(band_kernels)
        super().__init__(self.n_sites, potential, grad, hess, third, bandwidth, params=params,
                         name=name)

    def header(self):
        """The geometry entries of ``par`` (see the module docstring)."""
        return [float(self.lattice_dim), float(self.nx), float(self.ny),
                1.0 if self.boundary == "periodic" else 0.0]

    # -- geometry ------------------------------------------------------------
    def positions(self):
        """Site coordinates, shape (N, d): the index l (1D) or (i, j) (2D)."""
        idx = np.arange(self.n_sites)
        if self.lattice_dim == 1:
            return idx[:, None].astype(float)
        return np.stack([idx // self.ny, idx % self.ny], axis=1).astype(float)

    def neighbours(self, a):
        """Σ over nearest neighbours of a site field ``a`` (..., N)
        (NumPy; missing neighbours of fixed boundaries count as zero)."""
        a = np.asarray(a, dtype=float)
        f = a.reshape(a.shape[:-1] + (self.nx, self.ny))
        out = np.zeros_like(f)
        axes = (-1,) if self.lattice_dim == 1 else (-2, -1)
        for ax in axes:
            if self.boundary == "periodic":
                out += np.roll(f, 1, axis=ax) + np.roll(f, -1, axis=ax)
            else:
                sl = [slice(None)] * f.ndim
                lo, hi = list(sl), list(sl)
                lo[ax], hi[ax] = slice(1, None), slice(None, -1)
                out[tuple(lo)] += f[tuple(hi)]
                out[tuple(hi)] += f[tuple(lo)]
        return out.reshape(a.shape)

    def bonds(self, q):
        """Differences q_m − q_l across every bond, shape (..., n_bonds),
        and for each bond its two sites (−1 for a wall), shape (n_bonds, 2).
        Fixed boundaries have a bond from each edge site to the wall."""
        q = np.asarray(q, dtype=float)
        f = q.reshape(q.shape[:-1] + (self.nx, self.ny))
        idx = np.arange(self.n_sites).reshape(self.nx, self.ny)
        diffs, pairs = [], []
        axes = (1,) if self.lattice_dim == 1 else (0, 1)
        for ax in axes:
            fa = np.moveaxis(f, f.ndim - 2 + ax, -1)
            ia = np.moveaxis(idx, ax, -1)
            if self.boundary == "periodic":
                diffs.append((np.roll(fa, -1, axis=-1) - fa).reshape(q.shape[:-1] + (-1,)))
                pairs.append(np.stack([ia, np.roll(ia, -1, axis=-1)], -1).reshape(-1, 2))
            else:
                zero = np.zeros(fa.shape[:-1] + (1,))
                padded = np.concatenate([zero, fa, zero], axis=-1)
                diffs.append(np.diff(padded, axis=-1).reshape(q.shape[:-1] + (-1,)))
                wall = np.full(ia.shape[:-1] + (1,), -1)
                ip = np.concatenate([wall, ia, wall], axis=-1)
                pairs.append(np.stack([ip[..., :-1], ip[..., 1:]], -1).reshape(-1, 2))
        return np.concatenate(diffs, axis=-1), np.concatenate(pairs, axis=0)

    def split_bonds(self, energy, pairs):
        """Site shares of bond energies ``energy`` (..., n_bonds): half to
        each site of a bond, all of it to the site of a bond to a wall (so
        the shares sum to the total)."""
        energy = np.asarray(energy, dtype=float)
        out = np.zeros(energy.shape[:-1] + (self.n_sites,))
        a, b = pairs[:, 0], pairs[:, 1]
        inner = (a >= 0) & (b >= 0)
        np.add.at(out, (..., a[inner]), 0.5 * energy[..., inner])
        np.add.at(out, (..., b[inner]), 0.5 * energy[..., inner])
        wa = (a < 0)
        np.add.at(out, (..., b[wa]), energy[..., wa])
        wb = (b < 0)
        np.add.at(out, (..., a[wb]), energy[..., wb])
        return out

    # -- observables ---------------------------------------------------------
    def densities(self, x):
        """The conserved quantity's distribution over sites, shape (..., N)."""
        raise NotImplementedError

    #: What :meth:`densities` distributes ("energy" or "norm").
    density_of = "energy"

    def deviation_distribution(self, W):
        """The deviation vector distribution ξ_l = (δq_l² + δp_l²) / ‖w‖²
        of vectors ``W`` (..., 2N, k), shape (..., k, N) (Skokos, Gkolias &
        Flach 2013)."""
        W = np.asarray(W, dtype=float)
        n = self.n_sites
        w2 = W[..., :n, :] ** 2 + W[..., n:, :] ** 2
        w2 = np.moveaxis(w2, -1, -2)
        return w2 / np.sum(w2, axis=-1, keepdims=True)

    def initial_block(self, width=1, density=None, seed=0):
        """An initial state exciting a block of ``width`` (1D) or
        ``width × width`` (2D) sites at the centre of the lattice; see the
        subclasses for what ``density`` sets."""
        raise NotImplementedError

    def _block_sites(self, width):
        if isinstance(width, (bool, np.bool_)) or not isinstance(width, numbers.Integral)\
                or width < 1:
            raise ValueError(f"width must be a positive integer, got {width!r}")
        width = int(width)
        sides = (self.ny,) if self.lattice_dim == 1 else (self.nx, self.ny)
        if width > min(sides):
            raise ValueError(f"width {width} exceeds the lattice {self.shape}")
        starts = [(s - width) // 2 for s in sides]
        if self.lattice_dim == 1:
            return np.arange(starts[0], starts[0] + width)
        i = np.arange(starts[0], starts[0] + width)
        j = np.arange(starts[1], starts[1] + width)
        return (i[:, None] * self.ny + j[None, :]).ravel()

    # -- what a lattice without band kernels cannot give ---------------------
    def _band(self):
        if not self.band_kernels:
            raise ValueError(f"{self.name} has no band-stored Hessian (a 2D lattice, a ring, or "
                             "H not of the form T(p) + V(q)); its kicks apply the stencil "
                             "directly (method='tm')")

    def hessian_band(self, q, t=None):
        self._band()
        return super().hessian_band(q, t)

    def third_band(self, q, v, t=None):
        self._band()
        return super().third_band(q, v, t)

    def describe(self):
        d = super().describe()
        d.pop("inverse_mass", None)
        d.pop("params", None)
        d.update(shape=list(self.shape), boundary=self.boundary)
        return d

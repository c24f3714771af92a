"""The disordered discrete nonlinear Schrödinger (DDNLS) lattice in one and
two dimensions, in real canonical variables ψ_l = (q_l + i p_l)/√2:

    H = Σ_l [ (ε_l/2) r_l + (β/8) r_l² ] − Σ_{⟨l,m⟩} (q_l q_m + p_l p_m),   r_l = q_l² + p_l²,

i.e. H = Σ ε_l|ψ_l|² + (β/2)|ψ_l|⁴ − Σ_{⟨l,m⟩}(ψ_l ψ_m* + c.c.), the hopping
over nearest-neighbour bonds (Skokos, Gerlach, Bodyfelt, Papamikos & Eggl
2014; Many Manda, Senyange & Skokos 2020 in 2D). The on-site energies ε_l
are uniform in [−W/2, W/2], drawn by ``numpy.random.default_rng(seed)``
site by site. The sign of the hopping is immaterial: (q, p)_l → (−1)^l (q, p)_l
maps it onto the other sign and leaves every |ψ_l|² unchanged. The norm
S = Σ|ψ_l|² = ½ Σ r_l is the second integral (:meth:`DDNLS.norm`).

Parts (the three-part split of Skokos et al. 2014 and a two-part one):

* A = Σ (ε_l/2) r_l + (β/8) r_l²: every site rotates at its own frequency
  α_l = ε_l + β r_l/2 (r_l is conserved); with c, s = cos, sin(α_l h):
  q' = c q + s p, p' = c p − s q; tangent map, δα = β(q δq + p δp):
  δq' = c δq + s δp + h p' δα, δp' = −s δq + c δp − h q' δα.
* B = −Σ_bonds p_l p_m: q' = q − h K p, δq' = δq − h K δp (K: the sum over
  neighbours).
* C = −Σ_bonds q_l q_m: p' = p + h K q, δp' = δp + h K δq.
* L = B + C, the whole hopping, ψ' = e^{ihK} ψ: exact through the
  eigenvectors of K (per axis: K = Kx ⊕ Ky in 2D), O(N·(nx + ny)) per flow
  with dense eigenvector matrices, for the two-part split A + L
  (Gerlach, Meichsner & Skokos 2016 compare two- and three-part splits;
  which two parts they use could not be checked — this is one of the two
  natural choices). Every flow of A + L conserves the norm exactly.

The three-part schemes (ABC², s9ABC6, s11ABC6, s17ABC8, …) run on A, B, C;
the two-part ones (ABA864, SABA_n, …; no corrector) on A, L.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .._validate import array_bytes, check_memory
from .lattice import (HEADER, LatticeModel, Parts, check_boundary, check_real, check_seed,
                      hop, lattice_shape, neighbour_sum, no_band_kernel, no_gradient_kernel,
                      no_third_kernel)

__all__ = ["DDNLS"]

# par = header, β, β/2, ε_l; for the two-part split then λx, λy, Vx, Vy.
_BETA, _HALF, _EPS = HEADER, HEADER + 1, HEADER + 2


@njit(cache=True, error_model="numpy")
def _rotate(x, V, k, h, par):
    """e^{h L_A} and its tangent map (module docstring)."""
    n = x.shape[0] // 2
    beta, half = par[_BETA], par[_HALF]
    for s in range(n):
        q = x[s]
        p = x[n + s]
        a = (par[_EPS + s] + half * (q * q + p * p)) * h
        c = math.cos(a)
        sn = math.sin(a)
        qn = c * q + sn * p
        pn = c * p - sn * q
        x[s] = qn
        x[n + s] = pn
        hq = h * qn
        hp = h * pn
        for j in range(k):
            dq = V[j, s]
            dp = V[j, n + s]
            da = beta * (q * dq + p * dp)
            V[j, s] = c * dq + sn * dp + hp * da
            V[j, n + s] = c * dp - sn * dq - hq * da


@njit(cache=True, error_model="numpy")
def _to_modes(u, out, tmp, Vx, Vy, nx, ny):
    # out = Vxᵀ U Vy for the field U (nx, ny) stored row by row in u.
    for a in range(nx):
        for j in range(ny):
            acc = 0.0
            for i in range(nx):
                acc += Vx[i, a] * u[i * ny + j]
            tmp[a * ny + j] = acc
    for a in range(nx):
        for b in range(ny):
            acc = 0.0
            for j in range(ny):
                acc += tmp[a * ny + j] * Vy[j, b]
            out[a * ny + b] = acc


@njit(cache=True, error_model="numpy")
def _from_modes(m, u, tmp, Vx, Vy, nx, ny):
    # U = Vx M Vyᵀ, written into u.
    for i in range(nx):
        for b in range(ny):
            acc = 0.0
            for a in range(nx):
                acc += Vx[i, a] * m[a * ny + b]
            tmp[i * ny + b] = acc
    for i in range(nx):
        for j in range(ny):
            acc = 0.0
            for b in range(ny):
                acc += tmp[i * ny + b] * Vy[j, b]
            u[i * ny + j] = acc


@njit(cache=True, error_model="numpy")
def _hop_exact(x, V, k, h, par, work):
    """e^{h L_L}, L = B + C = −½(qᵀKq + pᵀKp): in the eigenbasis of K
    (eigenvalue λ) each mode rotates, â' = cos(λh) â − sin(λh) b̂,
    b̂' = cos(λh) b̂ + sin(λh) â; the map is linear, so the deviation
    vectors get the same one."""
    n = x.shape[0] // 2
    nx, ny = int(par[1]), int(par[2])
    o = _EPS + n
    lx = par[o:o + nx]
    ly = par[o + nx:o + nx + ny]
    o += nx + ny
    Vx = par[o:o + nx * nx].reshape(nx, nx)
    Vy = par[o + nx * nx:o + nx * nx + ny * ny].reshape(ny, ny)
    qa, pa, tmp = work[:n], work[n:2 * n], work[2 * n:3 * n]
    for f in range(k + 1):
        q = x[:n] if f == 0 else V[f - 1, :n]
        p = x[n:] if f == 0 else V[f - 1, n:]
        _to_modes(q, qa, tmp, Vx, Vy, nx, ny)
        _to_modes(p, pa, tmp, Vx, Vy, nx, ny)
        for a in range(nx):
            for b in range(ny):
                m = a * ny + b
                t = (lx[a] + ly[b]) * h
                c = math.cos(t)
                sn = math.sin(t)
                u = qa[m]
                qa[m] = c * u - sn * pa[m]
                pa[m] = c * pa[m] + sn * u
        _from_modes(qa, q, tmp, Vx, Vy, nx, ny)
        _from_modes(pa, p, tmp, Vx, Vy, nx, ny)


@njit(cache=True, error_model="numpy")
def _apply(part, h, x, V, k, par, work):
    n = x.shape[0] // 2
    dim, nx, ny, per = int(par[0]), int(par[1]), int(par[2]), par[3] != 0.0
    if part == 0:
        _rotate(x, V, k, h, par)
    elif part == 1:
        hop(x, V, k, 0, n, -h, nx, ny, dim, per)      # B: q −= h K p
    elif part == 2:
        hop(x, V, k, n, 0, h, nx, ny, dim, per)       # C: p += h K q
    else:
        _hop_exact(x, V, k, h, par, work)


@njit(cache=True, error_model="numpy")
def _field(x, par, out):
    n = x.shape[0] // 2
    dim, nx, ny, per = int(par[0]), int(par[1]), int(par[2]), par[3] != 0.0
    half = par[_HALF]
    for s in range(n):
        q = x[s]
        p = x[n + s]
        a = par[_EPS + s] + half * (q * q + p * p)
        out[s] = a * p - neighbour_sum(x, n, s, nx, ny, dim, per)
        out[n + s] = -a * q + neighbour_sum(x, 0, s, nx, ny, dim, per)


def _adjacency_eigen(m, periodic):
    """Eigenvalues and orthonormal eigenvectors of the adjacency matrix of
    a chain of m sites (a ring if periodic); m = 1: the 1×1 zero."""
    A = np.zeros((m, m))
    i = np.arange(m - 1)
    A[i, i + 1] = A[i + 1, i] = 1.0
    if periodic and m > 2:
        A[0, m - 1] = A[m - 1, 0] = 1.0
    return np.linalg.eigh(A)


class DDNLS(LatticeModel):
    """The disordered discrete nonlinear Schrödinger lattice (see the
    module docstring).

    Parameters
    ----------
    shape : int or (int, int)
        N sites of a chain, or (nx, ny) of a 2D lattice.
    W : float, default 4
        Disorder strength: ε_l ~ U[−W/2, W/2] (0: the ordered lattice).
    beta : float, default 1
        Nonlinearity β ≥ 0.
    seed : int, default 0
        Seed of the ε_l.
    boundary : {"fixed", "periodic"}
        Fixed: no hopping beyond the edges. Periodic: ring or torus.

    Notes
    -----
    H is not T(p) + V(q): only ``method="tm"`` (the part stepper) runs it.
    Relative energy errors of a run are measured against |H_q(q)| + |H_p(p)|
    (:meth:`potential` and :meth:`kinetic`: the parts of H in q alone and in
    p alone), which varint uses as the energy scale of every model.

    References
    ----------
    Ch. Skokos, E. Gerlach, J. D. Bodyfelt, G. Papamikos & S. Eggl, Phys.
    Lett. A 378, 1809 (2014); E. Gerlach, J. Meichsner & Ch. Skokos, Eur.
    Phys. J. Spec. Top. 225, 1103 (2016); C. Danieli, B. Many Manda, T.
    Mithun & Ch. Skokos, Math. Eng. 1, 447 (2019).
    """

    density_of = "norm"
    band_kernels = False

    def __init__(self, shape, W=4.0, beta=1.0, seed=0, boundary="fixed"):
        self.W = check_real(W, "W")
        if self.W < 0:
            raise ValueError(f"W must be >= 0 (the width of the disorder), got {W!r}")
        self.beta = check_real(beta, "beta")
        if self.beta < 0:
            raise ValueError(f"beta must be >= 0 (the nonlinearity), got {beta!r}")
        self.seed = check_seed(seed)
        nx, ny, dim = lattice_shape(shape, check_boundary(boundary))
        n = nx * ny
        name = f"DDNLS(shape={shape!r}, W={self.W:g}, beta={self.beta:g}, seed={self.seed})"
        check_memory(array_bytes(n, n, 2 * n, 2 * n), f"model {name} ({n} sites)")
        self.epsilon = np.random.default_rng(self.seed).uniform(-self.W / 2, self.W / 2, n)
        header = [float(dim), float(nx), float(ny), 1.0 if boundary == "periodic" else 0.0]
        par = np.concatenate([header, [self.beta, self.beta / 2], self.epsilon])
        self._setup(shape, boundary, name, self._Hq, no_gradient_kernel, no_band_kernel,
                    no_third_kernel, 0, par, False)
        self.parts = Parts(names=("A", "B", "C", "L"), apply=_apply, field=_field,
                           splits={3: ("A", "B", "C"), 2: ("A", "L")}, par=self.params,
                           default_scheme="s11ABC6", extend=self._extend)

    def _extend(self, n_parts):
        """``(par, n_work)``: the two-part split needs the eigenvectors of K
        (dense, nx² + ny² numbers), built here, only when it is run."""
        if n_parts != 2:
            return self.params, 0
        nx, ny = self.nx, self.ny
        check_memory(array_bytes(nx * nx, ny * ny, 3 * self.n_sites),
                     f"the two-part split of {self.name} (eigenvectors of the hopping, "
                     f"{nx}² + {ny}² numbers)")
        periodic = self.boundary == "periodic"
        lx, Vx = _adjacency_eigen(nx, periodic)
        ly, Vy = _adjacency_eigen(ny, periodic)
        par = np.concatenate([self.params, lx, ly, Vx.ravel(), Vy.ravel()])
        return par, 3 * self.n_sites

    # -- the Hamiltonian -----------------------------------------------------
    def _half(self, u):
        # The part of H in one half of the state (q or p) alone.
        u = np.asarray(u, dtype=float)
        return (np.sum(0.5 * self.epsilon * u * u + self.beta / 8.0 * u ** 4, axis=-1)
                - 0.5 * np.sum(u * self.neighbours(u), axis=-1))

    def _Hq(self, q):
        return self._half(q)

    def kinetic(self, p):
        """The part of H in p alone: Σ (ε/2)p² + (β/8)p⁴ − ½ pᵀKp."""
        return self._half(p)

    def energy(self, x):
        """H(x) for states of shape (..., 2N)."""
        x = np.asarray(x, dtype=float)
        n = self.n_sites
        q, p = x[..., :n], x[..., n:]
        return self._half(q) + self._half(p) + self.beta / 4.0 * np.sum(q * q * p * p, axis=-1)

    def norm(self, x):
        """S = Σ|ψ_l|² = ½ Σ (q_l² + p_l²), the second integral; shape (...)."""
        x = np.asarray(x, dtype=float)
        return 0.5 * np.sum(x * x, axis=-1)

    def vector_field(self, x):
        """ẋ = J∇H at the state x (2N,) (what the flows integrate)."""
        x = np.ascontiguousarray(x, dtype=np.float64)
        out = np.empty_like(x)
        _field(x, self.params, out)
        return out

    def densities(self, x):
        """Norm per site |ψ_l|² = (q_l² + p_l²)/2, shape (..., N)."""
        x = np.asarray(x, dtype=float)
        n = self.n_sites
        return 0.5 * (x[..., :n] ** 2 + x[..., n:] ** 2)

    def initial_block(self, width=1, density=1.0, seed=0):
        """|ψ_l|² = ``density`` on a central block of ``width`` (or width ×
        width) sites, zero elsewhere, with phases drawn uniformly by
        ``default_rng(seed)`` (all zero for ``seed=None``)."""
        a = check_real(density, "density", positive=True)
        sites = self._block_sites(width)
        phase = (np.zeros(sites.size) if seed is None
                 else np.random.default_rng(check_seed(seed)).uniform(0, 2 * np.pi, sites.size))
        x = np.zeros(2 * self.n_sites)
        x[sites] = np.sqrt(2 * a) * np.cos(phase)
        x[self.n_sites + sites] = np.sqrt(2 * a) * np.sin(phase)
        return x

    def describe(self):
        d = super().describe()
        d.update(W=self.W, beta=self.beta, seed=self.seed, disorder="uniform [-W/2, W/2]")
        return d

"""Exactly solvable parts of H = T(p) + V(q) and of H = A + V(q), fused
with their tangent maps.

The tangent map (TM) method needs, for each part of a split Hamiltonian,
its exact flow and the derivative of that flow (Skokos & Gerlach 2010,
Sect. V.C). Three kinds of part are solvable here:

* **T(p)**, any kinetic energy (relativistic, non-quadratic dispersion): p
  is constant along its flow, so ``q ← q + h ∇T(p)`` and, differentiated,
  ``δq ← δq + h D²T(p) δp`` (:func:`kinetic_drift`);
* **V(q)**, any potential: ``p ← p − h ∇V(q)``, ``δp ← δp − h D²V(q) δq``
  (:func:`potential_kick`; Skokos & Gerlach 2010, eq. 47);
* **A = ½a|p_⊥|² + ½b|q_⊥|² − Ω L + Σ_i (½a_i p_i² + ½b_i q_i²)**, with
  L = q_u p_v − q_v p_u the angular momentum in one plane (u, v) of the
  coordinates and the other coordinates decoupled (:func:`planar_flow`).
  With b = 0 this is free motion seen from a frame rotating at Ω about the
  axis normal to the plane (the restricted three-body problem, a rotating
  bar); with Ω = ω_L = qB/2m and b = m ω_L² it is a charged particle in a
  uniform magnetic field along that axis, symmetric gauge (the Larmor
  rotation). The isotropic oscillator ½a|p_⊥|² + ½b|q_⊥|² commutes with L,
  so the flow is the product of a rotation by −Ωh and the oscillator's own
  flow (cos/sin for ab > 0, free motion for b = 0, cosh/sinh for ab < 0):
  a linear map, which is also its tangent map.

Parameters of :func:`planar_flow` are packed by :func:`planar_params`.
Deviation vectors are the rows of ``V`` (k, 2N) (:mod:`varint.flows`).

References
----------
Ch. Skokos & E. Gerlach, Phys. Rev. E 82, 036704 (2010) — the TM method.
L. D. Landau & E. M. Lifshitz, *Mechanics*, §39 (motion in a rotating
frame); *The Classical Theory of Fields*, §21 (motion in a uniform
magnetic field).
"""

from __future__ import annotations

import math
from functools import cache

import numpy as np
from numba import njit

__all__ = ["kinetic_drift", "potential_kick", "planar_flow", "planar_params", "oscillator",
           "separable_apply", "rotating_apply", "hamiltonian_field", "PLANAR_HEADER"]

#: Entries of :func:`planar_params` before the per-coordinate (a_i, b_i):
#: the plane's two coordinate indices u and v, a, b and Ω.
PLANAR_HEADER = 5


@njit(error_model="numpy")
def kinetic_drift(h, x, V, k, par, g, D, grad_t, grad_hess_t):
    """The flow of T(p) for time h and its tangent map, in place:
    q ← q + h ∇T(p), δq ← δq + h D²T(p) δp (p and δp unchanged).

    ``g`` (N,) and ``D`` (N, N) are scratch; ``grad_t(p, par, g)`` and
    ``grad_hess_t(p, par, g, D)`` are the model's kernels of T.
    """
    n = x.shape[0] // 2
    p = x[n:]
    if k == 0:
        grad_t(p, par, g)
    else:
        grad_hess_t(p, par, g, D)
    for i in range(n):
        x[i] += h * g[i]
    for c in range(k):
        for i in range(n):
            acc = 0.0
            for j in range(n):
                acc += D[i, j] * V[c, n + j]
            V[c, i] += h * acc


@njit(error_model="numpy")
def potential_kick(h, x, V, k, par, g, D, grad_v, grad_hess_v):
    """The flow of V(q) for time h and its tangent map, in place:
    p ← p − h ∇V(q), δp ← δp − h D²V(q) δq (Skokos & Gerlach 2010,
    eq. 47); scratch and kernels as in :func:`kinetic_drift`."""
    n = x.shape[0] // 2
    q = x[:n]
    if k == 0:
        grad_v(q, par, g)
    else:
        grad_hess_v(q, par, g, D)
    for i in range(n):
        x[n + i] -= h * g[i]
    for c in range(k):
        for i in range(n):
            acc = 0.0
            for j in range(n):
                acc += D[i, j] * V[c, j]
            V[c, n + i] -= h * acc


@njit(cache=True, error_model="numpy")
def oscillator(a, b, h):
    """Coefficients (c, s1, s2) of the flow of ½a p² + ½b q² for time h:
    q ← c q + s1 p, p ← s2 q + c p (q̇ = a p, ṗ = −b q)."""
    ab = a * b
    if ab > 0.0:
        w = math.sqrt(ab)
        s = math.sin(w * h)
        return math.cos(w * h), a * s / w, -b * s / w
    if ab < 0.0:
        w = math.sqrt(-ab)
        s = math.sinh(w * h)
        return math.cosh(w * h), a * s / w, -b * s / w
    return 1.0, a * h, -b * h


@njit(cache=True, error_model="numpy")
def _pair(x, V, k, i, j, c, s1, s2):
    # (x_i, x_j) ← (c x_i + s1 x_j, s2 x_i + c x_j), on the orbit and every vector.
    xi, xj = x[i], x[j]
    x[i] = c * xi + s1 * xj
    x[j] = s2 * xi + c * xj
    for r in range(k):
        vi, vj = V[r, i], V[r, j]
        V[r, i] = c * vi + s1 * vj
        V[r, j] = s2 * vi + c * vj


@njit(cache=True, error_model="numpy")
def planar_flow(h, x, V, k, par):
    """The flow of A (module docstring) for time h, and its tangent map
    (the same linear map), in place; ``par`` from :func:`planar_params`."""
    n = x.shape[0] // 2
    u = int(par[0])
    v = int(par[1])
    c, s1, s2 = oscillator(par[2], par[3], h)
    _pair(x, V, k, u, n + u, c, s1, s2)
    _pair(x, V, k, v, n + v, c, s1, s2)
    # Rotation by −Ωh of (q_u, q_v) and of (p_u, p_v): the flow of −Ω L.
    cr = math.cos(par[4] * h)
    sr = math.sin(par[4] * h)
    _pair(x, V, k, u, v, cr, sr, -sr)
    _pair(x, V, k, n + u, n + v, cr, sr, -sr)
    for i in range(n):
        if i in (u, v):
            continue
        a = par[PLANAR_HEADER + 2 * i]
        b = par[PLANAR_HEADER + 2 * i + 1]
        c, s1, s2 = oscillator(a, b, h)
        _pair(x, V, k, i, n + i, c, s1, s2)


def planar_params(n, plane, a, b, omega, others):
    """The ``par`` of :func:`planar_flow`.

    Parameters
    ----------
    n : int
        Degrees of freedom N.
    plane : (int, int)
        The coordinates (u, v) of the rotation plane, L = q_u p_v − q_v p_u.
    a, b, omega : float
        A's coefficients in the plane: ½a|p_⊥|² + ½b|q_⊥|² − Ω L.
    others : dict of int -> (float, float)
        (a_i, b_i) of every other coordinate i: ½a_i p_i² + ½b_i q_i².
    """
    par = np.zeros(PLANAR_HEADER + 2 * n)
    par[:PLANAR_HEADER] = (plane[0], plane[1], a, b, omega)
    for i, (ai, bi) in others.items():
        par[PLANAR_HEADER + 2 * i] = ai
        par[PLANAR_HEADER + 2 * i + 1] = bi
    return par


# -- the part flows of a model, as the part stepper calls them ---------------------------
@cache
def separable_apply(grad_t, grad_hess_t, grad_v, grad_hess_v):
    """``apply(part, h, x, V, k, par, work)`` of H = T(p) + V(q): part 0 is
    the flow of T, part 1 that of V (:class:`varint.models.lattice.Parts`);
    ``work`` holds N + N² floats."""

    @njit(error_model="numpy")
    def apply(part, h, x, V, k, par, work):
        n = x.shape[0] // 2
        g = work[:n]
        D = work[n:n + n * n].reshape((n, n))
        if part == 0:
            kinetic_drift(h, x, V, k, par, g, D, grad_t, grad_hess_t)
        else:
            potential_kick(h, x, V, k, par, g, D, grad_v, grad_hess_v)

    return apply


@cache
def rotating_apply(grad_v, grad_hess_v):
    """``apply`` of H = A + V(q): part 0 is the flow of A
    (:func:`planar_flow`, whose parameters lead ``par``), part 1 that of V."""

    @njit(error_model="numpy")
    def apply(part, h, x, V, k, par, work):
        n = x.shape[0] // 2
        if part == 0:
            planar_flow(h, x, V, k, par)
        else:
            potential_kick(h, x, V, k, par, work[:n], work[n:n + n * n].reshape((n, n)),
                           grad_v, grad_hess_v)

    return apply


@cache
def hamiltonian_field(grad):
    """``field(x, par, out)``: the Hamiltonian vector field ẋ = J∇H from the
    model's kernel ``grad(x, par, g)`` = ∇H (for accumulators that need the
    flow, e.g. OFLI)."""

    @njit(error_model="numpy")
    def field(x, par, out):
        d = x.shape[0]
        n = d // 2
        g = np.empty(d)
        grad(x, par, g)
        for i in range(n):
            out[i] = g[n + i]
            out[n + i] = -g[i]

    return field

"""Gravitational interaction of a star and n planets in the canonical
coordinates of Wisdom–Holman maps, with the exact flows of the map's parts
fused with their tangent maps.

State x = (q, p), q and p of length N = 3n: planet i (0-based) at
q[3i:3i+3], p[3i:3i+3]; the star and the centre of mass are eliminated.
Two coordinate systems (``par[COORDS]``):

Jacobi (0)
    q_i is planet i's position relative to the centre of mass of the star
    and the planets inside it, p_i = m′_i q̇_i with m′_i = m_i M_{i−1}/M_i
    (M_i: the mass of the star and planets 0 … i). Then
    H = Σ p_i²/2m′_i + U(q) with U the Newtonian potential of all pairs, and
    the Wisdom–Holman split H = A + B is A = Σ [p_i²/2m′_i − G m_i M_{i−1}/|q_i|]
    (a Kepler problem per planet, μ_i = G M_i) and the interaction
    B = U + Σ G m_i M_{i−1}/|q_i|, a function of q alone (Wisdom & Holman
    1991; for the innermost planet the two star terms cancel exactly and
    are left out).
Democratic heliocentric (1)
    Q_i = x_i − x_star, P_i the barycentric momenta: H = H_K + H_I + H_J
    with H_K = Σ [P_i²/2m_i − G m₀m_i/|Q_i|] (μ = G m₀), H_I = −Σ_{i<j}
    G m_i m_j/|Q_i − Q_j| and H_J = |Σ P_i|²/2m₀ (Duncan, Levison & Lee
    1998), three parts each exactly solvable.

The heliocentric positions u_i = x_i − x_star follow from the Jacobi ones by
a lower-triangular map u = Lq (u_i = q_i + Σ_{j<i} m_j u_j / M_{i−1}), so
∇_q = Lᵀ∇_u and D²_q = Lᵀ D²_u L, each applied by an O(n) recursion
(:func:`jacobi_to_helio`, :func:`jacobi_transpose`); pair terms cost O(n²).

Parameters ``par`` (floats): n, G, the coordinate flag, then the masses
m₀ … m_n, the interior masses M₀ … M_n, the Kepler parameters μ_i and the
Kepler masses m′_i (:func:`planetary_params`).

References
----------
J. Wisdom & M. Holman, Astron. J. 102, 1528 (1991); M. J. Duncan,
H. F. Levison & M. H. Lee, Astron. J. 116, 2067 (1998); H. Rein &
D. Tamayo, Mon. Not. R. Astron. Soc. 452, 376 (2015) (WHFast, with the
variational equations of these flows).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .kepler import KEPLER_OK, kepler_step

__all__ = ["planetary_params", "JACOBI", "DEMOCRATIC", "KEPLER", "INTERACTION", "JUMP",
           "ENCOUNTER",
           "apply_flow", "vector_field", "potential_gradient", "potential_hessian_band",
           "potential_third_band", "unchecked_hessian", "unchecked_third",
           "interaction_gradient", "jacobi_to_helio",
           "jacobi_transpose", "n_work", "apply_word"]

#: Coordinate flags (``par[COORDS]``).
JACOBI, DEMOCRATIC = 0, 1
#: Part indices of :func:`apply_flow`.
KEPLER, INTERACTION, JUMP = 0, 1, 2
#: What a kick returns when two planets came closer than the
#: close-encounter distance (the Kepler solver's failures are 1 and 2).
ENCOUNTER = 3

_N, _G, _COORDS, _MASS = 0, 1, 2, 3


def planetary_params(masses, G, coordinates, close_encounter=None):
    """The kernels' ``par`` for a star and planets of ``masses`` (m₀ … m_n)
    in ``coordinates`` (:data:`JACOBI` or :data:`DEMOCRATIC`), stopping at
    a ``close_encounter`` (in mutual Hill radii; None: never).

    A close encounter of planets i and j is |u_i − u_j|² < f² R²_ij with
    the mutual Hill radius R²_ij = ((m_i + m_j)/3m₀)^{2/3} (|u_i|² + |u_j|²)/2
    at the planets' present distances from the star (the mean of squares:
    no square root in the kick); ``par`` holds f² and each pair's
    ((m_i + m_j)/3m₀)^{2/3}/2 after the Kepler masses."""
    m = np.asarray(masses, dtype=np.float64)
    n = len(m) - 1
    interior = np.cumsum(m)
    if coordinates == JACOBI:
        mu = G * interior[1:]
        kmass = m[1:] * interior[:-1] / interior[1:]
    else:
        mu = np.full(n, G * m[0])
        kmass = m[1:].copy()
    f2 = 0.0 if close_encounter is None else float(close_encounter) ** 2
    hill = [0.5 * np.cbrt((m[1 + i] + m[1 + j]) / (3 * m[0])) ** 2
            for i in range(n) for j in range(i + 1, n)]
    return np.concatenate([[n, G, coordinates], m, interior, mu, kmass, [f2], hill])


def n_work(n):
    """Scratch floats per orbit of :func:`apply_flow` for n planets: five
    vectors of 3n and c, s of each of the at most n(n + 3)/2 terms of B."""
    return 5 * 3 * n + n * (n + 3)


@njit(inline="always")
def _interior(n):
    return _MASS + n + 1


@njit(inline="always")
def _mu(n):
    return _MASS + 2 * n + 2


@njit(inline="always")
def _kmass(n):
    return _MASS + 3 * n + 2


@njit(cache=True, error_model="numpy")
def jacobi_to_helio(q, par, u):
    """u = Lq: heliocentric positions (3n,) from Jacobi positions ``q``;
    also maps Jacobi deviations δq to heliocentric ones (L is linear)."""
    n = int(par[_N])
    oi = _interior(n)
    sx = sy = sz = 0.0
    for i in range(n):
        inv = 1.0 / par[oi + i]          # 1/M_{i−1}: star and planets inside i
        u[3 * i] = q[3 * i] + sx * inv
        u[3 * i + 1] = q[3 * i + 1] + sy * inv
        u[3 * i + 2] = q[3 * i + 2] + sz * inv
        m = par[_MASS + 1 + i]
        sx += m * u[3 * i]
        sy += m * u[3 * i + 1]
        sz += m * u[3 * i + 2]


@njit(cache=True, error_model="numpy")
def jacobi_transpose(g, par, out):
    """out = Lᵀg: a gradient (or Hessian column) with respect to the
    heliocentric positions taken to the Jacobi ones (the transpose of
    :func:`jacobi_to_helio`, by the backward recursion
    out_j = g_j + m_j Σ_{i>j} out_i/M_{i−1})."""
    n = int(par[_N])
    oi = _interior(n)
    tx = ty = tz = 0.0
    for j in range(n - 1, -1, -1):
        m = par[_MASS + 1 + j]
        ox = g[3 * j] + m * tx
        oy = g[3 * j + 1] + m * ty
        oz = g[3 * j + 2] + m * tz
        out[3 * j], out[3 * j + 1], out[3 * j + 2] = ox, oy, oz
        inv = 1.0 / par[oi + j]
        tx += ox * inv
        ty += oy * inv
        tz += oz * inv


@njit(inline="always")
def _term(K, dx, dy, dz, cs, t):
    """Store c = K/r³ and s = 3/r² of the pair term φ(d) = −K/|d| as term
    ``t`` of ``cs``, and return c (its gradient is c·d, its Hessian
    c (I − s d dᵀ))."""
    r2 = dx * dx + dy * dy + dz * dz
    c = K / (r2 * math.sqrt(r2))
    cs[2 * t] = c
    cs[2 * t + 1] = 3.0 / r2
    return c


@njit(cache=True, error_model="numpy")
def _pair_gradient(u, par, g, star_from, cs):
    """g = ∂U/∂u for U = −Σ_{i ≥ star_from} G m₀m_i/|u_i| − Σ_{i<j} G m_i m_j/|u_i − u_j|,
    each term's c, s stored in ``cs`` (:func:`_term`: star terms, then the
    pairs); returns the number of terms."""
    n = int(par[_N])
    G = par[_G]
    m0 = par[_MASS]
    for a in range(3 * n):
        g[a] = 0.0
    t = 0
    for i in range(star_from, n):
        x, y, z = u[3 * i], u[3 * i + 1], u[3 * i + 2]
        c = _term(G * m0 * par[_MASS + 1 + i], x, y, z, cs, t)
        t += 1
        g[3 * i] += c * x
        g[3 * i + 1] += c * y
        g[3 * i + 2] += c * z
    for i in range(n):
        mi = par[_MASS + 1 + i]
        for j in range(i + 1, n):
            dx = u[3 * i] - u[3 * j]
            dy = u[3 * i + 1] - u[3 * j + 1]
            dz = u[3 * i + 2] - u[3 * j + 2]
            c = _term(G * mi * par[_MASS + 1 + j], dx, dy, dz, cs, t)
            t += 1
            g[3 * i] += c * dx
            g[3 * i + 1] += c * dy
            g[3 * i + 2] += c * dz
            g[3 * j] -= c * dx
            g[3 * j + 1] -= c * dy
            g[3 * j + 2] -= c * dz
    return t


@njit(inline="always")
def _pair_block(K, dx, dy, dz, ex, ey, ez, wx, wy, wz, third):
    """The 3-vector D²φ·e (or, with ``third``, (D³φ·w)·e) of the pair
    potential φ(d) = −K/|d| at separation d."""
    r2 = dx * dx + dy * dy + dz * dz
    ir2 = 1.0 / r2
    ir3 = ir2 / math.sqrt(r2)
    de = dx * ex + dy * ey + dz * ez
    if not third:
        # D²φ = K (I − 3 d dᵀ/r²)/r³.
        s = 3.0 * de * ir2
        return K * ir3 * (ex - s * dx), K * ir3 * (ey - s * dy), K * ir3 * (ez - s * dz)
    # D³φ·w = K [−3 (d·w) I − 3 (w dᵀ + d wᵀ) + 15 (d·w) d dᵀ/r²]/r⁵.
    dw = dx * wx + dy * wy + dz * wz
    we = wx * ex + wy * ey + wz * ez
    c = K * ir3 * ir2
    a = -3.0 * dw
    b = 15.0 * dw * de * ir2 - 3.0 * we
    return (c * (a * ex - 3.0 * de * wx + b * dx), c * (a * ey - 3.0 * de * wy + b * dy),
            c * (a * ez - 3.0 * de * wz + b * dz))


@njit(cache=True, error_model="numpy")
def _pair_operator(u, e, w, par, out, star_from, third):
    """out = D²U·e (or (D³U·w)·e with ``third``) with respect to the
    heliocentric positions ``u`` (U as in :func:`_pair_gradient`)."""
    n = int(par[_N])
    G = par[_G]
    m0 = par[_MASS]
    for a in range(3 * n):
        out[a] = 0.0
    for i in range(star_from, n):
        K = G * m0 * par[_MASS + 1 + i]
        bx, by, bz = _pair_block(K, u[3 * i], u[3 * i + 1], u[3 * i + 2], e[3 * i],
                                 e[3 * i + 1], e[3 * i + 2], w[3 * i], w[3 * i + 1],
                                 w[3 * i + 2], third)
        out[3 * i] += bx
        out[3 * i + 1] += by
        out[3 * i + 2] += bz
    for i in range(n):
        mi = par[_MASS + 1 + i]
        for j in range(i + 1, n):
            K = G * mi * par[_MASS + 1 + j]
            bx, by, bz = _pair_block(
                K, u[3 * i] - u[3 * j], u[3 * i + 1] - u[3 * j + 1], u[3 * i + 2] - u[3 * j + 2],
                e[3 * i] - e[3 * j], e[3 * i + 1] - e[3 * j + 1], e[3 * i + 2] - e[3 * j + 2],
                w[3 * i] - w[3 * j], w[3 * i + 1] - w[3 * j + 1], w[3 * i + 2] - w[3 * j + 2],
                third)
            out[3 * i] += bx
            out[3 * i + 1] += by
            out[3 * i + 2] += bz
            out[3 * j] -= bx
            out[3 * j + 1] -= by
            out[3 * j + 2] -= bz


@njit(inline="always")
def _coords(par):
    return int(par[_COORDS])


# -- the whole potential U(q): the model's kernels ---------------------------
@njit(cache=True, error_model="numpy")
def potential_gradient(q, par, g):
    """g = ∇U(q), the gradient of the Newtonian potential of all pairs in
    the model's coordinates (the ``grad`` kernel of
    :class:`varint.models.Planetary` in Jacobi coordinates)."""
    n3 = q.shape[0]
    n = n3 // 3
    u = np.empty(n3)
    gu = np.empty(n3)
    cs = np.empty(n * (n + 1))
    if _coords(par) == JACOBI:
        jacobi_to_helio(q, par, u)
        _pair_gradient(u, par, gu, 0, cs)
        jacobi_transpose(gu, par, g)
    else:
        _pair_gradient(q, par, g, 0, cs)


@njit(cache=True, error_model="numpy")
def _potential_columns(q, par, v, B, third):
    # Column j of D²U (or of Σ_k v_k D²∂_kU) is Lᵀ (D²_u U) L e_j.
    n3 = q.shape[0]
    jac = _coords(par) == JACOBI
    u, e, w = np.zeros(n3), np.zeros(n3), np.zeros(n3)
    col, tmp = np.zeros(n3), np.zeros(n3)
    if jac:
        jacobi_to_helio(q, par, u)
        if third:
            jacobi_to_helio(v, par, w)
    else:
        u[:] = q
        if third:
            w[:] = v
    unit = np.zeros(n3)
    for j in range(n3):
        unit[:] = 0.0
        unit[j] = 1.0
        if jac:
            jacobi_to_helio(unit, par, e)
        else:
            e[:] = unit
        _pair_operator(u, e, w, par, tmp, 0, third)
        if jac:
            jacobi_transpose(tmp, par, col)
        else:
            col[:] = tmp
        for i in range(j + 1):
            B[j - i, i] = col[i]


@njit(cache=True, error_model="numpy")
def potential_hessian_band(q, par, B):
    """D²U(q) in band storage of full bandwidth (B[b, i] = A[i, i + b])."""
    _potential_columns(q, par, q, B, False)


@njit(cache=True, error_model="numpy")
def potential_third_band(q, par, v, B):
    """Σ_k v_k D²(∂_kU)(q) in band storage of full bandwidth."""
    _potential_columns(q, par, v, B, True)


@njit(cache=True, error_model="numpy")
def unchecked_hessian(q, par, B):
    """The ``hess`` kernel a start check evaluates in place of
    :func:`potential_hessian_band` (:attr:`varint.models.Planetary.checked_kernels`):
    writes nothing, so the check's zeroed band stays finite."""


@njit(cache=True, error_model="numpy")
def unchecked_third(q, par, v, B):
    """The ``third`` kernel a start check evaluates in place of
    :func:`potential_third_band` (as :func:`unchecked_hessian`)."""


# -- the Wisdom–Holman parts ---------------------------------------------------
@njit(inline="always")
def _hessian_term(cs, t, dx, dy, dz, ex, ey, ez):
    """D²φ·e of term ``t`` (stored by :func:`_term`) at separation d."""
    c = cs[2 * t]
    a = cs[2 * t + 1] * (dx * ex + dy * ey + dz * ez)
    return c * (ex - a * dx), c * (ey - a * dy), c * (ez - a * dz)


@njit(cache=True, error_model="numpy")
def _interaction(q, par, work):
    """The gradient ∇B(q) of the interaction part into ``work[2·3n:3·3n]``,
    and what its Hessian needs: the heliocentric positions (``work[:3n]``)
    and each term's c, s (``work[5·3n:]``, :func:`_term`), in the order
    star terms, planet pairs, then (Jacobi) the Kepler terms removed.

    The terms of B: −G m₀m_i/|u_i| for i ≥ 1 (Jacobi; none in democratic
    heliocentric coordinates, where they are in H_K), −G m_i m_j/|u_i − u_j|,
    and (Jacobi) +G m_i M_{i−1}/|q_i| for i ≥ 1, a term of the same form
    with K = −G m_i M_{i−1} in the Jacobi positions themselves (module
    docstring; planet 0's two star terms cancel and are left out).
    """
    n = int(par[_N])
    n3 = 3 * n
    jac = _coords(par) == JACOBI
    u = work[:n3]
    gu = work[n3:2 * n3]
    g = work[2 * n3:3 * n3]
    cs = work[5 * n3:]
    if jac:
        jacobi_to_helio(q, par, u)
    else:
        for a in range(n3):
            u[a] = q[a]
    t = _pair_gradient(u, par, gu, 1 if jac else n, cs)
    if not jac:
        for a in range(n3):
            g[a] = gu[a]
        return
    jacobi_transpose(gu, par, g)
    oi = _interior(n)
    G = par[_G]
    for i in range(1, n):
        x, y, z = q[3 * i], q[3 * i + 1], q[3 * i + 2]
        c = _term(-G * par[_MASS + 1 + i] * par[oi + i], x, y, z, cs, t)
        t += 1
        g[3 * i] += c * x
        g[3 * i + 1] += c * y
        g[3 * i + 2] += c * z


@njit(cache=True, error_model="numpy")
def _interaction_hvp(q, e, par, work, out):
    """out = D²B(q)·e for a deviation of the positions ``e`` (3n,), from
    the geometry :func:`_interaction` left in ``work``."""
    n = int(par[_N])
    n3 = 3 * n
    jac = _coords(par) == JACOBI
    u = work[:n3]
    du = work[3 * n3:4 * n3]
    hv = work[4 * n3:5 * n3] if jac else out
    cs = work[5 * n3:]
    if jac:
        jacobi_to_helio(e, par, du)
    else:
        for a in range(n3):
            du[a] = e[a]
    for a in range(n3):
        hv[a] = 0.0
    t = 0
    if jac:
        for i in range(1, n):
            bx, by, bz = _hessian_term(cs, t, u[3 * i], u[3 * i + 1], u[3 * i + 2], du[3 * i],
                                       du[3 * i + 1], du[3 * i + 2])
            t += 1
            hv[3 * i] += bx
            hv[3 * i + 1] += by
            hv[3 * i + 2] += bz
    for i in range(n):
        for j in range(i + 1, n):
            bx, by, bz = _hessian_term(
                cs, t, u[3 * i] - u[3 * j], u[3 * i + 1] - u[3 * j + 1],
                u[3 * i + 2] - u[3 * j + 2], du[3 * i] - du[3 * j],
                du[3 * i + 1] - du[3 * j + 1], du[3 * i + 2] - du[3 * j + 2])
            t += 1
            hv[3 * i] += bx
            hv[3 * i + 1] += by
            hv[3 * i + 2] += bz
            hv[3 * j] -= bx
            hv[3 * j + 1] -= by
            hv[3 * j + 2] -= bz
    if not jac:
        return
    jacobi_transpose(hv, par, out)
    for i in range(1, n):
        bx, by, bz = _hessian_term(cs, t, q[3 * i], q[3 * i + 1], q[3 * i + 2], e[3 * i],
                                   e[3 * i + 1], e[3 * i + 2])
        t += 1
        out[3 * i] += bx
        out[3 * i + 1] += by
        out[3 * i + 2] += bz


@njit(cache=True, error_model="numpy")
def interaction_gradient(q, par, out, work):
    """out = ∇B(q), the gradient of the interaction part (module
    docstring); ``work`` holds :func:`n_work` floats of scratch."""
    _interaction(q, par, work)
    n3 = q.shape[0]
    for a in range(n3):
        out[a] = work[2 * n3 + a]


@njit(cache=True, error_model="numpy")
def _kick(x, V, k, h, par, work):
    """e^{h L_B}: p −= h∇B(q), δp −= h D²B(q) δq, for the k rows of V;
    returns :data:`ENCOUNTER` (after the kick) if two planets are closer
    than the close-encounter distance (:func:`planetary_params`), else 0."""
    n = int(par[_N])
    n3 = 3 * n
    q = x[:n3]
    _interaction(q, par, work)
    g = work[2 * n3:3 * n3]
    for a in range(n3):
        x[n3 + a] -= h * g[a]
    for c in range(k):
        _interaction_hvp(q, V[c, :n3], par, work, g)
        for a in range(n3):
            V[c, n3 + a] -= h * g[a]
    return _encounter(work[:n3], par)


@njit(cache=True, error_model="numpy")
def _encounter(u, par):
    """:data:`ENCOUNTER` if two planets at heliocentric positions ``u``
    are within the close-encounter distance, else 0."""
    n = int(par[_N])
    o = _MASS + 4 * n + 2
    f2 = par[o]
    if f2 == 0.0:
        return 0
    t = o + 1
    for i in range(n):
        ui = u[3 * i] ** 2 + u[3 * i + 1] ** 2 + u[3 * i + 2] ** 2
        for j in range(i + 1, n):
            uj = u[3 * j] ** 2 + u[3 * j + 1] ** 2 + u[3 * j + 2] ** 2
            d2 = ((u[3 * i] - u[3 * j]) ** 2 + (u[3 * i + 1] - u[3 * j + 1]) ** 2
                  + (u[3 * i + 2] - u[3 * j + 2]) ** 2)
            if d2 < f2 * par[t] * (ui + uj):
                return ENCOUNTER
            t += 1
    return 0


@njit(cache=True, error_model="numpy")
def _jump(x, V, k, h, par):
    """e^{h L_J}, H_J = |ΣP|²/2m₀: every Q_i += h ΣP/m₀ (and δQ likewise)."""
    n = int(par[_N])
    n3 = 3 * n
    c = h / par[_MASS]
    for f in range(k + 1):
        row = x if f == 0 else V[f - 1]
        sx = sy = sz = 0.0
        for i in range(n):
            sx += row[n3 + 3 * i]
            sy += row[n3 + 3 * i + 1]
            sz += row[n3 + 3 * i + 2]
        for i in range(n):
            row[3 * i] += c * sx
            row[3 * i + 1] += c * sy
            row[3 * i + 2] += c * sz


@njit(cache=True, error_model="numpy")
def _kepler(x, V, k, h, par):
    """The Kepler flow of every planet for time h; the first failing
    planet's status (the planets before it have moved)."""
    n = int(par[_N])
    n3 = 3 * n
    omu, okm = _mu(n), _kmass(n)
    for i in range(n):
        status = kepler_step(x, V, k, 3 * i, n3 + 3 * i, par[omu + i], par[okm + i], h)
        if status != KEPLER_OK:
            return status
    return KEPLER_OK


@njit(cache=True, error_model="numpy")
def apply_flow(part, h, x, V, k, par, work):
    """The exact flow of ``part`` (:data:`KEPLER`, :data:`INTERACTION` or
    :data:`JUMP`) for time ``h``, on the orbit ``x`` (2N,) and the first
    ``k`` rows of ``V`` (the deviation vectors, (≥k, 2N)), in place;
    ``work`` holds :func:`n_work` floats.

    Returns
    -------
    int
        0, the Kepler solver's failure
        (:data:`varint.kernels.kepler.KEPLER_UNCONVERGED`,
        :data:`~varint.kernels.kepler.KEPLER_DEGENERATE`), or
        :data:`ENCOUNTER` from a kick.
    """
    if part == KEPLER:
        return _kepler(x, V, k, h, par)
    if part == INTERACTION:
        return _kick(x, V, k, h, par, work)
    _jump(x, V, k, h, par)
    return KEPLER_OK


@njit(cache=True, error_model="numpy")
def vector_field(x, par, out):
    """out = ẋ = J∇H(x), the Hamiltonian vector field (2N,)."""
    n = int(par[_N])
    n3 = 3 * n
    okm = _kmass(n)
    g = np.empty(n3)
    potential_gradient(x[:n3], par, g)
    for i in range(n):
        inv = 1.0 / par[okm + i]
        for a in range(3):
            out[3 * i + a] = x[n3 + 3 * i + a] * inv
    if _coords(par) == DEMOCRATIC:
        inv0 = 1.0 / par[_MASS]
        for a in range(3):
            s = 0.0
            for i in range(n):
                s += x[n3 + 3 * i + a]
            for i in range(n):
                out[3 * i + a] += s * inv0
    for a in range(n3):
        out[n3 + a] = -g[a]


@njit(cache=True, error_model="numpy")
def apply_word(parts, h, x, V, k, par, work):
    """The flows ``parts[s]`` for times ``h[s]`` in order (a scheme's step
    or a corrector, :mod:`varint.correctors`); the first failure's status,
    with the flows before it applied."""
    for s in range(parts.shape[0]):
        status = apply_flow(parts[s], h[s], x, V, k, par, work)
        if status != KEPLER_OK:
            return status
    return KEPLER_OK

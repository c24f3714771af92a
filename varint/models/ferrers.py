"""The potential of a homogeneous-ellipsoid (Ferrers n = 2) bar, compiled:
Carlson's elliptic integrals, the index symbols W_ijk and the potential's
gradient and Hessian.

A Ferrers bar of index 2 has the density ρ = ρ_c (1 − m²)², m² = x²/a² +
y²/b² + z²/c² < 1, a > b > c, total mass M = 32π abc ρ_c / 105. Its
potential (Pfenniger 1984, eq. 3 and Appendix; Chandrasekhar 1969, Ch. 3)
is, with X_i = x_i² and α_i = a_i² + λ,

    Φ = −K [W − 3 Σ_i X_i W_i + 3 Σ_ij X_i X_j W_ij − Σ_ijk X_i X_j X_k W_ijk],
    W_{ij…}(λ) = ∫_λ^∞ du / (Δ(u) α_i(u) α_j(u) …),   Δ = (α_1 α_2 α_3)^{1/2},

K = π G abc ρ_c / 3 = 35 G M / 32, λ = 0 inside the bar and the positive
root of Σ X_i/α_i = 1 outside. Because the bracket (1 − m²)³ of the
integrand vanishes to third order at u = λ, the first three derivatives of
Φ are those of the polynomial in X with the W held fixed.

The W come from Carlson's symmetric integrals (W = 2R_F(α_1, α_2, α_3),
W_i = (2/3) R_D(α_j, α_k, α_i), with Σ_i W_i = 2/Δ; Carlson 1995, eq. 2.43),
the others from the partial-fraction
identities W_ij = (W_i − W_j)/(α_j − α_i), W_ijk = (W_ij − W_ik)/(α_k − α_j)
and the diagonal ones (2m + 1) W_{i^{m+1}} + Σ_{j≠i} W_{i^m j} =
2/(Δ α_i^m) (integration by parts of d/du [1/(Δ α_i^m)]). Far from the bar
the partial fractions lose digits, (λ/(b² − c²))² ε in W_ijk: Φ and its
derivatives are good to ~1e-12 at 25 scale lengths (tested against
quadrature of the defining integrals), to round-off inside the bar.

At fixed W the bracket and its derivatives in X are polynomials of degree
3, 2 and 1: their coefficients, summed once per distinct monomial of the
symmetric W and scaled by Φ's factors, are tabled once per bar for the
inside (λ = 0) and per point outside (:func:`_coefficients`), and
evaluated nested by the first index (Horner's rule in several variables).

References
----------
N. M. Ferrers, Q. J. Pure Appl. Math. 14, 1 (1877); D. Pfenniger,
Astron. Astrophys. 134, 373 (1984); S. Chandrasekhar, *Ellipsoidal Figures
of Equilibrium*, Yale (1969), Ch. 3; B. C. Carlson, Numer. Algorithms 10,
13 (1995) — R_F and R_D by duplication; W. H. Press et al., *Numerical
Recipes*, 3rd ed. (2007), Sect. 6.12.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["carlson_rf", "carlson_rd", "ferrers_lambda", "ferrers_w", "ferrers_potential",
           "ferrers_grad_hess", "ferrers_kick", "ferrers_force", "ferrers_add_potential",
           "inside_table", "FERRERS_K", "TABLE_SIZE"]

#: K = π G abc ρ_c / 3 in units of G M (n = 2).
FERRERS_K = 35.0 / 32.0


@njit(cache=True, error_model="numpy")
def carlson_rf(x, y, z):
    """Carlson's R_F(x, y, z) = ½ ∫_0^∞ dt / √((t+x)(t+y)(t+z)), x, y, z ≥ 0
    (at most one zero), by duplication until the arguments agree to 0.25 %
    (relative error of the fifth-order series ~1e-16; Press et al. 2007,
    Sect. 6.12)."""
    for _ in range(100):
        sx, sy, sz = math.sqrt(x), math.sqrt(y), math.sqrt(z)
        lam = sx * (sy + sz) + sy * sz
        x = 0.25 * (x + lam)
        y = 0.25 * (y + lam)
        z = 0.25 * (z + lam)
        ave = (x + y + z) / 3.0
        dx, dy, dz = (ave - x) / ave, (ave - y) / ave, (ave - z) / ave
        if max(abs(dx), abs(dy), abs(dz)) < 0.0025:
            break
    e2 = dx * dy - dz * dz
    e3 = dx * dy * dz
    return (1.0 + (e2 / 24.0 - 0.1 - 3.0 * e3 / 44.0) * e2 + e3 / 14.0) / math.sqrt(ave)


@njit(cache=True, error_model="numpy")
def carlson_rd(x, y, z):
    """Carlson's R_D(x, y, z) = (3/2) ∫_0^∞ dt / (√((t+x)(t+y)) (t+z)^{3/2}),
    by duplication until the arguments agree to 0.15 % (relative error
    ~1e-16)."""
    total = 0.0
    fac = 1.0
    for _ in range(100):
        sx, sy, sz = math.sqrt(x), math.sqrt(y), math.sqrt(z)
        lam = sx * (sy + sz) + sy * sz
        total += fac / (sz * (z + lam))
        fac *= 0.25
        x = 0.25 * (x + lam)
        y = 0.25 * (y + lam)
        z = 0.25 * (z + lam)
        ave = 0.2 * (x + y + 3.0 * z)
        dx, dy, dz = (ave - x) / ave, (ave - y) / ave, (ave - z) / ave
        if max(abs(dx), abs(dy), abs(dz)) < 0.0015:
            break
    ea = dx * dy
    eb = dz * dz
    ec = ea - eb
    ed = ea - 6.0 * eb
    ee = ed + ec + ec
    c1, c2, c3, c4 = 3.0 / 14.0, 1.0 / 6.0, 9.0 / 22.0, 3.0 / 26.0
    c5, c6 = 0.25 * c3, 1.5 * c4
    return 3.0 * total + fac * (1.0 + ed * (-c1 + c5 * ed - c6 * dz * ee)
                                + dz * (c2 * ee + dz * (-c3 * ec + dz * c4 * ea))) \
        / (ave * math.sqrt(ave))


@njit(cache=True, error_model="numpy")
def _lambda(X0, X1, X2, axes2):
    """:func:`ferrers_lambda` of X = (X0, X1, X2) as scalars (no array to
    allocate per call)."""
    if X0 / axes2[0] + X1 / axes2[1] + X2 / axes2[2] <= 1.0:
        return 0.0
    lam = max(0.0, X0 + X1 + X2 - axes2[0])
    for _ in range(200):
        # The terms in the order of the loop over i this unrolls (bits kept).
        inv = 1.0 / (axes2[0] + lam)
        f = -1.0 + X0 * inv
        df = 0.0 - X0 * inv * inv
        inv = 1.0 / (axes2[1] + lam)
        f += X1 * inv
        df -= X1 * inv * inv
        inv = 1.0 / (axes2[2] + lam)
        f += X2 * inv
        df -= X2 * inv * inv
        step = f / df
        lam -= step
        if abs(step) <= 4e-16 * lam:
            break
    return lam


@njit(cache=True, error_model="numpy")
def ferrers_lambda(X, axes2):
    """λ: 0 inside the ellipsoid (Σ X_i/a_i² ≤ 1), else the root of
    Σ X_i/(a_i² + λ) = 1, by Newton's method from below (f is convex and
    decreasing, so its iterates rise monotonically to the root)."""
    return _lambda(X[0], X[1], X[2], axes2)


@njit(cache=True, error_model="numpy")
def ferrers_w(lam, axes2, W1, W2, W3):
    """W (returned) and W_i, W_ij, W_ijk (written to W1 (3,), W2 (3, 3),
    W3 (3, 3, 3), symmetric) at λ for semi-axes² ``axes2`` (module
    docstring)."""
    al = (axes2[0] + lam, axes2[1] + lam, axes2[2] + lam)
    delta = math.sqrt(al[0] * al[1] * al[2])
    W0 = 2.0 * carlson_rf(al[0], al[1], al[2])
    W1[0] = 2.0 / 3.0 * carlson_rd(al[1], al[2], al[0])
    W1[1] = 2.0 / 3.0 * carlson_rd(al[2], al[0], al[1])
    # Σ_i R_D(α_j, α_k, α_i) = 3/Δ: the third, the largest (its α_3 is the
    # smallest), from the other two without cancellation.
    W1[2] = 2.0 / delta - W1[0] - W1[1]
    for i in range(3):
        for j in range(3):
            if i != j:
                W2[i, j] = (W1[i] - W1[j]) / (axes2[j] - axes2[i])
    for i in range(3):
        acc = 0.0
        for j in range(3):
            if j != i:
                acc += W2[i, j]
        W2[i, i] = (2.0 / (delta * al[i]) - acc) / 3.0
    for i in range(3):
        for j in range(3):
            if j != i:
                # W_iij, in every order of its indices.
                v = (W2[i, i] - W2[i, j]) / (axes2[j] - axes2[i])
                W3[i, i, j] = W3[i, j, i] = W3[j, i, i] = v
    v = (W2[0, 1] - W2[0, 2]) / (axes2[2] - axes2[1])
    W3[0, 1, 2] = W3[0, 2, 1] = W3[1, 0, 2] = W3[1, 2, 0] = W3[2, 0, 1] = W3[2, 1, 0] = v
    for i in range(3):
        acc = 0.0
        for j in range(3):
            if j != i:
                acc += W3[i, i, j]
        W3[i, i, i] = (2.0 / (delta * al[i] * al[i]) - acc) / 5.0
    return W0


#: The length of a table of coefficients (:func:`_coefficients`).
TABLE_SIZE = 74


def inside_table(axes2, gm):
    """The coefficients of :func:`_coefficients` at λ = 0 for a bar of mass
    G·M = ``gm``, (74,): constants everywhere inside the bar
    (:func:`ferrers_grad_hess`), made once per bar."""
    W1, W2, W3 = np.empty(3), np.empty((3, 3)), np.empty((3, 3, 3))
    W0 = ferrers_w(0.0, np.asarray(axes2, dtype=np.float64), W1, W2, W3)
    C = np.empty(TABLE_SIZE)
    _coefficients(W0, W1, W2, W3, FERRERS_K * float(gm), C)
    return C


@njit(cache=True, error_model="numpy")
def _coefficients(W0, W1, W2, W3, K, C):
    """The bracket F(X) = W − 3ΣX_iW_i + 3ΣX_iX_jW_ij − ΣX_iX_jX_kW_ijk
    and its derivatives in X at fixed W as polynomials in X = (x², y², z²),
    with the factors of Φ = −K F(x²) folded in (∂_iΦ = x_i P_i,
    ∂_ijΦ = x_i x_j Q_ij + δ_ij P_i), written to ``C`` (74,):

    * C[0:20]  Φ = −K F, cubic: the constant, X_i, X_jX_k (j ≤ k) and
      X_iX_jX_k (i ≤ j ≤ k), each in lexicographic order;
    * C[20:50] P_i = −2K F_i, quadratic, 10 per i (the constant, X_j,
      X_jX_k with j ≤ k), F_i = −3W_i + 6Σ_j X_jW_ij − 3Σ_jk X_jX_kW_ijk;
    * C[50:74] Q_ij = −4K F_ij, linear, 4 per pair i ≤ j (00, 01, 02, 11,
      12, 22), F_ij = 6W_ij − 6Σ_k X_kW_ijk.

    A symmetric W's terms are summed once per distinct monomial, with its
    count of index orders (1, 2; 1, 3, 6): 20 + 30 + 24 multiply-adds per
    evaluation where the index loops take 3 × 27."""
    C[0] = -K * W0
    for i in range(3):
        C[1 + i] = 3.0 * K * W1[i]
    o = 4
    for j in range(3):
        for k in range(j, 3):
            C[o] = -3.0 * K * W2[j, k] * (1.0 if j == k else 2.0)
            o += 1
    for i in range(3):
        for j in range(i, 3):
            for k in range(j, 3):
                orders = 1.0 if i == k else (6.0 if i != j and j != k else 3.0)
                C[o] = K * W3[i, j, k] * orders
                o += 1
    for i in range(3):
        o = 20 + 10 * i
        C[o] = 6.0 * K * W1[i]
        for j in range(3):
            C[o + 1 + j] = -12.0 * K * W2[i, j]
        o += 4
        for j in range(3):
            for k in range(j, 3):
                C[o] = 6.0 * K * W3[i, j, k] * (1.0 if j == k else 2.0)
                o += 1
    o = 50
    for i in range(3):
        for j in range(i, 3):
            C[o] = -24.0 * K * W2[i, j]
            for k in range(3):
                C[o + 1 + k] = 24.0 * K * W3[i, j, k]
            o += 4


@njit(cache=True, error_model="numpy")
def _quadratic(C, o, X0, X1, X2):
    """The quadratic C[o] + ΣC[o+1+j]X_j + Σ_{j≤k}C[o+4+·]X_jX_k, nested
    by the first index (9 multiply-adds)."""
    return (C[o] + X0 * (C[o + 1] + X0 * C[o + 4] + X1 * C[o + 5] + X2 * C[o + 6])
            + X1 * (C[o + 2] + X1 * C[o + 7] + X2 * C[o + 8]) + X2 * (C[o + 3] + X2 * C[o + 9]))


@njit(cache=True, error_model="numpy")
def _apply(q, X0, X1, X2, C, g, D, hessian, potential):
    """Φ (returned if ``potential``, else 0) from the table ``C``
    (:func:`_coefficients`), its gradient x_i P_i added to ``g`` and, if
    ``hessian``, its Hessian x_i x_j Q_ij + δ_ij P_i to ``D``. (Loops over
    i and j rather than each entry written out: the same operations, and
    a third of the code for numba to type and lower per compile.)"""
    P = (_quadratic(C, 20, X0, X1, X2), _quadratic(C, 30, X0, X1, X2),
         _quadratic(C, 40, X0, X1, X2))
    for i in range(3):
        g[i] += q[i] * P[i]
    if hessian:
        o = 50
        for i in range(3):
            for j in range(i, 3):
                v = q[i] * q[j] * (C[o] + X0 * C[o + 1] + X1 * C[o + 2] + X2 * C[o + 3])
                if i == j:
                    D[i, i] += v + P[i]
                else:
                    D[i, j] += v
                    D[j, i] += v
                o += 4
    if not potential:
        return 0.0
    return (C[0] + X0 * (C[1] + X0 * (C[4] + X0 * C[10] + X1 * C[11] + X2 * C[12])
                         + X1 * (C[5] + X1 * C[13] + X2 * C[14]) + X2 * (C[6] + X2 * C[15]))
            + X1 * (C[2] + X1 * (C[7] + X1 * C[16] + X2 * C[17]) + X2 * (C[8] + X2 * C[18]))
            + X2 * (C[3] + X2 * (C[9] + X2 * C[19])))


@njit(cache=True, error_model="numpy", inline="always")
def _derivatives(q, axes2, gm, g, D, hessian, inside, potential):
    """:func:`ferrers_grad_hess`, Φ computed (and returned) only if
    ``potential``. Inlined into its three callers by numba (a call passing
    four arrays costs about as much as the polynomials inside the bar); its
    callees stay calls (inlining them too nearly doubled the kernels'
    compile time)."""
    X0, X1, X2 = q[0] * q[0], q[1] * q[1], q[2] * q[2]
    lam = _lambda(X0, X1, X2, axes2)
    if lam == 0.0:
        return _apply(q, X0, X1, X2, inside, g, D, hessian, potential)
    # Outside the W depend on λ: their table, then its polynomials, here.
    W = np.empty(40 + TABLE_SIZE)
    W0 = ferrers_w(lam, axes2, W[1:4], W[4:13].reshape((3, 3)), W[13:40].reshape((3, 3, 3)))
    C = W[40:]
    _coefficients(W0, W[1:4], W[4:13].reshape((3, 3)), W[13:40].reshape((3, 3, 3)),
                  FERRERS_K * gm, C)
    return _apply(q, X0, X1, X2, C, g, D, hessian, potential)


@njit(cache=True, error_model="numpy")
def ferrers_grad_hess(q, axes2, gm, g, D, hessian, inside):
    """Φ of a Ferrers (n = 2) bar of mass G·M = ``gm`` (returned) at the
    position ``q`` (3,), its gradient added to ``g`` (3,) and, if
    ``hessian``, its Hessian added to ``D`` (at least 3 × 3, top-left).
    ``inside`` is :func:`inside_table` of these axes and ``gm``: inside the
    bar λ = 0 and Φ, its gradient and Hessian are polynomials in x² with
    these constant coefficients, so no elliptic integral is evaluated
    there, and nothing is allocated."""
    return _derivatives(q, axes2, gm, g, D, hessian, inside, True)


@njit(cache=True, error_model="numpy")
def ferrers_kick(q, axes2, gm, g, D, hessian, inside):
    """:func:`ferrers_grad_hess` without Φ (the same g and D, bit for bit):
    what a kick of a tangent map needs, a third fewer operations."""
    _derivatives(q, axes2, gm, g, D, hessian, inside, False)


@njit(cache=True, error_model="numpy")
def ferrers_force(q, g, D, hessian, axes2, gm, inside):
    """:func:`ferrers_kick` in the argument order of a generated stepper's
    extra force (:class:`varint.codegen.expressions.ExtraForce`): the
    positions, the gradient and Hessian to add to, then the constants."""
    _derivatives(q, axes2, gm, g, D, hessian, inside, False)


@njit(cache=True, error_model="numpy")
def ferrers_add_potential(X, axes2, gm, inside, out):
    """Φ at the positions X[m, :3] of every row of ``X`` (M, ≥ 3) added to
    ``out[m]``: a rotating bar's energy is its closed part's plus this
    (:meth:`varint.models.bar.RotatingBar._energy_term`)."""
    g = np.empty(3)
    D = np.empty((3, 3))
    for m in range(X.shape[0]):
        out[m] += ferrers_grad_hess(X[m, :3], axes2, gm, g, D, False, inside)


@njit(cache=True, error_model="numpy")
def ferrers_potential(Q, axes2, gm, inside, out):
    """Φ at every position of ``Q`` (M, 3), written to ``out`` (M,)."""
    g = np.empty(3)
    D = np.empty((3, 3))
    for m in range(Q.shape[0]):
        out[m] = ferrers_grad_hess(Q[m], axes2, gm, g, D, False, inside)

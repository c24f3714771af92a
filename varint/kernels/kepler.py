"""The Kepler drift: the exact flow of the two-body problem for any
eccentricity, and its exact tangent map, in universal variables.

A body at relative position r₀ with velocity v₀ around a centre of
gravitational parameter μ moves for a time h along the conic of those
initial conditions. With the universal anomaly X and the Stiefel (Gauss)
functions G_k(β, X) = X^k c_k(βX²), built on the Stumpff functions
c_k(z) = Σ_j (−z)^j/(2j + k)!, the solution is (Danby 1992, ch. 6.9;
Stiefel & Scheifele 1971)::

    β = 2μ/r₀ − v₀²,   η₀ = r₀·v₀,   ζ₀ = μ − βr₀
    Kepler's equation:  r₀X + η₀G₂ + ζ₀G₃ = h,   r = r₀ + η₀G₁ + ζ₀G₂
    r = (1 + f)r₀ + g v₀,   v = ḟ r₀ + (1 + ġ)v₀
    f = −μG₂/r₀,  g = h − μG₃,  ḟ = −μG₁/(r₀ r),  ġ = −μG₂/r

(f and ġ here are the usual f − 1 and ġ − 1, which avoids a cancellation
for short steps). β > 0 is an ellipse, β = 0 a parabola, β < 0 a
hyperbola: the same formulas hold for all, including e → 1 where the
classical anomalies break down.

Kepler's equation is solved to round-off. A resolved step takes one
evaluation of the series: a fourth-order guess of X(h), one third-order
correction (Chebyshev's), and the Stiefel functions moved to the corrected
X by their Taylor series (:func:`solve_fast`); the residual is then
checked. Otherwise F(X) = r₀X + η₀G₂ + ζ₀G₃ − h, which increases
(F′ = r > 0), is solved inside a bracket that always holds the root — from
r ≥ q (the pericentre distance) and r ≤ min(Q, r₀ + v_q|h|) (apocentre,
pericentre speed), X lies between h/min(Q, r₀ + v_q|h|) and h/q — with
bisection when an iterate leaves it or converges slowly; it stops when the
residual is at round-off or the iterates repeat (then the residual is
checked). A step whose equation cannot be solved (a collision orbit with
r₀ = 0, a non-finite state, no convergence) is reported, never returned as
a number. A radial orbit through the centre is not one: universal
variables regularise it, and the drift continues along the collision
ellipse.

The tangent map is the derivative of that solution with respect to
(r₀, v₀) (Mikkola & Innanen 1999): differentiating Kepler's equation at
fixed h gives δX = −(X δr₀ + G₂ δη₀ + G₃ δζ₀ + (η₀ ∂G₂/∂β + ζ₀ ∂G₃/∂β) δβ)/r,
with ∂G_k/∂X = G_{k−1}, ∂G₀/∂X = −βG₁ and ∂G_k/∂β = (kG_{k+2} − XG_{k+1})/2;
then δf, δg, δḟ, δġ follow by the chain rule. It is exact for the computed
X: the derivative of the numerical map, as the TM method needs.

The state holds canonical momenta p = m v (``mass`` m is the body's mass
in its Kepler Hamiltonian p²/2m − μm/r), so velocities and their
deviations are p/m and δp/m.

References
----------
J. M. A. Danby, *Fundamentals of Celestial Mechanics*, 2nd ed. (1992),
§6.9; E. Stiefel & G. Scheifele, *Linear and Regular Celestial Mechanics*
(1971); S. Mikkola & K. Innanen, Celest. Mech. Dyn. Astron. 74, 59 (1999)
(the tangent map of the Kepler step); H. Rein & D. Tamayo, Mon. Not. R.
Astron. Soc. 452, 376 (2015) (WHFast).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["stumpff", "gauss", "solve_universal", "solve_fast", "prepare", "fg_tangent",
           "beta_derivatives", "finish",
           "kepler_step", "KEPLER_OK", "KEPLER_UNCONVERGED", "KEPLER_DEGENERATE",
           "MAX_ITERATIONS", "RESIDUAL"]

#: :func:`kepler_step` succeeded.
KEPLER_OK = 0
#: Kepler's equation was not solved to round-off within
#: :data:`MAX_ITERATIONS` iterations (or its residual failed the check).
KEPLER_UNCONVERGED = 1
#: The step has no solution to find: r₀ = 0 (a collision) or a non-finite
#: state.
KEPLER_DEGENERATE = 2

#: Iterations of the safeguarded solver before giving up (one
#: suffices for a resolved step; bisection from the widest bracket needs
#: about 1100 halvings of double range, but each step that stays in the
#: bracket also shrinks it).
MAX_ITERATIONS = 200
#: A residual of Kepler's equation within this fraction of the size of its
#: terms is round-off: X is solved.
RESIDUAL = 4.0 * 2.0 ** -52

# 1/k! for k = 0 … 29: the Stumpff series.
_INV_FACT = np.array([1.0 / math.factorial(k) for k in range(30)])
# Constants as products: x / 6.0 is a division, x * (1/6) a multiplication.
_SIXTH, _TWENTY_FOURTH, _THIRD = 1.0 / 6.0, 1.0 / 24.0, 1.0 / 3.0
# Below this |z| the short series (7 terms) is exact to round-off; up to
# _SERIES the long one (12 terms); beyond, the closed forms.
_SHORT = 0.25
_SERIES = 4.0


@njit(inline="always")
def _series(z, k, terms):
    """c_k(z) = Σ_{j<terms} (−z)^j/(2j + k)! by Horner's rule."""
    acc = _INV_FACT[2 * (terms - 1) + k]
    for j in range(terms - 2, -1, -1):
        acc = _INV_FACT[2 * j + k] - z * acc
    return acc


@njit(inline="always")
def stumpff(z):
    """The Stumpff functions c₀(z) … c₅(z), c_k(z) = Σ_j (−z)^j/(2j + k)!.

    |z| ≤ 4: c₄ and c₅ from their series (7 terms below |z| = 1/4, 12 up
    to 4: the first omitted term is below 10⁻¹⁹ of the sum), then
    c_k = 1/k! − z c_{k+2} down to c₀, which cancels by at most a factor 4.
    |z| > 4: the closed forms with s = √|z| (cos, sin for z > 0; cosh, sinh
    for z < 0), c₄ = (½ − c₂)/z and c₅ = (⅙ − c₃)/z.

    Returns
    -------
    tuple of 6 floats
    """
    az = abs(z)
    if az <= _SERIES:
        terms = 7 if az <= _SHORT else 12
        c4 = _series(z, 4, terms)
        c5 = _series(z, 5, terms)
        c3 = 1.0 / 6.0 - z * c5
        c2 = 0.5 - z * c4
        c1 = 1.0 - z * c3
        c0 = 1.0 - z * c2
        return c0, c1, c2, c3, c4, c5
    s = math.sqrt(az)
    if z > 0.0:
        c0 = math.cos(s)
        sn = math.sin(s)
        c1 = sn / s
        half = math.sin(0.5 * s)
        c2 = 2.0 * half * half / az
        c3 = (s - sn) / (s * az)
    else:
        c0 = math.cosh(s)
        sn = math.sinh(s)
        c1 = sn / s
        half = math.sinh(0.5 * s)
        c2 = 2.0 * half * half / az
        c3 = (sn - s) / (s * az)
    c4 = (0.5 - c2) / z
    c5 = (1.0 / 6.0 - c3) / z
    return c0, c1, c2, c3, c4, c5


@njit(inline="always")
def gauss(beta, X):
    """The Stiefel functions G_k(β, X) = X^k c_k(βX²), k = 0 … 5.

    Returns
    -------
    tuple of 6 floats
    """
    X2 = X * X
    c0, c1, c2, c3, c4, c5 = stumpff(beta * X2)
    X3 = X2 * X
    return c0, c1 * X, c2 * X2, c3 * X3, c4 * X3 * X, c5 * X3 * X2


@njit(cache=True, error_model="numpy")
def _bracket(r0, beta, mu, h, h2):
    """Bounds (lo, hi) on the universal anomaly of a step h ≠ 0 (module
    docstring), widened by 10⁻¹² against their own rounding; the bound
    h/q is infinite for a radial orbit (q = 0)."""
    e2 = 1.0 - beta * h2 / (mu * mu)
    e = math.sqrt(e2) if e2 > 0.0 else 0.0
    q = h2 / (mu * (1.0 + e))
    vq = math.sqrt(max(2.0 * mu / q - beta, 0.0)) if q > 0.0 else np.inf
    far = r0 + vq * abs(h)
    if beta > 0.0:
        far = min(far, mu * (1.0 + e) / beta)
    near = h / q if q > 0.0 else math.copysign(np.inf, h)
    if beta < 0.0:
        # Beyond X√−β = 700 the Stiefel functions overflow (the distance
        # would grow by e^700): no step that is resolvable needs it.
        near = math.copysign(min(abs(near), 700.0 / math.sqrt(-beta)), h)
    slow = h / far
    widen = 1e-12
    if h > 0.0:
        return slow * (1.0 - widen), near * (1.0 + widen)
    return near * (1.0 + widen), slow * (1.0 - widen)


@njit(cache=True, error_model="numpy")
def _middle(lo, hi):
    """The bisection point of a bracket: its geometric mean while it spans
    more than a factor 16 on one side of 0 (the a-priori bounds of a
    near-parabolic orbit far from pericentre are decades apart), else its
    midpoint."""
    if lo > 0.0 and hi > 16.0 * lo:
        return math.sqrt(lo * hi)
    if hi < 0.0 and lo < 16.0 * hi:
        return -math.sqrt(lo * hi)
    return 0.5 * (lo + hi)


@njit(inline="always")
def _guess(r0, eta0, zeta0, beta, h):
    """X(h) to fourth order, from inverting h = r₀X + η₀X²/2 + ζ₀X³/6
    − βη₀X⁴/24 + O(X⁵), and h/r₀ (its first-order term)."""
    a1 = 1.0 / r0
    a12 = a1 * a1
    a2 = -0.5 * eta0 * a12 * a1
    a3 = (3.0 * eta0 * eta0 - r0 * zeta0) * (a12 * a12 * a1 * _SIXTH)
    a4 = -(eta0 * (a1 * a3 + 0.5 * a2 * a2) + 0.5 * zeta0 * a12 * a2
           - beta * eta0 * a12 * a12 * _TWENTY_FOURTH) * a1
    return h * (a1 + h * (a2 + h * (a3 + h * a4))), h * a1


@njit(inline="always")
def _residual(X, r0, eta0, zeta0, G2, G3, h):
    """F(X) = r₀X + η₀G₂ + ζ₀G₃ − h and the size of its terms."""
    F = r0 * X + eta0 * G2 + zeta0 * G3 - h
    return F, abs(r0 * X) + abs(eta0 * G2) + abs(zeta0 * G3) + abs(h)


@njit(inline="always")
def _correction(F, r0, eta0, zeta0, G0, G1, G2):
    """Chebyshev's third-order step d (1 + d F″/2F′), d = F/F′ (one
    division fewer than Halley's), or Newton's d where that factor is far
    from 1."""
    inv_r = 1.0 / (r0 + eta0 * G1 + zeta0 * G2)
    d = F * inv_r
    c = 0.5 * d * (eta0 * G0 + zeta0 * G1) * inv_r
    return d * (1.0 + c) if abs(c) < 0.5 else d


@njit(inline="always")
def _shifted(beta, G0, G1, G2, G3, G4, G5, dl):
    """The Stiefel functions at X + dl from their Taylor series about X
    (∂G_k/∂X = G_{k−1}, ∂G₀/∂X = −βG₁), to third order: for
    |dl| ≤ 1e-5 |X| the next term is below 1e-19 of each."""
    d2 = 0.5 * dl * dl
    d3 = dl * d2 * _THIRD
    bG1, bG0 = beta * G1, beta * G0
    return (G0 - bG1 * dl - bG0 * d2 + beta * bG1 * d3, G1 + G0 * dl - bG1 * d2 - bG0 * d3,
            G2 + G1 * dl + G0 * d2 - bG1 * d3, G3 + G2 * dl + G1 * d2 + G0 * d3,
            G4 + G3 * dl + G2 * d2 + G1 * d3, G5 + G4 * dl + G3 * d2 + G2 * d3)


@njit(inline="always")
def solve_fast(r0, eta0, zeta0, beta, h):
    """The common case of :func:`solve_universal`: the series guess, one
    third-order correction and the Stiefel functions moved to it by their
    Taylor series — one evaluation of the series in all. Returns
    (:data:`KEPLER_OK`, X, G₀ … G₅) when the residual is then at round-off,
    else (:data:`KEPLER_UNCONVERGED`, …) for the full solver to redo."""
    X, s = _guess(r0, eta0, zeta0, beta, h)
    if not (X * s > 0.0 and abs(X) < 2.0 * abs(s)):
        return KEPLER_UNCONVERGED, X, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    G0, G1, G2, G3, G4, G5 = gauss(beta, X)
    F, scale = _residual(X, r0, eta0, zeta0, G2, G3, h)
    if abs(F) <= RESIDUAL * scale:
        return KEPLER_OK, X, G0, G1, G2, G3, G4, G5
    dl = -_correction(F, r0, eta0, zeta0, G0, G1, G2)
    if not abs(dl) <= 1e-5 * abs(X):
        return KEPLER_UNCONVERGED, X, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    G0, G1, G2, G3, G4, G5 = _shifted(beta, G0, G1, G2, G3, G4, G5, dl)
    X = X + dl
    F, scale = _residual(X, r0, eta0, zeta0, G2, G3, h)
    status = KEPLER_OK if abs(F) <= RESIDUAL * scale else KEPLER_UNCONVERGED
    return status, X, G0, G1, G2, G3, G4, G5


@njit(cache=True, error_model="numpy")
def solve_universal(r0, eta0, zeta0, beta, mu, h, h2):
    """Kepler's equation r₀X + η₀G₂ + ζ₀G₃ = h for the universal anomaly X.

    First :func:`solve_fast`, which settles a resolved step (h a few
    percent of the orbit's time scales) with one evaluation of the series;
    otherwise the safeguarded iteration: Chebyshev's third-order method
    from the fourth-order series of X(h), inside a bracket of the root —
    the signs of the residuals seen so far, and the a-priori bounds of the
    module docstring once an iterate leaves it or a step does not halve the
    one before (then bisection, geometric across decades). It stops when
    the residual is at round-off (within :data:`RESIDUAL` of the size of
    its terms) or the iterates stop changing; a step stopped otherwise, or
    whose last residual exceeds 10⁻¹² of its terms, is unconverged.

    Parameters
    ----------
    r0, eta0, zeta0, beta : float
        |r₀|, r₀·v₀, μ − βr₀ and β = 2μ/r₀ − v₀² of the initial state.
    mu : float
        Gravitational parameter.
    h : float
        The step (may be negative; 0 gives X = 0).
    h2 : float
        |r₀ × v₀|², the squared specific angular momentum (for the
        bracket).

    Returns
    -------
    status : int
        :data:`KEPLER_OK` or :data:`KEPLER_UNCONVERGED`.
    X : float
    G0, G1, G2, G3, G4, G5 : float
        The Stiefel functions at X (:func:`gauss`).
    """
    if h == 0.0:
        return KEPLER_OK, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0
    fast = solve_fast(r0, eta0, zeta0, beta, h)
    if fast[0] == KEPLER_OK:
        return fast
    X, s = _guess(r0, eta0, zeta0, beta, h)
    lo, hi = -np.inf, np.inf
    bounded = False
    if not (X * s > 0.0 and abs(X) < 2.0 * abs(s)):
        # A long step, where the series is no guess: start in the bracket.
        lo, hi = _bracket(r0, beta, mu, h, h2)
        bounded = True
        X = _middle(lo, hi) if math.isfinite(hi - lo) else s
    before = np.nan
    last = np.inf           # the length of the previous step
    for _ in range(MAX_ITERATIONS):
        G0, G1, G2, G3, G4, G5 = gauss(beta, X)
        F, scale = _residual(X, r0, eta0, zeta0, G2, G3, h)
        if abs(F) <= RESIDUAL * scale and scale < np.inf:
            return KEPLER_OK, X, G0, G1, G2, G3, G4, G5
        if F < 0.0:
            lo = X
        elif F > 0.0:
            hi = X
        elif X > 0.0:
            # F overflowed: |X| is beyond the root (F grows with X).
            hi = X
        else:
            lo = X
        Xn = X - _correction(F, r0, eta0, zeta0, G0, G1, G2)
        # Bisect where the step leaves the bracket, or does not at least
        # halve the previous one (Newton creeping along an exponential far
        # from the root of a hyperbolic step).
        if not (lo <= Xn <= hi) or abs(Xn - X) > 0.5 * last:
            if not bounded:
                a, b = _bracket(r0, beta, mu, h, h2)
                lo, hi, bounded = max(lo, a), min(hi, b), True
            Xn = _middle(lo, hi)
            if not math.isfinite(Xn):
                break
        last = abs(Xn - X)
        if Xn in (X, before):
            ok = abs(F) <= 1e-12 * scale
            return (KEPLER_OK if ok else KEPLER_UNCONVERGED), X, G0, G1, G2, G3, G4, G5
        before = X
        X = Xn
    return KEPLER_UNCONVERGED, X, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0


@njit(inline="always")
def prepare(x, iq, ip, mu, inv_m):
    """The body's r₀, v₀ and the scalars of its Kepler problem:
    (ok, rx, ry, rz, vx, vy, vz, r₀, β, η₀, ζ₀, |r₀ × v₀|²); ok is False for
    a state with no step to solve (r₀ = 0 or not finite)."""
    rx, ry, rz = x[iq], x[iq + 1], x[iq + 2]
    vx, vy, vz = x[ip] * inv_m, x[ip + 1] * inv_m, x[ip + 2] * inv_m
    r0 = math.sqrt(rx * rx + ry * ry + rz * rz)
    v2 = vx * vx + vy * vy + vz * vz
    ok = r0 > 0.0 and r0 < np.inf and v2 < np.inf
    beta = (2.0 * mu) / r0 - v2
    eta0 = rx * vx + ry * vy + rz * vz
    zeta0 = mu - beta * r0
    # |r × v|² from the components: r²v² − η² cancels for near-radial orbits.
    hx = ry * vz - rz * vy
    hy = rz * vx - rx * vz
    hz = rx * vy - ry * vx
    return ok, rx, ry, rz, vx, vy, vz, r0, beta, eta0, zeta0, hx * hx + hy * hy + hz * hz


@njit(inline="always")
def beta_derivatives(X, eta0, zeta0, G2, G3, G4, G5):
    """(∂G₁/∂β, ∂G₂/∂β, ∂G₃/∂β, η₀ ∂G₂/∂β + ζ₀ ∂G₃/∂β) at fixed X, from
    ∂G_k/∂β = (kG_{k+2} − XG_{k+1})/2 (Mikkola & Innanen 1999; module
    docstring): the β-terms of δX, the same for every deviation vector."""
    G1b = 0.5 * (G3 - X * G2)
    G2b = 0.5 * (2.0 * G4 - X * G3)
    G3b = 0.5 * (3.0 * G5 - X * G4)
    return G1b, G2b, G3b, eta0 * G2b + zeta0 * G3b


@njit(inline="always")
def fg_tangent(dx, dy, dz, dvx, dvy, dvz, rx, ry, rz, vx, vy, vz, r0, beta, eta0, zeta0,
               X, G0, G1, G2, G3, G1b, G2b, G3b, tb, mu, inv_r0, inv_r):
    """(δf, δg, δḟ, δġ) along one deviation (δr₀, δv₀): δβ, δη₀, δζ₀,
    then δX from Kepler's equation differentiated at fixed h, then the
    chain rule (Mikkola & Innanen 1999; module docstring). ``tb`` and the
    ``G·b`` are :func:`beta_derivatives`. Scalar and inlined, so that
    :func:`finish` and the lanes of :mod:`varint.kernels.planetary_lanes`
    share it and the lanes still vectorise."""
    dr0 = (dx * rx + dy * ry + dz * rz) * inv_r0
    dbeta = -2.0 * mu * dr0 * inv_r0 * inv_r0 - 2.0 * (dvx * vx + dvy * vy + dvz * vz)
    deta0 = dx * vx + dy * vy + dz * vz + rx * dvx + ry * dvy + rz * dvz
    dzeta0 = -beta * dr0 - r0 * dbeta
    dX = -(X * dr0 + G2 * deta0 + G3 * dzeta0 + tb * dbeta) * inv_r
    dG1 = G0 * dX + G1b * dbeta
    dG2 = G1 * dX + G2b * dbeta
    dG3 = G2 * dX + G3b * dbeta
    dr = dr0 + G1 * deta0 + G2 * dzeta0 + eta0 * dG1 + zeta0 * dG2
    df = mu * (G2 * dr0 * inv_r0 - dG2) * inv_r0
    dg = -mu * dG3
    dfd = mu * (G1 * (dr0 * inv_r0 + dr * inv_r) - dG1) * inv_r0 * inv_r
    dgd = mu * (G2 * dr * inv_r - dG2) * inv_r
    return df, dg, dfd, dgd


@njit(inline="always")
def finish(x, V, k, iq, ip, mu, mass, inv_m, h, rx, ry, rz, vx, vy, vz, r0, beta, eta0, zeta0,
           X, G0, G1, G2, G3, G4, G5):
    """Move the body (and the k rows of V) along the solved step: the f
    and g functions and their derivatives (module docstring). Returns
    :data:`KEPLER_DEGENERATE` (nothing moved) if r is not positive."""
    r = r0 + eta0 * G1 + zeta0 * G2
    if not (r > 0.0 and r < np.inf):
        return KEPLER_DEGENERATE
    inv_r0 = 1.0 / r0
    inv_r = 1.0 / r
    f = -mu * G2 * inv_r0
    g = h - mu * G3
    fd = -mu * G1 * inv_r0 * inv_r
    gd = -mu * G2 * inv_r
    x[iq] = rx + (f * rx + g * vx)
    x[iq + 1] = ry + (f * ry + g * vy)
    x[iq + 2] = rz + (f * rz + g * vz)
    # p + m(ḟ r₀ + ġ v₀), never p → v → p: that round trip drifts the
    # energy by a fraction of an ulp per step, always the same way.
    px, py, pz = x[ip], x[ip + 1], x[ip + 2]
    fm = fd * mass
    x[ip] = px + (fm * rx + gd * px)
    x[ip + 1] = py + (fm * ry + gd * py)
    x[ip + 2] = pz + (fm * rz + gd * pz)
    if k == 0:
        return KEPLER_OK
    G1b, G2b, G3b, tb = beta_derivatives(X, eta0, zeta0, G2, G3, G4, G5)
    for c in range(k):
        dx, dy, dz = V[c, iq], V[c, iq + 1], V[c, iq + 2]
        dvx, dvy, dvz = V[c, ip] * inv_m, V[c, ip + 1] * inv_m, V[c, ip + 2] * inv_m
        df, dg, dfd, dgd = fg_tangent(dx, dy, dz, dvx, dvy, dvz, rx, ry, rz, vx, vy, vz, r0, beta,
                                      eta0, zeta0, X, G0, G1, G2, G3, G1b, G2b, G3b, tb, mu,
                                      inv_r0, inv_r)
        V[c, iq] = dx + (f * dx + g * dvx + df * rx + dg * vx)
        V[c, iq + 1] = dy + (f * dy + g * dvy + df * ry + dg * vy)
        V[c, iq + 2] = dz + (f * dz + g * dvz + df * rz + dg * vz)
        dfm = dfd * mass
        V[c, ip] += fm * dx + gd * V[c, ip] + dfm * rx + dgd * px
        V[c, ip + 1] += fm * dy + gd * V[c, ip + 1] + dfm * ry + dgd * py
        V[c, ip + 2] += fm * dz + gd * V[c, ip + 2] + dfm * rz + dgd * pz
    return KEPLER_OK


@njit(cache=True, error_model="numpy")
def kepler_step(x, V, k, iq, ip, mu, mass, h):
    """The Kepler flow of one body for time ``h`` and its tangent map, in
    place (module docstring).

    Parameters
    ----------
    x : ndarray, shape (2N,)
        The state; the body's position is ``x[iq:iq+3]``, its momentum
        (mass × velocity) ``x[ip:ip+3]``.
    V : ndarray, shape (≥k, 2N)
        Deviation vectors as rows; the first ``k`` are moved.
    k : int
    iq, ip : int
        Offsets of the body's position and momentum.
    mu : float
        Gravitational parameter of its Kepler problem.
    mass : float
        Its mass in the Kepler Hamiltonian (p = mass · v).
    h : float
        The step; negative steps run the flow backwards.

    Returns
    -------
    int
        :data:`KEPLER_OK`, or :data:`KEPLER_UNCONVERGED` /
        :data:`KEPLER_DEGENERATE` with ``x`` and ``V`` unchanged.
    """
    inv_m = 1.0 / mass
    ok, rx, ry, rz, vx, vy, vz, r0, beta, eta0, zeta0, h2 = prepare(x, iq, ip, mu, inv_m)
    if not ok:
        return KEPLER_DEGENERATE
    status, X, G0, G1, G2, G3, G4, G5 = solve_universal(r0, eta0, zeta0, beta, mu, h, h2)
    if status != KEPLER_OK:
        return status
    return finish(x, V, k, iq, ip, mu, mass, inv_m, h, rx, ry, rz, vx, vy, vz, r0, beta, eta0,
                  zeta0, X, G0, G1, G2, G3, G4, G5)

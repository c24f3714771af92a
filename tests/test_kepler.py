"""The Kepler drift (varint.kernels.kepler): Stumpff functions against
their series in 40 digits, the drift against the exact conic (Kepler's
equation solved in mpmath), its tangent map against finite differences of
the same map (target: 1e-8 relative for e in [0, 0.99]) and against
heyoka's variational equations over one orbit, symplecticity,
reversibility, and the failures it reports."""

import math

import mpmath as mp
import numpy as np
import pytest

from varint.kernels.kepler import (KEPLER_DEGENERATE, KEPLER_OK, kepler_step, solve_universal,
                                   stumpff)

J6 = np.block([[np.zeros((3, 3)), np.eye(3)], [-np.eye(3), np.zeros((3, 3))]])


def _stumpff_reference(z, k):
    with mp.workdps(40):
        z = mp.mpf(z)
        return sum((-z) ** j / mp.factorial(2 * j + k) for j in range(120))


@pytest.mark.parametrize("z", [0.0, 1e-9, -1e-9, 0.05, 0.25, -0.25, 0.3, 1.0, -1.0, 3.9, 4.0,
                               -4.0])
def test_stumpff_series_to_round_off(z):
    c = stumpff(z)
    for k in range(6):
        ref = _stumpff_reference(z, k)
        assert abs(float((mp.mpf(c[k]) - ref) / ref)) < 2e-16 * 4, (z, k)


@pytest.mark.parametrize("z", [4.5, 7.0, 30.0, -4.5, -10.0, -100.0])
def test_stumpff_closed_forms(z):
    """Beyond |z| = 4 the closed forms (cos/sin, cosh/sinh): c₀ … c₃ to a
    few ulps; c₄, c₅ = (1/k! − c_{k−2})/z lose at most a digit. (Where
    sin √z ≈ 0, e.g. z ≈ π², c₁ is ill-conditioned in z itself: the
    rounding of √z alone moves it by ~1e-14 relative; those z are left
    out.)"""
    c = stumpff(z)
    for k in range(6):
        ref = _stumpff_reference(z, k)
        tol = 2e-15 if k < 4 else 2e-14
        assert abs(float((mp.mpf(c[k]) - ref) / ref)) < tol, (z, k)


def _conic(a, e, M, mu=1.0, inc=0.4, Om=0.7, om=1.1):
    """Position and velocity (40 digits) on the conic (a, e) at mean
    anomaly M: Kepler's equation solved in mpmath."""
    with mp.workdps(40):
        a, e, M, mu = (mp.mpf(v) for v in (a, e, M, mu))
        if e < 1:
            E = mp.findroot(lambda E: E - e * mp.sin(E) - M, M if e < 0.8 else mp.pi)
            n = mp.sqrt(mu / a ** 3)
            x, y = a * (mp.cos(E) - e), a * mp.sqrt(1 - e * e) * mp.sin(E)
            Ed = n / (1 - e * mp.cos(E))
            vx, vy = -a * mp.sin(E) * Ed, a * mp.sqrt(1 - e * e) * mp.cos(E) * Ed
        else:
            start = mp.asinh(M / e) if e > 1.01 else mp.sign(M) * mp.cbrt(6 * abs(M))
            H = mp.findroot(lambda H: e * mp.sinh(H) - H - M, start)
            n = mp.sqrt(mu / (-a) ** 3)
            x, y = -a * (e - mp.cosh(H)), -a * mp.sqrt(e * e - 1) * mp.sinh(H)
            Hd = n / (e * mp.cosh(H) - 1)
            vx, vy = a * mp.sinh(H) * Hd, -a * mp.sqrt(e * e - 1) * mp.cosh(H) * Hd
        R = mp.matrix([[mp.cos(Om), -mp.sin(Om), 0], [mp.sin(Om), mp.cos(Om), 0], [0, 0, 1]]) \
            * mp.matrix([[1, 0, 0], [0, mp.cos(inc), -mp.sin(inc)], [0, mp.sin(inc), mp.cos(inc)]]) \
            * mp.matrix([[mp.cos(om), -mp.sin(om), 0], [mp.sin(om), mp.cos(om), 0], [0, 0, 1]])
        r = R * mp.matrix([x, y, 0])
        v = R * mp.matrix([vx, vy, 0])
        return [r[i] for i in range(3)], [v[i] for i in range(3)], n


CONICS = [(1.0, 0.0), (1.0, 0.3), (2.0, 0.9), (1.0, 0.99), (1.0, 0.999999), (-1.0, 1.5),
          (-0.5, 3.0), (-1.0, 1.000001)]


@pytest.mark.parametrize("a,e", CONICS)
@pytest.mark.parametrize("M0,h", [(0.3, 0.01), (2.0, 0.5), (-0.5, 1.3), (3.1, 7.0),
                                  (0.1, -2.0)])
def test_drift_is_the_exact_conic(a, e, M0, h):
    """Drift of (r₀, v₀) for h against the state at mean anomaly M₀ + nh,
    for ellipses to e = 1 − 10⁻⁶, hyperbolae, steps longer than a period
    and negative ones: the same to round-off (with m ≠ 1: p = m v)."""
    mass, mu = 0.37, 1.3
    r0, v0, n = _conic(a, e, M0, mu)
    r1, v1, _ = _conic(a, e, mp.mpf(M0) + n * mp.mpf(h), mu)
    x = np.array([float(c) for c in r0] + [float(mass * c) for c in v0])
    start = x.copy()
    status = kepler_step(x, np.zeros((0, 6)), 0, 0, 3, mu, mass, h)
    assert status == KEPLER_OK
    with mp.workdps(40):
        ref_r = np.array([float(c) for c in r1])
        ref_p = np.array([float(mass * c) for c in v1])
    # Round-off: 40 ulps of the larger of each vector's sizes at the two
    # ends, plus the motion over the time equivalent to a few ulps of the
    # step (|ẋ|·|h|·ε), which the rounding of X, h and the initial state
    # amount to for long steps and near pericentre.
    rate = (np.max(np.abs(ref_p)) / mass, mu * np.max(np.abs(ref_r)) ** -2 * mass)
    for (got, ref, before), v in zip(((x[:3], ref_r, start[:3]), (x[3:], ref_p, start[3:])),
                                     rate, strict=True):
        size = max(np.max(np.abs(ref)), np.max(np.abs(before)))
        assert np.max(np.abs(got - ref)) <= 40 * 2.2e-16 * (size + v * abs(h))


def _state(e, f=0.3, q=0.5, mu=1.0, mass=0.3):
    p = q * (1 + e)
    r = p / (1 + e * math.cos(f))
    R = np.array([[1, 0, 0], [0, math.cos(0.4), -math.sin(0.4)], [0, math.sin(0.4), math.cos(0.4)]])
    pos = R @ [r * math.cos(f), r * math.sin(f), 0.0]
    vel = R @ (math.sqrt(mu / p) * np.array([-math.sin(f), e + math.cos(f), 0.0]))
    return np.concatenate([pos, mass * vel])


def _step(x, h, mass=0.3, mu=1.0, V=None):
    y = x.copy()
    V = np.zeros((0, 6)) if V is None else V.copy()
    assert kepler_step(y, V, V.shape[0], 0, 3, mu, mass, h) == KEPLER_OK
    return y, V


def _finite_difference(x, h, d0=1e-4):
    """Fourth-order central differences of the drift, column by column."""
    J = np.empty((6, 6))
    for c in range(6):
        d = d0 * max(abs(x[c]), 1e-3)
        e = np.eye(6)[c] * d
        J[:, c] = (8 * (_step(x + e, h)[0] - _step(x - e, h)[0])
                   - (_step(x + 2 * e, h)[0] - _step(x - 2 * e, h)[0])) / (12 * d)
    return J


@pytest.mark.parametrize("e", [0.0, 0.1, 0.5, 0.9, 0.95, 0.99, 1.0, 1.5, 5.0])
@pytest.mark.parametrize("h", [0.05, 1.0, 7.0, -2.0])
def test_tangent_is_the_derivative_of_the_drift(e, h):
    """The tangent map (rows of V pushed forward: Jᵀ) against fourth-order
    finite differences of the drift itself: 1e-8 relative (measured:
    ≤ 7e-10), through pericentre passages and for steps over a period."""
    x = _state(e)
    _, V = _step(x, h, V=np.eye(6))
    J = V.T
    assert np.max(np.abs(J - _finite_difference(x, h))) <= 1e-8 * np.max(np.abs(J))


@pytest.mark.parametrize("e", [0.0, 0.5, 0.99, 1.0, 3.0])
def test_tangent_map_is_symplectic_and_the_drift_reversible(e):
    x = _state(e)
    y, V = _step(x, 3.0, V=np.eye(6))
    J = V.T
    assert np.max(np.abs(J.T @ J6 @ J - J6)) <= 1e-14 * np.max(np.abs(J)) ** 2
    back, Vb = _step(y, -3.0, V=V)
    # Forward and back amplify the rounding by the map's conditioning.
    assert np.max(np.abs(back - x)) <= 64 * 2.2e-16 * np.max(np.abs(J)) * np.max(np.abs(x))
    assert np.max(np.abs(Vb - np.eye(6))) <= 1e-13 * np.max(np.abs(J)) ** 2


def test_tangent_agrees_with_heyoka_over_one_orbit():
    """One period of an e = 0.7 orbit as 64 drifts: the product of their
    tangent maps against heyoka's variational equations of the two-body
    problem at tolerance 1e-18 in long double: round-off, i.e. ε times the
    conditioning ‖J‖ ≈ 2300 of the map over the orbit (measured 1.0e-13 of
    ‖J‖, the orbit 1e-15)."""
    hy = pytest.importorskip("heyoka")
    mu, mass, e = 1.0, 1.0, 0.7
    x0 = _state(e, f=0.0, q=0.3, mu=mu, mass=mass)
    a = 0.3 / (1 - e)
    period = 2 * math.pi * math.sqrt(a ** 3 / mu)
    x, V = x0.copy(), np.eye(6)
    for _ in range(64):
        assert kepler_step(x, V, 6, 0, 3, mu, mass, period / 64) == KEPLER_OK
    q = hy.make_vars("x", "y", "z")
    v = hy.make_vars("vx", "vy", "vz")
    r3 = hy.sum([c * c for c in q]) ** 1.5
    sys = [(q[i], v[i]) for i in range(3)] + [(v[i], -mu * q[i] / r3) for i in range(3)]
    vsys = hy.var_ode_sys(sys, hy.var_args.vars, order=1)
    ta = hy.taylor_adaptive(vsys, np.concatenate([x0, np.eye(6).ravel()]).astype(np.longdouble),
                            fp_type=np.longdouble, tol=np.longdouble(1e-18))
    ta.propagate_until(np.longdouble(period))
    ref = np.asarray(ta.state, dtype=float)
    assert np.max(np.abs(x - ref[:6])) <= 1e-13 * np.max(np.abs(x0))
    J = V.T
    Jref = ref[6:].reshape(6, 6)
    assert np.max(np.abs(J - Jref)) <= 4 * 2.2e-16 * np.max(np.abs(Jref)) ** 2


def test_unresolvable_steps_are_reported_and_leave_the_state():
    """A body at the centre, or a non-finite state, is degenerate; the
    state and the vectors are left as they were."""
    for x in (np.array([0.0, 0, 0, 0.1, 0, 0]), np.array([np.nan, 1, 0, 0, 1, 0]),
              np.array([1.0, 0, 0, np.inf, 0, 0])):
        y, V = x.copy(), np.eye(6)
        assert kepler_step(y, V, 6, 0, 3, 1.0, 1.0, 0.1) == KEPLER_DEGENERATE
        assert np.array_equal(y, x, equal_nan=True) and np.array_equal(V, np.eye(6))


def test_solver_is_at_round_off_and_zero_step_is_the_identity():
    x = _state(0.6)
    r0 = np.linalg.norm(x[:3])
    v = x[3:] / 0.3
    beta = 2 / r0 - v @ v
    eta, zeta = x[:3] @ v, 1 - beta * r0
    h2 = float(np.sum(np.cross(x[:3], v) ** 2))
    status, X, _, _, G2, G3, _, _ = solve_universal(r0, eta, zeta, beta, 1.0, 0.8, h2)
    assert status == KEPLER_OK
    assert abs(r0 * X + eta * G2 + zeta * G3 - 0.8) <= 4 * 2.2e-16 * 0.8 * 2
    y, V = _step(x, 0.0, V=np.eye(6))
    assert np.array_equal(y, x) and np.array_equal(V, np.eye(6))

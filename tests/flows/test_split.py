"""The solvable parts of H = T(p) + V(q) and H = A + V(q): the rotating /
Larmor flow against the matrix exponential of its linear equations, the
drift of a non-quadratic T against its closed form and finite differences,
measured orders of the two-part schemes against the Taylor reference, and
the symplecticity of their tangent maps."""

import numpy as np
import pytest
from scipy.linalg import expm

from tests.flows.steppers import (cr3bp, finite_difference, larmor, relativistic,
                                  symplectic_form, taylor_reference)
from tests.helpers import fitted_slope
from varint.flows.split import kinetic_drift, planar_flow, planar_params, potential_kick
from varint.methods.parts import parts_steps


def _quadratic_matrix(n, plane, a, b, omega, others):
    """S with A = ½ xᵀSx for the planar form (see varint.flows.split)."""
    S = np.zeros((2 * n, 2 * n))
    u, v = plane
    for i in range(n):
        ai, bi = (a, b) if i in plane else others[i]
        S[n + i, n + i] = ai
        S[i, i] = bi
    # −Ω (q_u p_v − q_v p_u)
    S[u, n + v] = S[n + v, u] = -omega
    S[v, n + u] = S[n + u, v] = omega
    return S


@pytest.mark.parametrize("a, b, omega, others", [
    (1.0, 0.0, 1.0, {}),                                  # the synodic frame
    (1.0, 1.0, 1.0, {2: (1.0, 1.0)}),                     # Larmor, B = 2, z oscillator
    (0.5, -0.3, 2.5, {2: (2.0, 0.0)}),                    # inverted oscillator, free z
    (2.0, 3.0, -0.7, {2: (1.0, -2.0), 3: (0.5, 4.0)}),
])
def test_planar_flow_is_the_exponential(a, b, omega, others):
    """The flow of A for time h, orbit and tangent rows, equals
    exp(h J S) (scipy's matrix exponential) to round-off, and is
    symplectic."""
    n = 2 + len(others)
    par = planar_params(n, (0, 1), a, b, omega, others)
    S = _quadratic_matrix(n, (0, 1), a, b, omega, others)
    J = symplectic_form(n)
    rng = np.random.default_rng(1)
    for h in (0.013, 0.4, -1.7):
        E = expm(h * J @ S)
        x = rng.standard_normal(2 * n)
        V = np.eye(2 * n)
        y = x.copy()
        planar_flow(h, y, V, 2 * n, par)
        assert np.abs(y - E @ x).max() < 1e-13 * (1 + np.abs(x).max())
        assert np.abs(V.T - E).max() < 1e-13 * max(1.0, np.abs(E).max())
        assert np.abs(V @ J @ V.T - J).max() < 1e-13 * max(1.0, np.abs(E).max() ** 2)


def test_kinetic_drift_of_a_relativistic_particle():
    """T = √(1 + |p|²): the drift is q + h p/√(1 + |p|²) and its tangent is
    the derivative (central differences)."""
    model = relativistic()
    rng = np.random.default_rng(2)
    x0 = rng.standard_normal(4)
    h = 0.3
    g, D = np.empty(2), np.empty((2, 2))
    par = model.parameters_at(None)

    def drift(x):
        y = x.copy()
        kinetic_drift(h, y, np.zeros((0, 4)), 0, par, g, D, model.grad_t, model.grad_hess_t)
        return y

    y = drift(x0)
    p = x0[2:]
    assert np.abs(y[:2] - (x0[:2] + h * p / np.sqrt(1 + p @ p))).max() < 1e-15
    V = np.eye(4)
    kinetic_drift(h, x0.copy(), V, 4, par, g, D, model.grad_t, model.grad_hess_t)
    assert np.abs(V.T - finite_difference(drift, x0)).max() < 1e-9

    def kick(x):
        y = x.copy()
        potential_kick(h, y, np.zeros((0, 4)), 0, par, g, D, model.grad_v, model.grad_hess_v)
        return y

    V = np.eye(4)
    potential_kick(h, x0.copy(), V, 4, par, g, D, model.grad_v, model.grad_hess_v)
    assert np.abs(V.T - finite_difference(kick, x0)).max() < 1e-9


_CASES = {
    "cr3bp": (cr3bp, np.array([0.5, 0.0, 0.0, 0.9])),
    "relativistic": (relativistic, np.array([0.1, 0.1, 0.3, 0.2])),
    "larmor": (larmor, np.array([0.5, 0.1, 0.2, 0.1, 0.6, 0.3])),
}


@pytest.mark.parametrize("case", sorted(_CASES))
@pytest.mark.parametrize("scheme, order, steps", [("SABA2", (2, 4), (80, 160, 320)),
                                                  ("ABA864", (4, 8), (40, 80, 160)),
                                                  ("s11odr6", (6, 6), (10, 20, 40))])
def test_two_part_schemes_measured_order(case, scheme, order, steps):
    """The part stepper's orbit and tangent map at t = 2 converge to the
    Taylor reference at the scheme's order: for H = A + εB with ε = 1,
    SABA2 (nominal (4,2)) has order 2 and ABA864 ((8,6,4)) order 4, and the
    measured slope lies between that and the highest nominal order (whose
    terms may still lead at these steps)."""
    build, x0 = _CASES[case]
    model = build()
    if case == "cr3bp" and scheme == "s11odr6":
        steps = (160, 320, 640)     # its close approach needs τ < 0.01 for the asymptote
    ref, M_ref = taylor_reference(model, x0, 2.0, tangent=True)
    errs, terrs = [], []
    for n in steps:
        x, W = parts_steps(model, x0, np.eye(model.dim), 2.0 / n, n, scheme)
        errs.append(np.abs(x - ref).max())
        terrs.append(np.abs(W - M_ref).max())
    taus = [2.0 / n for n in steps]
    low, high = order
    for e in (errs, terrs):
        assert low - 0.3 < fitted_slope(taus, e) < high + 0.5


@pytest.mark.parametrize("case", sorted(_CASES))
def test_part_stepper_tangent_is_symplectic_and_the_derivative(case):
    """100 ABA864 steps: MᵀJM = J to round-off, and M equals central
    differences of the same map (whose displaced orbits carry the vectors
    too, though they do not depend on them: one kernel per model)."""
    build, x0 = _CASES[case]
    model = build()
    d = model.dim
    _, M = parts_steps(model, x0, np.eye(d), 0.02, 100, "ABA864")
    J = symplectic_form(d // 2)
    assert np.abs(M.T @ J @ M - J).max() < 1e-12 * max(1.0, np.abs(M).max() ** 2)
    D = finite_difference(lambda z: parts_steps(model, z, np.eye(d), 0.02, 100, "ABA864")[0],
                          x0)
    assert np.abs(D - M).max() < 1e-8 * max(1.0, np.abs(M).max())


@pytest.mark.parametrize("case, order", [("cr3bp", 6), ("relativistic", 4)])
def test_rkn_scheme_keeps_its_order_only_for_quadratic_momenta(case, order):
    """SRKN14a is a Runge–Kutta–Nyström scheme: order 6 where A is quadratic
    in p and V depends on q ({V,{V,{V,A}}} = 0: the rotating frame of the
    CR3BP), order 4 for T = √(1 + |p|²) — why the separable models default to
    s11odr6 and the rotating ones to SRKN14a. The orbit carries the identity
    (the kernel of the other tests of the model; its orbit does not depend
    on the vectors)."""
    build, x0 = _CASES[case]
    model = build()
    ref = taylor_reference(model, x0, 2.0)
    steps = (80, 160, 320) if case == "cr3bp" else (10, 20, 40)
    errs = [np.abs(parts_steps(model, x0, np.eye(model.dim), 2.0 / n, n, "SRKN14a")[0]
                   - ref).max() for n in steps]
    assert fitted_slope([2.0 / n for n in steps], errs) == pytest.approx(order, abs=0.5)


def test_termwise_flows_are_exact_explicit_and_symplectic():
    """The magnetic bottle split into V and the parts of p_x, p_y, p_z: each
    flow x + hJ∇P is exact (the part's gradient is constant along it), so
    the order-6 composition converges at order 6 to the Taylor reference,
    and its tangent map equals central differences and is symplectic."""
    from varint.models.bottle import bottle_orbit

    model, x0 = bottle_orbit("chaotic")
    assert model.part_names == ("V", "p_x", "p_y", "p_z")
    scheme = model.default_scheme
    ref, M_ref = taylor_reference(model, x0, 2.0, tangent=True)
    steps = (10, 20, 40)
    errs, terrs = [], []
    for n in steps:
        x, W = parts_steps(model, x0, np.eye(6), 2.0 / n, n, scheme)
        errs.append(np.abs(x - ref).max())
        terrs.append(np.abs(W - M_ref).max())
    taus = [2.0 / n for n in steps]
    assert fitted_slope(taus, errs) == pytest.approx(6, abs=0.3)
    assert fitted_slope(taus, terrs) == pytest.approx(6, abs=0.3)
    _, M = parts_steps(model, x0, np.eye(6), 0.05, 40, scheme)
    J = symplectic_form(3)
    assert np.abs(M.T @ J @ M - J).max() < 1e-13
    # The displaced orbits carry the vectors too: the kernel above, not one for k = 0.
    D = finite_difference(lambda z: parts_steps(model, z, np.eye(6), 0.05, 40, scheme)[0], x0)
    assert np.abs(D - M).max() < 1e-8


def test_termwise_flow_is_the_flow_of_its_part():
    """One part's flow for a long time h (no splitting error within a part):
    the p_x part of the bottle, ½p_x² + p_x B_z y/2, integrated by heyoka
    alone, ends where x + hJ∇P puts it."""
    from varint.models import from_hamiltonian
    from varint.models.bottle import bottle_orbit

    model, x0 = bottle_orbit("chaotic")
    name, part = model._found.terms[1]
    assert name == "p_x"
    s = model.symbolic()
    alone = from_hamiltonian(part, s.q, s.p, structure="general")
    ref = taylor_reference(alone, x0, 1.3)
    x = x0.copy()
    model.parts.apply(1, 1.3, x, np.zeros((0, 6)), 0, model.parameters_at(None),
                      np.empty(model.parts.n_work))
    assert np.abs(x - ref).max() < 1e-14

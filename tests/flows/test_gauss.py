"""Gauss–Legendre steps for any H(q, p): the tableaux, measured orders
against the Taylor reference, the tangent map against finite differences
of the same step, and its symplecticity; the part stepper's step is this
step."""

import numpy as np
import pytest

from tests.flows.steppers import (coupled_general, finite_difference, gauss_steps,
                                  symplectic_form, taylor_reference)
from tests.helpers import fitted_slope
from varint.flows.gauss import GAUSS, GaussLegendre
from varint.flows.general import GENERAL_SCHEMES
from varint.methods.parts import parts_steps


@pytest.mark.parametrize("name", sorted(GAUSS))
def test_tableau_order_conditions(name):
    """B(2s), C(s) and the symplecticity condition b_i a_ij + b_j a_ji =
    b_i b_j (Hairer, Lubich & Wanner, Thm. VI.4.3) hold to round-off."""
    g = GAUSS[name]
    A, b, c, _, _ = g.arrays
    s = g.stages
    for k in range(1, 2 * s + 1):
        assert abs(b @ c ** (k - 1) - 1 / k) < 5e-16
    for k in range(1, s + 1):
        assert np.abs(A @ c ** (k - 1) - c ** k / k).max() < 5e-16
    M = b[:, None] * A + (b[:, None] * A).T - np.outer(b, b)
    assert np.abs(M).max() < 5e-16


def test_tableau_is_checked():
    with pytest.raises(ValueError, match="order 4"):
        GaussLegendre("bad", c=(0.2, 0.8), b=(0.5, 0.5), a=((0.25, 0.0), (0.5, 0.25)), order=6)
    with pytest.raises(ValueError, match="2 entries"):
        GaussLegendre("bad", c=(0.2, 0.8), b=(1.0,), a=((0.25, 0.0), (0.5, 0.25)), order=4)


@pytest.mark.parametrize("name, steps", [("GL4", (10, 20, 40)), ("GL6", (10, 20, 40)),
                                         ("GL8", (5, 10, 20))])
def test_measured_order_orbit_and_tangent(name, steps):
    """The errors of the orbit and of the tangent map at t = 2 against
    heyoka's Taylor method on Hamilton's equations fall as τ^(2s)."""
    model = coupled_general()
    x0 = np.array([0.1, 0.05, 0.2, 0.25])
    ref, M_ref = taylor_reference(model, x0, 2.0, tangent=True)
    taus = [2.0 / n for n in steps]
    errors, tangent_errors = [], []
    for n in steps:
        x, W = gauss_steps(model, x0, np.eye(4), 2.0 / n, n, name)
        errors.append(np.abs(x - ref).max())
        tangent_errors.append(np.abs(W - M_ref).max())
    order = GAUSS[name].order
    assert fitted_slope(taus, errors) == pytest.approx(order, abs=0.3)
    assert fitted_slope(taus, tangent_errors) == pytest.approx(order, abs=0.3)


@pytest.mark.parametrize("name", sorted(GENERAL_SCHEMES))
def test_part_stepper_runs_the_same_step(name):
    """One step through the part stepper (varint.methods.parts, what
    method="tm" runs on a general H) is the Gauss–Legendre step of
    varint.flows.gauss from the explicit guess, bit for bit, orbit and
    tangent map (on two generic vectors: every entry of the tangent map
    enters both). The part stepper compiles the scheme's step alone
    (Parts.apply_only): the step another scheme's index selects does
    nothing there, so a wrong index would leave the state unchanged. Here
    beside the other tests of gauss_steps, whose compiled loop on this
    model it shares: in tests/flows/test_general_methods.py, run by the
    other xdist worker, it compiled that loop a second time (12.6 CPU s
    cold, studies/results/stop57/suite_profile_stop57.json)."""
    model = coupled_general()
    x0 = np.array([0.1, 0.05, 0.2, 0.25])
    W0 = np.random.default_rng(0).standard_normal((4, 2))
    x, W = parts_steps(model, x0, W0, 0.1, 1, name)
    x_ref, W_ref = gauss_steps(model, x0, W0, 0.1, 1, name)
    assert np.array_equal(x, x_ref)
    assert np.array_equal(W, W_ref)


def test_tangent_is_the_derivative_of_the_step():
    """Central differences of three steps of the same map agree with the
    tangent map to the differences' own error (ε² ~ 1e-12 relative)."""
    model = coupled_general()
    x0 = np.array([0.1, 0.05, 0.2, 0.25])
    _, W = gauss_steps(model, x0, np.eye(4), 0.1, 3, "GL6")
    D = finite_difference(lambda z: gauss_steps(model, z, None, 0.1, 3, "GL6")[0], x0)
    assert np.abs(D - W).max() < 1e-9


@pytest.mark.parametrize("name", sorted(GAUSS))
def test_tangent_is_symplectic(name):
    """MᵀJM = J to round-off after 50 steps: the tangent map of the
    converged implicit step is symplectic."""
    model = coupled_general()
    x0 = np.array([0.1, 0.05, 0.2, 0.25])
    _, M = gauss_steps(model, x0, np.eye(4), 0.1, 50, name)
    J = symplectic_form(2)
    assert np.abs(M.T @ J @ M - J).max() < 1e-13


def test_energy_bounded_over_long_times():
    """A symplectic method's energy error stays bounded (no drift) over
    10⁴ steps (measured 5e-9 to 5e-8 in every tenth). On the coupled
    general H the order tests use, with GL4: their compiled loop, not one
    of its own for another model (Tao's example took 11 CPU s cold)."""
    model = coupled_general()
    x0 = np.array([0.1, 0.05, 0.2, 0.25])
    e0 = model.energy(x0)
    errs = []
    x = x0
    for _ in range(10):
        x, _ = gauss_steps(model, x, None, 0.1, 1000, "GL4")
        errs.append(abs(model.energy(x) - e0) / e0)
    assert max(errs) < 1e-6
    # Bounded: the last tenth's error is not an order above the first's.
    assert errs[-1] < 10 * max(errs[:3])


@pytest.mark.parametrize("name", sorted(GAUSS))
def test_iterated_tangent_equals_the_factorised_one(name):
    """Up to FIXED_POINT_VECTORS vectors the tangent is iterated to
    round-off, beyond it comes from an LU factorisation: the same vectors
    agree to 1e-13 after 50 steps."""
    from varint.flows.gauss import FIXED_POINT_VECTORS

    model = coupled_general()
    x0 = np.array([0.1, 0.05, 0.2, 0.25])
    _, M = gauss_steps(model, x0, np.eye(4), 0.1, 50, name)            # LU
    for j in range(0, 4, FIXED_POINT_VECTORS):
        cols = np.eye(4)[:, j:j + FIXED_POINT_VECTORS]
        _, W = gauss_steps(model, x0, cols, 0.1, 50, name)             # iterated
        assert np.abs(W - M[:, j:j + FIXED_POINT_VECTORS]).max() < 1e-13 * np.abs(M).max()


def test_extrapolated_start_converges_to_the_same_step():
    """Started from the previous step's collocation polynomial the
    iteration reaches the same stages: 200 steps carried on from the
    previous stages agree with 200 steps each started from Euler's guess to
    round-off (1e-14)."""
    model = coupled_general()
    x0 = np.array([0.1, 0.05, 0.2, 0.25])
    carried, _ = gauss_steps(model, x0, None, 0.1, 200, "GL6")
    fresh = x0
    for _ in range(200):
        fresh, _ = gauss_steps(model, fresh, None, 0.1, 1, "GL6")
    assert np.abs(carried - fresh).max() < 1e-14


@pytest.mark.parametrize("name", sorted(GAUSS))
def test_extrapolation_is_exact_for_the_collocation_polynomial(name):
    """E reproduces a polynomial of degree s through the nodes: for
    u(τ) = τ^m (m ≤ s), Z_i = u(c_i), E Z = u(1 + c_j) − u(1)."""
    c = GAUSS[name].arrays[2]
    E = GAUSS[name].arrays[4]
    for m in range(1, len(c) + 1):
        assert np.abs(E @ c ** m - ((1 + c) ** m - 1)).max() < 1e-12


def test_time_dependent_hamiltonian():
    """H = √(1 + p²) + ½ q² (1 + ½ cos t) + q⁴/4: GL6's orbit converges at
    order 6 to the Taylor reference (heyoka with hy.time), and the extended
    energy K = H + p_t (p_t advanced by the same stages) is conserved to
    the method's accuracy."""
    import sympy as sp

    from varint.models import from_hamiltonian

    q, p, t = sp.symbols("q p t")
    model = from_hamiltonian(sp.sqrt(1 + p ** 2) + q ** 2 * (1 + sp.cos(t) / 2) / 2 + q ** 4 / 4,
                             [q], [p], time=t)
    x0 = np.array([0.8, 0.1])
    ref = taylor_reference(model, x0, 3.0)
    steps = (15, 30, 60)
    errs = []
    for n in steps:
        pt = np.zeros(1)
        x, _ = gauss_steps(model, x0, None, 3.0 / n, n, "GL6", pt=pt)
        errs.append(np.abs(x - ref).max())
    assert fitted_slope([3.0 / n for n in steps], errs) == pytest.approx(6, abs=0.3)
    K0 = model.energy(x0, 0.0, 0.0)
    assert abs(model.energy(x, 3.0, pt[0]) - K0) < 1e-9

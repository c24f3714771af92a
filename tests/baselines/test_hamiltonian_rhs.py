"""The reference methods' right-hand side of any H(q, p): Hamilton's
equations and the variational equations from the model's ∇H and D²H agree
with heyoka's Taylor integration of the same expression."""

import numpy as np
import pytest
import sympy as sp
from scipy.integrate import solve_ivp

from tests.flows.steppers import bottle, coupled_general, cr3bp, taylor_reference
from varint.baselines.rhs import CLOCK, pack, tangent_rhs
from varint.models import from_hamiltonian


@pytest.mark.parametrize("build, x0", [
    (coupled_general, [0.1, 0.05, 0.2, 0.25]),
    (cr3bp, [0.5, 0.0, 0.0, 0.9]),
    (bottle, [0.2, 0.1, 0.3, 0.1, -0.2, 0.4]),
])
def test_rhs_of_any_hamiltonian_against_taylor(build, x0):
    model = build()
    x0 = np.asarray(x0, dtype=float)
    _, fun = tangent_rhs(model)
    y0 = pack(x0, np.eye(model.dim))
    sol = solve_ivp(fun, (0.0, 1.5), y0, method="DOP853", rtol=1e-13, atol=1e-15)
    ref, M = taylor_reference(model, x0, 1.5, tangent=True)
    d = model.dim
    assert np.abs(sol.y[:d, -1] - ref).max() < 1e-11
    assert np.abs(sol.y[d:, -1].reshape(d, d) - M).max() < 1e-10


def test_rhs_of_a_time_dependent_hamiltonian():
    """H = √(1 + p²) + ½x²(1 + ½cos t): the clock (t, p_t) ends the state,
    ṫ = 1 and ṗ_t = −∂_tH, so K = H + p_t is conserved."""
    x, p, t = sp.symbols("x p t")
    H = sp.sqrt(1 + p ** 2) + x ** 2 * (1 + sp.cos(t) / 2) / 2
    model = from_hamiltonian(H, [x], [p], time=t)
    _, fun = tangent_rhs(model)
    y0 = pack(np.array([0.5, 0.1]), np.eye(2), clock=(0.0, 0.0))
    sol = solve_ivp(fun, (0.0, 5.0), y0, method="DOP853", rtol=1e-12, atol=1e-14)
    y = sol.y[:, -1]
    assert y[-CLOCK] == pytest.approx(5.0, rel=1e-13)
    K0 = model.energy(y0[:2], 0.0, 0.0)
    assert model.energy(y[:2], y[-CLOCK], y[-1]) == pytest.approx(K0, rel=1e-10)

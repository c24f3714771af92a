"""Tao's extended-phase-space flows: measured orders against the Taylor
reference, each flow's tangent against finite differences, the extended
tangent map's symplecticity, and the first copy's tangent (carried by G)
against finite differences of the physical map."""

import numpy as np
import pytest

from tests.flows.steppers import (coupled_general, finite_difference, symplectic_form,
                                  taylor_reference, tao_steps)
from tests.helpers import fitted_slope
from varint.flows.tao import tao_flow_c, tao_flows


@pytest.mark.parametrize("scheme, order, steps", [("ABC2", 2, (20, 40, 80)),
                                                  ("ABC4_Y", 4, (20, 40, 80)),
                                                  ("ABC6_Y", 6, (40, 80, 160))])
def test_measured_order(scheme, order, steps):
    """Errors of the orbit and of the tangent map at t = 2 against heyoka's
    Taylor method fall as τ^l (l = 2, 4, 6) at a fixed binding ω."""
    model = coupled_general()
    x0 = np.array([0.1, 0.05, 0.2, 0.25])
    ref, M_ref = taylor_reference(model, x0, 2.0, tangent=True)
    taus = [2.0 / n for n in steps]
    errs, terrs = [], []
    for n in steps:
        x, W, _, _ = tao_steps(model, x0, np.eye(4), 2.0 / n, n, scheme, omega=1.0)
        errs.append(np.abs(x - ref).max())
        terrs.append(np.abs(W - M_ref).max())
    assert fitted_slope(taus, errs) == pytest.approx(order, abs=0.35)
    assert fitted_slope(taus, terrs) == pytest.approx(order, abs=0.35)


def _extended(flow, h, z, model):
    """One flow on the extended state z = (q, p, x, y) (4N,) and its
    tangent map (4N, 4N) (the images of the unit vectors)."""
    d = model.dim
    x, x2 = z[:d].copy(), z[d:].copy()
    E = np.eye(2 * d)
    scratch = np.empty(d), np.empty(d), np.empty((d, d))
    par = model.parameters_at(None)
    if flow == "c":
        tao_flow_c(h, 3.0, x, x2, E, 2 * d)
    else:
        tao_flows(model.grad_hess_h)[flow == "b"](h, x, x2, E, 2 * d, par, *scratch)
    return np.concatenate([x, x2]), E.T


@pytest.mark.parametrize("flow", ["a", "b", "c"])
def test_each_flow_tangent_and_symplecticity(flow):
    """Each flow's tangent map is the derivative of the flow (central
    differences) and symplectic in the doubled phase space."""
    model = coupled_general()
    rng = np.random.default_rng(3)
    z = 0.3 * rng.standard_normal(8)
    _, Phi = _extended(flow, 0.07, z, model)
    D = finite_difference(lambda w: _extended(flow, 0.07, w, model)[0], z)
    assert np.abs(D - Phi).max() < 1e-9
    # The doubled space's form: J ⊕ J on (q, p) and (x, y).
    J = np.zeros((8, 8))
    J[:4, :4] = J[4:, 4:] = symplectic_form(2)
    assert np.abs(Phi.T @ J @ Phi - J).max() < 1e-14


def test_first_copy_tangent_is_the_derivative_of_the_physical_map():
    """The deviation vectors carried through G are the derivative of the
    map x0 ↦ x_n of the first copy, started on the diagonal."""
    model = coupled_general()
    x0 = np.array([0.1, 0.05, 0.2, 0.25])
    _, W, _, _ = tao_steps(model, x0, np.eye(4), 0.1, 5, "ABC4_Y", omega=2.0)
    D = finite_difference(lambda z: tao_steps(model, z, None, 0.1, 5, "ABC4_Y",
                                              omega=2.0)[0], x0)
    assert np.abs(D - W).max() < 1e-9


def test_restart_from_carried_state_is_bitwise():
    """Two runs of 3 + 4 steps, handing on the second copy and G, give the
    bits of one run of 7 steps (the method's state is (x, W, copy, G))."""
    model = coupled_general()
    x0 = np.array([0.1, 0.05, 0.2, 0.25])
    W0 = np.eye(4)[:, :2]
    x, W, c, G = tao_steps(model, x0, W0, 0.1, 3, "ABC4_Y")
    x, W, c, G = tao_steps(model, x, W, 0.1, 4, "ABC4_Y", copy=c, G=G)
    y, V, c2, G2 = tao_steps(model, x0, W0, 0.1, 7, "ABC4_Y")
    for a, b in ((x, y), (W, V), (c, c2), (G, G2)):
        assert a.tobytes() == b.tobytes()

"""The rotating bar on its generated stepper: the closed part (the rotating
frame's drift) written out, the whole potential (disc, bulge, Ferrers bar)
added in every kick by its compiled kernel
(:class:`varint.codegen.expressions.ExtraForce`,
:func:`varint.models.bar.galaxy_force`)."""

import numpy as np
import pytest
import sympy as sp
from numba import njit

from varint.codegen.expressions import ExtraForce
from varint.methods.parts import generated_rotating, parts_steps, runs_parts
from varint.methods.tm import tangent_map_steps
from varint.models import from_hamiltonian
from varint.models.bar import bar_orbit


@pytest.fixture(scope="module")
def regular():
    return bar_orbit("regular")


def test_two_part_schemes_take_the_generated_stepper(regular):
    model, _ = regular
    assert generated_rotating(model)
    assert not runs_parts(model, "SRKN14a") and not runs_parts(model, "ABA864")
    # A corrector would need the bar's third derivatives: the part stepper
    # takes it, and refuses it with its reason.
    assert runs_parts(model, "SBAB2C")


@pytest.mark.parametrize("n_steps, bound", [(1, 1e-14), (500, 1e-11)])
def test_generated_stepper_is_the_part_flows_to_round_off(regular, n_steps, bound):
    """The same scheme through the part flows (its own arithmetic: no fused
    multiply–adds, the rotation as c x + s y) and through the generated
    stepper: the same map up to round-off — one step, and t = 100 of
    SRKN14a at τ = 0.2 on a quasi-periodic orbit (round-off grows linearly
    along it; measured 7e-13)."""
    model, x0 = regular
    W = np.eye(6)
    xa, Wa = parts_steps(model, x0, W, 0.2, n_steps, scheme="SRKN14a")
    xb, Wb = tangent_map_steps(model, x0, W, 0.2, n_steps, scheme="SRKN14a")
    assert np.max(np.abs(xb - xa)) <= bound * np.max(np.abs(xa))
    assert np.max(np.abs(Wb - Wa)) <= bound * np.max(np.abs(Wa))
    assert not np.array_equal(xa, xb) or n_steps == 1


@pytest.mark.parametrize("name", ["regular", "chaotic"])
def test_generated_tangent_map_is_finite_differences(name):
    """TS of 40 steps (t = 8, inside and outside the bar) against central
    differences of the generated map S itself."""
    model, x0 = bar_orbit(name)
    _, W = tangent_map_steps(model, x0, np.eye(6), 0.2, 40, scheme="ABA864")
    eps = 1e-6
    fd = np.empty((6, 6))
    for j in range(6):
        e = np.zeros(6)
        e[j] = eps
        plus, _ = tangent_map_steps(model, x0 + e, None, 0.2, 40, scheme="ABA864")
        minus, _ = tangent_map_steps(model, x0 - e, None, 0.2, 40, scheme="ABA864")
        fd[:, j] = (plus - minus) / (2 * eps)
    assert np.max(np.abs(W - fd)) <= 1e-7 * np.max(np.abs(W))


def test_generated_stepper_keeps_the_jacobi_energy(regular):
    """SRKN14a (order 6) at τ = 0.2 over t = 100 keeps E_J as the part
    flows do (4.3e-12 both, measured)."""
    model, x0 = regular
    x, _ = tangent_map_steps(model, x0, None, 0.2, 500, scheme="SRKN14a")
    assert abs(model.energy(x) - model.energy(x0)) < 2e-11


def test_corrector_scheme_is_refused(regular):
    model, x0 = regular
    for steps in (parts_steps, tangent_map_steps):
        with pytest.raises(ValueError, match="corrector"):
            steps(model, x0, None, 0.2, 1, scheme="SBAB2C")


# -- the hook, on a model that has a closed form of its extra term ---------------------------
@njit(cache=True, error_model="numpy")
def _spring(q, g, D, hessian, k, centre):
    """The extra force of ½k|q − centre|² (an ExtraForce kernel)."""
    for i in range(q.shape[0]):
        g[i] += k * (q[i] - centre[i])
        if hessian:
            D[i, i] += k


def _rotating(with_spring):
    x, y, z, px, py, pz = sp.symbols("x y z p_x p_y p_z")
    V = -1 / sp.sqrt(1 + x ** 2 + 2 * y ** 2 + 3 * z ** 2)
    if with_spring:
        V += sp.Rational(3, 10) * ((x - 1) ** 2 + (y + sp.Rational(1, 2)) ** 2 + z ** 2) / 2
    H = (px ** 2 + py ** 2 + pz ** 2) / 2 - sp.Rational(1, 20) * (x * py - y * px) + V
    return from_hamiltonian(H, (x, y, z), (px, py, pz))


def test_extra_force_hook_adds_its_term_to_the_closed_part():
    """A model declares part of its potential as a compiled kernel (a spring,
    whose closed form is known) and its closed part by ``closed_symbolic``:
    its generated stepper is the one generated for the whole potential in
    closed form, to round-off (the terms are summed in another order)."""
    whole = _rotating(True)
    split = _rotating(False)
    split.extra_force = ExtraForce(_spring, (0.3, (1.0, -0.5, 0.0)))
    split.closed_symbolic = split.symbolic
    assert generated_rotating(whole) and generated_rotating(split)
    x0 = np.array([0.4, 0.1, 0.2, 0.0, 0.6, 0.1])
    xa, Wa = tangent_map_steps(whole, x0, np.eye(6), 0.1, 200, scheme="SRKN14a")
    xb, Wb = tangent_map_steps(split, x0, np.eye(6), 0.1, 200, scheme="SRKN14a")
    assert np.max(np.abs(xb - xa)) <= 1e-12 * np.max(np.abs(xa))
    assert np.max(np.abs(Wb - Wa)) <= 1e-12 * np.max(np.abs(Wa))
    # Without the kernel the stepper is another map: the test can fail.
    xc, _ = tangent_map_steps(_rotating(False), x0, None, 0.1, 200, scheme="SRKN14a")
    assert np.max(np.abs(xc - xa)) > 1e-3

"""The rotating bar on its generated stepper: the closed part (rotating
frame, disc, bulge) written out, the Ferrers bar added in every kick by its
compiled kernel (:class:`varint.codegen.expressions.ExtraForce`)."""

import numpy as np
import pytest

from varint.methods.parts import generated_rotating, parts_steps, runs_parts
from varint.methods.tm import tangent_map_steps
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

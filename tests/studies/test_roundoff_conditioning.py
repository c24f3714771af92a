"""The conditioning study (studies/roundoff_conditioning.py): one
rounding's growth on R1 and C2 against a quadruple-precision reference, the
laws it follows, and the floor model it gives."""

import json

import numpy as np
import pytest

from studies import roundoff_conditioning as rc
from studies.common import RESULTS


@pytest.fixture(scope="module")
def quick(tmp_path_factory):
    return rc.main(["--quick", "--out", str(tmp_path_factory.mktemp("conditioning"))])


@pytest.fixture(scope="module")
def stored():
    return json.loads((RESULTS / "roundoff_conditioning.json").read_text())


def test_one_ulp_moves_every_nonzero_component_to_its_neighbour():
    x = np.array([0.0, 0.558, -0.25, 1e-300])
    y = rc.one_ulp(x, np.random.default_rng(1))
    assert y[0] == 0.0
    assert np.all(np.abs(y[1:] - x[1:]) == np.spacing(np.abs(x[1:])))


def test_the_symplectic_inverse_inverts():
    # A product of two symplectic shears, conditioned like C2's Φ(1e4).
    rng = np.random.default_rng(0)
    S, T = rng.standard_normal((2, 2, 2)) * 1e3
    S, T = S + S.T, T + T.T
    A = np.block([[np.eye(2), S], [np.zeros((2, 2)), np.eye(2)]])
    B = np.block([[np.eye(2), np.zeros((2, 2))], [T, np.eye(2)]])
    Phi = (A @ B).astype(np.longdouble)
    error = np.abs(np.asarray(rc.symplectic_inverse(Phi) @ Phi - np.eye(4), dtype=float)).max()
    # Rounding of the products only: ε(long double) · ‖Φ‖², no division.
    assert error < 100 * float(np.finfo(np.longdouble).eps) * float(np.linalg.norm(Phi)) ** 2


def test_a_perturbed_quadruple_run_follows_the_tangent_map(quick):
    """Two independent quadruple-precision runs (x₀ and x₀ + one ulp)
    differ by Φ(t) δx₀ from a third (the tangent map): the perturbation
    stays linear (measured 6e-15 relative)."""
    for s in quick["orbits"].values():
        assert s["linearity"] < 1e-10, s["orbit"]
        assert 0.5e-16 < s["relative_perturbation"]["state"] < 4.5e-16


def test_r1_quick_responses_shear_like_a_torus(quick):
    """On R1's 2-torus one rounding of the state grows ∝ t by t = 300
    (a change of the actions shifts the frequencies); one of the vector
    stays bounded (the tangent map is a shear)."""
    laws = quick["orbits"]["R1"]["laws"]
    assert laws["xx"]["exponent"] == pytest.approx(1.0, abs=0.15)
    assert laws["ww"]["exponent"] == pytest.approx(0.0, abs=0.3)


def test_the_stationary_sum_agrees_with_the_exact_one(quick):
    """F_w's part from the orbit is a stationary sum; on F_x, where the
    exact sum is known, the two agree within a factor of two."""
    for s in quick["orbits"].values():
        for f in s["floors"]:
            assert 0.5 < f["F_x_stationary"] / f["plain"]["F_x"] < 2.0, (s["orbit"], f["tau"])


def test_compensation_lowers_the_modelled_floor_with_the_step(quick):
    """Rounding only a step's increment (compensated summation) leaves a
    floor that falls with τ (∝ τ^½), the plain one rises (∝ τ^−½)."""
    for s in quick["orbits"].values():
        by_tau = {f["tau"]: f for f in s["floors"]}
        fine, coarse = by_tau[min(by_tau)], by_tau[max(by_tau)]
        assert fine["increment"]["F_x"] < coarse["increment"]["F_x"]
        assert fine["plain"]["F_x"] > coarse["plain"]["F_x"]


def test_stored_r1_responses_follow_the_torus_laws(stored):
    """To t = 1e4: state → state and state → vector ∝ t, vector → vector
    bounded (fitted t = 10 … 1e4)."""
    laws = stored["orbits"]["R1"]["laws"]
    assert laws["xx"]["exponent"] == pytest.approx(1.0, abs=0.1)
    assert laws["xw"]["exponent"] == pytest.approx(1.0, abs=0.15)
    assert laws["ww"]["exponent"] == pytest.approx(0.0, abs=0.1)


def test_stored_c2_state_responds_as_a_sticky_orbit(stored):
    """C2 is sticky until t ≈ 1e6 with χ₁ ≈ 4e-6 (Skokos & Gerlach 2010):
    over t ≤ 1e4, e^{χ₁t} ≤ 1.04, so its state responds to a rounding as
    a torus's does, ∝ t (not exponentially); its vector's dependence on
    the orbit grows faster (measured ∝ t^1.7) and sets C2's floors."""
    laws = stored["orbits"]["C2"]["laws"]
    assert laws["xx"]["exponent"] == pytest.approx(1.0, abs=0.15)
    assert laws["xw"]["exponent"] > laws["xx"]["exponent"] + 0.3
    floors = stored["orbits"]["C2"]["floors"]
    assert all(f["plain"]["F_w_from_orbit"] > f["plain"]["F_x"] for f in floors)


def test_stored_compensated_floors_follow_the_increment_model():
    """The compensated runs' smallest errors against the quadruple
    reference (R1 and C2, t = 1e3 and 1e4) lie within a factor of ten of
    the model that rounds only each step's increment, at their step, and
    at least ten times below the model that rounds the state (what any
    integrator keeping its state in double pays). The model is an
    expectation, so a minimum over a ladder may fall below it, a median
    of draws does not fall far (C2, t = 1e3: 12 draws per step)."""
    floors = json.loads((RESULTS / "roundoff_conditioning_floors.json").read_text())
    assert len(floors["cases"]) == 4
    for c in floors["cases"]:
        assert 0.1 < c["floor"] / c["model_increment"] < 10, c
        assert c["model_plain"] > 10 * c["floor"], c
    for d in floors["draws"]:
        assert len(d["errors"]) == rc.DRAWS and d["median"] > d["model_increment"] / 3, d

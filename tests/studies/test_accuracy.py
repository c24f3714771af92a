"""The accuracy study's quick mode (R1 and C1, t ≤ 100; TDH departures to
t = 1e4), and the laws that hold at its horizon.

The default suite runs the study with every TM run on the generic stepper
(kernels/tm.py: the scheme's stages are data, one compilation for all 26
schemes) instead of the straight-line steppers generated per scheme layout
(21 of them, s35odr10's of 71 stages among them: most of the study's
compile time). Every law checked here is a scheme's (its order, its error
against the reference) and does not depend on which stepper runs it:
test_generated_stepper checks that the two are the same map to round-off,
and the stored fingerprints pin every generated stepper bitwise. The study
as it runs (generated steppers) is the same tests marked slow.
"""

import pytest

import varint
import varint.methods.tm
from studies import accuracy


@pytest.fixture(scope="module", params=[
    "generic", pytest.param("generated", marks=pytest.mark.slow)])
def result(request, tmp_path_factory):
    out = tmp_path_factory.mktemp("accuracy")
    with pytest.MonkeyPatch.context() as patch:
        if request.param == "generic":
            # No generated stepper: TangentMapPropagator runs the generic one.
            patch.setattr(varint.methods.tm, "_generated_stepper", lambda *args: None)
        return accuracy.main(["--quick", "--out", str(out)]), out


def test_the_extended_reference_is_exact_to_double_rounding_at_t_100(result):
    """Against quadruple precision: measured ≤ 1.3e-16, while double-precision
    Taylor is off by 5e-15 (R1) and 5e-13 (C1), so the bound discriminates."""
    res, _ = result
    rows = [r for r in res["validity"] if r["t"] == 100.0]
    assert {r["orbit"] for r in rows} == {"R1", "C1"}
    for r in rows:
        assert max(r["extended_orbit"], r["extended_tangent"]) < 1e-15
        assert r["double_tangent"] > 1e-15


def test_tm_errors_follow_the_order_of_every_scheme(result):
    """Slope of the tangent and orbit errors at t = 100 through the three
    smallest τ above round-off: the scheme's order ± 0.3, for every
    registered scheme on both orbits."""
    res, _ = result
    tm = [r for r in res["slopes"] if r["family"] == "TM"]
    assert len(tm) == 2 * len(varint.schemes.registered(2))
    for r in tm:
        if r["expected_order"] >= 8 and r["points"] < 3:
            # The study's τ ladder reaches round-off within two points at
            # orders 8–10; tests/test_schemes.py measures those orders on
            # ladders of their own.
            continue
        assert r["points"] == 3, r
        assert abs(r["tangent_slope"] - r["expected_order"]) <= 0.3, r
        assert abs(r["orbit_slope"] - r["expected_order"]) <= 0.3, r


def test_orders_of_the_tdh_methods_and_the_baselines(result):
    """TDHcc and TDHes: O(τ) (freezing the Hessian); TDHeps with SBAB2C:
    O(τ⁴); DOP853 with one step per interval: O(τ⁸) or better; CVODE's
    error does not depend on τ."""
    res, _ = result
    by = {(r["orbit"], r["config"]): r for r in res["slopes"]}
    for orbit in ("R1", "C1"):
        for config, order in (("TDHcc", 1), ("TDHes", 1), ("TDHeps", 4)):
            assert abs(by[orbit, config]["tangent_slope"] - order) <= 0.3
        assert by[orbit, "DOP853 δ=1e-5"]["tangent_slope"] >= 7.7
        assert abs(by[orbit, "CVODE 1e-10"]["tangent_slope"]) < 0.5


def test_tdh_methods_level_off_and_the_level_grows_with_tau(result):
    res, _ = result
    rows = {(r["method"], r["tau"]): r for r in res["departure"]}
    for method, small, large in (("tdhcc", 0.1, 0.2), ("tdheps", 0.2, 0.4)):
        a, b = rows[method, small], rows[method, large]
        assert a["t_x1"] is not None and b["t_x1"] is not None
        assert 0 < a["level"] < b["level"]
        assert b["t_x1"] < a["t_x1"]  # a larger τ departs earlier
        # X1 at the horizon sits near the level, far above the regular
        # orbit's decay (X1 of R1 is ~6e-4 at t = 1e4).
        assert b["x1_end"] > 2e-3
    assert res["departure_reference_check"] < 1e-6


def test_tm_indicator_errors_are_small_against_the_reference(result):
    """At t = 100, τ = 0.05 on R1: relative X1 error and GALI error (in
    decades) of TM with ABA864 below 1e-7; the TDHcc ones above 1e-3."""
    res, _ = result
    last = {r["config"]: r for r in res["time"] if r["orbit"] == "R1" and r["t"] == 100.0}
    assert last["TM ABA864"]["X1_relative_error"] < 1e-7
    assert last["TM ABA864"]["gali_log10_error"] < 1e-7
    assert last["TDHcc"]["X1_relative_error"] > 1e-3
    assert last["TDHcc"]["gali_log10_error"] > 1e-3


def test_claims_and_files(result):
    res, out = result
    assert res["claims"] and all(c["holds"] is not False for c in res["claims"])
    for name in ("accuracy.claims.json", "accuracy_convergence.csv", "accuracy_time.csv",
                 "accuracy_departure.csv", "accuracy_convergence.png", "accuracy_time_R1.png",
                 "accuracy_departure.png", "accuracy_validity.png"):
        assert (out / name).exists(), name
    assert not (out / "accuracy.partial.json").exists()

"""The studies behind the accuracy verdict and the automatic step, in quick
mode: the automatic step's cost and the held-out stiff quartic
(default_step), verdicts against the energy error (energy_tolerance), and
the maps' pilot tolerance (map_defaults). Minutes each: slow."""

import pytest

from studies import default_step, energy_tolerance, map_defaults
from varint import stepsize
from varint.accuracy import DEFAULT_ENERGY_TOL

pytestmark = pytest.mark.slow


def test_default_step_quick(tmp_path):
    res = default_step.main(["--quick", "--out", str(tmp_path)])
    for row in res["costs"]:
        assert row["work_ratio_1000"] <= 1.5 and row["work_ratio_10000"] <= 1.5, row["orbit"]
    assert res["margin"]["largest"]["ratio"] < stepsize.PILOT_MARGIN
    auto, fixed = res["held_out"]["automatic"], res["held_out"]["tau=0.05"]
    # The defaults call the regular box orbit regular, without a warning;
    # tau = 0.05 calls it chaotic and warns.
    assert auto["sali"] > 1e-8 and auto["mean_megno"] == pytest.approx(2.0, abs=0.5)
    assert not auto["warned"] and auto["energy_error"] < DEFAULT_ENERGY_TOL
    assert fixed["sali"] < 1e-8 and fixed["warned"]
    # The automatic steps of higher-order schemes keep chaotic orbits' mean X1.
    assert max(abs(r["z"]) for r in res["chaotic_sea"]["rows"]) < 3
    assert (tmp_path / "default_step.claims.json").exists()


def test_energy_tolerance_quick(tmp_path):
    res = energy_tolerance.main(["--quick", "--out", str(tmp_path)])
    rows = [r for r in res["rows"] if not r["failed"]]
    kinds = ("x1_wrong", "sali_wrong", "megno_wrong", "fli_wrong")
    # The held-out case: SBAB2C at tau = 0.05 turns Q1 chaotic, with an
    # energy error far above the default tolerance.
    q1 = next(r for r in rows if (r["orbit"], r["scheme"], r["tau"]) == ("Q1", "SBAB2C", 0.05))
    assert all(q1[k] for k in kinds) and q1["energy_error"] > 100 * DEFAULT_ENERGY_TOL
    assert (tmp_path / "energy_tolerance.png").exists()


def test_map_defaults_quick(tmp_path):
    res = map_defaults.main(["--quick", "--out", str(tmp_path)])
    assert min(res["floor"].values()) >= 0.99  # two tight maps classify alike
    assert res["rows"][1]["note"] == "peer"  # heyoka's batch mode sets the bar too
    assert all(res["needed"][i] >= res["rows"][1][f"agree_{i}"] for i in res["needed"])
    piloted = {}
    for r in res["rows"][2:]:
        piloted.setdefault(r["scheme"], []).append(r)
    for scheme, (loose, tight) in piloted.items():
        # A tighter pilot tolerance gives a smaller step and classifies at
        # least as well.
        assert loose["tolerance"] > tight["tolerance"]
        assert tight["tau"] < loose["tau"], scheme
        assert tight["agree_min"] >= loose["agree_min"], scheme

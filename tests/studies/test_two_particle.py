"""The two-particle study in quick mode: its tables, the error laws in d0
it measures, and its claims in the report's format."""

import json

import pytest

from studies import two_particle as tp


@pytest.mark.slow  # references, then ~150 short runs: about 2 minutes
def test_quick_study(tmp_path):
    res = tp.main(["--quick", "--out", str(tmp_path)])
    for name in tp.ORBITS:
        law = res["laws"][(name, min(tp.TAUS[1]))]
        # The error from the curvature of the flow grows as d0; rounding
        # makes it grow again as d0 → 0; the best d0 lies between.
        assert law["curvature_slope"] == pytest.approx(1.0, abs=0.3)
        assert law["rounding_slope"] < -0.5
        assert 1e-10 <= law["best_d0"] <= 1e-5
    claims = json.loads((tmp_path / "two_particle.claims.json").read_text())
    assert any(c.get("source") == "paper" for c in claims)
    assert all({"claim", "paper", "ours", "holds"} <= set(c) for c in claims)
    for name in ("two_particle_error.csv", "two_particle_cost.csv", "two_particle.png",
                 "two_particle.json"):
        assert (tmp_path / name).exists()

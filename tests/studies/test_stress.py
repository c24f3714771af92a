"""The stress study's quick mode, and the claims that hold at its horizon."""

import numpy as np

from studies import stress


def test_stress_quick(tmp_path):
    res = stress.main(["--quick", "--out", str(tmp_path)])
    stab = {r["scheme"]: r["tau_max"] for r in res["stability"]}
    # Higher-order schemes with more force evaluations tolerate larger steps.
    assert stab["SBAB1"] < stab["SBAB2C"] < stab["ABA864"] < stab["SRKN14a"]
    assert 0.5 < stab["SBAB1"] < 2.0  # leapfrog: linear limit ωτ < 2, ω ≈ 1
    esc = {round(r["energy"], 6): r for r in res["escape"]}
    assert esc[0.2]["escaped_at"] is not None and "escaped" in esc[0.2]["message"]
    assert all(np.isfinite(r["X1"]) for r in res["escape"] if r["escaped_at"] is None)
    assert res["overflow"]["detected"] and 1e4 < res["overflow"]["t"] < 2e4
    assert res["overflow"]["partial_result_kept"]
    assert all(c["holds"] is not False for c in res["claims"])
    assert (tmp_path / "stress.claims.json").exists()
    assert (tmp_path / "stress_long_run.png").exists()

"""studies/lattices.py: the equal-error interpolation on an exact power
law, and the quick run, whose independent integrators (TM, DOP853,
heyoka's Taylor method) must agree on the mLCE and whose scheme ladders
must converge."""

import csv
import json
from itertools import pairwise

import numpy as np
import pytest

from studies import lattices


def test_time_at_equal_error_is_exact_for_power_laws():
    """err = c τ^p and time = k/τ: the time for a target error is
    k (target/c)^(−1/p), which log–log interpolation gives exactly."""
    taus = np.array([0.4, 0.2, 0.1, 0.05])
    c, p, k = 3.0, 4.0, 0.7
    errs, times = c * taus ** p, k / taus
    target = 1e-4
    assert lattices.time_at(errs, times, target) == pytest.approx(k * (target / c) ** (-1 / p),
                                                                  rel=1e-12)
    assert lattices.time_at(errs, times, 1e-9) is None        # outside the ladder


@pytest.mark.slow
def test_quick_run(tmp_path):
    out = lattices.main(["--quick", "--out", str(tmp_path)])
    rows = out["efficiency"]
    for case in ("fput", "kg", "ddnls", "ddnls2d"):
        sel = [r for r in rows if r["case"] == case]
        # The accurate runs of every method agree on X1 at the end.
        accurate = [r["x1"] for r in sel if r["energy_error"] < 1e-7]
        assert len(accurate) >= 2, case
        assert np.ptp(accurate) < 1e-3 * abs(np.median(accurate)), (case, accurate)
        # Halving τ lowers every scheme's energy error.
        for method in {r["method"] for r in sel if r["setting"].startswith("τ")}:
            errs = [r["energy_error"] for r in sel if r["method"] == method]
            assert all(a > b for a, b in pairwise(errs)), (case, method, errs)
    # The plain loop of the speed comparison is the same algorithm as varint's.
    plain = out["speed"][-1]
    assert plain["x1_plain"] == pytest.approx(plain["x1_varint"], rel=1e-10)
    methods = {r["method"] for r in rows if r["case"] == "kg"}
    assert {"DOP853", "Taylor (heyoka)", "ABA864"} <= methods
    with open(tmp_path / "lattices_laws.csv") as f:
        laws = list(csv.DictReader(f))
    assert [r["case"] for r in laws] == [c[0] for c in lattices.LAWS]
    assert all(float(r["max_energy_error"]) < 1e-4 for r in laws)
    claims = json.loads((tmp_path / "lattices_laws.claims.json").read_text())
    assert sum("∝ t^" in c["claim"] for c in claims) == 2 * len(lattices.LAWS)
    claims = json.loads((tmp_path / "lattices.claims.json").read_text())
    assert any(c["claim"].startswith("D19: the most efficient scheme for ddnls") for c in claims)


def test_exponent_rule_tells_neighbouring_laws_apart():
    from studies.claims import exponent_law

    assert exponent_law(-0.26, 0.01, -0.25, (1e3, 1e5)).holds is True
    assert exponent_law(-0.25, 0.01, -0.3, (1e3, 1e5)).holds is False    # weak vs strong
    assert exponent_law(0.32, 0.04, 1 / 3, (1e3, 1e5)).holds is True      # 2σ = 0.08 band
    assert exponent_law(0.0, 0.13, -0.25, (1e3, 1e5)).holds is None       # too few to tell
    assert exponent_law(float("nan"), 0.01, -0.25, (1e3, 1e5)).holds is None


def test_the_2d_run_part_runs_its_lattice_to_the_horizon(tmp_path):
    """``--part kg2d`` (quick: 20 × 20 to t = 100): the run reaches t_end
    with the energy conserved to ABA864's accuracy at τ = 0.05 and a
    finite-time mLCE of a weakly chaotic packet (0 < Λ ≪ 1)."""
    row = lattices.main(["--quick", "--part", "kg2d", "--out", str(tmp_path)])["kg2d"]
    assert row["sites"] == 400 and row["t_end"] == 100.0
    assert row["energy_error"] < 1e-7 and 0 < row["mlce"] < 0.1
    assert row["cpu_s"] > 0

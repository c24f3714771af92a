"""studies/bench_stepper.py in its quick mode: every target's row is
printed and written, with a measured (finite, positive) ratio."""

import csv

import numpy as np

from studies import bench_stepper


def test_quick_table(tmp_path, capsys):
    out = tmp_path / "stepper.csv"
    assert bench_stepper.main(["--quick", "--csv", str(out)]) == 0
    rows = list(csv.DictReader(out.open()))
    cases = [r["case"] for r in rows]
    assert any("orbit only" in c for c in cases) and any("1000 outputs" in c for c in cases)
    assert any("new process" in c for c in cases) and any("FLI map" in c for c in cases)
    ratios = np.array([float(r["ratio"]) for r in rows])
    assert np.isfinite(ratios).all() and (ratios > 0).all()
    assert "target" in capsys.readouterr().out

"""The bar's force-cost study's quick mode: its position sets are where
they say (inside the bar's ellipsoid, outside it), and every contender has
a time per evaluation on each set."""

import numpy as np

from studies import bar_force_cost
from varint.models.bar import SPA02


def test_position_sets_lie_inside_and_outside_the_bar():
    sets = bar_force_cost.positions(quick=True)
    m2 = {name: (Q ** 2 / np.array(SPA02["axes"]) ** 2).sum(1) for name, Q in sets.items()}
    assert (m2["inside"] < 1).all() and (m2["outside"] > 1).all()
    # The orbits: the regular one inside the bar throughout, the chaotic
    # one leaving it.
    assert 0.5 < (m2["orbits"] < 1).mean() < 1


def test_bar_force_cost_quick(tmp_path):
    rows = bar_force_cost.main(["--quick", "--out", str(tmp_path)])
    labels = {r["contender"] for r in rows}
    assert {"varint ferrers_grad_hess", "varint ferrers_kick", "varint model grad_hess_v"} <= labels
    assert {r["points"] for r in rows} == {"inside", "outside", "orbits"}
    assert all(r["ns_per_eval"] > 0 for r in rows)
    assert (tmp_path / "bar_force_cost_after.json").exists()

"""studies/map_steps.py: the bookkeeping that turns the race's timings into
ratios at equal agreement (the runs themselves take minutes)."""

import numpy as np
import pytest

from studies import map_steps


def test_each_varint_contender_meets_the_cheapest_heyoka_that_agrees_as_well():
    rows = [{"contender": "varint defaults", "seconds": 2.0, "agreement": 0.99},
            {"contender": "varint, tau='orbit'", "seconds": 1.0, "agreement": 0.98},
            {"contender": "heyoka batch 8, tol 1e-06", "seconds": 0.5, "agreement": 0.98},
            {"contender": "heyoka batch 8, tol 1e-08", "seconds": 0.8, "agreement": 0.995}]
    s = map_steps._equal_agreement(rows, "varint defaults")
    assert s["heyoka"] == "heyoka batch 8, tol 1e-08" and s["ratio"] == 0.4
    s = map_steps._equal_agreement(rows, "varint, tau='orbit'")
    assert s["heyoka"] == "heyoka batch 8, tol 1e-06" and s["ratio"] == 0.5
    assert s["heyoka_reaches"]
    s = map_steps._equal_agreement(rows[:1] + rows[2:3], "varint defaults")
    assert not s["heyoka_reaches"] and s["heyoka"] == "heyoka batch 8, tol 1e-06"


def test_the_small_core_potential_is_the_cored_logarithmic_one():
    """V = ½ ln(R_c² + x² + y²/q²): at the centre ln(R_c), on the x axis at
    r ≫ R_c ≈ ln r (flat rotation curve, v_c = 1)."""
    model = map_steps.cored_logarithmic()
    x = np.array([[0.0, 0.0, 0.0, 0.0], [0.5, 0.0, 0.0, 0.0], [0.0, 0.4, 0.0, 0.0]])
    e = model.energy(x)
    assert np.allclose(e, [np.log(0.03), 0.5 * np.log(0.03**2 + 0.25),
                           0.5 * np.log(0.03**2 + 0.16 / 0.64)], rtol=1e-14)


def test_a_map_that_calls_every_orbit_alike_cannot_judge():
    """The mix rule: a reference calling (nearly) every orbit chaotic or
    every one regular is refused, as is one with its FLIs on the fence."""
    rng = np.random.default_rng(0)
    threshold = 2 * np.log(1000.0)
    regular = rng.uniform(5.0, threshold - 2.0, 40)
    chaotic = rng.uniform(threshold + 2.0, 50.0, 36)
    assert map_steps.judging(np.r_[regular, chaotic], threshold)["ok"]
    for values in (chaotic, regular, np.r_[regular[:3], chaotic]):
        judged = map_steps.judging(values, threshold)
        assert not judged["ok"] and not 0.25 <= judged["chaotic"] <= 0.75
    fence = np.r_[regular, chaotic, threshold + rng.uniform(-1.0, 1.0, 8)]
    judged = map_steps.judging(fence, threshold)
    assert not judged["ok"] and judged["in_band"] > 0.05
    with pytest.raises(ValueError, match=r"calls 100\.0% of its orbits chaotic"):
        map_steps.require_judging("cr3bp", chaotic, threshold)


@pytest.mark.slow
@pytest.mark.parametrize("grid_of, judges", [(map_steps.race_map, True),
                                             (map_steps.case, False)])
def test_the_three_body_race_grid_can_judge_and_the_old_one_cannot(grid_of, judges):
    """The reference (heyoka, tol 1e-15) on the quick three-body grid: to
    t = 1000 (the race's) a real mix with a gap about the threshold; to
    t = 200 (the race of stop 47) the FLIs overlap the threshold and the
    race refuses it."""
    pytest.importorskip("heyoka")
    model, grid, t_end = grid_of("cr3bp", True)
    if judges:
        ref = map_steps.reference("cr3bp", model, grid.states, t_end)
        assert 0.25 <= ref["judging"]["chaotic"] <= 0.75
        assert ref["judging"]["in_band"] <= 0.05
    else:
        with pytest.raises(ValueError, match="cannot judge"):
            map_steps.reference("cr3bp", model, grid.states, t_end)

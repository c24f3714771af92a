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


def test_the_cored_race_grid_can_judge_and_the_old_one_cannot():
    """The reference (heyoka, tol 1e-15) on a 6 × 5 grid over the cored
    race's region, to its t_end: a mix (47 % chaotic when written) with no
    orbit within ±1.5 of 2 ln t; on the quick grid of the race before stop
    49 (the whole section to t = 200, 3.8 % chaotic) the race refuses to
    judge (a few seconds each)."""
    pytest.importorskip("heyoka")
    model = map_steps.cored_logarithmic()
    grid = map_steps.core_grid(model, (6, 5))
    ref = map_steps.reference("core", model, grid.states, map_steps.CORE_T_END)
    assert ref["threshold"] == 2 * np.log(map_steps.CORE_T_END)
    assert 0.25 <= ref["judging"]["chaotic"] <= 0.75
    assert ref["judging"]["in_band"] <= 0.05
    model, old, t_end = map_steps.case("core", True)
    with pytest.raises(ValueError, match=r"'core' cannot judge .* calls 3\.8% of its orbits"):
        map_steps.reference("core", model, old.states, t_end)


def test_a_radial_orbit_passes_through_the_centre_and_a_loop_orbit_does_not():
    """On the x axis (y = p_y = 0) the orbit oscillates through the centre:
    its closest approach is 0 to round-off. A loop orbit started at x = 0.5
    with p_x = 0 and p_y = 1 (angular momentum L = 0.5) keeps r ≥ L / v_max,
    v_max² = 2(E − ln R_c) (energy conservation bounds the speed)."""
    pytest.importorskip("heyoka")
    X = np.array([[0.5, 0.0, 0.0, 0.0], [0.5, 0.0, 0.0, 1.0]])
    closest = map_steps.closest_approach(X, 20.0)
    energy = map_steps.cored_logarithmic().energy(X[1:])[0]
    assert closest[0] < 1e-9
    assert 0.5 / np.sqrt(2 * (energy - np.log(map_steps.CORE_RADIUS))) <= closest[1] <= 0.5

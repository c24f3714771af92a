"""studies/map_steps.py: the bookkeeping that turns the race's timings into
ratios at equal agreement (the runs themselves take minutes)."""

import numpy as np

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

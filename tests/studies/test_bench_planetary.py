"""The planetary benchmark's rules (its verdict and agreement, its grid)
and the planetary laws study's helpers — never its timings; the quick runs
of both (and of the map-lanes study) are slow (they compile the planetary
steppers and heyoka's) and run with ``-m slow``."""

import numpy as np
import pytest

from studies import bench_planetary as bp
from studies import planetary as pl
from studies import planetary_map_lanes as pml


def test_a_failed_or_escaped_orbit_counts_as_chaotic():
    values = np.array([2.0, 3.9, 4.1, np.nan, 2.1])
    status = np.array([0, 0, 0, 0, 10])
    assert bp.chaotic(values, status).tolist() == [False, False, True, True, True]
    assert bp.chaotic(values).tolist() == [False, False, True, True, False]
    assert bp.agreement([True, False, True], [True, True, True]) == pytest.approx(2 / 3)


def test_grid_spans_the_tutorials_elements():
    model = bp.Planetary(bp.MASSES)
    g = bp.grid(model, 3)
    el = np.array([model.to_elements(x)[1] for x in g.states])
    assert np.allclose(el[:, 0], np.tile([7.0, 8.5, 10.0], 3))
    assert np.allclose(el[:, 1], np.repeat([0.0, 0.25, 0.5], 3), atol=1e-12)


def test_slope_is_a_power_law_fit():
    x = np.array([0.1, 0.2, 0.4])
    assert pl.slope(x, 3 * x ** 4) == pytest.approx(4.0)


@pytest.mark.slow
def test_quick_runs(tmp_path):
    result = bp.main(["--quick", "--out", str(tmp_path)])
    assert {row["code"] for row in result["rows"]} == {"varint", "varint, no early stopping",
                                                       "REBOUND"}
    laws = pl.main(["--quick", "--out", str(tmp_path)])
    assert laws["worst_tangent_vs_differences"] < 1e-8


def test_clopper_pearson_interval_follows_its_closed_forms():
    """k = n: the lower bound is (α/2)^(1/n); k = 0: the upper is
    1 − (α/2)^(1/n); and every interval contains k/n."""
    from studies.planetary_agreement import clopper_pearson

    assert clopper_pearson(128, 128) == pytest.approx((0.025 ** (1 / 128), 1.0), rel=1e-12)
    assert clopper_pearson(0, 50) == pytest.approx((0.0, 1 - 0.025 ** (1 / 50)), rel=1e-12)
    for k in (1, 60, 125):
        lo, hi = clopper_pearson(k, 128)
        assert lo < k / 128 < hi


@pytest.mark.slow
def test_quick_map_lanes_run_is_bitwise(tmp_path):
    result = pml.main(["--quick", "--out", str(tmp_path)])
    assert result["bitwise_equal"] == {"early stopping": True, "no early stopping": True}

"""The rules of studies/claims.py on series whose answer is known: a clean
1/t decay, a levelled series, one that departs from its law at a known
time, and numbers on either side of each tolerance."""

import math

import numpy as np
import pytest

from studies import claims as rules
from studies.laws import stretch_excess

T = np.geomspace(1.0, 1e8, 161)  # 20 points per decade, as the stored runs


def test_a_clean_inverse_t_falls_as_inverse_t_and_does_not_level():
    y = 3e-2 / T
    j = rules.inverse_t(T, y)
    assert j.holds and j.value == pytest.approx(-1.0, abs=1e-12)
    assert j.window == pytest.approx((1e6, 1e8))  # the last LATE_DECADES decades
    assert rules.levels_off(T, y).holds is False
    assert rules.grows(T, y).holds is False


def test_the_logarithm_of_a_regular_exponent_passes_once_ln_t_is_large():
    # X = (ln t + c)/t has local slope −1 + 1/(ln t + c): within 0.3 of −1
    # once ln t + c > 1/0.3 (the docstring of SLOPE_TOLERANCE).
    assert rules.inverse_t(T, (np.log(T) + 1.0) / T).holds
    # c = −3 over t = 1e2 … 1e3: ln t + c = 1.6 … 3.9, a slope of about −0.6.
    j = rules.inverse_t(T, (np.log(T) - 3.0) / T, window=(1e2, 1e3))
    assert j.holds is False and -0.7 < j.value < -0.5


def test_a_levelled_series_levels_off_at_its_level_with_its_spread():
    y = np.full_like(T, 7.4e-5)
    y[-5] = 9e-5  # one excursion: the median stays, the spread shows it
    j = rules.levels_off(T, y)
    assert j.holds and abs(j.value) < 0.05
    assert "level 7.4e-05 (7.4e-05–9e-05)" in j.text
    assert rules.inverse_t(T, y).holds is False
    # A series that reaches its level from a 1/t fall in the last decades
    # has not levelled over them.
    assert rules.levels_off(T, 1e-5 + 1e2 / T).holds is False


def test_the_level_band_and_the_inverse_t_band_do_not_overlap():
    for s in np.linspace(-1.5, 0.5, 41):
        y = T ** s
        assert not (rules.levels_off(T, y).holds and rules.inverse_t(T, y).holds), s
    assert rules.levels_off(T, T ** -0.29).holds and not rules.levels_off(T, T ** -0.31).holds
    assert rules.inverse_t(T, T ** -0.71).holds and not rules.inverse_t(T, T ** -0.69).holds


def test_growth():
    assert rules.grows(T, 1e-12 * T).holds
    assert rules.grows(T, 1e-8 * T ** 0.2).holds is False


def test_power_law_tolerance_scales_with_steep_powers():
    assert rules.power_tolerance(0) == rules.power_tolerance(-2) == pytest.approx(0.3)
    assert rules.power_tolerance(-16) == pytest.approx(2.4)
    assert rules.power_law(T, T ** -14.0, -16).holds
    assert rules.power_law(T, T ** -4.7, -4).holds is False
    j = rules.power_law(T, T ** -2.0, -2, window=(1e2, 1e4))
    assert j.holds and j.window == (1e2, 1e4)
    assert rules.power_law(T, T, 1, window=(1e9, 1e10)).holds is None  # no points


def test_power_law_by_decade_stops_at_a_floor():
    g = np.maximum(T ** -2.0, 1e-12)  # a floor from t = 1e6
    j = rules.power_law_decades(T, g, -2, 1e3)
    assert j.holds is False and j.value == pytest.approx(1e6)
    assert rules.power_law_decades(T, g, -2, 1e3, until=2e6).holds
    assert rules.power_law_decades(T, g, -2, 1e3, until=5e3).window is None


def test_a_departure_at_a_known_time():
    # Λ = ln t until 1e5, then a growth at rate 1e-3: the vector is a
    # decade (DEPARTURE_FACTOR) longer than the reference's from
    # t = 1e5 + ln(10)/1e-3.
    ref = np.log(T) / T
    x1 = (np.log(T) + 1e-3 * np.maximum(T - 1e5, 0.0)) / T
    t, excess = stretch_excess(T, x1, T, ref)
    j = rules.departure(t, excess)
    expected = 1e5 + math.log(rules.DEPARTURE_FACTOR) / 1e-3
    assert j.holds and j.value == pytest.approx(expected, rel=0.13)  # the output grid
    assert rules.departure(*stretch_excess(T, ref, T, ref)).holds is False
    # An excursion that comes back does not count.
    bump = np.where((T > 1e3) & (T < 1e4), 5.0, 0.0)
    assert rules.departure(T, bump).value is None


def test_ratio_rules_at_their_edges():
    f = rules.RATIO_FACTOR
    assert rules.agrees(2.9e-5, 1e-5).holds and not rules.agrees(3.1e-5, 1e-5).holds
    assert rules.agrees(1e-5 / 2.9, 1e-5).holds and not rules.agrees(-1e-5, 1e-5).holds
    assert rules.agrees(None, 1.0).holds is None
    assert rules.at_most(2.9e-7, 1e-7).holds and not rules.at_most(3.1e-7, 1e-7).holds
    assert rules.above(3.1, 1.0).holds and not rules.above(2.9, 1.0).holds
    assert f == rules.ABOVE_FACTOR  # "above" starts where "agrees" ends
    assert rules.in_band(2e-8, 1.8e-8, 1.3e-7).holds
    assert not rules.in_band(5e-7, 1.8e-8, 1.3e-7).holds
    assert not rules.in_band(5e-9, 1.8e-8, 1.3e-7).holds


def test_times_read_off_a_plot():
    assert rules.same_time([3.5e3, 4.7e3], 1e4, 1e8).holds
    assert not rules.same_time([3e2], 1e4, 1e8).holds
    assert rules.same_time([None], 1e5, 1e4).holds is None  # the run ends too early
    assert rules.same_time([None], 1e5, 1e8).holds is False


def test_costs_and_rates():
    assert rules.costs_more(1.21, 1.0).holds and not rules.costs_more(1.05, 1.0).holds
    assert rules.same_cost(1.01, 1.0).holds and not rules.same_cost(2.2, 1.0).holds
    assert rules.rate_law(0.0524, 0.0462, (130, 571)).holds
    assert not rules.rate_law(0.06, 0.0462, (130, 571)).holds


def test_verdict_and_records():
    yes, no = rules.agrees(1.0, 1.0), rules.agrees(10.0, 1.0)
    unknown = rules.agrees(None, 1.0)
    assert rules.verdict([yes, yes]) is True
    assert rules.verdict([yes, no, unknown]) is False
    assert rules.verdict([yes, unknown]) is None and rules.verdict([]) is None
    rec = rules.levels_off(T, np.ones_like(T)).record()
    assert rec["rule"] == "levels_off" and rec["window"] == pytest.approx([1e6, 1e8])
    assert set(rules.RULES) >= {"agrees", "above", "levels_off", "inverse_t", "departure"}


def test_a_verdict_on_its_threshold_is_stated_with_its_margin(tmp_path):
    """A ratio of 3.24 against the factor 3 differs, but by 8 %: the claim's
    note says so; at 2 (a third inside) nothing is added. A CPU ratio of
    1.108 against 1.10 holds by 0.7 %."""
    from studies.common import Claims

    near, far = rules.agrees(3.24e-5, 1e-5), rules.agrees(2e-5, 1e-5)
    assert near.holds is False and abs(near.edge - 1.08) < 1e-12 and "8.0 %" in near.margin()
    assert far.margin() == ""
    cpu = rules.costs_more(1.108, 1.0)
    assert cpu.holds and "0.7 %" in cpu.margin()
    claims = Claims("t", tmp_path)
    claims.add("c", "1e-5", "3.24e-5", near.holds, note="why", rules=[near])
    claims.add("d", "1e-5", "2e-5", far.holds, rules=[far])
    assert claims.items[0]["note"].startswith("why; agrees sits on its threshold")
    assert claims.items[1]["note"] == "" and claims.items[0]["rules"][0]["edge"] == near.edge

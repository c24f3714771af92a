"""The helpers that read the paper's laws off time series, on series whose
law is known in closed form."""

import numpy as np
import pytest

from studies import laws


def test_slope_of_a_power_law():
    t = np.geomspace(1.0, 1e6, 61)
    assert laws.slope(t, 3.0 * t ** -2.5, 10.0, 1e5) == pytest.approx(-2.5, abs=1e-12)
    # Negative values count by their size (X2 may change sign).
    assert laws.late_slope(t, -t ** -1.0, decades=2) == pytest.approx(-1.0, abs=1e-12)


def test_decay_rate_stops_at_the_round_off_floor():
    t = np.linspace(0.0, 2000.0, 401)
    g = np.maximum(np.exp(-0.045 * t), 1e-16)  # saturates as GALIs do
    rate, (a, b) = laws.decay_rate(t, g)
    assert rate == pytest.approx(0.045, rel=1e-10)
    assert np.exp(-0.045 * a) < 1e-2 and np.exp(-0.045 * b) > 1e-12


def test_roundoff_time_finds_where_a_gali_meets_its_floor():
    # GALI_4 of an orbit on a 2-torus: two vanishing singular values, each
    # ∝ 1/t², each floored at √(t/τ)·ε (R1 with TM: GALI_4 ≈ 1e-24 at 1e8).
    tau, eps = 0.05, np.finfo(float).eps
    t = np.geomspace(1.0, 1e8, 161)
    floor = (np.sqrt(t / tau) * eps) ** 2
    g = np.maximum(1e-2 * t ** -4.0, floor)
    hit = laws.roundoff_time(t, g, 2, tau, 10.0)
    assert hit == t[np.flatnonzero(1e-2 * t ** -4.0 <= 10 * floor)[0]]
    assert 1e5 < hit < 1e6
    assert laws.roundoff_time(t, 1e-2 * t ** -4.0, 2, tau, 1e-30) is None
    assert laws.roundoff_time(t, np.ones_like(t), 0, tau, 10.0) is None  # nothing vanishes


def test_local_exponents_and_the_gali_law():
    # Λ_i = σ_i t exactly: the local rates are the σ_i over any window.
    t = np.linspace(1.0, 1000.0, 500)
    sigma = np.array([0.05, 0.01, -0.01, -0.05])
    assert laws.local_exponents(t, np.tile(sigma, (t.size, 1)), (100.0, 600.0)) == \
        pytest.approx(sigma)


def test_x1_law_excess():
    # Regular (Λ = ln t + 1) until 1e6, then exponential growth at 1e-5:
    # the excess over the fitted linear-growth law is that growth.
    t = np.geomspace(1.0, 1e8, 161)
    lam = np.log(t) + 1.0 + 1e-5 * np.maximum(t - 1e6, 0.0)
    assert laws.x1_law_excess(t, lam / t) == pytest.approx(1e-5 * np.maximum(t - 1e6, 0.0),
                                                          abs=1e-9)


def test_stretch_excess_and_growth_after():
    # Reference: regular, Λ = ln t. Method: Λ = ln t + L·t, L = 1e-3.
    t = np.geomspace(1.0, 1e6, 121)
    ref = np.log(t) / t
    tt, excess = laws.stretch_excess(t, ref + 1e-3, t, ref)
    assert excess == pytest.approx(1e-3 * tt, rel=1e-9)
    # Its vector grows at rate L after any time: X1 levels off there.
    assert laws.growth_after(t, ref + 1e-3, 1e4) == pytest.approx(1e-3, rel=0.01)
    assert laws.growth_after(t, ref + 1e-3, 8e5) is None  # the run ends before 2·t_d
    assert laws.growth_after(t, ref, None) is None
    # Only the times within the reference's horizon.
    assert laws.stretch_excess(t, ref, t[:61], ref[:61])[0][-1] == t[60]


def test_gali_and_law_deficits():
    t = np.geomspace(1.0, 1e7, 141)
    law = t ** -2.0
    g = law * np.exp(-np.maximum(t - 1e5, 0.0) * 1e-5)  # leaves the law after 1e5
    tt, deficit = laws.gali_deficit(t, g, t, law)
    assert deficit == pytest.approx(np.maximum(tt - 1e5, 0.0) * 1e-5, abs=1e-9)
    assert laws.law_deficit(t, g, -2.0) == pytest.approx(deficit, abs=1e-9)
    assert laws.law_deficit(t, 5 * law, -2.0) == pytest.approx(0.0, abs=1e-9)


def test_regular_gali_powers():
    # Eq. 15 of the paper for an N-torus of an N-dof system.
    assert laws.regular_gali_powers(2) == {2: 0, 3: -2, 4: -4}
    assert laws.regular_gali_powers(3) == {2: 0, 3: 0, 4: -2, 5: -4, 6: -6}
    # Skokos, Bountis & Antonopoulos (2008), s-torus in N dof: the FPU orbit R3.
    p = laws.regular_gali_powers(8, 4)
    assert [p[k] for k in (2, 3, 4, 5, 8, 9, 12, 13, 14, 16)] == \
        [0, 0, 0, -1, -4, -5, -8, -10, -12, -16]


def test_log_growth_of_linearly_growing_vectors():
    t = np.geomspace(1.0, 1e8, 161)
    assert laws.log_growth(t, (np.log(t) + 3.0) / t) == pytest.approx(1.0, abs=1e-9)
    assert laws.log_growth(t, -(np.log(t) - 2.0) / t) == pytest.approx(-1.0, abs=1e-9)
    assert laws.log_growth(t, (np.log(t) + 1e-4 * t) / t) > 100  # exponential growth


def test_decade_slopes():
    t = np.geomspace(1.0, 1e8, 161)
    g = np.maximum(t ** -2.0, 1e-12)  # a round-off floor from t = 1e6
    slopes = laws.decade_slopes(t, g, 1e3)
    assert [lo for lo, *_ in slopes] == pytest.approx([1e3, 1e4, 1e5, 1e6, 1e7])
    assert [s for *_, s in slopes] == pytest.approx([-2.0, -2.0, -2.0, 0.0, 0.0], abs=1e-9)

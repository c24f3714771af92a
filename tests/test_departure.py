"""varint.departure: the criterion on curves whose answer is known, and the
cases the paper settles (TM never departs; the TDH methods do, earlier for
larger τ, and level off at the paper's value)."""

import math

import numpy as np
import pytest

import varint
from varint.departure import departure, departure_time
from varint.run import Run

LN10 = math.log(10.0)


def test_departure_time_of_an_exponential_growth():
    """Λ − Λ_ref = L·t exceeds ln 10 from t = ln 10 / L on."""
    t = np.logspace(0, 5, 201)
    L = 1e-3
    expected = t[np.argmax(L * t > LN10)]
    assert departure_time(t, L * t, LN10) == expected
    assert abs(expected / (LN10 / L) - 1) < 10 ** (5 / 200) - 1


def test_departure_time_ignores_excursions_that_come_back():
    t = np.arange(1.0, 11.0)
    excess = np.array([0, 3, 3, 0, 0, 3, 3, 3, 3, 3], dtype=float)
    assert departure_time(t, excess, LN10) == 6.0
    assert departure_time(t, excess[::-1], LN10) is None
    assert departure_time(t, np.full(10, 5.0), LN10) == 1.0
    excess[7] = np.nan  # a failed output is not "above"
    assert departure_time(t, excess, LN10) == 9.0


def test_departure_time_checks_shapes():
    with pytest.raises(ValueError, match="same length"):
        departure_time([1.0, 2.0], [1.0], LN10)


def test_tm_never_departs(r1):
    """TM with SBAB2C against TM with ABA864: X1 and every GALI follow the
    reference to t = 1e5 (the TDH methods depart before 1e4 at this τ)."""
    model, x0 = r1
    d = departure(model, x0, "tm", 0.05, 1e5)
    assert d.t_x1 is None and d.level is None
    assert d.t_gali == {2: None, 3: None, 4: None}
    assert -1.2 < d.reference_slope < -0.7      # X1 ∝ ln t / t (measured −0.88)
    assert np.max(np.abs(d.x1 - d.x1_reference) * d.t) < 1.0


@pytest.fixture(scope="module")
def tdhcc_departures():
    model, x0 = varint.paper_orbit("R1")
    return {tau: departure(model, x0, "tdhcc", tau, 2e4) for tau in (0.2, 0.05)}


def test_tdhcc_departs_earlier_for_larger_tau(tdhcc_departures):
    big, small = tdhcc_departures[0.2], tdhcc_departures[0.05]
    # Measured: X1 at 1.8e3 and 6.4e3; GALIs at (1.3, 1.1, 0.9)e3 and
    # (5.7, 3.2, 3.2)e3 — the paper's Fig. 4 has them follow the laws to ~1e4.
    assert big.t_x1 < small.t_x1 / 2 < 1e4
    for k in (2, 3, 4):
        assert big.t_gali[k] < small.t_gali[k] / 2
    assert big.level > 2 * small.level


def test_tdhcc_levels_off_at_the_papers_value(tdhcc_departures):
    """Table I: TDHcc, τ = 0.05, X1 = 9.4e-4 at t = 1e8 (measured here from
    the growth after departure: 9.5e-4)."""
    d = tdhcc_departures[0.05]
    assert abs(d.level / 9.4e-4 - 1) < 0.1
    # After departure the vectors grow like e^{level·t}: X1 tends to level.
    assert abs(d.x1_end / d.level - 1) < 0.2


def test_input_is_checked(r1):
    model, x0 = r1
    with pytest.raises(ValueError, match="one state"):
        departure(model, np.stack([x0, x0]), "tdhcc", 0.05, 100.0)
    with pytest.raises(ValueError, match="reference"):
        departure(model, x0, "tdhcc", 0.05, 100.0, reference={"scheme": "ABA864"})
    with pytest.raises(ValueError, match="threshold"):
        departure(model, x0, "tdhcc", 0.05, 100.0, threshold=0.0)


def test_every_run_is_checked_before_any_runs(r1, monkeypatch):
    # An option the reference's method does not take, or a GALI order out
    # of range, is refused before the method under test has run.
    model, x0 = r1
    ran = []
    monkeypatch.setattr(Run, "execute", lambda self: ran.append(self.method))
    with pytest.raises(TypeError, match="rtol"):
        departure(model, x0, "tdhcc", 0.05, 100.0, reference={"method": "tm", "rtol": 1e-9})
    with pytest.raises(ValueError, match="GALI order"):
        departure(model, x0, "tdhcc", 0.05, 100.0, gali_orders=(2, 9))
    assert ran == []


def test_a_chaotic_reference_is_flagged(c1):
    model, x0 = c1
    with pytest.warns(RuntimeWarning, match="may not be regular"):
        departure(model, x0, "tdhcc", 0.05, 2e3, gali_orders=())

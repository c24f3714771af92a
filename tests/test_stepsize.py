"""The automatic step (varint.stepsize): the largest rung of the ladder whose
pilot meets the tolerance, recorded in the provenance; on the paper's five
orbits it costs at most 1.5 times SBAB2C at τ = 0.05, pilot included; given
steps are used as they are; orbits no step can fix fall back with a
warning."""

import math
import warnings

import numpy as np
import pytest
import sympy as sp

import varint
from varint import stepsize
from varint.accuracy import AccuracyWarning
from varint.models import from_potential
from varint.run import prepare


def _gradients_per_step(scheme):
    model, x0 = varint.paper_orbit("R1")
    r = varint.integrate(model, x0, 1.0, tau=0.05, scheme=scheme)
    return r.provenance.counts["gradient"] / r.provenance.counts["steps"]


@pytest.mark.parametrize("name", ["R1", "C1", "C2", "R2", "R3"])
def test_the_automatic_step_costs_at_most_one_and_a_half_times_tau_005(name):
    """Cost in force evaluations of a Lyapunov spectrum to t = 1e4 (the
    pilot's evaluations included) against SBAB2C at τ = 0.05."""
    model, x0 = varint.paper_orbit(name)
    t_end = 1e4
    job = prepare(model, x0, "lyapunov", t_end)
    choice = job.tau_choice
    # The run's own default scheme: SBAB2C, or a lattice's (R3 is an FPU
    # chain: ABA864).
    scheme = varint.schemes.default_for(model, "tm")
    assert choice["rule"] == "pilot" and choice["scheme"] == scheme
    auto = (choice["counts"]["gradient"]
            + round(t_end / job.tau) * _gradients_per_step(scheme))
    fixed = round(t_end / 0.05) * _gradients_per_step("SBAB2C")
    assert auto / fixed <= 1.5
    # The pilot met the tolerance at the chosen rung, and missed it at the
    # rung above (the largest step that meets it).
    tried = dict((round(t, 12), e) for t, e in choice["tried"])
    rung = max(t for t, e in tried.items() if e <= choice["tolerance"])
    assert job.tau <= rung and job.tau == pytest.approx(rung, rel=0.01)
    above = round(rung * 2 ** 0.25, 12)
    assert above > 1.0 or tried[above] > choice["tolerance"]
    # t_end is a whole number of steps.
    assert t_end / job.tau == pytest.approx(round(t_end / job.tau), abs=1e-9)


def test_the_choice_is_in_the_provenance_and_deterministic():
    model, x0 = varint.paper_orbit("C1")
    a = varint.sali(model, x0, 500.0)
    b = varint.sali(model, x0, 500.0)
    assert a.provenance.tau == b.provenance.tau
    assert a.provenance.tau_choice["tried"] == b.provenance.tau_choice["tried"]
    assert a.sali.tobytes() == b.sali.tobytes()
    tol = a.provenance.tau_choice["tolerance"]
    assert tol == varint.accuracy.DEFAULT_ENERGY_TOL / stepsize.PILOT_MARGIN
    # A tighter energy_tol gives a smaller step.
    tight = varint.sali(model, x0, 500.0, energy_tol=1e-6)
    assert tight.provenance.tau < a.provenance.tau


def test_a_given_step_is_used_as_it_is():
    model, x0 = varint.paper_orbit("R1")
    r = varint.lyapunov_spectrum(model, x0, 100.0, tau=0.05)
    assert r.provenance.tau == 0.05 and r.provenance.tau_choice == {"rule": "given"}


def test_the_step_respects_the_first_output_time_and_short_runs():
    model, x0 = varint.paper_orbit("R1")
    r = varint.lyapunov_spectrum(model, x0, 10.0, t_out=[0.04, 1.0, 10.0])
    assert r.provenance.tau <= 0.04 and r.t[0] == pytest.approx(0.04, rel=1e-9)
    short = varint.integrate(model, x0, 0.03)
    assert short.provenance.tau <= 0.03 and short.t[-1] == pytest.approx(0.03)


def test_methods_whose_tau_is_not_a_step_keep_005():
    model, x0 = varint.paper_orbit("R1")
    job = prepare(model, x0, "sali", 10.0, method="cvode")
    assert job.tau == 0.05 and job.tau_choice["rule"] == "fixed"


def test_no_step_fixes_an_orbit_through_a_singularity_so_it_falls_back_with_a_warning():
    x, y = sp.symbols("x y")
    model = from_potential(1 / x + y**2 / 2, [x, y], name="1/x")
    with pytest.warns(AccuracyWarning) as record:
        r = varint.lyapunov_spectrum(model, [-1.0, 0.1, 0.0, 0.0], 100.0)
    first = str(record[0].message)
    assert "does not shrink with the step" in first and "running with tau = 0.05" in first
    assert r.provenance.tau == 0.05 and r.provenance.tau_choice["rule"] == "fallback"
    # The run itself then reports what happened: an energy error of ~60.
    assert any("relative energy error" in str(w.message) for w in record[1:])


def test_escaping_orbits_count_up_to_their_escape():
    """Hénon–Heiles above the escape energy with an escape radius: the
    pilot measures the orbit until it leaves, and the run then fails as
    escaped, as with a given step."""
    model = varint.models.HenonHeiles(escape_radius=5.0)
    x0 = varint.solve_momentum(model, [0.0, 0.0], [0.0, 0.2], 0.25)
    with pytest.raises(varint.IntegrationError, match="escaped"):
        varint.gali(model, x0, 100.0)
    job = prepare(model, x0, "gali", 100.0)
    assert job.tau_choice["rule"] == "pilot"


def test_maps_choose_their_step_from_a_sample_with_the_map_defaults():
    from varint.maps import MAP_PILOT_TOL, MAP_SCHEME, pilot_tolerance

    model = varint.models.HenonHeiles()
    grid = varint.section_grid(model, 0.125, np.linspace(-0.4, 0.6, 8), np.linspace(-0.4, 0.4, 8))
    with warnings.catch_warnings():
        warnings.simplefilter("error", AccuracyWarning)
        r = varint.chaos_map(model, grid, "sali", t_end=100.0, progress=False)
    choice = r.provenance.tau_choice
    # SALI declares a tighter pilot tolerance than the maps' default.
    assert choice["rule"] == "pilot" and choice["tolerance"] == 1e-8 < MAP_PILOT_TOL
    assert pilot_tolerance(varint.indicators.resolve("sali")[0]) == 1e-8
    assert pilot_tolerance(varint.indicators.resolve("fli")[0]) == MAP_PILOT_TOL
    assert choice["scheme"] == r.provenance.method_options["scheme"]["name"] == MAP_SCHEME
    assert choice["orbits"] == min(len(grid), stepsize.PILOT_ORBITS)
    assert choice["quantile"] == 0.9
    # With a given step the scheme stays the run's default.
    fixed = varint.chaos_map(model, grid, "sali", t_end=100.0, tau=0.05, progress=False)
    assert fixed.provenance.method_options["scheme"]["name"] == "SBAB2C"
    assert fixed.provenance.tau_choice == {"rule": "given"}


def test_the_ladder_search_finds_the_largest_passing_rung(monkeypatch):
    """On a fake error law e(τ) = τ⁴ the search ends on the largest rung with
    τ⁴ ≤ tol, having climbed back from its prediction."""
    calls = []

    def fake(model, X, tau, t_end, scheme, reference, quantile, counts, setup, build):
        calls.append(tau)
        return tau ** 4

    monkeypatch.setattr(stepsize, "_pilot", fake)
    model, x0 = varint.paper_orbit("R1")
    tau, info = stepsize.choose_step(model, x0[None], 1e4, 1e-4)
    best = 2.0 ** (-14 / 4)  # (2^(j/4))^4 <= 1e-4 for j <= -13.3
    assert tau == pytest.approx(1e4 / math.ceil(1e4 / best), rel=1e-12)
    # τ = 1 misses by 1e4: the order predicts 14 rungs down, which meets the
    # tolerance; one rung up misses it.
    assert calls == [1.0, best, 2.0 ** (-13 / 4)]
    assert info["rule"] == "pilot"


def test_options_are_checked_before_the_pilot_naming_the_methods_that_take_them(monkeypatch):
    """A misspelt or misplaced option fails before any pilot runs; a method
    without a pilot keeps its own message."""
    def no_pilot(*args):
        raise AssertionError("the pilot ran")

    monkeypatch.setattr(stepsize, "_pilot", no_pilot)
    model, x0 = varint.paper_orbit("R1")
    with pytest.raises(TypeError, match=r"unknown option 'rtol' for method 'tm'; valid "
                                        r"options: .*\('rtol' is an option of .*cvode"):
        varint.sali(model, x0, 10.0, rtol=1e-9)
    with pytest.raises(ValueError, match="method 'taylor' takes no scheme"):
        varint.sali(model, x0, 10.0, method="taylor", scheme="ABA864")


@pytest.mark.parametrize("scheme", ["s15odr8", "s17odr8", "s35odr10"])
def test_the_orders_8_and_10_get_an_automatic_step_that_meets_the_tolerance(scheme,
                                                                            monkeypatch):
    """The pilot's ladder predicts the next rung from the scheme's order, so
    the new orders need nothing of their own: on R1 their step is the
    largest rung (≤ TAU_MAX) whose pilot met energy_tol / PILOT_MARGIN, and
    the run's energy error stays below energy_tol. The law concerns the
    orbit's step alone, so the run carries no deviation vectors (their
    kernels cost three to four times the orbit's to compile), and it runs
    on the generic stepper, which takes the scheme as data: one kernel for
    the three schemes instead of one generated per scheme (s35odr10's
    alone took 12 s to compile); the two steppers differ by round-off."""
    from varint.methods import tm

    monkeypatch.setattr(tm, "symbolic_fits", lambda model, k: False)
    model, x0 = varint.paper_orbit("R1")
    r = varint.integrate(model, x0, 200.0, scheme=scheme)
    choice = r.provenance.tau_choice
    assert choice["rule"] == "pilot" and choice["scheme"] == scheme
    assert 0.5 < choice["tau"] <= stepsize.TAU_MAX
    passing = [e for t, e in choice["tried"] if t >= choice["tau"] * (1 - 1e-12)
               and e <= choice["tolerance"]]
    assert passing, choice["tried"]
    assert r.energy_error.max() <= choice["tolerance"] * stepsize.PILOT_MARGIN

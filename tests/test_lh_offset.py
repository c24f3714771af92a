"""The offset δ of the logarithmic Hamiltonian chosen by the map's pilot
(varint.time_transform_step.agreeing_offset): on a potential with a deep,
near-singular core the pilot prices a δ below the rule's cheaper (the
physical step h/(T + δ) varies by (T_max + δ)/δ along an orbit, and the
core needs that variation), and held-out orbits at the chosen (δ, h) cost
fewer force evaluations than at the rule's with the reference's verdicts;
on Hénon–Heiles (no deep centre) it keeps the rule; a rotating frame is
not priced; the map at the chosen δ is the explicit map at (δ, h) bit for
bit; a given offset is kept; bad offsets are refused in one line."""

import math
import warnings

import numpy as np
import pytest
import sympy as sp

import varint
from varint.accuracy import DEFAULT_ENERGY_TOL, Reference
from varint.maps import MAP_QUANTILE
from varint.models import from_potential
from varint.models.cr3bp import CR3BP, SUN_JUPITER_MU
from varint.state import initial_deviations
from varint.step_agreement import same_verdict
from varint.time_transform import LogHamiltonian
from varint.time_transform_step import RETRY_CEILING, agreeing_h, agreeing_offset, retried

T_END = 100.0
PILOT = {"quantile": MAP_QUANTILE, "ceiling": RETRY_CEILING * DEFAULT_ENERGY_TOL,
         "retry": DEFAULT_ENERGY_TOL}


@pytest.fixture(scope="module")
def core():
    """The cored logarithmic potential of studies/map_steps.py (R_c = 0.03,
    q = 0.8): its box orbits pass through the near-singular centre."""
    x, y = sp.symbols("x y")
    return from_potential(sp.log(sp.Float(0.03)**2 + x**2 + y**2 / sp.Float(0.8)**2) / 2,
                          [x, y], name="cored logarithmic")


def _core_orbits(model, n, lo=-0.9, hi=0.9):
    """Orbits on the section y = 0, p_y ≥ 0 at E = 0 (the rule's δ is 1)."""
    return varint.section_grid(model, 0.0, np.linspace(lo, hi, n), np.linspace(lo, hi, n),
                               plane=1).states


def test_a_deep_core_takes_a_smaller_offset_and_held_out_orbits_cost_less(core):
    """Pilot on one grid, held-out orbits on another: the chosen δ is below
    the rule's (1 at E = 0) and priced cheaper than it; the held-out orbits
    at (δ, h), each retried to energy_tol as the map runs them, take fewer
    force evaluations than at the rule's δ and its own h, and keep the
    verdicts of the tight reference (the rule at h/16) on ≥ 90 % of them."""
    pilot, held = _core_orbits(core, 6), _core_orbits(core, 5, -0.85, 0.85)
    lh = LogHamiltonian(core, "ABA864")
    chosen, h, choice = agreeing_offset(lh, pilot, T_END, **PILOT)
    assert choice["offset"] is not None and choice["offset"] < 1.0
    assert chosen.offset == choice["offset"] and lh.offset is None
    prices = {d: p for d, _, p in choice["offsets"]}
    assert prices[choice["offset"]] < prices[None]
    assert "offset δ = " in choice["offset_summary"] and choice["offset_pricing"] > 0
    h_rule, _ = agreeing_h(lh, pilot, T_END, **PILOT)
    W0 = initial_deviations(core.dim, 1, len(held), 0)[:, :, 0]
    ref = Reference(core, held)
    at_offset, _ = retried(chosen, held, W0, T_END, h, DEFAULT_ENERGY_TOL, ref)
    at_rule, _ = retried(lh, held, W0, T_END, h_rule, DEFAULT_ENERGY_TOL, ref)
    assert at_offset.counts[:, 2].sum() < at_rule.counts[:, 2].sum()
    reference = lh.outputs(held, W0, T_END, h_rule / 16).fli
    assert np.isfinite(reference).all()
    assert same_verdict(at_offset.fli, reference, T_END).mean() >= MAP_QUANTILE


def test_henon_heiles_keeps_the_rule_and_a_rotating_frame_is_not_priced():
    """Hénon–Heiles (no deep centre: adapting the step only costs) keeps
    δ = max(−E, 1), the next δ priced no cheaper; the three-body problem's
    A takes both signs, so its δ is the rule's, unpriced."""
    hh = varint.models.HenonHeiles()
    X = varint.section_grid(hh, 0.125, np.linspace(-0.4, 0.65, 5),
                            np.linspace(-0.4, 0.4, 4)).states
    _, _, choice = agreeing_offset(LogHamiltonian(hh, "ABA864"), X, T_END, **PILOT)
    assert choice["offset"] is None and choice["offsets"][0][0] is None
    assert len(choice["offsets"]) >= 2 and choice["offsets"][1][2] >= choice["offsets"][0][2]
    model = CR3BP(SUN_JUPITER_MU)
    X = model.section_grid(3.05, np.linspace(0.3, 0.85, 3), np.linspace(-0.3, 0.3, 2)).states
    lh = LogHamiltonian(model, "ABA864")
    assert not lh.kinetic
    _, h, choice = agreeing_offset(lh, X, 20.0, **PILOT)
    assert choice["offset"] is None and choice["offsets"] == [] and choice["offset_pricing"] == 0
    assert "not priced" in choice["offset_summary"]


def test_the_map_at_the_chosen_offset_is_the_explicit_map_there(core):
    """The map with an automatic h and δ: its provenance and verdict name
    δ; on every orbit not retried its values are, bit for bit, the explicit
    map's at tau = h and offset = δ; a given offset is kept, not priced."""
    X = _core_orbits(core, 5, -0.85, 0.85)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = varint.chaos_map(core, X, "fli", t_end=50.0, progress=False, time_transform="log")
        choice = r.provenance.tau_choice
        assert choice["offset"] is not None
        assert r.provenance.method_options["offset"] == choice["offset"]
        assert r.accuracy.notes["offset"] == choice["offset_summary"]
        explicit = varint.chaos_map(core, X, "fli", t_end=50.0, progress=False,
                                    time_transform="log", tau=choice["h"],
                                    offset=choice["offset"])
        given = varint.chaos_map(core, X, "fli", t_end=50.0, progress=False,
                                 time_transform="log", offset=0.5)
    kept = np.asarray(choice["levels"]) == 0
    assert kept.any()
    assert np.array_equal(r.values[kept], explicit.values[kept], equal_nan=True)
    g = given.provenance.tau_choice
    assert g["offset"] == 0.5 and g["offsets"] == [] and g["offset_pricing"] == 0
    assert given.provenance.method_options["offset"] == 0.5
    assert given.accuracy.notes["offset"] == "offset δ = 0.5 as given"


@pytest.mark.parametrize("bad", [0, -1.0, math.nan, math.inf, "0.5", True])
def test_bad_offsets_are_refused_in_one_line(core, bad):
    """Before any work: the map, the stepper and with_offset name the value."""
    X = _core_orbits(core, 3)
    with pytest.raises(ValueError, match=r"offset must be a finite number > 0, got "):
        varint.chaos_map(core, X, "fli", t_end=10.0, progress=False, time_transform="log",
                         offset=bad)
    with pytest.raises(ValueError, match=r"offset must be a finite number > 0, got "):
        LogHamiltonian(core, "ABA864").with_offset(bad)


def test_with_offset_is_a_fresh_stepper_at_that_offset(core):
    """with_offset shares the kernels and gives the bits of a stepper built
    at that offset; the original keeps its own."""
    X = _core_orbits(core, 3)
    W0 = initial_deviations(core.dim, 1, len(X), 0)[:, :, 0]
    lh = LogHamiltonian(core, "ABA864")
    other = lh.with_offset(0.25)
    a = other.outputs(X, W0, 20.0, 0.05)
    b = LogHamiltonian(core, "ABA864", offset=0.25).outputs(X, W0, 20.0, 0.05)
    assert np.array_equal(a.fli, b.fli) and np.array_equal(a.x, b.x)
    assert lh.offset is None and other.offset == 0.25
    assert np.array_equal(other.constants(X), lh.energy(X) + 0.25)
    assert np.array_equal(lh.constants(X), lh.energy(X) + 1.0)   # E = 0: δ = max(−E, 1)


def test_starts_are_each_orbits_own_and_a_run_given_them_is_the_same_run(core):
    """LogHamiltonian.starts: H = A + V and V of each orbit (the model's
    own energy and potential to round-off), the same bits for an orbit
    whatever the others (a pilot takes its sample's rows of the map's
    starts), C and U₀ as constants and start_u compute them; a run given
    them is the run that computes them, bit for bit."""
    lh = LogHamiltonian(core, "ABA864")
    X = _core_orbits(core, 5)
    starts = lh.starts(X)
    n = X.shape[1] // 2
    assert np.allclose(starts.energy, core.energy(X), rtol=0, atol=1e-14)
    assert np.allclose(starts.potential, core.potential(X[:, :n]), rtol=0, atol=1e-14)
    pick = np.array([17, 3, 11, 20])
    mine = lh.starts(X[pick])
    assert np.array_equal(mine.energy, starts.rows(pick).energy)
    assert np.array_equal(mine.potential, starts.rows(pick).potential)
    for offset in (None, 0.25):
        other = lh.with_offset(offset)
        assert np.array_equal(other.constants(X, starts), other.constants(X))
        assert np.array_equal(other.start_u(X, starts=starts), other.start_u(X))
        assert np.all(other.start_u(X, starts=starts) > 0)
    W0 = initial_deviations(core.dim, 1, len(pick), 0, pick)[:, :, 0]
    other = lh.with_offset(0.25)
    for t_end, h, lanes in ((20.0, 0.05, None), (9.0, 0.1, True), (9.0, 0.1, False)):
        a = other.outputs(X[pick], W0, t_end, h, every=4.0, starts=mine, lanes=lanes)
        b = other.outputs(X[pick], W0, t_end, h, every=4.0)
        for name in ("fli", "status", "x", "t", "x_worst", "t_worst", "counts"):
            assert np.array_equal(getattr(a, name), getattr(b, name), equal_nan=True), name
    assert (b.status == 0).all() and np.isfinite(b.fli).all()
    with pytest.raises(ValueError, match="starts must hold the 4 orbits"):
        lh.outputs(X[pick], W0, 20.0, 0.05, starts=starts)
    with pytest.raises(ValueError, match="t_end must be a finite number > 0, got -1"):
        other.outputs(X[pick], W0, -1.0, 0.05, starts=mine)
    with pytest.raises(ValueError, match="h must be finite numbers > 0, got nan"):
        other.outputs(X[pick], W0, 1.0, math.nan, starts=mine)


def test_the_pilot_over_lanes_chooses_what_one_orbit_at_a_time_does(core, monkeypatch):
    """Every pilot run of the offset's pricing and the h descent over SIMD
    lanes (their work threshold at 0, as when the map runs over them or
    this process has them compiled) gives the choice of the same pilot run
    one orbit at a time, every figure of it (prices, counts, energy
    errors, h and δ) bit for bit."""
    from varint import time_transform

    pilot = _core_orbits(core, 6)
    one = LogHamiltonian(core, "ABA864")
    one.lanes_kernels = (None, None)
    assert not one.lanes_ready(1)
    _, h_one, one_choice = agreeing_offset(one, pilot, T_END, **PILOT)
    monkeypatch.setattr(time_transform, "LANES_WORK", 0.0)
    lanes = LogHamiltonian(core, "ABA864")
    _, h_lanes, lanes_choice = agreeing_offset(lanes, pilot, T_END, **PILOT)
    assert lanes.lanes_ready(1)
    assert h_one is not None and h_lanes == h_one
    assert repr(lanes_choice) == repr(one_choice)

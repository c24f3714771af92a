"""The automatic fictitious step of the logarithmic Hamiltonian
(varint.time_transform_step) and the map defaults that choose it: the h
chosen on some orbits keeps held-out orbits of the same model within the
tolerance while twice that h does not; a Hénon–Heiles map never switches;
a map of a softened point mass, which no constant step keeps within the
tolerance, does (priced by tests/test_step_agreement.py's rule), says so,
and ``time_transform=None`` keeps constant steps."""

import logging

import numpy as np
import pytest
import sympy as sp

import varint
from varint.accuracy import Reference
from varint.maps import MAP_QUANTILE
from varint.models import from_potential
from varint.models.cr3bp import CR3BP, SUN_JUPITER_MU
from varint.time_transform import LogHamiltonian
from varint.time_transform_step import RETRY_LEVELS, choose_h, retried

TOL = 1e-6


def _plummer_orbits(seed, m):
    """Eccentric bound orbits of a softened point mass (ε = 1e-3), with
    pericentres down to ~0.01."""
    rng = np.random.default_rng(seed)
    return np.column_stack([rng.uniform(0.5, 1.0, m), np.zeros(m), np.zeros(m),
                            rng.uniform(0.05, 0.5, m)])


def _cr3bp_orbits(seed, m):
    """Sun–Jupiter orbits on the section y = 0 at C = 3.05 (studies/map_steps.py)."""
    model = CR3BP(SUN_JUPITER_MU)
    rng = np.random.default_rng(seed)
    grid = model.section_grid(3.05, np.sort(rng.uniform(0.3, 0.85, m)),
                              np.sort(rng.uniform(-0.3, 0.3, m)))
    return grid.states


def _model(which):
    if which == "plummer":
        x, y = sp.symbols("x y")
        return from_potential(-1 / sp.sqrt(x**2 + y**2 + sp.Float(1e-3)**2), [x, y])
    return CR3BP(SUN_JUPITER_MU)


def _errors(lh, X, t_end, h):
    out = lh.outputs(X, None, t_end, h, every=t_end / 50)
    assert (out.status == 0).all()
    return Reference(lh.model, X).errors(out.x_worst)["energy_error"]


@pytest.mark.parametrize("which", ["plummer", "cr3bp"])
def test_chosen_h_meets_the_tolerance_on_held_out_orbits(which):
    """h from a pilot on one set of orbits: 16 other orbits of the model
    run to the map's t_end (twice the pilot's) meet the tolerance at the
    map's quantile within the ladder's resolution (one rung, 2^(1/4) in h,
    is 2^(p/4) = 2 in the error of an order-4 scheme; measured: Plummer
    1.09e-6, three held-out orbits of 16 just above 1e-6), and at 2h (error
    ×2^p) they miss it."""
    model = _model(which)
    orbits = _plummer_orbits if which == "plummer" else _cr3bp_orbits
    lh = LogHamiltonian(model, "ABA864")
    t_end = 40.0
    h, choice = choose_h(lh, orbits(0, 16), t_end / 2, TOL, quantile=MAP_QUANTILE)
    assert choice["rule"] == "pilot" and choice["h"] == h
    held_out = orbits(1, 16)
    e = _errors(lh, held_out, t_end, h)
    assert np.quantile(e, MAP_QUANTILE) <= 2 * TOL, (h, np.sort(e))
    assert np.quantile(_errors(lh, held_out, t_end, 2 * h), MAP_QUANTILE) > 2 * TOL


def test_henon_heiles_defaults_never_switch():
    """A Hénon–Heiles FLI map with the defaults is the constant-step map,
    bit for bit (``time_transform=None``)."""
    hh = varint.models.HenonHeiles()
    grid = varint.section_grid(hh, 0.125, np.linspace(-0.4, 0.65, 4), np.linspace(-0.4, 0.4, 3))
    a = varint.chaos_map(hh, grid, "fli", t_end=50.0, progress=False)
    b = varint.chaos_map(hh, grid, "fli", t_end=50.0, progress=False, time_transform=None)
    assert a.provenance.method == "tm" and np.array_equal(a.values, b.values)


def test_near_singular_defaults_take_the_log_hamiltonian(caplog):
    """A softened point mass (ε = 1e-3) with eccentric orbits: no constant
    step meets the map's tolerance (its pilot falls back, and that map's
    energy errors are O(1) and more); the LH's step chosen by indicator
    agreement is priced cheaper than constant steps (with the pilot run
    their next rung still has to make), so the defaults run
    the LH, say so (method, the prices, one log line) and give the explicit
    LH map at that h and offset δ bit for bit, accurate; time_transform=None keeps
    constant steps."""
    model = _model("plummer")
    X = _plummer_orbits(2, 8)
    with caplog.at_level(logging.INFO, logger="varint.maps"):
        r = varint.chaos_map(model, X, "fli", t_end=40.0, progress=False)
    assert r.provenance.method == "tm+log"
    # The defaults' pilot (both steps priced) and the LH map's run timed
    # apart from compilation (empty before).
    assert set(r.provenance.timing) == {"compile", "pilot", "run"}
    assert min(r.provenance.timing["pilot"], r.provenance.timing["run"]) > 0
    choice = r.provenance.tau_choice
    # Priced against the constant steps with the pilot run their next rung
    # still had to make (maps._pilot_share; 8 orbits to t = 40, all of them
    # pilots: the run costs twice the map).
    prices = choice["prices"]
    assert choice["rule"] == "indicator" and prices["pilot_share"] == 2.0
    # Cheaper, or no constant step agreed below the LH's price (since
    # lhprice18 the LH's pricing pilots to t = 25 agree to the map's t = 40,
    # map_verdict: its price here is above the constant's last rung).
    assert (prices["log"] < prices["constant"] * (1 + prices["pilot_share"])
            or choice["constant"]["rule"] == "none"), (prices, choice["constant"]["rule"])
    assert sum("logarithmic-Hamiltonian step" in m for m in caplog.messages) == 1
    explicit = varint.chaos_map(model, X, "fli", t_end=40.0, progress=False,
                                time_transform="log", tau=choice["h"], offset=choice["offset"])
    # Orbits not retried (each meets energy_tol at h) are the explicit map's.
    kept = np.array(choice["levels"]) == 0
    assert kept.any()
    assert np.array_equal(r.values[kept], explicit.values[kept], equal_nan=True)
    assert r.accuracy.accurate.all()
    with pytest.warns(varint.AccuracyWarning):
        plain = varint.chaos_map(model, X, "fli", t_end=40.0, progress=False,
                                 time_transform=None)
    assert plain.provenance.method == "tm" and not plain.accuracy.accurate.all()


def test_an_orbit_above_the_ceiling_is_retried_until_it_meets_it():
    """retried: at a coarse h some softened-point-mass orbits exceed the
    ceiling (measured here by Reference on a plain run); exactly those run
    again, each ends at the coarsest h/2^level whose own error meets the
    ceiling (the run at h/2^(level−1) did not), and each orbit's result is,
    bit for bit, that orbit run alone at its recorded step."""
    model = _model("plummer")
    lh = LogHamiltonian(model, "ABA864")
    X = _plummer_orbits(5, 10)
    W0 = np.random.default_rng(0).standard_normal(X.shape)
    t_end, h = 30.0, 0.2
    ref = Reference(model, X)

    def largest(out):   # over the outputs and the end, as the map's verdict
        a, b = ref.errors(out.x)["energy_error"], ref.errors(out.x_worst)["energy_error"]
        return np.fmax(a, b)

    plain = largest(lh.outputs(X, W0, t_end, h))
    ceiling = float(np.median(plain))
    out, level = retried(lh, X, W0, t_end, h, ceiling, ref)
    assert ((level > 0) == (plain > ceiling)).all() and 0 < (level > 0).sum() < len(X)
    assert (largest(out)[level < RETRY_LEVELS] <= ceiling).all()
    for m in np.flatnonzero(level):
        alone = lh.outputs(X[[m]], W0[[m]], t_end, h * 2.0**-level[m])
        coarser = lh.outputs(X[[m]], W0[[m]], t_end, h * 2.0 ** (1 - level[m]))
        assert Reference(model, X[[m]]).errors(coarser.x_worst)["energy_error"][0] > ceiling \
            or Reference(model, X[[m]]).errors(coarser.x)["energy_error"][0] > ceiling
        assert alone.fli[0] == out.fli[m] and np.array_equal(alone.x[0], out.x[m])
    # The work of every run is counted: a retried orbit did more than its last run.
    assert (out.counts[level > 0, 2] > lh.outputs(X[level > 0], W0[level > 0], t_end, h)
            .counts[:, 2] * 2).all()


def test_a_retried_map_is_the_same_in_any_chunks_and_threads_and_records_each_step():
    """An LH map with an automatic h whose orbits are retried (energy_tol
    1e-6; at the offset δ its pilot chooses, 1e-4 retries none): the same
    bits in chunks of 3 and of all, on 1 and 2 threads;
    ``tau_choice["h_orbit"]`` is each orbit's step (h/2^level), and the
    explicit map at each recorded step (and the chosen offset δ) gives
    that orbit's value."""
    import numba

    model = _model("plummer")
    X = _plummer_orbits(2, 8)
    runs = []
    before = numba.get_num_threads()
    try:
        for size, threads in ((None, 1), (3, min(2, numba.config.NUMBA_NUM_THREADS))):
            numba.set_num_threads(threads)
            runs.append(varint.chaos_map(model, X, "fli", t_end=40.0, progress=False,
                                         time_transform="log", energy_tol=1e-6,
                                         chunk_size=size))
    finally:
        numba.set_num_threads(before)
    a, b = runs
    assert np.array_equal(a.values, b.values) and np.array_equal(a.state, b.state)
    choice = a.provenance.tau_choice
    assert choice == b.provenance.tau_choice
    level, h_orbit = np.array(choice["levels"]), np.array(choice["h_orbit"])
    assert level.any() and np.array_equal(h_orbit, choice["h"] * 2.0**-level)
    assert a.accuracy.accurate.all() and "retried" in a.accuracy.notes
    for h in np.unique(h_orbit):
        rows = h_orbit == h
        alone = varint.chaos_map(model, X, "fli", t_end=40.0, progress=False,
                                 time_transform="log", tau=h, offset=choice["offset"])
        assert np.array_equal(alone.values[rows], a.values[rows])


def _cored_section(nx, npx):
    """The cored race's section of studies/map_steps.py (V = ½ ln(R_c² + x²
    + y²/q²), R_c = 0.03, q = 0.8; y = 0, p_y ≥ 0 at E = 0; box orbits
    through the near-singular centre): an nx × npx grid of (x, p_x) in
    [−0.1, 0.1] × [0.3, 0.85]."""
    x, y = sp.symbols("x y")
    model = from_potential(sp.log(sp.Float(0.03)**2 + x**2 + y**2 / sp.Float(0.8)**2) / 2,
                           [x, y])
    grid = varint.section_grid(model, 0.0, np.linspace(-0.1, 0.1, nx),
                               np.linspace(0.3, 0.85, npx), plane=1)
    return model, grid.states


def test_agreeing_h_keeps_the_verdicts_of_a_map_ten_times_its_pilot(monkeypatch):
    """A cored map of 24 orbits to t = 1000, ten times the pilot's t = 100:
    at the h its pilot chooses (values agreeing to the map's t_end, the
    maps' rule) at least MAP_QUANTILE of the orbits have the verdict of a
    tight reference (the same orbits at h/8) at the chaotic level, the
    pilot's own criterion; at the coarser h the verdict rule chooses (the
    same side of the level at the pilot's t, the rule before) fewer do."""
    from varint import time_transform
    from varint.state import initial_deviations
    from varint.step_agreement import same_verdict
    from varint.time_transform_step import agreeing_h

    monkeypatch.setattr(time_transform, "LANES_WORK", 0.0)   # the same bits, faster
    model, X = _cored_section(6, 4)
    t_end = 1000.0
    lh = LogHamiltonian(model, "ABA864", offset=0.25)
    W0 = initial_deviations(model.dim, 1, len(X), 0)[:, :, 0]
    h, choice = agreeing_h(lh, X, t_end, quantile=MAP_QUANTILE, ceiling=1e-2)
    assert choice["agreement"] == "map_verdict" and h is not None
    h_verdict, _ = agreeing_h(lh, X, t_end, quantile=MAP_QUANTILE, ceiling=1e-2,
                              agree=same_verdict)
    assert h_verdict > h
    reference = lh.outputs(X, W0, t_end, h / 8).fli
    assert np.isfinite(reference).all()
    at_h = same_verdict(lh.outputs(X, W0, t_end, h).fli, reference, t_end)
    at_verdict_h = same_verdict(lh.outputs(X, W0, t_end, h_verdict).fli, reference, t_end)
    assert at_h.mean() >= MAP_QUANTILE > at_verdict_h.mean(), (h, at_h, h_verdict, at_verdict_h)

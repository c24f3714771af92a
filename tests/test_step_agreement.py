"""Steps judged by what an FLI map reports (varint.step_agreement and
varint.time_transform_step.agreeing_h): the h the LH pilot chooses on some
orbits keeps held-out orbits' FLI verdicts in agreement with a tight
reference (the same orbits at h/16) to the map's t_end, twice the pilot's,
at the chaotic level;
a clearly too coarse h (numerical chaos, energy errors O(1)) is rejected;
the cost-based switch of the map defaults takes the LH where it is priced
cheaper, the constant step chosen by the same agreement where it is not,
and says so."""

import math
import warnings
from collections import Counter

import numpy as np
import pytest
import sympy as sp

import varint
from varint import maps, step_cost
from varint.maps import MAP_QUANTILE
from varint.compiling import Clock
from varint.methods.tm import TangentMapPropagator
from varint.runspec import specify
from varint.models import from_potential
from varint.models.cr3bp import CR3BP, SUN_JUPITER_MU
from varint.state import initial_deviations
from varint.step_agreement import (agreeing, chaotic_level, descend, map_verdict, passes,
                                   same_verdict)
from varint.time_transform import LogHamiltonian
from varint.time_transform_step import agreeing_h

#: The held-out orbits run to twice the pilot's time (PILOT_T = 100).
T_END = 200.0


def _cr3bp_orbits(seed, m, jacobi):
    """Sun–Jupiter orbits on the section y = 0 at Jacobi constant ``jacobi``."""
    rng = np.random.default_rng(seed)
    grid = CR3BP(SUN_JUPITER_MU).section_grid(jacobi, np.sort(rng.uniform(0.3, 0.85, m)),
                                              np.sort(rng.uniform(-0.3, 0.3, m)))
    return grid.states


def _plummer():
    x, y = sp.symbols("x y")
    return from_potential(-1 / sp.sqrt(x**2 + y**2 + sp.Float(1e-3)**2), [x, y])


def _plummer_orbits(seed, m, p_y=(0.05, 0.5)):
    """Bound orbits of a softened point mass from (x, 0) with x in
    [0.5, 1] and the velocity p_y in ``p_y``: eccentric (the default range,
    pericentres ~0.01) or rounder as p_y nears the circular velocity
    (1/√x: 1 to 1.4)."""
    rng = np.random.default_rng(seed)
    return np.column_stack([rng.uniform(0.5, 1.0, m), np.zeros(m), np.zeros(m),
                            rng.uniform(*p_y, m)])


def _fli(lh, X, h, seed=0):
    W0 = initial_deviations(lh.model.dim, 1, len(X), seed)[:, :, 0]
    return lh.outputs(X, W0, T_END, h).fli


def test_agreement_rule():
    """Values within 0.05 dex agree, further apart they do not, unless
    both lie above the chaotic level; verdicts agree on the same side of
    the level, whatever the values; NaN agrees with nothing; a step
    passes only with the quantile of agreement and of the energy errors."""
    t = 100.0
    level = chaotic_level(t)
    assert level == pytest.approx(np.log(1e5))
    coarse = np.array([5.0, 5.0, level + 1, level + 1, np.nan, 0.5])
    fine = np.array([5.5, 6.0, level + 30, level - 2, 5.0, 0.9])
    assert agreeing(coarse, fine, t).tolist() == [True, False, True, False, False, True]
    assert same_verdict(coarse, fine, t).tolist() == [True, True, True, False, False, True]
    assert same_verdict(coarse, fine, t, t_end=1e4).tolist() == same_verdict(coarse, fine, t).tolist()
    # The maps' rule: the verdict where the pilot reaches the map's end, the
    # values within 0.05 dex times t/t_end beyond it (5.0 and 5.5 differ by
    # 0.041 dex: within 0.05, not within 0.005).
    assert map_verdict(coarse, fine, t, t_end=t).tolist() == same_verdict(coarse, fine, t).tolist()
    assert map_verdict(coarse, fine, t).tolist() == same_verdict(coarse, fine, t).tolist()
    assert map_verdict(coarse, fine, t, t_end=2 * t).tolist() == agreeing(coarse, fine, t, 2 * t).tolist()
    assert map_verdict(coarse, fine, t, t_end=10 * t).tolist() == [False, False, True, False,
                                                                   False, True]
    assert map_verdict([5.0], [5.0 * 10**0.0049], t, t_end=10 * t).tolist() == [True]
    assert passes(np.ones(10, bool), np.full(10, 1e-4), 0.9, 1e-3)[0]
    assert not passes(np.ones(10, bool), np.full(10, 1e-2), 0.9, 1e-3)[0]
    assert not passes(np.arange(10) < 8, np.full(10, 1e-4), 0.9, 1e-3)[0]


@pytest.mark.parametrize("which", ["cr3bp", "plummer"])
def test_chosen_h_keeps_held_out_verdicts_and_coarse_h_is_rejected(which):
    """h from the pilot (to t = 100) on 16 orbits by the maps' rule (the
    same verdict at h and h/2, energy errors within 1e-3); held-out orbits
    (the three-body problem at another Jacobi constant, C = 3.1 against the
    pilot's 3.05; other eccentric orbits of the softened point mass) run to
    t = 200: at h at least 90 % of them give the verdict of the tight
    reference (h/16) at the chaotic level; the ladder's first step 2h₀,
    tried and rejected, misses that on the same orbits."""
    if which == "cr3bp":
        model, pilot, held_out = (CR3BP(SUN_JUPITER_MU), _cr3bp_orbits(0, 16, 3.05),
                                  _cr3bp_orbits(1, 16, 3.1))
    else:
        model, pilot, held_out = _plummer(), _plummer_orbits(0, 16), _plummer_orbits(1, 16)
    lh = LogHamiltonian(model, "ABA864")
    h, choice = agreeing_h(lh, pilot, T_END, quantile=MAP_QUANTILE, ceiling=1e-3)
    assert choice["rule"] == "indicator" and choice["h"] == h
    assert choice["agreement"] == "map_verdict"
    # The ladder's first step, 2h₀, was tried and rejected (the search
    # stops at the first that passes).
    coarse_h = choice["tried"][0][0]
    assert coarse_h >= 2 * h
    assert choice["summary"].startswith("step chosen by indicator agreement between h and h/2")
    reference = _fli(lh, held_out, h / 16)
    assert np.isfinite(reference).all()
    at_h = same_verdict(_fli(lh, held_out, h), reference, T_END)
    assert at_h.mean() >= MAP_QUANTILE, (h, _fli(lh, held_out, h), reference)
    coarse = _fli(lh, held_out, coarse_h)
    assert same_verdict(coarse, reference, T_END).mean() < MAP_QUANTILE, (coarse, reference)


def test_no_agreeing_step_is_said_and_warned():
    """A ladder too short to reach agreement (monkeypatched to its first
    two steps): the explicit LH map falls back to the energy pilot's h,
    warns that its FLI was not checked, and its verdict says so."""
    model = CR3BP(SUN_JUPITER_MU)
    X = _cr3bp_orbits(2, 6, 3.05)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr("varint.time_transform_step.LEVELS", 2)
        with pytest.warns(varint.AccuracyWarning, match="did not agree between h and h/2"):
            r = varint.chaos_map(model, X, "fli", t_end=20.0, progress=False,
                                 time_transform="log")
    choice = r.provenance.tau_choice
    assert choice["rule"] == "pilot" and choice["indicator"]["rule"] == "none"
    assert "step chosen by the energy error" in r.accuracy.verdict


def test_henon_heiles_defaults_build_no_log_hamiltonian():
    """Hénon–Heiles (U spread 1.1 < U_SPREAD_MIN): the defaults never
    price the LH, and keep the constant-step map bit for bit. Five orbits,
    fewer than a block of SIMD lanes: the one-orbit stepper runs them (the
    eight of a 4 × 3 grid, spread 1.12 too, compiled the lanes of
    SRKN14a's FLI stepper, 20 CPU s cold, for this test alone)."""
    hh = varint.models.HenonHeiles()
    grid = varint.section_grid(hh, 0.125, np.linspace(-0.4, 0.65, 3), np.linspace(-0.4, 0.4, 3))
    assert len(grid.states) < TangentMapPropagator.MIN_LANES
    assert maps._u_spread(hh, grid.states, kinetic=True) < maps.U_SPREAD_MIN
    a = varint.chaos_map(hh, grid, "fli", t_end=50.0, progress=False)
    b = varint.chaos_map(hh, grid, "fli", t_end=50.0, progress=False, time_transform=None)
    assert "prices" not in a.provenance.tau_choice
    assert a.provenance.method == "tm" and np.array_equal(a.values, b.values)


def test_three_body_map_of_the_study_runs_the_constant_step_measured_cheaper():
    """The Sun–Jupiter FLI map of studies/hamiltonians.py (1172 orbits,
    t = 1000): its LH at h = 0.274 costs 0.89 CPU s, SRKN14a's lanes at
    τ = 0.125, the constant ladder's agreeing step, 0.65 s
    (studies/results/map25/, AMD EPYC, load 4): the tables fitted on this
    machine (studies/switch_check.py, part fit) price the LH's force
    evaluation over lanes at 3.5–4.5 times the lanes', so the defaults run
    constant steps at that τ (the Intel Xeon's tables, 2.2 times, ran the
    LH). Only the pilot runs here: the prices, not a timing, choose."""
    model = CR3BP(SUN_JUPITER_MU)
    grid = model.section_grid(3.05, np.linspace(0.3, 0.85, 40), np.linspace(-0.3, 0.3, 30))
    spec = specify(model, grid.states, "fli", 1000.0, None, method="tm",
                                  t_out=None, seed=0, escape_radius=None, energy_tol=None,
                                  what="x", kernels_what="x", t_out_name="t_check")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        h_choice, stepped = maps._cheaper_steps(spec, 1, Clock("the map", False))
    assert h_choice is None and stepped is not None and stepped.tau == 0.125
    prices = stepped.tau_choice["prices"]
    assert 3.5 <= prices["log_gradient_cost"] / prices["constant_gradient_cost"] <= 4.5


@pytest.mark.parametrize("cost, method", [(1e6, "tm"), (1e-6, "tm+log")])
def test_switch_follows_the_prices(cost, method):
    """The three-body map's defaults with the LH's cost per force
    evaluation set very high (1e6 additions, the constant step's is
    ~10²) run constant steps at the step chosen by agreement, and say so
    in their verdict; set very low (1e-6) they run the LH at its agreeing
    h, the explicit LH map at that h bit for bit on every orbit not
    retried at a smaller step."""
    model = CR3BP(SUN_JUPITER_MU)
    X = _cr3bp_orbits(3, 8, 3.05)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(step_cost, "log_gradient_cost", lambda lh, lanes=False: (cost, Counter()))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            r = varint.chaos_map(model, X, "fli", t_end=40.0, progress=False)
    assert r.provenance.method == method
    choice = r.provenance.tau_choice
    prices = choice["prices"]
    # A constant step that wins may stop the LH's descent before it prices h.
    assert (prices["log"] is not None and prices["log"] < prices["constant"]) \
        == (method == "tm+log")
    if method == "tm":
        assert choice["rule"] == "indicator" and r.provenance.tau == choice["tau"]
        # By the LH's rule: the values to the map's t_end (the verdict at the
        # pilot's t before pilot19).
        assert choice["agreement"] == "map_verdict"
        assert "step chosen by indicator agreement between tau and tau/2" in r.accuracy.verdict
    else:
        assert choice["rule"] == "indicator" and choice["constant"]["rule"] in ("indicator", "none")
        explicit = varint.chaos_map(model, X, "fli", t_end=40.0, progress=False,
                                    time_transform="log", tau=choice["h"])
        # Orbits retried at h/2, h/4, ... (levels > 0) ran at other steps.
        at_h = np.asarray(choice["levels"]) == 0
        assert at_h.any()
        assert np.array_equal(r.values[at_h], explicit.values[at_h], equal_nan=True)


def _pilot_runs(mp):
    """Record every pilot run of the defaults' switch, in order, as
    (stepper, step, force evaluations per orbit and unit of time): the
    constant steps' (varint.step_agreement's pilot_errors) and the LH's
    (LogHamiltonian.outputs), by hook, not by time."""
    from varint import step_agreement

    runs = []
    constant_run, lh_run = step_agreement.pilot_errors, LogHamiltonian.outputs

    def constant(model, X, tau, t_pilot, *args, **kwargs):
        counts = args[2]
        before = counts.get("gradient", 0)
        out = constant_run(model, X, tau, t_pilot, *args, **kwargs)
        runs.append(("constant", tau, (counts["gradient"] - before) / (len(X) * t_pilot)))
        return out

    def log(self, X, W0, t_end, h, *args, **kwargs):
        out = lh_run(self, X, W0, t_end, h, *args, **kwargs)
        runs.append(("log", h, out.counts[:, 2].sum() / (len(X) * t_end)))
        return out

    mp.setattr(step_agreement, "pilot_errors", constant)
    mp.setattr(LogHamiltonian, "outputs", log)
    return runs


def test_constant_pilot_that_wins_stops_the_lh_descent():
    """The three-body map of studies/map_steps.py --quick, where constant
    steps win: the pilots run in order of price, so the LH's descent stops
    once a constant step agreed below its rung's price. Of the runs priced
    above the winner's (counted by hook), each stepper makes at most one,
    the fine run of the last rung it judged (the sequential pilots, the
    LH's to its agreeing h, made two LH runs there: h and h/2 of its last
    rung). The choice and the map are those of the sequential pilots: the
    constant step their composition (agreeing_offset, then agreeing_tau
    stopped at the LH's price) chooses, the map at that step bit for bit."""
    from varint.step_agreement import agreeing_tau
    from varint.stepsize_orbits import indicator_judge
    from varint.time_transform_step import RETRY_CEILING, agreeing_offset

    model = CR3BP(SUN_JUPITER_MU)
    grid = model.section_grid(3.05, np.linspace(0.3, 0.85, 10), np.linspace(-0.3, 0.3, 8))
    with pytest.MonkeyPatch.context() as mp, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        runs = _pilot_runs(mp)
        r = varint.chaos_map(model, grid, "fli", t_end=T_END, progress=False)
    choice = r.provenance.tau_choice
    assert r.provenance.method == "tm" and choice["log"]["rule"] == "none"
    prices = choice["prices"]
    unit = {"constant": prices["constant_gradient_cost"], "log": prices["log_gradient_cost"]}
    winner = prices["constant"]
    dearer = Counter(kind for kind, _, rate in runs if rate * unit[kind] > winner)
    assert dearer["constant"] == 1 and dearer["log"] <= 1, runs
    # The sequential pilots, composed from the public functions.
    X, ind = grid.states, varint.INDICATORS["fli"]
    lh = maps._log_hamiltonian(model, maps.LOG_MAP_OPTIONS["scheme"], None)
    tol = varint.accuracy.DEFAULT_ENERGY_TOL
    _, h, log_choice = agreeing_offset(lh, X, T_END, quantile=MAP_QUANTILE,
                                       ceiling=RETRY_CEILING * tol, seed=0,
                                       every=maps.LOG_MAP_OPTIONS["every"], retry=tol)
    log_price = log_choice["gradient_rate"] * unit["log"]
    log_runs = [rate for kind, _, rate in runs if kind == "log"]
    assert h is not None and len(log_runs) < len(log_choice["tried"]) + 1
    judge = indicator_judge(ind, model, {}, maps.pilot_tolerance(ind), tol)
    tau, _ = agreeing_tau(model, X, T_END, scheme=maps.MAP_SCHEME, seed=0, k=1,
                          renorm=ind.renorm, accumulator=ind.accumulator_for({}),
                          value=judge.value, quantile=MAP_QUANTILE, ceiling=tol,
                          stop_above=log_price / unit["constant"], agree=map_verdict)
    assert tau is not None and tau == r.provenance.tau == choice["tau"] and winner < log_price
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fixed = varint.chaos_map(model, grid, "fli", t_end=T_END, progress=False,
                                 time_transform=None, tau=tau, scheme=maps.MAP_SCHEME)
    assert np.array_equal(r.values, fixed.values, equal_nan=True)


#: The tables of varint.step_cost fitted on an Intel Xeon (before map25's
#: refit on an AMD EPYC), nanoseconds per operation of each class: tests
#: of the switch's logic that need a map whose two prices lie close take
#: them, whatever the machine the module's tables were fitted on.
XEON_TABLES = {"LH_WEIGHTS": {"arithmetic": 0.0, "division": 0.57, "call": 4.1, "check": 1.3},
               "LH_LANES_WEIGHTS": {"arithmetic": 0.0, "division": 0.18, "call": 1.3,
                                    "check": 0.41},
               "VECTOR_LANE_WEIGHTS": {"arithmetic": 0.0080, "division": 0.49, "call": 0.0,
                                       "check": 0.68},
               "SCALAR_LANE_WEIGHTS": {"arithmetic": 0.0, "division": 0.0, "call": 0.0,
                                       "check": 4.0}}


@pytest.fixture
def xeon_tables():
    """varint.step_cost priced by :data:`XEON_TABLES` (its per-process
    caches cleared before and after)."""
    by_kind = {name: {kind: table[cls] for cls, kinds in step_cost.CLASSES.items()
                      for kind in kinds} for name, table in XEON_TABLES.items()}
    caches = (step_cost._log_cost, step_cost._constant_cost)
    with pytest.MonkeyPatch.context() as mp:
        for name, table in by_kind.items():
            mp.setattr(step_cost, name, table)
        for cache in caches:
            cache.cache_clear()
        yield
    for cache in caches:
        cache.cache_clear()


@pytest.mark.usefixtures("xeon_tables")
def test_switch_skips_a_pilot_run_that_cannot_pay_for_itself():
    """The defaults' switch prices the pilot each choice still has to run
    (maps._pilot_share): once the LH's pilot is spent, a constant rung is
    judged only while its τ/2 pilot run and its map together cost less
    than the LH's map. A small map of the softened point mass (26
    orbits, p_y in [0.55, 0.95]: the LH priced 1.21x the constant step's
    map by the Xeon's tables of varint.step_cost, a rung's pilot run costs 0.6
    of its map; the kernels of the held-out test above and of
    tests/test_time_transform_step.py), runs counted by hook: no constant
    run after the LH's last is the fine run of a rung that cannot pay for
    itself, and the LH's map is run. The switch as it was (pilot share 0,
    the map alone priced) makes such a run, and takes the constant
    step whose pilot run and map together cost more than the LH's map, so
    the test fails without the change."""
    model, X = _plummer(), _plummer_orbits(0, 26, p_y=(0.55, 0.95))

    def defaults(mp):
        runs = _pilot_runs(mp)
        hooked = LogHamiltonian.outputs

        def log(self, X, W0, t_end, *args, **kwargs):
            # The LH's map runs through the hook too: mark its runs (to t_end).
            out = hooked(self, X, W0, t_end, *args, **kwargs)
            runs[-1] = (*runs[-1], t_end)
            return out

        mp.setattr(LogHamiltonian, "outputs", log)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            r = varint.chaos_map(model, X, "fli", t_end=T_END, progress=False)
        return r, [run[:3] for run in runs if len(run) == 3 or run[3] < T_END]

    def dear(runs, prices, share):
        # Each run after the LH's pilot is the fine run of a rung at twice
        # the rung's rate.
        last = max(i for i, (kind, _, _) in enumerate(runs) if kind == "log")
        return [rate for kind, _, rate in runs[last + 1:] if kind == "constant"
                and rate / 2 * prices["constant_gradient_cost"] * (1 + share) > prices["log"]]

    with pytest.MonkeyPatch.context() as mp:
        r, runs = defaults(mp)
    prices = r.provenance.tau_choice["prices"]
    share = prices["pilot_share"]
    m, pilots = len(X), min(len(X), 16)
    assert share == pytest.approx(2 * pilots * 100.0 / (m * T_END))
    assert r.provenance.method == "tm+log" and dear(runs, prices, share) == [], runs
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(maps, "_pilot_share", lambda spec: 0.0)
        before, runs_before = defaults(mp)
    constant_runs = [Counter(kind for kind, _, _ in rs)["constant"] for rs in (runs, runs_before)]
    # The extra run, and (step_agreement.descend) the fine run of the last
    # rung the current switch judged, failing on its energy errors alone.
    assert before.provenance.method == "tm" and constant_runs[1] == constant_runs[0] + 2
    assert dear(runs_before, prices, share), runs_before
    # What the old choice still had to run when the LH's pilot was spent:
    # its rung's fine pilot run and its map, dearer than the LH's map.
    constant = before.provenance.tau_choice["gradient_rate"] * prices["constant_gradient_cost"]
    assert constant < prices["log"] < constant * (1 + share)


def _synthetic_ladder(levels):
    """A ladder of ``levels`` rungs whose pilot runs are made up, recorded
    as they are made: the energy error at step j is 10^−j, the force
    evaluations 2^j, and the values agree between rungs 3 and 4 only."""
    made = []

    def run(j):
        made.append(j)
        values = np.full(10, 5.0 if j >= 3 else float(j))
        return values, np.full(10, 10.0**-j), 2.0**j

    return run, made


def _naive(levels, ceiling, stop_above):
    """The descent as it was, every rung's fine run made: the first j that
    agrees with j + 1 with energy errors within ``ceiling``, stopping where
    a coarse run's rate exceeds ``stop_above``."""
    run, made = _synthetic_ladder(levels)
    for j in range(levels):
        coarse, errors, rate = run(j)
        if rate > stop_above:
            return None, made
        fine = run(j + 1)[0]
        if np.all(np.abs(coarse - fine) < 0.5) and errors.max() <= ceiling:
            return j, made
    return None, made


@pytest.mark.parametrize("stop_above, chosen, spared", [(math.inf, 3, 0), (3.0, None, 1)])
def test_descend_spares_runs_that_cannot_change_the_rung(stop_above, chosen, spared):
    """descend on a made-up ladder (energy errors 10^−j against a ceiling
    of 2e-3, values agreeing between rungs 3 and 4, rates 2^j): the rung
    chosen is the one a descent that makes every fine run chooses; the
    rungs 0–2, failing on their energy errors alone, are judged without
    their fine runs (share None); with stop_above 3 (rung 2's rate 4)
    rung 1 fails on its energy and rung 2, priced by the floor before it
    runs, is never run, where the full descent ran it as rung 1's fine run."""
    run, made = _synthetic_ladder(8)
    memo: dict = {}

    def memoised(j):
        if j not in memo:
            memo[j] = run(j)
        return memo[j]

    def floor(j):
        return None if j in memo or j - 1 not in memo else 2.0 * memo[j - 1][2]

    tried, got = descend(memoised, range(8), lambda j: 2.0**-j, 100.0, None, 1.0, 2e-3,
                         stop_above=stop_above, agree=lambda a, b, t, t_end: np.abs(a - b) < 0.5,
                         floor=floor)
    expected, naive_made = _naive(8, 2e-3, stop_above)
    assert (None if got is None else got[0]) == expected == chosen
    assert [share for _, share, _ in tried][:3] == [None] * min(3, len(tried))
    assert sorted(made) == sorted(set(made)) and len(made) == len(set(naive_made)) - spared
    assert set(made) <= set(naive_made)


#: The made-up ladders' pilot time, map's t_end, rungs and quantile.
_LAW_T, _LAW_T_END, _LAW_LEVELS, _LAW_QUANTILE = 100.0, 1000.0, 8, 0.9


def _made_up_ladder(rng):
    """A made-up ladder of 16 orbits (values converging as 2^−pj, p from
    0.5 to 4, to each orbit's own, some chaotic; energy errors as 2^−pj;
    rates growing down the ladder by 1 to 2.5 a rung), a ceiling and a
    competitor's price (none, or about one rung's rate)."""
    level, levels = chaotic_level(_LAW_T), _LAW_LEVELS
    truth = np.where(rng.random(16) < 0.3, level + rng.uniform(1, 20, 16),
                     rng.uniform(2.0, 8.0, 16))
    scale, order = 10.0 ** rng.uniform(-3, 1), rng.uniform(0.5, 4.0)
    values = [truth * (1 + scale * 2.0**(-order * j) * rng.normal(size=16))
              for j in range(levels + 1)]
    errors = [scale * 2.0**(-order * j) * rng.lognormal(size=16) for j in range(levels + 1)]
    rates = np.cumprod(rng.uniform(1.0, 2.5, levels + 1))
    ceiling = 10.0 ** rng.uniform(-5, 0)
    limit = rng.choice([math.inf, *rates[:levels]]) * rng.uniform(0.8, 1.2)
    return values, errors, rates, ceiling, limit


def _passes_by_hand(values, errors, ceiling, j):
    """Rung j of a made-up ladder passes: a 0.9 share agreeing with rung
    j + 1 by map_verdict to the map's t_end, the 0.9 quantile of its
    energy errors within the ceiling."""
    share = np.mean(map_verdict(values[j], values[j + 1], _LAW_T, _LAW_T_END))
    return bool(share >= _LAW_QUANTILE
                and np.quantile(errors[j], _LAW_QUANTILE, method="higher") <= ceiling)


def _descend_made_up(values, errors, rates, ceiling, limit, with_floor):
    """descend over a made-up ladder: the rung chosen (or None)."""
    made: set = set()

    def run(j):
        made.add(j)
        return values[j], errors[j], rates[j]

    def floor(j):
        # The rung above's rate: a lower bound where rates grow.
        return rates[j - 1] if j - 1 in made and j not in made else None

    _, chosen = descend(run, range(_LAW_LEVELS), lambda j: 2.0**-j, _LAW_T, _LAW_T_END,
                        _LAW_QUANTILE, ceiling, stop_above=limit, agree=map_verdict,
                        floor=floor if with_floor else None)
    return None if chosen is None else chosen[0]


def test_descend_never_picks_a_failing_rung_nor_stops_before_a_cheaper_passing_one():
    """The laws of a ladder's descent, on 400 made-up ladders
    (_made_up_ladder): the rung chosen passes by map_verdict to a map 10
    times the pilot's t (checked by hand), and it is the first rung in
    order that does; where a competitor's price stops the descent, every
    rung that passes costs more than that price, so no cheaper agreeing
    step is discarded — with the floor and without it alike."""
    rng = np.random.default_rng(19)
    outcomes: Counter = Counter()
    for _ in range(400):
        values, errors, rates, ceiling, limit = _made_up_ladder(rng)
        passing = [j for j in range(_LAW_LEVELS) if _passes_by_hand(values, errors, ceiling, j)]
        first_dear = next((j for j in range(_LAW_LEVELS) if rates[j] > limit), _LAW_LEVELS)
        expected = next((j for j in passing if j < first_dear), None)
        for with_floor in (False, True):
            got = _descend_made_up(values, errors, rates, ceiling, limit, with_floor)
            assert got == expected
            if got is None:
                assert all(rates[j] > limit for j in passing)
            else:
                assert passing[0] == got
        outcomes["chosen" if expected is not None else
                 "stopped" if passing else "none passes"] += 1
    # The made-up ladders reach every outcome.
    assert min(outcomes.values()) >= 20 and len(outcomes) == 3, outcomes


@pytest.mark.usefixtures("xeon_tables")
def test_constant_ladder_spares_the_fine_run_of_a_rung_failing_on_energy():
    """The small softened-point-mass map of the test above, where the LH
    wins by the Xeon's tables: its constant ladder, judged under the LH's prices, ends on the
    rung τ = 1/16, whose energy errors (0.086) exceed the ceiling
    (energy_tol 1e-3). Every constant pilot run made (counted by hook) is
    the coarse run of a rung judged, or the fine run of a rung judged by
    agreement: the ladder as it was also made τ = 1/32, the fine run of that
    last rung and its dearest run (half of its force evaluations), so this
    fails without the shortcuts of step_agreement.descend. The choice is
    the prices' (the LH's, its map bitwise that of the LH at its h, tested
    above), the ladder's rungs judged down to the same step."""
    model, X = _plummer(), _plummer_orbits(0, 26, p_y=(0.55, 0.95))
    with pytest.MonkeyPatch.context() as mp, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        runs = _pilot_runs(mp)
        r = varint.chaos_map(model, X, "fli", t_end=T_END, progress=False)
    constant = r.provenance.tau_choice["constant"]
    assert r.provenance.method == "tm+log" and constant["rule"] == "none"
    tried = constant["tried"]
    judged = {round(tau, 12) for tau, _, _ in tried}
    compared = {round(tau / 2, 12) for tau, share, _ in tried if share is not None}
    made = [round(tau, 12) for kind, tau, _ in runs if kind == "constant"]
    assert made and len(made) == len(set(made)) and set(made) <= judged | compared, (made, tried)
    # The last rung judged failed on its energy errors alone, above the ceiling.
    assert tried[-1][1] is None and tried[-1][2] > constant["ceiling"]
    assert min(made) == tried[-1][0]


def _constant_pilot_run(model, X, tau, **kwargs):
    """One constant-step pilot run of an FLI map's ladder on ``X`` at ``tau``
    (the map's scheme, vector, accumulator and judge): (errors, values,
    counts)."""
    from varint import accuracy
    from varint.stepsize import default_scheme, pilot_errors
    from varint.stepsize_orbits import indicator_judge

    ind = varint.INDICATORS["fli"]
    judge = indicator_judge(ind, model, {}, maps.pilot_tolerance(ind), 1e-3)
    W0 = initial_deviations(model.dim, 1, len(X), 0)
    counts: dict = {}
    errors, values = pilot_errors(model, X, tau, 100.0, default_scheme(model, maps.MAP_SCHEME),
                                  accuracy.Reference(model, X), counts,
                                  (W0, ind.renorm, ind.accumulator_for({}), False),
                                  value=judge.value, **kwargs)
    return errors, values, counts


def test_a_ladder_propagator_and_lazy_errors_give_a_fresh_runs_bits():
    """The propagators of a ladder's rungs (PilotPropagators: the class
    chosen once by make_propagator, the others built at their τ, each kept
    for later ladders) run as propagators built afresh, also when a later
    ladder reuses them, and errors measured on demand (lazy) are those
    measured at once: on the three-body problem (a rotating frame, whose
    class make_propagator chooses from its symbolic form), at the first τ
    built and at two more, every error, FLI and count bitwise equal; the
    lazy errors are measured once, on their first read."""
    from varint.methods import make_propagator
    from varint.stepsize import PilotPropagators, default_scheme

    model = CR3BP(SUN_JUPITER_MU)
    X = _cr3bp_orbits(4, 12, 3.05)
    ind = varint.INDICATORS["fli"]
    scheme = default_scheme(model, maps.MAP_SCHEME)

    def afresh(tau):
        return make_propagator("tm", model, tau, ind.renorm, ind.accumulator_for({}),
                               scheme=scheme)

    for _ in range(2):   # the second ladder reuses the first one's propagators
        build = PilotPropagators(model, ind.renorm, ind.accumulator_for({}), scheme)
        for tau in (0.5, 0.25, 1.0):
            fresh = _constant_pilot_run(model, X, tau, build=afresh)
            measure, values, counts = _constant_pilot_run(model, X, tau, build=build, lazy=True)
            assert callable(measure) and counts == fresh[2] and counts["gradient"] > 0
            errors = measure()
            assert measure() is errors
            assert np.array_equal(errors, fresh[0]) and np.array_equal(values, fresh[1],
                                                                         equal_nan=True)
            assert np.all(np.isfinite(errors)) and np.all(errors > 0)


def test_pilot_propagators_are_kept_per_model_state_and_settings():
    """A later ladder of the same model, settings and τ gets the propagator
    built before; another τ, another model object, other settings, or the
    model changed in place (its parameters, escape radius, masses: what a
    propagator reads of it) get a new one, built as make_propagator builds
    it."""
    from varint.methods import make_propagator
    from varint.stepsize import PilotPropagators, default_scheme

    model = CR3BP(SUN_JUPITER_MU)
    ind = varint.INDICATORS["fli"]
    acc = ind.accumulator_for({})
    scheme = default_scheme(model, maps.MAP_SCHEME)

    def ladder(m=model, renorm=ind.renorm):
        return PilotPropagators(m, renorm, acc, scheme)

    first = ladder()(0.25)
    assert type(first) is type(make_propagator("tm", model, 0.25, ind.renorm, acc, scheme=scheme))
    assert ladder()(0.25) is first and ladder()(np.float64(0.25)) is first
    assert ladder()(0.125) is not first and ladder()(0.125).tau == 0.125
    assert ladder(CR3BP(SUN_JUPITER_MU))(0.25) is not first
    assert ladder(renorm="qr")(0.25) is not first
    model.escape_radius = 10.0
    moved = ladder()(0.25)
    assert moved is not first and moved._escape_r2 == 100.0
    model.params = np.array([1.0])
    assert ladder()(0.25) is not moved
    changed = ladder()(0.25)
    model.inverse_mass[:] = 2.0     # in place: the array's bytes change
    assert ladder()(0.25) is not changed


def test_descend_measures_the_energy_errors_of_judged_rungs_only():
    """descend with errors given as functions (pilot_errors' lazy) on the
    made-up ladder of the tests above: it measures the errors of each rung
    it judges as a coarse run, once, and never those of the fine run of
    the rung that passes (rung 4, 3's fine run), nor of a run whose rate
    stops the descent; the rung chosen is the one of the same ladder with
    its errors given as arrays."""
    measured = []

    def lazy(run):
        memo: dict = {}

        def memoised(j):
            if j not in memo:
                values, errors, rate = run(j)
                memo[j] = (values, lambda e=errors, j=j: measured.append(j) or e, rate)
            return memo[j]

        return memoised

    def agree(a, b, t, t_end):
        return np.abs(a - b) < 0.5

    for stop_above, chosen, judged in ((math.inf, 3, [0, 1, 2, 3]), (5.0, None, [0, 1, 2])):
        measured.clear()
        eager, _ = _synthetic_ladder(8)
        run, made = _synthetic_ladder(8)
        tried, got = descend(lazy(run), range(8), lambda j: 2.0**-j, 100.0, None, 1.0, 2e-3,
                             stop_above=stop_above, agree=agree)
        expected_tried, expected = descend(eager, range(8), lambda j: 2.0**-j, 100.0, None,
                                           1.0, 2e-3, stop_above=stop_above, agree=agree)
        assert tried == expected_tried and got == expected
        assert (None if got is None else got[0]) == chosen
        assert measured == judged and max(made) == judged[-1] + 1, (measured, made)


def test_pilot_sample_is_drawn_once_and_each_caller_gets_a_copy():
    """The pilot's orbits of a map depend on the number of orbits and the
    seed alone: the indices handed out again are a fresh draw's (a seeded
    sample of 16, sorted), each caller's own writable copy, so no caller
    changes them for the next (and numba sees no read-only array)."""
    from varint.step_agreement import pilot_sample

    X = np.zeros((40, 4))
    pick = pilot_sample(X, 3)
    fresh = np.sort(np.random.default_rng(3).choice(40, 16, replace=False))
    assert np.array_equal(pick, fresh) and pick.flags.writeable
    pick[0] = 39
    again = pilot_sample(np.ones((40, 4)), 3)
    assert again is not pick and np.array_equal(again, fresh)
    assert not np.array_equal(pilot_sample(X, 4), fresh)
    assert np.array_equal(pilot_sample(X[:10], 3), np.arange(10))

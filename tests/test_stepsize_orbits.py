"""A step per orbit in maps (``chaos_map(tau="orbit")``,
varint.stepsize_orbits): each orbit runs with τ = U/n of its own pilot, on
the map's common check times; the values are those of the same orbits run
at that step, bitwise across chunking, threads and resume; orbits that pass
a near-singular centre get smaller steps than those that do not."""

import dataclasses

import numba
import numpy as np
import pytest
import sympy as sp

import varint
from varint import accuracy, maps, schemes, state, stepsize, stepsize_orbits
from varint.indicators import resolve
from varint.models import from_potential
from varint.models.maps import StandardMap


@pytest.fixture(scope="module")
def cored():
    """A cored logarithmic potential with a small core (R_c = 0.03), and
    three orbits from (0.5, 0): one nearly radial (p_y = 1e-3, through the
    centre), and two at E = 0 (p_y from the energy): p_x = 1.1 and a
    near-circular loop orbit (p_x = 0)."""
    x, y = sp.symbols("x y")
    model = from_potential(sp.log(sp.Float(0.03) ** 2 + x**2 + y**2 / sp.Float(0.64)) / 2,
                           [x, y])

    def at(x0, px):
        v = 0.5 * np.log(0.03**2 + x0**2)
        return [x0, 0.0, px, np.sqrt(-2 * v - px**2)]

    return model, np.array([[0.5, 0.0, 0.0, 1e-3], at(0.5, 1.1), at(0.5, 0.0)])


def test_orbits_through_the_core_take_smaller_steps(cored):
    """The near-radial orbit passes the core (force gradient ~1/R_c²), the
    loop orbit stays at r ≈ 0.5: its step is several times larger; every
    step divides the unit, so all orbits share the check times."""
    model, X = cored
    r = varint.chaos_map(model, X, "fli", t_end=50.0, tau="orbit", threshold=None)
    choice = r.provenance.tau_choice
    n = np.asarray(choice["divisions"])
    assert choice["rule"] == "orbit" and r.provenance.tau == choice["unit"]
    assert n[0] >= 4 * n[2]
    assert np.array_equal(stepsize_orbits.on_ladder(n), n)
    assert np.all(r.t_stop == r.t[-1])
    assert choice["fallback"] == [] and choice["tolerance"] == maps.pilot_tolerance(
        resolve("fli")[0])


@pytest.fixture(scope="module")
def henon_heiles():
    """Hénon–Heiles orbits whose FLI needs a larger step than the energy
    tolerance asks for (the judge chooses some of their steps)."""
    model = varint.models.HenonHeiles()
    return model, varint.section_grid(model, 0.125, np.linspace(-0.4, 0.6, 6),
                                      np.linspace(-0.3, 0.3, 5)).states[:6]


@pytest.mark.filterwarnings("ignore::varint.accuracy.AccuracyWarning")
@pytest.mark.parametrize("orbits", ["cored", "henon_heiles"])
def test_each_orbit_runs_at_its_own_step_and_meets_the_tolerance(orbits, request):
    """Every orbit's FLI equals, bit for bit, that of the same orbit in a
    map run at the fixed step U/n. An orbit whose step the energy error
    chose keeps it within the pilot's tolerance over the pilot's horizon (at
    the pilot's 50 checks); one whose step its indicator chose keeps it
    within the judge's bound, and its FLI at the pilot's end, from maps run
    at its step and at the smaller step it was compared with, agrees within
    the judge's agreement. (The fixed-step maps at the larger orbits' steps
    are not accurate for the orbit through the core: that is the point.)"""
    model, X = request.getfixturevalue(orbits)
    per = varint.chaos_map(model, X, "fli", t_end=50.0, tau="orbit", threshold=None)
    choice = per.provenance.tau_choice
    judge = choice["judge"]
    assert (choice["judged"] != []) == (orbits == "henon_heiles")
    assert judge == {"indicator": "fli", "agreement": stepsize_orbits.AGREEMENT,
                     "energy_bound": min(stepsize_orbits.BOUND_FACTOR * choice["tolerance"],
                                         accuracy.DEFAULT_ENERGY_TOL / 100)}
    compared = dict(zip(choice["judged"], choice["compared"], strict=True))
    for m, n in enumerate(choice["divisions"]):
        tau = choice["unit"] / n
        fixed = varint.chaos_map(model, X, "fli", t_end=50.0, tau=tau, threshold=None,
                                 scheme=choice["scheme"])
        assert per.values[m] == fixed.values[m]
        checks = min(50, round(choice["pilot_t"] / tau))
        run = varint.run(model, X[m], "fli", choice["pilot_t"], tau=tau,
                         scheme=choice["scheme"], t_out=checks)
        if m not in compared:
            assert np.max(run.energy_error) <= choice["tolerance"]
            continue
        assert compared[m] > n and np.max(run.energy_error) <= judge["energy_bound"]
        at = [varint.chaos_map(model, X, "fli", t_end=choice["pilot_t"], threshold=None,
                               tau=choice["unit"] / d, scheme=choice["scheme"]).values[m]
              for d in (n, compared[m])]
        assert abs(at[0] - at[1]) <= judge["agreement"] * max(1.0, abs(at[1]))


def test_the_indicator_takes_larger_steps_than_the_energy_error(henon_heiles):
    """On Hénon–Heiles orbits the energy tolerance asks for steps the FLI
    does not need: with the judge every orbit's step is at least as large
    as without it, and some are larger (the orbits it judged)."""
    model, X = henon_heiles
    ind, fixed = resolve("fli")
    options = ind.configure(model, dict(fixed))
    common = {"scheme": maps.MAP_SCHEME, "k": 1, "renorm": ind.renorm,
              "accumulator": ind.accumulator_for(options)}
    tol = maps.pilot_tolerance(ind)
    _, by_energy, plain = stepsize_orbits.choose_steps(model, X, 50.0, tol, **common)
    judge = stepsize_orbits.indicator_judge(ind, model, options, tol, 1e-3)
    _, by_value, judged = stepsize_orbits.choose_steps(model, X, 50.0, tol, judge=judge,
                                                       **common)
    assert "judge" not in plain
    assert np.all(by_value <= by_energy)
    assert np.flatnonzero(by_value < by_energy).tolist() == judged["judged"] != []


def test_the_pilot_reads_the_value_the_map_shows():
    """The pilot's value at its end is, bit for bit, the map's value of the
    same orbits (same vectors, step and horizon)."""
    model = varint.models.HenonHeiles()
    X = varint.section_grid(model, 0.125, np.linspace(-0.3, 0.5, 3),
                            np.linspace(-0.2, 0.2, 2)).states
    # FLI (an accumulator's value) and SALI (the vectors'); MEGNO's value is
    # an accumulator's too, and its stepper one more to compile (~15 CPU s).
    for name in ("fli", "sali"):
        ind, fixed = resolve(name)
        options = ind.configure(model, dict(fixed))
        k = ind.vectors(model, options, None)
        judge = stepsize_orbits.indicator_judge(ind, model, options, 1e-7, 1e-3)
        W0 = state.initial_deviations(model.dim, k, len(X), 0, np.arange(len(X)))
        _, values = stepsize.pilot_errors(
            model, X, 0.25, 20.0, schemes.get_scheme(maps.MAP_SCHEME),
            accuracy.Reference(model, X), {},
            (W0, ind.renorm, ind.accumulator_for(options), False), value=judge.value)
        ref = varint.chaos_map(model, X, name, t_end=20.0, tau=0.25, threshold=None,
                               scheme=maps.MAP_SCHEME)
        assert np.array_equal(values, ref.values), name


def test_the_judge_compares_values_or_their_logarithms():
    """Relative to max(1, |u|) of the smaller step's value; log₁₀ for a
    log-scale indicator; NaN agrees with nothing."""
    judge = stepsize_orbits.Judge(value=None, name="x", log_scale=False, agreement=0.05,
                                  bound=1e-5)
    coarse = np.array([10.4, 10.6, 0.03, 0.07, np.nan, 1.0])
    fine = np.array([10.0, 10.0, 0.0, 0.0, 1.0, np.nan])
    assert judge.agrees(coarse, fine).tolist() == [True, False, True, False, False, False]
    logs = dataclasses.replace(judge, log_scale=True)
    assert logs.agrees(np.array([1e-10, 1e-10, 0.5]), np.array([1e-10 * 10**0.45, 1e-11,
                                                                0.5 * 10**0.04])).tolist() \
        == [True, False, True]


def test_steps_per_orbit_are_bitwise_across_chunking_threads_and_resume(tmp_path,
                                                                       henon_heiles):
    """The orbits and indicator (FLI, an accumulator in the state) of the
    tests above, whose stepper they compiled: fewer orbits than a block of
    SIMD lanes run one at a time (a map of 30 orbits compiled the lanes of
    a stepper of its own, ~50 CPU s cold; the lanes are bitwise the
    one-orbit stepper, tests/test_generated_stepper.py)."""
    model, X = henon_heiles
    a = varint.chaos_map(model, X, "fli", t_end=50.0, tau="orbit")
    threads = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        b = varint.chaos_map(model, X, "fli", t_end=50.0, tau="orbit", chunk_size=2,
                             checkpoint=tmp_path / "m")
    finally:
        numba.set_num_threads(threads)
    (tmp_path / "m" / "chunk_000001.npz").unlink()
    c = varint.chaos_map(model, X, "fli", t_end=50.0, tau="orbit", chunk_size=2,
                         checkpoint=tmp_path / "m")
    assert c.provenance.options["chunks_resumed"] == len(list((tmp_path / "m").glob("chunk_*")))\
        - 1
    for other in (b, c):
        for name in ("values", "t_stop", "status", "state", "energy_error"):
            assert np.array_equal(getattr(a, name), getattr(other, name), equal_nan=True), name
        assert other.provenance.tau_choice["divisions"] == a.provenance.tau_choice["divisions"]


def test_the_divisor_follows_the_order():
    """e ∝ τ^p: an error 2^p times the tolerance asks for half the step; a
    non-finite one for a step 16 times smaller; at least one more. An error
    that did not halve when the step did is not the truncation error."""
    n = stepsize_orbits._next_divisor(np.array([3, 3, 3, 3]),
                                      np.array([1e-7 * 2.0**6, np.inf, 1.0000001e-7, 1e300]),
                                      1e-7, 6)
    assert n.tolist() == [6, 48, 4, 2**62]
    tried_n = np.array([[1, 2], [1, 2], [1, 0]])
    tried_e = np.array([[1e-3, 9e-4], [1e-3, 9e-4], [1e-3, 0.0]])
    stuck = stepsize_orbits._not_shrinking(tried_n, tried_e, np.array([2, 2, 2]),
                                           np.array([9e-4, 1e-5, np.inf]))
    assert stuck.tolist() == [True, False, True]


def test_divisors_round_up_to_the_ladder():
    """Each divisor becomes the smallest integer at least as large with at
    most LADDER_BITS significant binary digits (checked against a search
    over the integers): a step at most 1.5 times smaller, and within each
    octave only 2^(LADDER_BITS − 1) divisors, so orbits share few groups."""
    n = np.arange(1, 2000)
    up = stepsize_orbits.on_ladder(n)

    def bits(v):
        return v.bit_length() - (v & -v).bit_length() + 1

    ladder = [v for v in range(1, 4000) if bits(v) <= stepsize_orbits.LADDER_BITS]
    assert up.tolist() == [next(v for v in ladder if v >= m) for m in n.tolist()]
    assert np.all(up < 1.5 * n + 1)
    assert len([v for v in ladder if 64 <= v < 128]) == 2 ** (stepsize_orbits.LADDER_BITS - 1)
    with pytest.raises(ValueError, match="at least 1, got 0"):
        stepsize_orbits.on_ladder(np.array([3, 0]))


@pytest.mark.parametrize("model, kwargs, match", [
    ("hh", {"tau": "auto"}, "None or 'orbit'"),
    ("hh", {"tau": "orbit", "method": "dop853"}, "no such step"),
    ("hh", {"tau": "orbit", "t_check": [10.0, 20.0]}, "as a count or None"),
    ("sm", {"tau": "orbit"}, "no such step"),
])
def test_steps_per_orbit_refuse_what_they_cannot_do(model, kwargs, match):
    m = varint.models.HenonHeiles() if model == "hh" else StandardMap(1.2)
    x = np.array([[0.0, 0.1, 0.3, 0.0]]) if model == "hh" else np.array([[0.1, 0.2]])
    with pytest.raises(ValueError, match=match):
        varint.chaos_map(m, x, "fli", t_end=20.0, **kwargs)

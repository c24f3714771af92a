"""The baselines obey the propagator protocol of varint.methods: chunking
and resuming are bitwise invisible, options are checked, failures are
reported per orbit, work is counted, provenance names the libraries."""

import copy

import numpy as np
import pytest

import varint
from varint.baselines.blocks import COND_LIMIT
from varint.protocol import Status
from varint.methods import make_propagator
from varint.models import HenonHeiles, Model
from varint.state import RunState, initial_deviations

#: Every baseline configuration with its own code path; CVODE with a short
#: block so that block ends fall inside the chunks below.
CONFIGS = [("taylor", {}), ("taylor", {"precision": "extended"}), ("cvode", {"block": 7}),
           ("dop853", {}), ("dop853", {"engine": "scipy"}), ("dop853", {"engine": "lanes"})]
CONFIG_IDS = ["taylor", "taylor-extended", "cvode", "dop853", "dop853-scipy", "dop853-lanes"]


def start(c1, r1, k=3):
    x = np.stack([c1[1], r1[1]])
    return RunState.start(x, initial_deviations(4, k, 2, seed=0))


def same_state(a, b):
    return (a.step == b.step and a.counts == b.counts and
            all(np.array_equal(getattr(a, f), getattr(b, f))
                for f in ("x", "W", "acc_m", "acc_e", "status", "fail_step")))


@pytest.mark.parametrize("method, options", CONFIGS, ids=CONFIG_IDS)
@pytest.mark.parametrize("renorm", ["qr", "normalize", "none"])
def test_chunked_and_resumed_runs_are_bitwise_identical(method, options, renorm, c1, r1):
    """Rules 3 and 8: advance(a); advance(b) = advance(a + b), also when each
    chunk resumes from a copy of the state with a new propagator (a
    checkpoint)."""
    model = c1[0]
    whole = start(c1, r1)
    make_propagator(method, model, 0.05, renorm, **options).advance(whole, 40)
    chunked = start(c1, r1)
    for n in (3, 11, 1, 5, 20):
        make_propagator(method, model, 0.05, renorm, **options).advance(chunked, n)
        chunked = copy.deepcopy(chunked)
    assert same_state(whole, chunked)
    assert whole.counts["steps"] == 80


@pytest.mark.parametrize("method, options", CONFIGS, ids=CONFIG_IDS)
def test_no_deviation_vectors_means_no_tangent_work(method, options, r1):
    """Rule 7: with k = 0 only the orbit is integrated; it matches the orbit
    integrated alongside vectors."""
    model, x0 = r1
    bare = varint.integrate(model, x0, 2.0, method=method, **options)
    full = varint.integrate(model, x0, 2.0, method=method, deviations=np.eye(4)[:, :1], **options)
    assert bare.deviations.shape == (4, 0)
    assert np.allclose(bare.state, full.state, rtol=0, atol=1e-9)
    work = {k: v for k, v in bare.provenance.counts.items() if k != "steps"}
    work_full = {k: v for k, v in full.provenance.counts.items() if k != "steps"}
    assert work and all(work[k] <= work_full[k] for k in work)


@pytest.mark.parametrize("method, options", CONFIGS, ids=CONFIG_IDS)
def test_escaping_orbit_fails_alone_at_its_interval(method, options, c1):
    """Rules 2 and 4: an orbit above the escape energy is stopped when |q|
    passes the escape radius, with its interval; the other orbit of the
    batch runs on exactly as alone."""
    model = HenonHeiles(escape_radius=2.0)
    escaping = varint.solve_momentum(model, [0.0, 0.0], [0.0, 0.2], 0.25)
    x0 = np.stack([c1[1], escaping])
    kw = dict(method=method, n_exponents=2, t_out=10, **options)
    with pytest.warns(RuntimeWarning):
        both = varint.lyapunov_spectrum(model, x0, 20.0, errors="flag", **kw)
    alone = varint.lyapunov_spectrum(model, c1[1], 20.0, **kw)
    assert list(both.status) == [Status.OK, Status.ESCAPED]
    assert np.array_equal(both.exponents[0], alone.exponents)
    assert np.isnan(both.exponents[1, -1]).all()
    with pytest.raises(varint.IntegrationError, match="escaped") as info:
        varint.lyapunov_spectrum(model, escaping, 20.0, **kw)
    tm = pytest.raises(varint.IntegrationError, varint.lyapunov_spectrum, model, escaping, 20.0,
                       tau=0.05, n_exponents=2, t_out=10)  # the baselines' τ
    # The escape happens in the same interval as for the TM method, give or take one.
    assert abs(info.value.step - tm.value.step) <= 1


def test_an_orbit_blowing_up_fails_in_the_same_interval_for_every_baseline():
    """Above the escape energy, without an escape radius, the orbit reaches
    infinity in finite time (t ≈ 16.5). Every baseline reports it in the
    same interval — also when blocks ended early on the way (a failure of
    the integrator beyond an early block end must not count) — and the TM
    method within two intervals."""
    model = HenonHeiles()
    x0 = varint.solve_momentum(model, [0.0, 0.0], [0.0, 0.2], 0.25)
    steps = {}
    for (method, options), name in zip(CONFIGS + [("tm", {})], CONFIG_IDS + ["tm"], strict=True):
        with pytest.raises(varint.IntegrationError) as info:
            if method == "tm":
                # TM chooses its own step with a pilot run, which sees the
                # blow-up and says so.
                with pytest.warns(varint.AccuracyWarning, match="no step of SBAB2C keeps"):
                    varint.lyapunov_spectrum(model, x0, 30.0, method=method, **options)
            else:
                varint.lyapunov_spectrum(model, x0, 30.0, method=method, **options)
        steps[name] = info.value.step
    assert len({steps[name] for name in CONFIG_IDS}) == 1, steps
    assert abs(steps["tm"] - steps["taylor"]) <= 2 and 300 < steps["tm"] < 360, steps


def test_virtual_renormalisation_ends_a_block_when_it_would_lose_accuracy(c1):
    """Along a block the renormalised vectors are the raw ones times C; once
    C's condition exceeds COND_LIMIT the block is cut short (so the raw
    vectors never carry more than that spread of scales) — at the same
    interval however the run is chunked."""
    model, x0 = c1
    W0 = initial_deviations(4, 4, 1, seed=0)
    whole = RunState.start(x0[None], W0)
    make_propagator("taylor", model, 0.05, "qr", block=10_000).advance(whole, 4000)
    assert whole.counts["blocks"] > 1  # 200 time units: several blocks despite block=10000
    d = np.abs(np.diag(whole.extra["taylor_C"][0]))
    assert d.max() <= COND_LIMIT * d.min()
    stepwise = RunState.start(x0[None], W0)
    prop = make_propagator("taylor", model, 0.05, "qr", block=10_000)
    for _ in range(4000):
        prop.advance(stepwise, 1)
    assert same_state(whole, stepwise)


@pytest.mark.parametrize("method", ["taylor", "cvode", "dop853"])
def test_options_are_checked_and_scheme_is_refused(method, r1):
    model, x0 = r1
    with pytest.raises(TypeError, match="unknown option 'rtl'.*valid options"):
        make_propagator(method, model, 0.05, "qr", rtl=1e-9)
    with pytest.raises(ValueError, match="takes no scheme"):
        varint.lyapunov_spectrum(model, x0, 1.0, method=method, scheme="SBAB2C")


@pytest.mark.parametrize("method, options, message", [
    ("taylor", {"precision": "quad"},
     "unknown precision 'quad'; expected one of: double, extended"),
    ("taylor", {"tol": -1.0}, "tol must be a positive finite number"),
    ("taylor", {"precision": "extended", "block": 5}, "block must be 1"),
    ("taylor", {"block": 0}, "block must be a positive integer"),
    ("taylor", {"compact_mode": "yes"}, "compact_mode must be"),
    ("cvode", {"rtol": 0.0}, "rtol must be a positive finite number"),
    ("cvode", {"atol": float("nan")}, "atol must be a positive finite number"),
    ("cvode", {"linsolver": "lu"}, "unknown linsolver 'lu'; expected one of: dense, gmres"),
    ("dop853", {"delta": 1e-8, "rtol": 1e-8}, "either delta"),
    ("dop853", {"delta": -1e-8}, "delta must be a positive finite number"),
    ("dop853", {"engine": "numba"}, "unknown engine 'numba'; expected one of: compiled, scipy"),
])
def test_bad_option_values_raise_value_errors_naming_them(method, options, message, r1):
    with pytest.raises(ValueError, match=message):
        make_propagator(method, r1[0], 0.05, "qr", **options)


def test_taylor_needs_a_symbolic_potential(r1):
    plain = Model(2, r1[0]._potential, r1[0].grad_kernel, r1[0].hess_kernel, r1[0].third_kernel,
                  bandwidth=1, name="plain")
    with pytest.raises(ValueError, match="from_potential"):
        make_propagator("taylor", plain, 0.05, "qr")
    # The right-hand-side baselines need only the kernels.
    make_propagator("cvode", plain, 0.05, "qr")


def test_unknown_method_lists_the_baselines(r1):
    with pytest.raises(ValueError, match="taylor.*cvode.*dop853|dop853"):
        varint.lyapunov_spectrum(*r1, 1.0, method="rk45")


@pytest.mark.parametrize("method, options, package, counted", [
    ("taylor", {"precision": "extended"}, "heyoka", "taylor_steps"),
    ("cvode", {"rtol": 1e-9}, "scikit-sundae", "rhs_evaluations"),
    ("dop853", {"delta": 1e-7}, "scipy", "rhs_evaluations"),
])
def test_provenance_records_options_versions_and_work(method, options, package, counted, r1):
    r = varint.lyapunov_spectrum(*r1, 1.0, method=method, n_exponents=2, **options)
    p = r.provenance
    assert p.method == method and p.versions[package]
    for key, value in options.items():
        assert p.method_options[key] == value
    assert p.counts[counted] > 0 and p.counts["steps"] == 20
    if method == "dop853":
        assert p.method_options["rtol"] == p.method_options["atol"] == 1e-7


@pytest.mark.parametrize("method, options", CONFIGS, ids=CONFIG_IDS)
def test_resuming_from_a_checkpoint_file_is_bitwise_identical(method, options, c1, r1, tmp_path):
    """Rule 8 through varint.checkpoint: the long-double state of the
    extended reference and the pending block outputs survive the file."""
    from varint import checkpoint

    model = c1[0]
    whole = start(c1, r1)
    make_propagator(method, model, 0.05, "qr", **options).advance(whole, 30)
    part = start(c1, r1)
    make_propagator(method, model, 0.05, "qr", **options).advance(part, 17)
    checkpoint.write(tmp_path / "c.ckpt", checkpoint.Snapshot({}, part, [], 0.0))
    resumed = checkpoint.read(tmp_path / "c.ckpt").state
    make_propagator(method, model, 0.05, "qr", **options).advance(resumed, 13)
    assert same_state(whole, resumed)


def test_a_cut_block_makes_the_next_as_long_as_the_part_used(c1):
    """After a block is cut at output j (COND_LIMIT), the next block is j
    intervals long; a block used whole makes the next BLOCK_GROWTH times
    longer, never beyond the block size."""
    from varint.baselines.blocks import BLOCK_GROWTH

    model, x0 = c1
    cap = 5000
    prop = make_propagator("taylor", model, 0.05, "qr", block=cap)
    state = RunState.start(x0[None], initial_deviations(4, 4, 1, seed=0))
    starts, lengths = [], []
    integrate = prop._integrate

    def spy(state, m, y0, n_out):
        lengths.append(n_out)
        return integrate(state, m, y0, n_out)

    new_block = prop._new_block

    def spy_block(state, m, step):
        starts.append(step)
        return new_block(state, m, step)

    prop._integrate, prop._new_block = spy, spy_block
    prop.advance(state, 40_000)
    used = np.diff(starts)
    assert lengths[0] == cap and (used < np.array(lengths[:-1])).sum() >= 5
    grown = 0
    for length, part, after in zip(lengths, used, lengths[1:], strict=False):
        if part < length:
            assert after == part
        else:
            # Used whole; cut right at its last output it stays as long.
            assert after in (length, min(cap, int(length * BLOCK_GROWTH) + 1))
            grown += after > length
    assert grown >= 1


def test_dop853_lanes_is_the_same_method_and_an_orbit_keeps_its_bits_in_any_batch(c1, r1):
    """The lanes engine integrates the paper's DOP853 in plain loops: it
    agrees with the compiled engine (SciPy's arithmetic) to rounding on a
    regular orbit, does the same work, and an orbit alone and in a batch of
    ten with others gives the same bits."""
    W0 = initial_deviations(4, 4, 1, seed=0)
    states = {}
    for engine in ("compiled", "lanes"):
        state = RunState.start(r1[1][None], W0)
        make_propagator("dop853", r1[0], 0.05, "qr", engine=engine).advance(state, 2000)
        states[engine] = state
    a, b = states["compiled"], states["lanes"]
    assert np.abs(a.x - b.x).max() < 1e-12 and np.abs(a.W - b.W).max() < 1e-11
    assert a.counts == b.counts
    X = np.stack([c1[1], r1[1]] * 5)
    W = initial_deviations(4, 4, 10, seed=2)
    batch = RunState.start(X, W)
    prop = make_propagator("dop853", c1[0], 0.05, "qr", engine="lanes")
    prop.advance(batch, 500)
    for m in (0, 3, 9):
        alone = RunState.start(X[m:m + 1], W[m:m + 1])
        prop.advance(alone, 500)
        assert np.array_equal(alone.x[0], batch.x[m]) and np.array_equal(alone.W[0], batch.W[m])

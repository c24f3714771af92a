"""A prepared run (:func:`varint.prepare`) called with new initial states
gives the one-shot call's result bit for bit, checks each call's states as
the one-shot call does, and refuses what it cannot reuse."""

import dataclasses

import numpy as np
import pytest

import varint
from varint.models import StandardMap
from varint.run import prepare as prepare_run

#: Provenance fields that differ between any two runs: when and how long,
#: and the counts of force evaluations (a chunk's first step evaluates the
#: force its previous step would have passed on, and chunks are sized by
#: time; the steps are compared).
_CLOCK = {"wall_time", "created", "machine", "timing", "cpu_time", "counts"}


def _same(a, b):
    """Two results equal bit for bit in every array and in their
    provenance but its clock."""
    assert type(a) is type(b)
    for f in dataclasses.fields(a):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if f.name == "provenance":
            assert x.counts["steps"] == y.counts["steps"]
            for g in dataclasses.fields(x):
                if g.name not in _CLOCK:
                    assert getattr(x, g.name) == getattr(y, g.name), g.name
        elif f.name == "accuracy":
            assert x.verdict == y.verdict
            np.testing.assert_array_equal(x.energy_error, y.energy_error)
        elif isinstance(x, dict):
            assert x.keys() == y.keys()
            for key in x:
                np.testing.assert_array_equal(x[key], y[key], strict=True)
        elif isinstance(x, np.ndarray):
            np.testing.assert_array_equal(x, y, strict=True)
        else:
            assert x == y, f.name


def _one_shot(*args, **kwargs):
    """``varint.run(*args, **kwargs)`` built from scratch (never a
    remembered call's set-up, :mod:`varint.remembered`): the independent
    reference of a prepared run's calls."""
    return prepare_run(*args, **kwargs).execute()


def _states(x0, n):
    """``n`` states near ``x0``, seeded."""
    return x0 + 1e-3 * np.random.default_rng(7).standard_normal((n, len(x0)))


def test_one_step_with_given_vectors_is_the_one_shot_call():
    """The fixed-cost case (studies/call_profile.py): every call, the first
    (which builds the run) and the later ones (which reuse it), bitwise."""
    model, x0 = varint.paper_orbit("R1")
    w = np.random.default_rng(1).standard_normal((4, 1))
    w /= np.linalg.norm(w)
    run = varint.prepare(model, "integrate", 0.05, tau=0.05, scheme="s15odr8", deviations=w)
    for x in _states(x0, 3):
        _same(run(x), varint.integrate(model, x, 0.05, tau=0.05, scheme="s15odr8",
                                       deviations=w))


@pytest.mark.parametrize("indicator, options", [
    ("lyapunov", {}), ("megno", {}), ("gali", {"k": (2, 4)}), ("sali", {"t_out": 5})])
def test_seeded_indicators_are_the_one_shot_calls(indicator, options):
    model, x0 = varint.paper_orbit("C1")
    run = varint.prepare(model, indicator, 20.0, tau=0.05, **options)
    for x in _states(x0, 2):
        _same(run(x), _one_shot(model, x, indicator, 20.0, 0.05, **options))


def test_batches_of_other_sizes_and_given_vectors_per_call():
    """A batch after one state (other seeded vectors: as many orbits, drawn
    again), then vectors given for one call only."""
    model, x0 = varint.paper_orbit("R1")
    run = varint.prepare(model, "lyapunov", 5.0, tau=0.05, scheme="ABA864")
    X = _states(x0, 3)
    _same(run(x0), varint.lyapunov_spectrum(model, x0, 5.0, tau=0.05, scheme="ABA864"))
    _same(run(X), varint.lyapunov_spectrum(model, X, 5.0, tau=0.05, scheme="ABA864"))
    q, _ = np.linalg.qr(np.random.default_rng(3).standard_normal((4, 4)))
    _same(run(x0, deviations=q),
          varint.lyapunov_spectrum(model, x0, 5.0, tau=0.05, scheme="ABA864", deviations=q))
    # And back to the seeded vectors.
    _same(run(X[1]), varint.lyapunov_spectrum(model, X[1], 5.0, tau=0.05, scheme="ABA864"))


def test_prepared_vectors_for_another_number_of_orbits():
    """Vectors given to prepare, shared by all orbits, are checked again
    for a batch after a single state."""
    model, x0 = varint.paper_orbit("C1")
    w = np.array([[1.0, 0.0], [0.0, 1.0], [0.0, 0.0], [0.0, 0.0]])
    run = varint.prepare(model, "sali", 10.0, tau=0.05, deviations=w)
    X = _states(x0, 2)
    _same(run(x0), varint.sali(model, x0, 10.0, tau=0.05, deviations=w))
    _same(run(X), varint.sali(model, X, 10.0, tau=0.05, deviations=w))


@pytest.mark.parametrize("method", ["dop853", "cvode"])
def test_reference_methods(method):
    """Their propagators keep solvers between calls (CVODE's per size), as
    between the chunks of one run."""
    model, x0 = varint.paper_orbit("R1")
    run = varint.prepare(model, "megno", 2.0, tau=0.1, method=method)
    for x in _states(x0, 2):
        _same(run(x), varint.megno(model, x, 2.0, tau=0.1, method=method))


def test_a_map():
    smap = StandardMap(K=1.2)
    run = varint.prepare(smap, "fli", 50)
    for x in ([0.1, 0.2], [[0.3, 0.1], [2.0, 1.0]]):
        _same(run(x), _one_shot(smap, x, "fli", 50))


def test_a_drawn_seed_is_drawn_at_every_call():
    """seed=None: every call draws its own seed, as every one-shot call
    does (the first run's vectors are not reused)."""
    model, x0 = varint.paper_orbit("C1")
    run = varint.prepare(model, "lyapunov", 1.0, tau=0.05, seed=None)
    a, b = run(x0), run(x0)
    assert a.provenance.seed != b.provenance.seed
    _same(b, varint.lyapunov_spectrum(model, x0, 1.0, tau=0.05, seed=b.provenance.seed))


def test_each_call_checks_its_states():
    model, x0 = varint.paper_orbit("R1")
    run = varint.prepare(model, "lyapunov", 1.0, tau=0.05)
    run(x0)
    with pytest.raises(ValueError, match=r"x0 must have shape \(4,\) or \(M, 4\).*got shape \(3,\)"):
        run(x0[:3])
    with pytest.raises(ValueError, match="x0 must be finite; component 2 is nan"):
        run(np.array([0.0, 0.1, np.nan, 0.0]))
    with pytest.raises(ValueError, match="n_exponents = 4 but 2 deviation vectors were given"):
        run(x0, deviations=np.eye(4)[:, :2])
    carry = varint.prepare(model, "integrate", 1.0, tau=0.05, deviations=np.eye(4)[:, :1])
    carry(x0)
    with pytest.raises(ValueError, match=r"deviations must hold 1 vectors .* got 2"):
        carry(x0, deviations=np.eye(4)[:, :2])
    # A failure is reported as by the one-shot call (the energy is above
    # the escape energy: the orbit leaves).
    far = np.array([0.0, 0.0, 1.0, 0.3])
    with pytest.raises(varint.IntegrationError) as one_shot:
        varint.lyapunov_spectrum(model, far, 200.0, tau=0.05, escape_radius=5.0)
    with pytest.raises(varint.IntegrationError) as prepared:
        varint.prepare(model, "lyapunov", 200.0, tau=0.05, escape_radius=5.0)(far)
    assert str(prepared.value) == str(one_shot.value)


def test_each_call_checks_the_kernels_at_its_states():
    # The kernels' check keeps its buffers between calls: a state where a
    # derivative is not finite is refused with the one-shot call's message,
    # and the next good state is not judged by what the bad one left. One
    # exponent: the one-shot call's stepper is then tests/test_accuracy.py's
    # on this model (the full spectrum compiled two of its own, ~23 s cold).
    import sympy as sp

    x, y = sp.symbols("x y")
    model = varint.models.from_potential(1 / x + y**2 / 2, [x, y], name="1/x")
    good, bad = np.array([1.0, 0.1, 0.1, 0.0]), np.array([0.0, 0.1, 0.1, 0.0])
    run = varint.prepare(model, "lyapunov", 0.2, tau=0.05, n_exponents=1)
    _same(run(good), varint.lyapunov_spectrum(model, good, 0.2, tau=0.05, n_exponents=1))
    with pytest.raises(ValueError) as one_shot:
        varint.lyapunov_spectrum(model, bad, 0.2, tau=0.05, n_exponents=1)
    for _ in range(2):
        with pytest.raises(ValueError) as prepared:
            run(bad)
        assert str(prepared.value) == str(one_shot.value)
    assert "the gradient ∇V is [-inf, 0.1]" in str(one_shot.value)
    _same(run(good), varint.lyapunov_spectrum(model, good, 0.2, tau=0.05, n_exponents=1))
    with pytest.raises(ValueError, match="not finite at the initial state of orbit 1, q = "
                                         r"\[0.0, 0.1\]"):
        run(np.array([good, bad]))


def test_what_a_prepared_run_refuses_before_any_work():
    model, _ = varint.paper_orbit("R1")
    with pytest.raises(ValueError, match="a prepared run needs tau="):
        varint.prepare(model, "lyapunov", 10.0)
    with pytest.raises(ValueError, match="a prepared run takes no checkpoint"):
        varint.prepare(model, "lyapunov", 10.0, tau=0.05, checkpoint="x.ckpt")
    with pytest.raises(ValueError, match="unknown method .rk4.; expected one of"):
        varint.prepare(model, "lyapunov", 10.0, tau=0.05, method="rk4")
    with pytest.raises(ValueError, match="unknown errors .ignore.; expected one of"):
        varint.prepare(model, "lyapunov", 10.0, tau=0.05, errors="ignore")
    assert "lyapunov of HenonHeiles by tm, tau=0.05, t_end=10" in repr(
        varint.prepare(model, "lyapunov", 10.0, tau=0.05))


def test_results_of_one_prepared_run_share_no_provenance():
    # The provenance's fixed parts are worked out once per prepared run;
    # each result still holds its own copies, so changing one result's
    # provenance leaves the next one's as the one-shot call's.
    model, x0 = varint.paper_orbit("R1")
    run = varint.prepare(model, "lyapunov", 1.0, tau=0.05)
    first = run(x0)
    first.provenance.model["inverse_mass"].append(0.0)
    first.provenance.method_options["scheme"]["name"] = "changed"
    first.provenance.versions["numpy"] = "changed"
    again, alone = run(x0).provenance, varint.lyapunov_spectrum(model, x0, 1.0, tau=0.05).provenance
    for field in ("model", "method_options", "options", "versions"):
        assert getattr(again, field) == getattr(alone, field), field


def test_the_one_pass_check_of_a_short_call_refuses_and_accepts_as_the_one_shot_call():
    # A short call tests one float64 state and its kernels finite in one
    # pass (KernelCheck.states); any other state, and any state that pass
    # refuses, goes through the one-shot call's checks in their order, so
    # the result or the message is the one-shot call's.
    import sympy as sp

    x, y = sp.symbols("x y")
    model = varint.models.from_potential(1 / x + y**2 / 2, [x, y], name="1/x")
    good = np.array([1.0, 0.1, 0.1, 0.0])
    run = varint.prepare(model, "lyapunov", 0.2, tau=0.05)
    run(good)
    assert run._again.short is not None
    accepted = [good[::-1][::-1], good.astype(np.float32), good.tolist(), good.astype(">f8"),
                np.array([good, good])[:, ::1][0], np.array([[1.0, 0.1, 0.1, 0.0]])]
    for state in accepted:
        _same(run(state), varint.lyapunov_spectrum(model, state, 0.2, tau=0.05))
    refused = [np.array([0.0, 0.1, 0.1, 0.0]),        # ∇V not finite
               np.array([np.nan, 0.1, 0.1, 0.0]),     # q not finite (the kernels see it)
               np.array([0.0, 0.1, np.inf, 0.0]),     # p not finite, ∇V not finite
               np.array([1.0, 0.1, 0.1, np.nan]),     # p not finite, the kernels finite
               np.array([1.0, 0.1, 0.1]),
               np.array([[1.0, 0.1, 0.1, 0.0], [1.0, 0.1, 0.1, np.nan]])]
    for state in refused:
        with pytest.raises(ValueError) as one_shot:
            varint.lyapunov_spectrum(model, state, 0.2, tau=0.05)
        with pytest.raises(ValueError) as prepared:
            run(state)
        assert str(prepared.value) == str(one_shot.value)
    # The buffers hold nothing over from a refused state.
    _same(run(good), varint.lyapunov_spectrum(model, good, 0.2, tau=0.05))


def test_the_compiled_finiteness_test_is_numpys():
    # KernelCheck.states tests the kernels' values finite in one compiled
    # pass (varint.finite_values): a NaN or infinity anywhere refuses, the
    # largest and smallest finite numbers do not.
    from varint.finite_values import ALL_FINITE, _all_finite

    base = np.linspace(-1.0, 1.0, 14)
    assert _all_finite(base) and _all_finite(base[:0])
    for bad in (np.nan, np.inf, -np.inf, 1.7976931348623157e308, 5e-324, -0.0):
        for i in range(base.size):
            v = base.copy()
            v[i] = bad
            assert _all_finite(v) == bool(np.isfinite(v).all()), (bad, i)
            assert ALL_FINITE(v) == _all_finite(v)

"""A prepared run's short calls (:class:`varint.rerun.ShortCall`: the
stepper driven from fresh arrays, the result assembled directly) give the
one-shot call's result bit for bit, and leave failures and long calls to
the general path (:meth:`varint.run.Run.with_orbits`)."""

import copy
import dataclasses
import pickle
import warnings
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
import sympy as sp

import varint
from varint import accuracy
from varint.methods.general import GeneralPropagator
from varint.models import from_hamiltonian
from varint.rerun import ShortCall
from varint.protocol import Status
from varint.run import Run

from .test_prepared import _one_shot, _same, _states


@pytest.fixture
def general(monkeypatch):
    """The calls that took the general path, counted."""
    calls = []
    original = Run.with_orbits

    def counted(self, *args, **kwargs):
        calls.append(args)
        return original(self, *args, **kwargs)

    monkeypatch.setattr(Run, "with_orbits", counted)
    return calls


@pytest.mark.parametrize("indicator, options", [
    ("integrate", {"scheme": "s15odr8", "deviations": np.eye(4)[:, :1]}),
    ("integrate", {"t_out": [0.5, 1.0]}),
    ("lyapunov", {"t_out": [0.3, 1.0]}), ("megno", {}),
    # GALI_3 and the compensated spectrum compile kernels of their own (19
    # and 28 CPU s cold): under -m slow; GALI's short path is checked by
    # default with two vectors, compensation's with one.
    pytest.param("gali", {"k": 3}, marks=pytest.mark.slow),
    ("gali", {"k": 2, "renormalize_every": 4}), ("sali", {"t_out": 5}), ("fli", {}),
    pytest.param("lyapunov", {"compensated": True}, marks=pytest.mark.slow),
    # Compensated with one vector: the kernel of test_compensated's run against the reference.
    ("integrate", {"scheme": "SRKN14a", "compensated": True, "deviations": np.eye(4)[:, :1]})])
def test_short_calls_are_the_one_shot_calls(indicator, options, general):
    # Several states, one and two at a time, after the first call (which
    # builds the run), take the short path.
    model, x0 = varint.paper_orbit("R1")
    run = varint.prepare(model, indicator, 1.0, tau=0.05, **options)
    states = _states(x0, 4)
    run(states[0])
    for x in (*states[1:], states[:2], states[2:]):
        _same(run(x), _one_shot(model, x, indicator, 1.0, 0.05, **options))
    # The first run was one orbit: the batches of two take the general
    # path (as many orbits as the first call only).
    assert run._again.short is not None and len(general) == 2


def test_a_failing_orbit_takes_the_general_path(general):
    # An orbit that escapes: with errors="flag", its status, its NaN
    # outputs and the warning are the one-shot call's; with "raise", the
    # message. The next good state is bitwise again (fresh buffers).
    model, x0 = varint.paper_orbit("R1")
    far = np.array([0.0, 0.0, 1.0, 0.3])
    run = varint.prepare(model, "lyapunov", 30.0, tau=0.05, escape_radius=5.0, errors="flag")
    run(x0)
    with pytest.warns(RuntimeWarning, match="1 of 1 orbits failed") as prepared:
        a = run(far)
    with pytest.warns(RuntimeWarning, match="1 of 1 orbits failed") as one_shot:
        b = varint.lyapunov_spectrum(model, far, 30.0, tau=0.05, escape_radius=5.0,
                                     errors="flag")
    _same(a, b)
    assert a.status == Status.ESCAPED
    assert np.isnan(a.exponents[-1]).all()
    assert str(prepared[0].message) == str(one_shot[0].message)
    assert len(general) == 1
    _same(run(x0), varint.lyapunov_spectrum(model, x0, 30.0, tau=0.05, escape_radius=5.0))
    assert len(general) == 1

    raising = varint.prepare(model, "lyapunov", 30.0, tau=0.05, escape_radius=5.0)
    raising(x0)
    with pytest.raises(varint.IntegrationError) as prepared_error:
        raising(far)
    with pytest.raises(varint.IntegrationError) as one_shot_error:
        varint.lyapunov_spectrum(model, far, 30.0, tau=0.05, escape_radius=5.0)
    assert str(prepared_error.value) == str(one_shot_error.value)
    _same(prepared_error.value.partial, one_shot_error.value.partial)


def test_a_long_call_takes_the_general_path(general):
    # Expected to last longer than one of the driver's chunks (its time per
    # step taken from the calls before): the driver's chunks, Ctrl-C and
    # the progress bar.
    model, x0 = varint.paper_orbit("R1")
    run = varint.prepare(model, "megno", 20.0, tau=0.05)
    run(x0)
    assert run._again.short.takes(run.spec.with_states(x0).x0)
    run._again.short.per_step = 1e-3          # 400 steps: 0.4 s
    x = x0 + [0.0, 0.0, 1e-3, 0.0]
    _same(run(x), varint.megno(model, x, 20.0, tau=0.05))
    assert len(general) == 1
    # That call's own time per step is taken as the next estimate.
    assert run._again.short.per_step < 1e-3


@pytest.mark.parametrize("indicator, t_out", [("megno", 9), ("lyapunov", None)])
def test_a_call_of_many_driver_chunks_is_one_stepper_call_with_the_same_bits(
        indicator, t_out, general):
    # 800 steps: the driver runs them in chunks of 64 steps and more (its
    # Pace), a short call in one call of the stepper (rule 3 of the
    # propagator protocol: chunking changes no bit).
    model, x0 = varint.paper_orbit("R1")
    run = varint.prepare(model, indicator, 40.0, tau=0.05, t_out=t_out)
    run(x0)
    for x in _states(x0, 2):
        _same(run(x), _one_shot(model, x, indicator, 40.0, 0.05, t_out=t_out))
    assert len(general) == 0


@pytest.mark.parametrize("make", [
    lambda: varint.paper_orbit("R1")[0], lambda: varint.models.ThreeDof(),
    lambda: varint.models.FPUT(8, beta=1.0)])
def test_reference_and_errors_is_the_reference_and_its_errors(make):
    # One evaluation of T and V over the states and the outputs gives, bit
    # for bit, the Reference of the states and its errors at the outputs.
    model = make()
    rng = np.random.default_rng(3)
    for m, reps in ((1, 1), (1, 3), (2, 2)):
        x0 = 0.1 * rng.standard_normal((m, model.dim))
        x = x0[np.tile(np.arange(m), reps)] + 1e-3 * rng.standard_normal((m * reps, model.dim))
        reference, errors = accuracy.reference_and_errors(model, x0, x)
        alone = accuracy.Reference(model, x0)
        for key in ("values", "scales"):
            for name, v in getattr(alone, key).items():
                np.testing.assert_array_equal(getattr(reference, key)[name], v, strict=True)
        expected = alone.errors(x)
        assert errors.keys() == expected.keys()
        for key, v in expected.items():
            np.testing.assert_array_equal(errors[key], v, strict=True)
    x0 = np.zeros((1, model.dim))
    x0[0, 0] = np.nan      # the Reference's own refusal
    with pytest.raises(ValueError, match="not finite at the initial state"):
        accuracy.reference_and_errors(model, x0, np.zeros((1, model.dim)))


def _same_verdict(a, b):
    """Two verdicts equal in every field, types included."""
    for name in ("energy_error", "t_worst", "accurate"):
        x, y = getattr(a, name), getattr(b, name)
        assert type(x) is type(y), name
        np.testing.assert_array_equal(x, y, strict=True)
    assert a.conserved.keys() == b.conserved.keys()
    for key in a.conserved:
        assert type(a.conserved[key]) is type(b.conserved[key])
        np.testing.assert_array_equal(a.conserved[key], b.conserved[key], strict=True)
    assert (a.energy_tol, a.tau, a.notes) == (b.energy_tol, b.tau, b.notes)


class _Doubled(varint.models.HenonHeiles):
    """Hénon–Heiles with a second conserved quantity, 2H (relative to |2H|,
    not to |T| + |V|): its conserved quantities are not the base model's."""

    def conserved(self, x, t=0.0, p_t=0.0):
        energy = self.energy(x)
        return {"energy": energy, "doubled": 2.0 * energy}


@pytest.mark.parametrize("model", [varint.models.HenonHeiles(), _Doubled()],
                         ids=["T+V", "other conserved"])
@pytest.mark.parametrize("m", [1, 2])
def test_the_short_calls_verdict_and_warning_are_the_one_shot_calls(model, m, general):
    # Every field of the verdict, one orbit and two; within the tolerance
    # and above it (the warning's text too), T + V by the compiled errors
    # and other conserved quantities by the general path's functions.
    x0 = varint.paper_orbit("R1")[1]
    states = _states(x0, 3 * m).reshape(3, m, 4)
    states = [s[0] for s in states] if m == 1 else list(states)
    for tol in (None, 1e-9):
        run = varint.prepare(model, "megno", 0.5, tau=0.1, t_out=3, energy_tol=tol)
        with warnings.catch_warnings(record=True) as seen:
            warnings.simplefilter("always")
            run(states[0])
            got = [run(x) for x in states[1:]]
            alone = [varint.megno(model, x, 0.5, tau=0.1, t_out=3, energy_tol=tol)
                     for x in states[1:]]
        messages = [str(w.message) for w in seen if w.category is accuracy.AccuracyWarning]
        assert len(messages) == (0 if tol is None else 2 * len(states) - 1)
        if tol is not None:     # each short call's warning is its one-shot call's
            assert messages[1:len(states)] == messages[len(states):]
        for a, b in zip(got, alone, strict=True):
            _same(a, b)
            _same_verdict(a.accuracy, b.accuracy)
            assert a.accuracy.accurate.all() == (tol is None)
    assert len(general) == 0 and run._again.short.plain == (type(model) is not _Doubled)


def test_a_result_outlives_the_next_calls():
    # The short calls keep their buffers between calls: a result's arrays
    # are its own, the next calls change none of them.
    model, x0 = varint.paper_orbit("R1")
    run = varint.prepare(model, "lyapunov", 0.5, tau=0.05, t_out=4)
    run(x0)
    first = run(x0 + 1e-3)
    kept = {name: np.copy(getattr(first, name)) for name in ("t", "state", "exponents",
                                                             "energy_error", "deviations")
            if getattr(first, name, None) is not None}
    for dp in (2e-3, 3e-3):
        last = run(x0 + dp)
    for name, value in kept.items():
        np.testing.assert_array_equal(getattr(first, name), value, strict=True)
    _same(first, varint.lyapunov_spectrum(model, x0 + 1e-3, 0.5, tau=0.05, t_out=4))
    # And every buffer starts each call afresh: the last call's counts too.
    alone = varint.lyapunov_spectrum(model, x0 + 3e-3, 0.5, tau=0.05, t_out=4)
    _same(last, alone)
    assert last.provenance.counts == alone.provenance.counts


def test_large_snapshots_are_not_kept_between_calls(monkeypatch, general):
    # Over KEEP_BYTES, each call makes its buffers: the same bits, and the
    # prepared run holds none of them after the call.
    monkeypatch.setattr(ShortCall, "KEEP_BYTES", 0)
    model, x0 = varint.paper_orbit("R1")
    run = varint.prepare(model, "lyapunov", 0.5, tau=0.05, t_out=4)
    run(x0)
    for x in _states(x0, 2):
        _same(run(x), varint.lyapunov_spectrum(model, x, 0.5, tau=0.05, t_out=4))
    assert getattr(run._again.short._local, "run", None) is None and len(general) == 0


def test_threads_calling_one_prepared_run_get_the_one_shot_results():
    # Each thread's short calls have their own buffers.
    model, x0 = varint.paper_orbit("R1")
    run = varint.prepare(model, "megno", 1.0, tau=0.05)
    run(x0)
    states = _states(x0, 4)
    expected = [varint.megno(model, x, 1.0, tau=0.05) for x in states]

    def calls(x):
        return [run(x) for _ in range(30)]

    with ThreadPoolExecutor(4) as pool:
        done = list(pool.map(calls, states))
    for results, one_shot in zip(done, expected, strict=True):
        for r in results:
            np.testing.assert_array_equal(r.mean_megno, one_shot.mean_megno, strict=True)
            np.testing.assert_array_equal(r.state, one_shot.state, strict=True)
            np.testing.assert_array_equal(r.energy_error, one_shot.energy_error, strict=True)


def test_a_short_calls_provenance_is_read_saved_and_pickled_whole(tmp_path):
    # Its fixed parts stay pickled until read; each result reads its own
    # copies, and pickling, saving and the summary see every field.
    model, x0 = varint.paper_orbit("R1")
    run = varint.prepare(model, "lyapunov", 0.5, tau=0.05)
    run(x0)
    a, b = run(x0), run(x0)
    assert "_pickled" in vars(a.provenance)
    alone = varint.lyapunov_spectrum(model, x0, 0.5, tau=0.05)
    copied = pickle.loads(pickle.dumps(a))
    assert "_pickled" not in vars(copied.provenance)
    for p, q in ((copied.provenance, a.provenance), (copy.copy(b.provenance), b.provenance)):
        for f in dataclasses.fields(p):
            assert getattr(p, f.name) == getattr(q, f.name), f.name
    a.provenance.model["inverse_mass"].append(0.0)
    assert b.provenance.model == alone.provenance.model != a.provenance.model
    assert a.summary() == alone.summary().replace(
        f"{alone.provenance.wall_time:.3g} s", f"{a.provenance.wall_time:.3g} s")
    b.save(tmp_path / "b.npz")
    loaded = varint.load_result(tmp_path / "b.npz")
    assert loaded.provenance == b.provenance
    assert loaded.provenance.to_dict() == b.provenance.to_dict()
    with pytest.raises(AttributeError, match="no attribute 'nothing'"):
        b.provenance.nothing  # noqa: B018


def test_a_short_call_measures_v_compiled_only_where_it_is_the_models_own(general):
    # Hénon–Heiles' compiled V (potential_rows) serves its short calls; a
    # subclass with another V keeps its own, and both give the one-shot
    # call's result.
    model, x0 = varint.paper_orbit("R1")

    class Shifted(type(model)):
        def potential(self, q, t=0.0):
            return super().potential(q, t) + 0.125

    x = _states(x0, 1)[0]
    # (No compiled V at all where NumPy's power is not libm's.)
    for m, compiled in ((model, model.potential_rows is not None), (Shifted(), False)):
        run = varint.prepare(m, "integrate", 0.2, tau=0.05)
        run(x0)
        short = run._again.short
        assert short is not None and (short.potential_kernel is not None) == compiled
        _same(run(x), _one_shot(m, x, "integrate", 0.2, 0.05))
    assert not general


def _general_h():
    """A general H(q, p) (Gauss–Legendre on the part stepper by default):
    the held-out "angular coupling" of test_remembered's symbolic models."""
    q1, q2, p1, p2 = sp.symbols("q1 q2 p1 p2")
    hh = (q1 ** 2 + q2 ** 2) / 2 + q1 ** 2 * q2 - q2 ** 3 / 3
    H = (p1 ** 2 + p2 ** 2) / 2 + hh + sp.Rational(1, 10) * (q1 * p2 - q2 * p1) ** 2
    return from_hamiltonian(H, (q1, q2), (p1, p2)), np.array([0.1, 0.05, 0.2, 0.25])


@pytest.mark.parametrize("t_end, t_out", [(0.1, None), (1.0, [0.3, 1.0]), (8.0, 9)])
def test_the_part_steppers_short_calls_are_the_one_shot_calls(t_end, t_out, general):
    # One step, two outputs, nine outputs over 80 steps (the driver's
    # chunks against one stepper call per output): the short path of the
    # part stepper (varint.methods.fresh_parts_run) gives the one-shot
    # call's result, bit for bit, for one orbit and for two.
    model, x0 = _general_h()
    for states in (_states(x0, 3), _states(x0, 4).reshape(2, 2, 4)):
        run = varint.prepare(model, "lyapunov", t_end, tau=0.1, t_out=t_out)
        run(states[0])
        for x in states[1:]:
            _same(run(x), _one_shot(model, x, "lyapunov", t_end, 0.1, t_out=t_out))
        assert run._again.short is not None
    assert len(general) == 0


def test_a_failing_orbit_of_the_part_stepper_takes_the_general_path(general):
    model, x0 = _general_h()
    run = varint.prepare(model, "lyapunov", 1.0, tau=0.1, escape_radius=1.0, errors="flag")
    run(x0)
    far = np.array([0.9, 0.3, 0.5, 0.4])
    with pytest.warns(RuntimeWarning, match="1 of 1 orbits failed"):
        a = run(far)
    with pytest.warns(RuntimeWarning, match="1 of 1 orbits failed"):
        b = varint.lyapunov_spectrum(model, far, 1.0, tau=0.1, escape_radius=1.0,
                                     errors="flag")
    _same(a, b)
    assert len(general) == 1
    _same(run(x0 + 1e-3), _one_shot(model, x0 + 1e-3, "lyapunov", 1.0, 0.1,
                                     escape_radius=1.0, errors="flag"))
    assert len(general) == 1


def test_taos_method_has_no_short_path():
    # Its second copy of phase space lives in the run state.
    model, _ = _general_h()
    tao = GeneralPropagator(model, 0.1, "qr", scheme="TAO4")
    gauss = GeneralPropagator(model, 0.1, "qr")
    assert not tao.runs_fresh(1, 4) and gauss.runs_fresh(1, 4)


@pytest.mark.parametrize("make", [
    lambda: varint.models.DisorderedKG(8, seed=1), lambda: varint.models.FPUT(8, beta=1.0),
    lambda: varint.models.DDNLS(8, seed=1)], ids=["KG", "FPUT", "DDNLS"])
def test_a_lattices_short_calls_are_the_one_shot_calls(general, make):
    # The lattices run by the part stepper take its short path too (each
    # lattice its own default scheme: two parts for KG and FPUT, three for
    # DDNLS).
    model = make()
    x0 = model.initial_block(width=2, seed=1)
    run = varint.prepare(model, "lyapunov", 1.0, tau=0.1, n_exponents=2, t_out=[0.5, 1.0])
    run(x0)
    for x in _states(x0, 2):
        _same(run(x), _one_shot(model, x, "lyapunov", 1.0, 0.1, n_exponents=2,
                                t_out=[0.5, 1.0]))
    assert run._again.short is not None and len(general) == 0

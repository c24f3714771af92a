"""A prepared run's short calls (:class:`varint.prepared._ShortCall`: the
stepper driven from fresh arrays, the result assembled directly) give the
one-shot call's result bit for bit, and leave failures and long calls to
the general path (:meth:`varint.run.Run.with_orbits`)."""

import numpy as np
import pytest

import varint
from varint import accuracy
from varint.protocol import Status
from varint.run import Run

from .test_prepared import _same, _states


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
    ("lyapunov", {"t_out": [0.3, 1.0]}), ("megno", {}), ("gali", {"k": 3}),
    ("gali", {"k": 2, "renormalize_every": 4}), ("sali", {"t_out": 5}), ("fli", {}),
    ("lyapunov", {"compensated": True}),
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
        _same(run(x), varint.run(model, x, indicator, 1.0, 0.05, **options))
    # The first run was one orbit: the batches of two take the general
    # path (as many orbits as the first call only).
    assert run._short is not None and len(general) == 2


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
    assert run._short.takes(run.spec.with_states(x0))
    run._short.per_step = 1e-3          # 400 steps: 0.4 s
    x = x0 + [0.0, 0.0, 1e-3, 0.0]
    _same(run(x), varint.megno(model, x, 20.0, tau=0.05))
    assert len(general) == 1
    # That call's own time per step is taken as the next estimate.
    assert run._short.per_step < 1e-3


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

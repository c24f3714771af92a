"""A one-shot call that repeats an earlier one's arguments runs its set-up
again (:mod:`varint.remembered`) and gives, bit for bit, the result built
from scratch; a changed argument or a model changed in place is not
mistaken for the earlier call; bad input is refused as before."""

import dataclasses
import subprocess
import sys

import numpy as np
import pytest
import sympy as sp
from numba import types

import varint
from varint import remembered
from varint.methods import fresh_run
from varint.methods.tm import TangentMapPropagator
from varint.models import from_hamiltonian
from varint.models.bar import bar_orbit
from varint.protocol import Renorm
from varint.run import Run

from .test_prepared import _one_shot, _same, _states


@pytest.fixture
def general(monkeypatch):
    """The one-shot calls that built their run from scratch, counted."""
    calls = []
    original = Run.__init__

    def counted(self, *args, **kwargs):
        calls.append(args)
        original(self, *args, **kwargs)

    monkeypatch.setattr(Run, "__init__", counted)
    return calls


def test_repeated_calls_are_the_calls_built_from_scratch(general):
    model, x0 = varint.paper_orbit("R1")
    states = _states(x0, 4)
    w = np.random.default_rng(3).standard_normal((4, 4, 1))
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    for x, v in zip(states, w, strict=True):
        got = varint.integrate(model, x, 0.5, tau=0.05, scheme="s15odr8", deviations=v)
        _same(got, _one_shot(model, x, "integrate", 0.5, 0.05, scheme="s15odr8", deviations=v))
        got = varint.lyapunov_spectrum(model, x, 1.0, tau=0.05, t_out=[0.5, 1.0])
        _same(got, _one_shot(model, x, "lyapunov", 1.0, 0.05, t_out=[0.5, 1.0]))
    # Each reference built its run; of the calls, only the first of each
    # argument set (the t_out list is keyed by its values).
    assert len(general) == 2 * len(states) + 2


def test_read_only_or_strided_start_arrays_reset_a_fresh_run_as_writable_ones():
    """A repeated call's fresh run (varint.methods.fresh_run) resets its
    buffers from read-only or non-contiguous states and vectors as from
    writable C-contiguous ones: the same bits, and one compiled version of
    the reset (numba types a read-only array apart: a second compile, ~3 s
    cold). R1 with s15odr8 and one vector: the stepper of the test above."""
    model, x0 = varint.paper_orbit("R1")
    prop = TangentMapPropagator(model, 0.05, Renorm.NONE, scheme="s15odr8", parallel=False)
    run = prop.fresh_run(1, 1, np.array([5, 10]), np.empty((1, 0, 0)))
    x, w = np.array(x0, ndmin=2), np.eye(4)[None, :, 1:2].copy()
    run(x, w)
    ref = run.x.copy(), run.W.copy()
    read_only = [a.copy() for a in (x, w)]
    for a in read_only:
        a.flags.writeable = False
    strided = (np.repeat(x, 2, axis=1)[:, ::2], np.eye(4)[None, :, 1:2])
    assert not strided[0].flags.c_contiguous and not strided[1].flags.c_contiguous
    for args in (read_only, strided):
        run(*args)
        np.testing.assert_array_equal(run.x, ref[0], strict=True)
        np.testing.assert_array_equal(run.W, ref[1], strict=True)
    arrays = [t for sig in fresh_run._reset.signatures for t in sig if isinstance(t, types.Array)]
    assert arrays and all(t.mutable and t.layout == "C" for t in arrays)


@pytest.mark.parametrize("change", ["params", "escape_radius", "inverse_mass"])
def test_a_model_changed_in_place_is_run_from_scratch(change, general):
    model, x0 = varint.paper_orbit("R1")
    first = varint.megno(model, x0, 1.0, tau=0.05)
    if change == "params":
        model.params = np.array([1.0])
    elif change == "escape_radius":
        model.escape_radius = 10.0
    else:
        model.inverse_mass[:] = 2.0     # in place: the array's bytes change
    second = varint.megno(model, x0, 1.0, tau=0.05)
    assert len(general) == 2
    _same(second, _one_shot(model, x0, "megno", 1.0, 0.05))
    if change == "inverse_mass":
        assert not np.array_equal(first.megno, second.megno)


def test_bad_input_after_a_remembered_call_is_refused_as_before():
    model, x0 = varint.paper_orbit("R1")
    varint.megno(model, x0, 1.0, tau=0.05, seed=1)
    # Equal to 1 but a bool: another key, refused by the seed's check.
    with pytest.raises(ValueError, match="seed must be a non-negative integer"):
        varint.megno(model, x0, 1.0, tau=0.05, seed=True)
    with pytest.raises(ValueError, match="x0 must be finite"):
        varint.megno(model, x0 * np.nan, 1.0, tau=0.05, seed=1)
    w = np.eye(4)[:, :1]
    varint.integrate(model, x0, 1.0, tau=0.05, deviations=w)
    with pytest.raises(ValueError, match="deviations must be finite"):
        varint.integrate(model, x0, 1.0, tau=0.05, deviations=np.where(w == 1.0, np.inf, w))


def test_another_number_of_vectors_is_another_call():
    model, x0 = varint.paper_orbit("R1")
    one = varint.integrate(model, x0, 0.5, tau=0.05, deviations=np.eye(4)[:, :1])
    two = varint.integrate(model, x0, 0.5, tau=0.05, deviations=np.eye(4)[:, :2])
    assert one.deviations.shape == (4, 1) and two.deviations.shape == (4, 2)
    np.testing.assert_array_equal(one.deviations[:, 0], two.deviations[:, 0])


def test_at_most_capacity_calls_are_kept():
    model, x0 = varint.paper_orbit("R1")
    for i in range(remembered.CAPACITY + 3):
        varint.megno(model, x0, 0.5 + 0.05 * i, tau=0.05)
    assert len(remembered._calls) == remembered.CAPACITY


def test_a_drawn_seed_or_a_pilot_step_is_not_remembered():
    model, x0 = varint.paper_orbit("R1")
    a = varint.megno(model, x0, 1.0, tau=0.05, seed=None)
    b = varint.megno(model, x0, 1.0, tau=0.05, seed=None)
    assert a.provenance.seed != b.provenance.seed and not remembered._calls


def test_a_call_without_a_short_path_is_run_from_scratch(general):
    model, x0 = varint.paper_orbit("R1")
    for x in _states(x0, 3):
        got = varint.megno(model, x, 1.0, tau=0.05, method="dop853")
        _same(got, _one_shot(model, x, "megno", 1.0, 0.05, method="dop853"))
    assert len(general) == 6
    # Kept as such, holding no run.
    (entry,) = remembered._calls.values()
    assert entry[0] is None and entry[2] is False


def test_a_first_run_imports_no_rerun():
    # The short path's kernels load at a process's first repeated call,
    # not in its first run (issue 28's start-up).
    code = ("import sys, varint\n"
            "model, x0 = varint.paper_orbit('R1')\n"
            "varint.megno(model, x0, 1.0, tau=0.05)\n"
            "assert 'varint.rerun' not in sys.modules\n"
            "varint.megno(model, x0 + 1e-3, 1.0, tau=0.05)\n"
            "assert 'varint.rerun' in sys.modules\n")
    subprocess.run([sys.executable, "-c", code], check=True)


def _same_accuracy(a, b):
    """Two verdicts equal in every field, bit for bit."""
    for f in dataclasses.fields(a):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, dict):
            assert x.keys() == y.keys(), f.name
            for key in x:
                np.testing.assert_array_equal(x[key], y[key], strict=True)
        else:
            np.testing.assert_array_equal(x, y, strict=True)


def _symbolic_models():
    """The rotating bar (a symbolic integrable part with a compiled extra
    force) and two ``from_hamiltonian`` models (separable, general): models
    whose symbolic records (SymPy symbols in tuples, the bar's plane
    parameters) sit deeper than plain attributes."""
    q1, q2, p1, p2 = sp.symbols("q1 q2 p1 p2")
    well = (q1 ** 2 + q2 ** 2) / 2 + q1 ** 4 / 4 + q1 ** 2 * q2 ** 2 / 2
    hh = (q1 ** 2 + q2 ** 2) / 2 + q1 ** 2 * q2 - q2 ** 3 / 3
    bar, x_bar = bar_orbit("chaotic")
    # One vector given, one seeded: both run the bar's one-vector kernel
    # (a second kernel, for all six vectors, costs ~70 s to compile cold).
    return {"bar": (bar, x_bar, {"deviations": np.full((6, 1), 1 / np.sqrt(6))}),
            "bar seeded": (bar, x_bar, {"n_exponents": 1}),
            "separable": (from_hamiltonian(sp.sqrt(1 + p1 ** 2 + p2 ** 2) + well, (q1, q2),
                                           (p1, p2)), np.array([0.3, 0.2, 0.4, 0.3]), {}),
            "general": (from_hamiltonian((p1 ** 2 + p2 ** 2) / 2 + hh
                                         + sp.Rational(1, 10) * (q1 * p2 - q2 * p1) ** 2,
                                         (q1, q2), (p1, p2)),
                        np.array([0.1, 0.05, 0.2, 0.25]), {})}


@pytest.mark.parametrize("name", ["bar", "bar seeded", "separable", "general"])
def test_symbolic_models_are_remembered_and_bitwise(name, general):
    # Their keys once failed on depth (SymPy symbols 5 levels down), so
    # every call was built from scratch (issue 28: ~0.8 ms per t = 1 call).
    remembered.forget()
    model, x0, kw = _symbolic_models()[name]
    states = _states(x0, 4)
    for x in states:
        got = varint.lyapunov_spectrum(model, x, 1.0, tau=0.1, **kw)
        ref = _one_shot(model, x, "lyapunov", 1.0, 0.1, **kw)
        _same(got, ref)
        _same_accuracy(got.accuracy, ref.accuracy)
    assert remembered.call_key(model, x0, "lyapunov", 1.0, 0.1, kw) is not None
    # The references (4) and the first call; the others took the short
    # path (the generated stepper's of the bar, the part stepper's of the
    # other two, varint.methods.fresh_parts_run): the caches the first call
    # filled (the model's memo, which its __getstate__ leaves out) change
    # no key.
    assert len(general) == 4 + 1


def test_a_key_leaves_out_what_a_model_does_not_pickle():
    # A HamiltonianModel's memo (made from H, dropped by its __getstate__)
    # changes no key; its state (here escape_radius) does.
    model, x0, _ = _symbolic_models()["general"]
    key = remembered.call_key(model, x0, "lyapunov", 1.0, 0.1, {})[0]
    model._memoised("test", lambda: [1.0, np.zeros(3)])
    assert remembered.call_key(model, x0, "lyapunov", 1.0, 0.1, {})[0] == key
    model.escape_radius = 10.0
    assert remembered.call_key(model, x0, "lyapunov", 1.0, 0.1, {})[0] != key


@dataclasses.dataclass(frozen=True)
class _Settings:
    """A user's frozen record holding an array (changed in place below)."""

    scale: np.ndarray


def test_a_users_frozen_record_changed_in_place_changes_the_key():
    # varint's own frozen records are keyed by identity; a user's may hold
    # an array changed in place, so it is keyed by its state.
    model, x0 = varint.paper_orbit("R1")
    model.settings = _Settings(np.ones(2))
    key = remembered.call_key(model, x0, "lyapunov", 1.0, 0.1, {})[0]
    assert remembered.call_key(model, x0, "lyapunov", 1.0, 0.1, {})[0] == key
    model.settings.scale[0] = 2.0
    assert remembered.call_key(model, x0, "lyapunov", 1.0, 0.1, {})[0] != key


def test_a_models_key_is_walked_again_only_when_its_state_changed():
    # The token of an unchanged model is the last walk's (its checks hold);
    # a change anywhere in its state, a nested dict or an array included,
    # makes a new walk and another key (the bar's state is 4 levels deep).
    remembered.forget()
    model, x0 = bar_orbit("regular")
    key = remembered.call_key(model, x0, "lyapunov", 1.0, 0.1, {})[0]
    again = remembered.call_key(model, x0, "lyapunov", 1.0, 0.1, {})[0]
    assert again == key and again.items[0] is key.items[0]
    original = model.planar["others"][2]
    model.planar["others"][2] = (1.0, 1e-3)
    changed = remembered.call_key(model, x0, "lyapunov", 1.0, 0.1, {})[0]
    assert changed != key
    model.planar["others"][2] = original
    assert remembered.call_key(model, x0, "lyapunov", 1.0, 0.1, {})[0] == key
    inside = model._inside[0]
    model._inside[0] = 2.0 * inside
    assert remembered.call_key(model, x0, "lyapunov", 1.0, 0.1, {})[0] != key
    model._inside[0] = inside
    model.values["omega"] = 0.054 + 0.0     # an equal float, another object
    assert remembered.call_key(model, x0, "lyapunov", 1.0, 0.1, {})[0] == key
    model.values["omega"] = 1     # an int: another key
    assert remembered.call_key(model, x0, "lyapunov", 1.0, 0.1, {})[0] != key


def test_sparse_rows_of_a_fresh_run_are_the_snapshots_rows():
    # A fresh run's snapshots copied between renormalisations: their rows
    # renormalised by the kernel's compiled version over kept views are
    # Snapshots.rows', bit for bit, and so are the renormalised vectors.
    from varint.state import renormalized_copy

    model, x0 = bar_orbit("regular")
    prop = TangentMapPropagator(model, 0.2, Renorm.QR, scheme="SRKN14a", parallel=False)
    if not prop.sparse:
        pytest.skip("the bar's stepper renormalises at every step here")
    run = prop.fresh_run(1, 2, np.array([2, 5]), np.empty((1, 0, 0)))
    w = np.linalg.qr(np.random.default_rng(2).standard_normal((6, 2)))[0][None]
    for _ in range(2):
        run(np.array(x0, ndmin=2), w)
        got, want = run.rows(Renorm.QR), run.snapshots.rows(Renorm.QR)
        for name in ("x", "W", "acc_m", "acc_e", "step"):
            assert getattr(got, name).tobytes() == getattr(want, name).tobytes(), name
        W, acc_m, acc_e = run.renormalized(Renorm.QR)
        for a, b in zip((W, acc_m, acc_e), renormalized_copy(run.W, run.acc_m, run.acc_e,
                                                            Renorm.QR), strict=True):
            assert a.tobytes() == b.tobytes()

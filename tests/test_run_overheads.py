"""What a run does besides stepping, made cheap without changing what it
means: the pace of chunks, the kernel check remembered per model, plain
options kept canonical without a JSON round trip, fresh stage tables."""

import json
import pickle

import numpy as np
import sympy as sp
import pytest

import varint
from varint import _validate as check
from varint import driver
from varint.files import canonical, canonical_json
from varint.models import from_potential
from varint.schemes import get_scheme, stage_arrays


def test_quick_chunks_grow_faster_but_a_slow_one_at_most_eightfold():
    pace = driver.Pace()
    n = pace.chunk
    # Mostly the fixed cost of a call: the next chunk lasts <= ~64 ms.
    pace.took(n, 1e-5)
    assert pace.chunk == 64 * n
    # A chunk of 10 ms would want 20 times more steps for 0.2 s: capped at 8.
    m = pace.chunk
    pace.took(m, 1e-2)
    assert pace.chunk == 8 * m
    # Slower than the target: it shrinks towards 0.2 s, at most 8-fold.
    pace.took(pace.chunk, 0.4)
    assert pace.chunk == 4 * m


def test_a_chunk_whose_fixed_cost_exceeds_the_target_grows_back():
    """A call of 1 s whatever its steps (a GPU call for many orbits: the
    transfers): the chunk shrinks once (mean cost per step), then the
    shorter call's equal time shows the fixed cost, and the chunk grows
    8-fold per call by the marginal cost of a step, instead of shrinking
    to one step (a call per step)."""
    pace = driver.Pace()
    pace.took(64, 1.0)
    assert pace.chunk == 12                       # 64 * 0.2 s / 1 s
    pace.took(12, 1.0 - 12e-5)                    # 1e-5 s per step beyond 1 s
    assert pace.chunk == 96
    pace.took(96, 1.0 - 12e-5 + 84e-5)
    assert pace.chunk == 768
    # The mean rules where it is the smaller (a marginal cost of noise).
    pace.took(768, 0.5)
    assert pace.chunk == 307                      # 768 * 0.2 / 0.5


def test_the_kernel_check_names_the_first_singular_state(monkeypatch):
    """A batch's kernels are evaluated in one compiled pass; the first state
    where one is not finite is named as from Python; kernels the pass
    cannot call (here: parameters of another type) are evaluated from
    Python at every state."""
    x, y = sp.symbols("x y")
    model = from_potential(0.5 * (x ** 2 + y ** 2) + 1 / x, [x, y])
    X = np.column_stack([np.linspace(0.5, 2.0, 80), np.zeros(80), np.zeros(80), np.ones(80)])
    check.kernels(model, X)
    assert check._scan(model, np.ascontiguousarray(X[:, :2])) == -1
    X[63, 0] = X[70, 0] = 0.0
    assert check._scan(model, np.ascontiguousarray(X[:, :2])) == 63
    for _ in range(2):
        with pytest.raises(ValueError, match=r"initial state of orbit 63, q = .0.0, 0.0.: the "
                                             "gradient"):
            check.kernels(model, X)
    with pytest.raises(ValueError, match="initial state of orbit 1, q = .0.0, 0.0."):
        check.kernels(model, X[62:65])
    with pytest.raises(ValueError, match="not finite"):
        varint.lyapunov_spectrum(model, X[63], 1.0, tau=0.1)
    calls = []
    original = check._evaluate
    monkeypatch.setattr(check, "_evaluate", lambda m, q, todo, *a: (calls.append(len(todo)),
                                                                     original(m, q, todo, *a)))
    monkeypatch.setattr(model, "params", model.params.astype(np.float32))
    check.kernels(model, X[:60])
    assert calls == [60]


def test_a_model_that_ran_still_pickles_as_it_was():
    """What runs remember per model (kernel checks, stepper modules) lives
    beside it: a model sent to Dask workers after a run pickles, and
    carries nothing more."""
    model, x0 = varint.paper_orbit("C1")
    before = pickle.dumps(model)
    varint.lyapunov_spectrum(model, x0, 10.0, tau=0.1)
    assert pickle.dumps(model) == before


@pytest.mark.parametrize("obj", [
    {"b": 1, "a": [1, 2.5, None, True, "x", {"z": 1e300, "y": -0.0}]},
    {"a": (1, 2)}, {1: 2}, {}, [], {"a": np.float64(1.5)}, {"k": np.arange(3)}, 3, "x",
    {"nested": [{"b": [], "a": {}}]},
])
def test_canonical_is_the_json_round_trip(obj):
    fast = canonical(obj)
    slow = json.loads(canonical_json(obj))
    assert fast == slow and json.dumps(fast) == json.dumps(slow)   # keys in the same order
    assert all(type(a) is type(b) for a, b in zip(_leaves(fast), _leaves(slow), strict=True))


def _leaves(obj):
    if isinstance(obj, dict):
        return [v for value in obj.values() for v in _leaves(value)]
    if isinstance(obj, list):
        return [v for value in obj for v in _leaves(value)]
    return [obj]


def test_stage_tables_are_new_arrays_every_call():
    scheme = get_scheme("ABA864")
    kinds, h, hc = stage_arrays(scheme, 0.05)
    h[:] = 0.0
    assert np.all(stage_arrays(scheme, 0.05)[1] != 0.0)


@pytest.mark.parametrize("n_end, n", [(1, 1), (7, 3), (20000, 1), (20000, 7), (999, 1000 // 3)])
def test_counted_output_steps_are_the_evenly_spaced_ones_and_the_callers_own(n_end, n):
    """``t_out`` as a count: the steps kept per (n_end, n) are those of
    linspace rounded (the law: n steps, strictly increasing, ending at
    n_end, each within half a step of k·n_end/n), and every call gets its
    own writable copy."""
    from varint import state

    steps = state.output_steps(n_end * 0.5, 0.5, n)
    assert steps.flags.writeable and steps[-1] == n_end and len(steps) == n
    assert (np.diff(steps) > 0).all()
    assert np.abs(steps - np.arange(1, n + 1) * n_end / n).max() <= 0.5
    steps[:] = -1
    again = state.output_steps(n_end * 0.5, 0.5, n)
    assert again[-1] == n_end and np.array_equal(again, state._spaced(n_end, n))


@pytest.mark.parametrize("n", [1, check._PYTHON_STATES, check._PYTHON_STATES + 1])
def test_few_states_are_checked_from_python_and_name_the_same_state(n, monkeypatch):
    """Up to ``_PYTHON_STATES`` initial states skip the compiled pass (its
    fixed cost is more than theirs); either way the first singular state is
    named, and the pass is used only for more states."""
    x, y = sp.symbols("x y")
    model = from_potential(0.5 * (x ** 2 + y ** 2) + 1 / x, [x, y])
    X = np.column_stack([np.linspace(0.5, 2.0, n), np.zeros(n), np.zeros(n), np.ones(n)])
    scans = []
    original = check._scan
    monkeypatch.setattr(check, "_scan", lambda m, q: (scans.append(len(q)), original(m, q))[1])
    check.kernels(model, X)
    X[n - 1, 0] = 0.0
    where = "initial state" if n == 1 else f"initial state of orbit {n - 1}"
    with pytest.raises(ValueError, match=rf"{where}, q = .0.0, 0.0.: the gradient"):
        check.kernels(model, X)
    assert scans == ([] if n <= check._PYTHON_STATES else [n, n])


def test_the_source_check_decides_finite_only_and_leaves_the_rest_compiled(monkeypatch):
    """``_finite_from_source`` answers "finite" from the built-in kernels'
    Python source, and nothing else: a state where they overflow, a kernel
    that raises in Python, a model of its own kernels or of more numbers
    than the bound go to the compiled check, whose message is the same as
    when the source check is skipped."""
    model, x0 = varint.paper_orbit("R1")
    Q = np.atleast_2d(np.asarray(x0, dtype=float))[:, :2]
    # As in a new process, where none of the kernels is loaded yet.
    monkeypatch.setattr(check, "_unloaded_built_in", lambda kernel: True)
    assert check._finite_from_source(model, Q)
    assert not check._finite_from_source(model, Q * 1e200)        # x² overflows
    assert not check._finite_from_source(model, np.repeat(Q, check._SOURCE_NUMBERS, axis=0))
    big = np.array([[1e200, 0.0]])
    with pytest.raises(ValueError) as via_kernels:
        check.kernels(model, big)
    monkeypatch.setattr(check, "_finite_from_source", lambda m, q: False)
    with pytest.raises(ValueError) as compiled:
        check.kernels(model, big)
    assert str(via_kernels.value) == str(compiled.value)
    monkeypatch.undo()
    x, y = sp.symbols("x y")
    own = from_potential(0.5 * (x ** 2 + y ** 2), [x, y])      # generated, not built in
    assert not check._unloaded_built_in(own.grad_kernel)

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
    pace = driver._Pace()
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


def test_the_kernel_check_remembers_only_the_states_that_passed():
    """A chaos map checks its grid, then each chunk its orbits: states found
    finite are not evaluated again; one that is not is refused every time,
    named by its place in the batch even when states before it were
    skipped."""
    x, y = sp.symbols("x y")
    model = from_potential(0.5 * (x ** 2 + y ** 2) + 1 / x, [x, y])
    good = np.array([[1.0, 0.0, 0.0, 0.1], [0.5, 0.2, 0.1, 0.0], [2.0, -1.0, 0.0, 0.0]])
    singular = np.array([0.0, 0.3, 0.0, 0.1])

    def remembered():
        return sum(len(states) for states in check._FINITE_AT[model].values())

    check.kernels(model, good)
    assert remembered() == 3
    batch = np.vstack([good[:2], singular, good[2:]])
    for _ in range(2):
        with pytest.raises(ValueError, match="initial state of orbit 2, q = .0.0, 0.3."):
            check.kernels(model, batch)
    assert remembered() == 3
    with pytest.raises(ValueError, match="not finite"):
        varint.lyapunov_spectrum(model, singular, 1.0, tau=0.1)


def test_many_states_are_checked_in_one_compiled_pass(monkeypatch):
    """Past _SCAN_STATES the kernels are evaluated by one compiled loop
    (the grid of a large map), which then checks that model's later
    batches too; the state where one is not finite is named as from
    Python."""
    x, y = sp.symbols("x y")
    model = from_potential(0.5 * (x ** 2 + y ** 2) + 1 / x, [x, y])
    monkeypatch.setattr(check, "_SCAN_STATES", 50)
    X = np.column_stack([np.linspace(0.5, 2.0, 80), np.zeros(80), np.zeros(80), np.ones(80)])
    check.kernels(model, X)
    assert check._SCANS[model][1] is not None and model not in check._FINITE_AT
    X[63, 0] = 0.0
    with pytest.raises(ValueError, match=r"initial state of orbit 63, q = .0.0, 0.0.: the "
                                         "gradient"):
        check.kernels(model, X)
    # A small batch of the same model: the compiled pass, not the memo.
    with pytest.raises(ValueError, match="initial state of orbit 1, q = .0.0, 0.0."):
        check.kernels(model, X[62:65])
    assert model not in check._FINITE_AT


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

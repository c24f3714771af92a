"""Small numerical helpers shared by the tests."""

import numpy as np


def fitted_slope(x, y):
    """Least-squares slope of log|y| against log x."""
    return float(np.polyfit(np.log(np.asarray(x, float)), np.log(np.abs(np.asarray(y, float))), 1)[0])


def assert_bitwise_equal(a, b):
    """Two results hold the same bits in every array (NaNs included) and
    the same provenance apart from wall and CPU time, the split into
    compile, pilot and run time, creation date, the machine's load and
    evaluation counts (a propagator may re-evaluate a force at the start of
    each chunk of work, so those depend on the chunking; the steps done do
    not)."""
    import dataclasses

    for f in dataclasses.fields(a):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if f.name == "provenance":
            px, py = x.to_dict(), y.to_dict()
            for key in ("wall_time", "cpu_time", "created", "counts", "timing", "machine"):
                px.pop(key), py.pop(key)
            assert px == py
            assert x.counts.get("steps") == y.counts.get("steps")
        else:
            _assert_same(x, y, f.name)


def _assert_same(x, y, name):
    """Same bits in arrays and numbers, the same keys and values in dicts,
    and field by field in a nested dataclass (the accuracy verdict)."""
    import dataclasses

    if dataclasses.is_dataclass(x):
        assert type(x) is type(y), name
        for f in dataclasses.fields(x):
            _assert_same(getattr(x, f.name), getattr(y, f.name), f"{name}.{f.name}")
    elif isinstance(x, dict):
        assert x.keys() == y.keys(), name
        for key in x:
            _assert_same(x[key], y[key], f"{name}[{key}]")
    elif isinstance(x, (np.ndarray, np.generic, float)):
        _assert_same_bits(x, y, name)
    else:
        assert x == y, name


def _assert_same_bits(x, y, name):
    x, y = np.asarray(x), np.asarray(y)
    assert (x.dtype, x.shape) == (y.dtype, y.shape), name
    assert x.tobytes() == y.tobytes(), f"{name} differs"


def hook_advance(monkeypatch, method, at, action):
    """Call ``action()`` just after the ``at``-th ``advance`` of the
    propagator class registered under ``method`` (1-based), or after the
    first one whose state satisfies ``at(state)``; returns the list of
    calls so far, for counting. Chunks grow at most 8-fold meanwhile, so
    that a short run still takes several (quick chunks may otherwise grow
    64-fold, see ``varint.driver.Pace``)."""
    import importlib

    import varint
    from varint import driver

    # stepsize binds the TM step when it is first imported, so that its
    # pilot is not part of the run; imported here first, it binds the
    # unhooked one whatever the order the tests ran in (imported after the
    # hook, it would call the hook with the pilot's positional checks).
    importlib.import_module("varint.stepsize")
    monkeypatch.setattr(driver, "_QUICK_CHUNK", 0.0)

    module, _, name = varint.METHODS[method].partition(":")
    cls = getattr(importlib.import_module(module), name)
    original = cls.advance
    calls = []

    def advance(self, state, n, **kwargs):
        result = original(self, state, n, **kwargs)
        calls.append(n)
        if (at(state) if callable(at) else len(calls) == at):
            action()
        return result

    monkeypatch.setattr(cls, "advance", advance)
    return calls


def generic_tangent_map_steps(model, x, W=None, tau=0.05, n_steps=1, scheme=None, every=None):
    """``n_steps`` of the numerical map and its tangent map, as
    :func:`varint.methods.tm.tangent_map_steps`, on the generic TM stepper
    (kernels/tm.py: the scheme's stages are data, so one compilation serves
    every scheme) instead of the straight-line stepper generated per
    (model, scheme, k). A law of the scheme itself (its order,
    reversibility, symplecticity) does not depend on which of the two runs
    it; test_generated_stepper checks that they are the same map to
    round-off, and the stored fingerprints pin every generated stepper
    bitwise.

    Returns the final state and vectors, and with ``every`` the states
    after every ``every`` steps (shape (n_steps // every, 2N)) first.
    """
    from varint.methods.tm import TangentMapPropagator
    from varint.protocol import Renorm, Status
    from varint.state import RunState

    x = np.array(x, dtype=np.float64).reshape(1, -1)
    W = np.zeros((model.dim, 0)) if W is None else np.array(W, dtype=np.float64)
    state = RunState.start(x, W.reshape(model.dim, -1)[None])
    p = TangentMapPropagator(model, float(tau), Renorm.NONE, scheme=scheme, parallel=False)
    p._generated[state.k] = None          # the generic stepper
    if every is None:
        p.advance(state, int(n_steps))
    else:
        states = []
        for _ in range(int(n_steps) // every):
            p.advance(state, every)
            states.append(state.x[0].copy())
    assert state.status[0] == Status.OK, state.status[0]
    if every is None:
        return state.x[0], state.W[0]
    return np.array(states), state.x[0], state.W[0]

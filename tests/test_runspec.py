"""The run specification (varint.runspec): built and checked once, executed
by Run, shared by a chaos map's chunks and the fan-out of maps and
ensembles (varint.fanout)."""

import warnings

import numpy as np
import pytest

import varint
from varint import _validate, fanout
from varint.run import Run, prepare
from varint.runspec import specify
from varint.state import initial_deviations, output_steps

HH = varint.models.HenonHeiles()
X = np.array([[0.0, 0.10, 0.35, 0.10], [0.0, -0.20, 0.40, 0.05],
              [0.0, 0.15, 0.30, -0.10], [0.0, 0.05, 0.45, 0.0]])


def test_a_run_over_some_orbits_of_a_spec_repeats_them_bit_for_bit():
    # Orbits are independent and orbit m draws its vectors from [seed, m]:
    # a run of the spec over rows 1 and 3, given those rows' seeded vectors
    # (what a map's chunk does), reproduces the rows of the run over all.
    spec = specify(HH, X, "lyapunov", 20.0, 0.05, seed=7)
    whole = Run(spec).execute()
    rows = np.array([1, 3])
    vectors = initial_deviations(HH.dim, 4, len(rows), 7, rows)
    part = Run(spec.for_orbits(X[rows]), deviations=vectors).execute()
    assert np.array_equal(part.exponents, whole.exponents[rows])
    assert np.array_equal(part.energy_error, whole.energy_error[rows])


def test_with_step_fixes_tau_and_takes_the_outputs_of_the_call_or_the_indicator():
    spec = specify(HH, X[0], "integrate", 10.02, t_out=None)
    assert spec.tau is None and spec.steps is None
    fixed = spec.with_step(0.05)
    assert fixed.tau == 0.05 and fixed.t_end == 10.02
    # "integrate" records only the end by default; a map's checks do not
    # take the indicator's times but the log-spaced ones.
    assert fixed.steps.tolist() == [200]
    checks = spec.with_step(0.05, indicator_times=False).steps
    assert np.array_equal(checks, output_steps(10.02, 0.05)) and len(checks) > 1
    with pytest.raises(ValueError, match="shorter than one step"):
        spec.with_step(20.0)
    given = specify(HH, X[0], "integrate", 10.0, t_out=[1.0, 5.0]).with_step(0.05)
    assert given.steps.tolist() == [20, 100]
    assert given.tau_choice == {"rule": "given"}


def test_specify_leaves_the_callers_model_and_refuses_before_any_work():
    model = varint.models.HenonHeiles()
    spec = specify(model, X, "sali", 10.0, 0.05, escape_radius=3.0)
    assert spec.model is not model and spec.model.escape_radius == 3.0
    assert model.escape_radius != 3.0
    assert spec.run_options == {"escape_radius": 3.0}
    with pytest.raises(ValueError, match="indicator 'gali_3' fixes k = 3; do not pass k="):
        specify(HH, X, "gali_3", 10.0, k=2)
    with pytest.raises(ValueError, match="seed must be a non-negative integer or None, got -1"):
        specify(HH, X, "sali", 10.0, seed=-1)
    with pytest.raises(ValueError, match="seed must be a non-negative integer, got None"):
        varint.chaos_map(HH, X, "sali", t_end=10.0, tau=0.05, seed=None)
    with pytest.raises(ValueError, match="model must be a varint model"):
        specify("henon-heiles", X, "sali", 10.0)


def test_a_map_checks_its_orbits_once_not_once_per_chunk(monkeypatch):
    calls = []
    original = _validate.kernels

    def counting(model, states, *args, **kwargs):
        calls.append(len(states))
        return original(model, states, *args, **kwargs)

    monkeypatch.setattr(_validate, "kernels", counting)
    m = varint.chaos_map(HH, X, "sali", t_end=5.0, tau=0.05, chunk_size=1, progress=False)
    assert m.provenance.options["chunks"] == 4
    assert calls == [4]
    # The chunks ran the map's spec: each orbit's value is that of a run.
    alone = prepare(HH, X, "sali", 5.0, 0.05).execute().sali[:, -1]
    assert np.array_equal(m.values, alone)


class _Outcome:
    def __init__(self, key, interrupted=False):
        self.key, self.interrupted = key, interrupted


def test_the_fan_out_keeps_what_finished_and_stops_at_an_interruption():
    kept = []

    def task(key):
        if key == "boom":
            raise KeyboardInterrupt
        return _Outcome(key, interrupted=key == "stop")

    def keep(key, outcome):
        kept.append((key, outcome.key))
        return 1

    assert fanout.fan_out(None, ["a", "b"], task, lambda k: (k,), keep) is False
    assert kept == [("a", "a"), ("b", "b")]
    kept.clear()
    assert fanout.fan_out(None, ["a", "stop", "c"], task, lambda k: (k,), keep) is True
    assert kept == [("a", "a")]
    kept.clear()
    assert fanout.fan_out(None, ["a", "boom", "c"], task, lambda k: (k,), keep) is True
    assert kept == [("a", "a")]


def test_failures_are_counted_by_reason_in_one_warning():
    status = np.array([0, int(varint.Status.ESCAPED), int(varint.Status.ESCAPED), -1])
    with pytest.warns(RuntimeWarning, match=r"^2 of 4 orbits failed \(2: .*\); their values"):
        fanout.warn_failures(status, "orbits", "their values are NaN")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        fanout.warn_failures(np.zeros(3, dtype=np.int64), "orbits", "")
    assert fanout.total_cpu([1.0, 2.5]) == 3.5 and fanout.total_cpu([1.0, None]) is None

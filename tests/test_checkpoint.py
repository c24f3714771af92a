"""Checkpoint and resume: a run stopped anywhere and resumed from its
checkpoint gives bitwise the result of a run that never stopped, for every
public run and every method; a checkpoint of other parameters is refused,
naming them."""

import dataclasses
import os

import numpy as np
import pytest

import varint
from varint import checkpoint as ckpt
from varint.state import RunState
from tests.helpers import assert_bitwise_equal, hook_advance

T_END = 200.0  # 4000 steps of τ = 0.05 for TM: tens of chunks, a fraction of a second
# Runs pass τ, so that the crash points count chunks of a known step; the
# automatic step resumes too (test_the_automatic_step_resumes_bitwise).


class Crash(Exception):
    """Stands for anything that ends a process between two checkpoints."""


def crash():
    raise Crash


RUNS = {
    "lyapunov_spectrum": lambda model, x0, **kw: varint.lyapunov_spectrum(
        model, x0, T_END, tau=0.05, **kw),
    "gali": lambda model, x0, **kw: varint.gali(model, x0, T_END, tau=0.05, **kw),
    "sali": lambda model, x0, **kw: varint.sali(model, x0, T_END, tau=0.05, **kw),
    "integrate": lambda model, x0, **kw: varint.integrate(
        model, x0, T_END, tau=0.05, deviations=np.eye(4)[:, :2], t_out=50, **kw),
}


def crash_then_resume(monkeypatch, path, run, at=2, method="tm"):
    """Run with a checkpoint after every chunk, crash after the ``at``-th
    chunk, then resume with the same call; returns the resumed result and
    the checkpoint's step at the crash."""
    with monkeypatch.context() as patch:
        hook_advance(patch, method, at, crash)
        with pytest.raises(Crash):
            run(checkpoint=path, checkpoint_interval=0)
    step = ckpt.read(path).state.step
    return run(checkpoint=path, checkpoint_interval=0), step


def test_checkpoint_stores_every_field_of_the_run_state():
    """Rule 8 makes the RunState the whole continuation state; a field
    added to it without being checkpointed would break resuming."""
    stored = set(ckpt.STATE_ARRAYS) | {"step", "counts", "extra"}
    assert {f.name for f in dataclasses.fields(RunState)} == stored


@pytest.mark.parametrize("kind", sorted(RUNS))
def test_checkpointing_does_not_change_the_result(kind, c1, tmp_path):
    reference = RUNS[kind](*c1)
    saved = RUNS[kind](*c1, checkpoint=tmp_path / "c.ckpt", checkpoint_interval=0)
    assert_bitwise_equal(saved, reference)


@pytest.mark.parametrize("kind", sorted(RUNS))
def test_resume_after_a_crash_is_bitwise_identical(kind, c1, tmp_path, monkeypatch):
    reference = RUNS[kind](*c1)
    resumed, step = crash_then_resume(monkeypatch, tmp_path / "c.ckpt",
                                      lambda **kw: RUNS[kind](*c1, **kw))
    assert 0 < step < reference.provenance.counts["steps"]  # it really stopped part-way
    assert_bitwise_equal(resumed, reference)


@pytest.mark.parametrize("method", sorted(varint.METHODS))
def test_resume_is_bitwise_identical_for_every_method(method, c1, tmp_path, monkeypatch):
    """Rules 3 and 8 of varint.methods, checked through a checkpoint."""
    def run(**kw):
        return varint.lyapunov_spectrum(*c1, 20.0, tau=0.05, method=method, **kw)

    reference = run()
    resumed, step = crash_then_resume(monkeypatch, tmp_path / "c.ckpt", run, at=2,
                                      method=method)
    assert step > 0
    assert_bitwise_equal(resumed, reference)


def test_the_automatic_step_resumes_bitwise(c1, tmp_path, monkeypatch):
    """Without τ the pilot chooses the step again when the run resumes: it
    is deterministic, so the resumed run continues the same steps (the
    pilot's own steps are not the run's chunks and are not hooked)."""
    def run(**kw):
        return varint.lyapunov_spectrum(*c1, T_END, **kw)

    reference = run()
    assert reference.provenance.tau_choice["rule"] == "pilot"
    resumed, step = crash_then_resume(monkeypatch, tmp_path / "c.ckpt", run)
    assert 0 < step < round(T_END / reference.provenance.tau)
    assert_bitwise_equal(resumed, reference)


def test_batch_with_a_flagged_failure_resumes_bitwise(c1, tmp_path, monkeypatch):
    """Frozen orbits, NaN records and status survive a checkpoint."""
    escaping = varint.models.solve_momentum(c1[0], [0.0, 0.0], [0.0, 0.2], 0.25)
    x0 = np.stack([c1[1], escaping, c1[1] * 0.99])
    with pytest.warns(RuntimeWarning, match="1 of 3 orbits failed"):
        reference = varint.lyapunov_spectrum(c1[0], x0, T_END, tau=0.05, errors="flag")
        resumed, _ = crash_then_resume(monkeypatch, tmp_path / "c.ckpt", lambda **kw:
                                       varint.lyapunov_spectrum(c1[0], x0, T_END, tau=0.05,
                                                                errors="flag", **kw),
                                       at=lambda state: state.step > T_END / 0.05 / 2)
    assert list(reference.status != 0) == [False, True, False]
    assert_bitwise_equal(resumed, reference)


def test_a_run_stopped_by_a_failure_can_be_continued_with_errors_flag(c1, tmp_path,
                                                                      monkeypatch):
    """errors= is not part of a checkpoint's parameters: the run that raised
    was saved at the failure; the same call raises the same error again
    without integrating, and errors="flag" continues it to the result of an
    uninterrupted errors="flag" run."""
    escaping = varint.models.solve_momentum(c1[0], [0.0, 0.0], [0.0, 0.2], 0.25)
    x0 = np.stack([c1[1], escaping])
    path = tmp_path / "c.ckpt"
    with pytest.raises(varint.IntegrationError) as first:
        varint.lyapunov_spectrum(c1[0], x0, T_END, tau=0.05, checkpoint=path)
    calls = hook_advance(monkeypatch, "tm", 10 ** 9, lambda: None)
    with pytest.raises(varint.IntegrationError) as again:
        varint.lyapunov_spectrum(c1[0], x0, T_END, tau=0.05, checkpoint=path)
    assert str(again.value) == str(first.value) and not calls
    with pytest.warns(RuntimeWarning, match="orbits failed"):
        continued = varint.lyapunov_spectrum(c1[0], x0, T_END, tau=0.05, checkpoint=path,
                                             errors="flag")
        reference = varint.lyapunov_spectrum(c1[0], x0, T_END, tau=0.05, errors="flag")
    assert_bitwise_equal(continued, reference)


def test_a_finished_checkpoint_returns_the_result_without_integrating(c1, tmp_path,
                                                                     monkeypatch):
    path = tmp_path / "c.ckpt"
    first = varint.gali(*c1, T_END, tau=0.05, checkpoint=path)
    calls = hook_advance(monkeypatch, "tm", 10 ** 9, lambda: None)
    again = varint.gali(*c1, T_END, tau=0.05, checkpoint=path)
    assert not calls
    assert_bitwise_equal(again, first)


def test_seed_none_resumes_with_the_seed_it_drew(c1, tmp_path, monkeypatch):
    """With seed=None the first call draws a seed; the resumed call must
    continue the same random vectors, not draw new ones."""
    resumed, _ = crash_then_resume(monkeypatch, tmp_path / "c.ckpt", lambda **kw:
                                   varint.lyapunov_spectrum(*c1, T_END, tau=0.05, seed=None, **kw))
    assert isinstance(resumed.provenance.seed, int)
    reference = varint.lyapunov_spectrum(*c1, T_END, tau=0.05, seed=resumed.provenance.seed)
    assert_bitwise_equal(resumed, reference)


def test_provenance_sums_wall_time_and_work_over_sessions(c1, tmp_path, monkeypatch):
    path = tmp_path / "c.ckpt"
    resumed, _ = crash_then_resume(monkeypatch, path, lambda **kw:
                                   varint.lyapunov_spectrum(*c1, T_END, tau=0.05, **kw))
    assert resumed.provenance.counts["steps"] == round(T_END / 0.05)
    assert resumed.provenance.wall_time >= ckpt.read(path).wall_time > 0


@pytest.mark.parametrize("change, named", [
    (dict(tau=0.1), "tau (checkpoint: 0.05, this call: 0.1)"),
    (dict(t_end=300.0), "t_end (checkpoint: 200.0, this call: 300.0)"),
    (dict(t_out=7), "t_out"),
    (dict(scheme="ABA864"), "method_options.scheme.name (checkpoint: 'SBAB2C', "
                            "this call: 'ABA864')"),
    (dict(n_exponents=2), "options.n_exponents (checkpoint: 4, this call: 2)"),
    (dict(seed=1), "seed (checkpoint: 0, this call: 1)"),
    (dict(escape_radius=50.0), "options.escape_radius"),
    (dict(x0=[0.0, -0.25, 0.42, 0.0]), "x0"),
    (dict(deviations=np.eye(4)), "deviations"),
    (dict(model=varint.models.HenonHeiles(escape_radius=9.0)), "model.escape_radius"),
])
def test_a_checkpoint_of_other_parameters_is_refused_naming_them(change, named, c1, tmp_path):
    path = tmp_path / "c.ckpt"
    varint.lyapunov_spectrum(*c1, T_END, tau=0.05, checkpoint=path)
    before = path.read_bytes()
    args = dict(model=c1[0], x0=c1[1], t_end=T_END, tau=0.05, checkpoint=path)
    args.update(change)
    with pytest.raises(varint.CheckpointError, match="other parameters") as err:
        varint.lyapunov_spectrum(**args)
    assert named in str(err.value)
    assert path.read_bytes() == before  # nothing lost


def test_a_checkpoint_of_another_kind_of_run_is_refused(c1, tmp_path):
    path = tmp_path / "c.ckpt"
    varint.sali(*c1, T_END, tau=0.05, checkpoint=path)
    with pytest.raises(varint.CheckpointError, match="kind .checkpoint: 'sali', this call: 'gali'"):
        varint.gali(*c1, T_END, tau=0.05, checkpoint=path)


def test_a_checkpoint_from_other_package_versions_is_refused(c1, tmp_path):
    """Bitwise resumption holds only for the same numerical code."""
    path = tmp_path / "c.ckpt"
    varint.lyapunov_spectrum(*c1, T_END, tau=0.05, checkpoint=path)
    snap = ckpt.read(path)
    snap.parameters["versions"]["numba"] = "0.1"
    ckpt.write(path, snap)
    with pytest.raises(varint.CheckpointError, match=r"versions\.numba \(checkpoint: '0\.1'"):
        varint.lyapunov_spectrum(*c1, T_END, tau=0.05, checkpoint=path)


def test_write_read_round_trip_keeps_every_bit(tmp_path):
    """Method state in RunState.extra (any numeric dtype) and records
    come back with their dtypes and bits; nothing is pickled."""
    rng = np.random.default_rng(1)
    state = RunState.start(rng.standard_normal((3, 4)), rng.standard_normal((3, 4, 2)))
    state.step, state.counts = 17, {"gradient": 34}
    state.status[1], state.fail_step[1] = 2, 9
    state.extra = {"h": rng.standard_normal(3), "n": np.arange(3, dtype=np.int32)}
    records = [{"a": rng.standard_normal((3, 2)), "b": np.full(3, np.nan)} for _ in range(4)]
    path = tmp_path / "c.ckpt"
    ckpt.write(path, ckpt.Snapshot({"kind": "test", "x": [1.5]}, state, records, 2.5))
    back = ckpt.read(path)
    assert back.parameters == {"kind": "test", "x": [1.5]} and back.wall_time == 2.5
    assert back.state.step == 17 and back.state.counts == {"gradient": 34}
    for name in ckpt.STATE_ARRAYS:
        a, b = getattr(state, name), getattr(back.state, name)
        assert a.dtype == b.dtype and a.tobytes() == b.tobytes()
    for key in state.extra:
        assert state.extra[key].dtype == back.state.extra[key].dtype
        assert state.extra[key].tobytes() == back.state.extra[key].tobytes()
    assert len(back.records) == 4
    for r, s in zip(records, back.records, strict=True):
        assert all(r[k].tobytes() == s[k].tobytes() for k in r)
    state.extra["bad"] = np.array([object()])
    with pytest.raises(TypeError, match="extra__bad"):
        ckpt.write(path, ckpt.Snapshot({}, state, records))
    assert ckpt.read(path).state.step == 17  # the failed write left the file alone
    assert os.listdir(tmp_path) == ["c.ckpt"]

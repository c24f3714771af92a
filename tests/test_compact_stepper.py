"""The compact TM stepper (varint.codegen.tm.TMBody.compact_stages): the
stages as a loop over the stage arrays, with the floating-point operations
of the stepper whose stages are written out, in the same order — so the
same bits (a law: identical arithmetic), on every kind of step the loop
folds (drift or kick first, the carried first kick, correctors, the
compensation levels, a rotating frame's drift, a failure mid-step) — and
the rule that picks one of them (COMPACT_WORK)."""

import numpy as np
import pytest
import sympy as sp

import varint
from varint.codegen.tm import compact_shape
from varint.indicators.megno import MEGNO_ACCUMULATOR
from varint.methods.tm import TangentMapPropagator
from varint.models import CR3BP, HenonHeiles
from varint.protocol import Renorm, Status
from varint.schemes import DRIFT, KICK, registered, stage_arrays
from varint.state import RunState

HH = HenonHeiles()
X0 = np.array([0.0, 0.558, 0.23337397, 0.0])

_x, _y = sp.symbols("x y")
#: No force for x < 0 (V = −√x): an orbit heading there fails mid-step
#: (tests/test_compensated.py).
CLIFF = varint.models.from_potential(-sp.sqrt(_x) + _y**2 / 2, [_x, _y])

#: (model, x0, scheme, renorm, k, options, accumulator, steps): each a kind
#: of step the loop folds.
CASES = {
    # kick first and last: the carried first kick, correctors on both ends;
    # MEGNO's rule in the loop
    "SBAB2C megno": (HH, X0, "SBAB2C", "qr", 1, {}, "megno", 300),
    # drift first and last, no corrector, no vector; sparse QR with two
    "ABA864 orbit": (HH, X0, "ABA864", "none", 0, {}, None, 300),
    "SABA2C sparse k=2": (HH, X0, "SABA2C", "qr", 2, {}, None, 300),
    # compensation: every update; the orbit's displacement per step
    "SBAB3 compensated": (HH, X0, "SBAB3", "qr", 1, {"compensated": True}, None, 300),
    "SABA3 step": (HH, X0, "SABA3", "qr", 1, {"compensated": "step"}, None, 300),
    # a rotating frame's drift: its coefficients per stage as arrays
    "CR3BP SABA2": (CR3BP(0.01215), np.array([0.5, 0.0, 0.0, 0.9]), "SABA2", "qr", 1, {},
                    None, 300),
    # a kick's forces non-finite mid-step, with the p a kick moved put back
    "cliff step": (CLIFF, np.array([0.5, 0.0, -2.0, 0.1]), "SABA2", "none", 0,
                   {"compensated": "step"}, None, 400),
}


def _run(case, work, chunks=(1.0,)):
    """The case's run in chunks (shares of its steps) with COMPACT_WORK =
    ``work``: its state, schedule, accumulator, counts, status."""
    model, x0, scheme, renorm, k, options, acc, n = CASES[case]
    accumulator = MEGNO_ACCUMULATOR if acc == "megno" else None
    p = TangentMapPropagator(model, 0.01 if model is CLIFF else 0.05, Renorm.parse(renorm),
                             accumulator=accumulator, scheme=scheme, parallel=False, **options)
    p.COMPACT_WORK = work
    state = RunState.start(x0[None].copy(), np.eye(x0.size)[:, :k][None].copy())
    if accumulator is not None:
        state.extra[accumulator.key] = np.tile(np.array(accumulator.initial), (1, k, 1))
    done = 0
    for share in chunks:
        steps = int(round(share * n))
        p.advance(state, steps)
        done += steps
    assert done == n
    return state


def _same(a, b, counts=True):
    """The same run state; the same counts unless ``counts`` is False (a
    call's first kick of a kick-first step evaluates its forces anew)."""
    assert a.status.tolist() == b.status.tolist()
    assert a.fail_step.tolist() == b.fail_step.tolist()
    assert a.step == b.step
    assert a.counts == b.counts or not counts
    for name in ("x", "W", "acc_m", "acc_e"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert a.extra.keys() == b.extra.keys()
    for key in a.extra:
        assert np.array_equal(a.extra[key], b.extra[key], equal_nan=True), key


@pytest.mark.parametrize("case", sorted(CASES))
def test_compact_is_bitwise_the_written_out_stepper(case):
    """The same operations in the same order: the same bits, status,
    failure step and derivative counts; and a run whose chunks take either
    form is bitwise the one-chunk run (resume and chunking)."""
    written = _run(case, 0)
    compact = _run(case, 10 ** 18)
    _same(written, compact)
    # A piece's form follows its work: compact below 30 % of the run, so a
    # 25 %/75 % split takes compact then written out.
    model, x0, scheme, renorm, k, options, acc, n = CASES[case]
    _same(_run(case, int(0.3 * n), chunks=(0.25, 0.75)), written, counts=False)


def test_cases_are_what_they_claim():
    """The cases cover both first stages and correctors, and the cliff
    fails in a kick after the step's first (two per SABA2 step): the p
    the first kick moved is put back from its displacement."""
    shapes = {compact_shape(*_stages(CASES[c][2])) for c in CASES}
    assert {kinds[0] for kinds, _ in shapes} == {DRIFT, KICK}
    assert any(any(corrected) for _, corrected in shapes)
    state = _run("cliff step", 10 ** 18)
    assert int(state.status[0]) == int(Status.GRADIENT_NONFINITE)
    assert state.counts["gradient"] % 2 == 0


def _stages(scheme):
    kinds, _, hc = stage_arrays(varint.get_scheme(scheme), 0.1)
    return kinds, (hc != 0.0) & (kinds != DRIFT)


def test_compact_shape_of_every_scheme():
    """Every registered splitting scheme alternates drifts and kicks with
    correctors on its end kicks only: each has a compact shape of 2 or 3
    stages with its first and last kinds; non-alternating stages or a
    corrector inside have none."""
    for scheme in registered(2):
        kinds, corrected = _stages(scheme)
        shape = compact_shape(kinds, corrected)
        assert shape is not None, scheme.name
        short, ends = shape
        assert (short[0], short[-1]) == (kinds[0], kinds[-1])
        assert ends[0] == ends[-1] == bool(corrected.any())
    assert compact_shape([DRIFT, DRIFT, KICK], [False] * 3) is None
    assert compact_shape([DRIFT, KICK, DRIFT, KICK, DRIFT],
                         [False, False, False, True, False]) is None


def test_schemes_of_one_shape_share_one_compact_stepper():
    """ABA864 (15 stages), SABA2 (5) and s35odr10 (71) are drift first and
    last without corrector: one compact module; their written-out ones
    differ. SBAB2C and SABA2C (kick first and last, correctors on the
    ends) share another."""
    def module(scheme, compact):
        p = TangentMapPropagator(HH, 0.05, Renorm.QR, scheme=scheme)
        return p._stepper(1, compact=compact)
    assert module("ABA864", True) is module("SABA2", True) is module("s35odr10", True)
    assert module("ABA864", False) is not module("SABA2", False)
    assert module("SBAB2C", True) is module("SABA2C", True)
    assert module("SBAB2C", True) is not module("ABA864", True)


def test_the_rule_runs_compact_until_the_work_reaches_compact_work(monkeypatch):
    """Where the written-out stepper is not compiled yet, one orbit runs
    compact (a module without lanes) while the model's one-orbit work with
    k vectors in this process, the call's included, stays below
    COMPACT_WORK, and written out (with lanes) from the call that reaches
    it on; the work is counted per k and per model, across propagators."""
    monkeypatch.setattr(TangentMapPropagator, "COMPACT_WORK", 1000)
    model = HenonHeiles()            # its own count of work
    p = TangentMapPropagator(model, 0.05, Renorm.QR, scheme="SBAB2C")
    p._readiness.update({1: False, 2: False})
    first = p._orbit_stepper(1, 600)
    assert not hasattr(first, "lanes") and first is p._stepper(1, compact=True)
    again = TangentMapPropagator(model, 0.05, Renorm.QR, scheme="SBAB2C")
    again._readiness.update({1: False})
    then = again._orbit_stepper(1, 400)
    assert hasattr(then, "lanes") and then is again._stepper(1)
    assert p._orbit_stepper(2, 999) is p._stepper(2, compact=True)
    assert p._orbit_stepper(2, 1) is p._stepper(2)


def test_a_compiled_written_out_stepper_is_taken_for_any_work():
    """Once the written-out stepper is loaded (or its file is in the cache),
    even the shortest run takes it: its compile is paid."""
    x, y = sp.symbols("x y")
    # A coupling no other test uses: its steppers are made here.
    c = 0.5 + np.random.default_rng().random()
    model = varint.models.from_potential((x**2 + y**2) / 2 + c * x**2 * y**2, [x, y])
    p = TangentMapPropagator(model, 0.05, Renorm.QR, scheme="ABA864")
    assert not p._ready(1)
    assert p._orbit_stepper(1, 10) is p._stepper(1, compact=True)
    written = p._stepper(1)
    fresh = TangentMapPropagator(model, 0.05, Renorm.QR, scheme="ABA864")
    assert fresh._ready(1) and fresh._orbit_stepper(1, 10) is written


def test_a_fresh_run_counts_its_work_as_one_orbit_calls_do(monkeypatch):
    """A prepared run's or a repeated call's runs (FreshRun) take the
    stepper a one-orbit call of their work would: compact while the
    model's work with k vectors stays below COMPACT_WORK, written out from
    the run that reaches it on (then without asking again), with the same
    bits throughout; written out from the first run where that stepper is
    compiled."""
    monkeypatch.setattr(TangentMapPropagator, "COMPACT_WORK", 50)
    model = HenonHeiles()            # its own count of work
    p = TangentMapPropagator(model, 0.05, Renorm.NONE, scheme="ABA864", parallel=False)
    p._readiness[0] = False
    run = p.fresh_run(1, 0, np.array([10, 20]), np.empty((1, 0, 0)))
    steppers, states = [], []
    for _ in range(4):               # 20 orbit-steps each: 20, 40, 60, 80
        run(X0[None].copy(), np.empty((1, 4, 0)))
        steppers.append(run._stepper)
        states.append(np.concatenate([run.x.ravel(), run.snapshots.x.ravel()]))
    compact, written = p._stepper(0, compact=True), p._stepper(0)
    assert compact is not written
    assert steppers == [compact.batch_serial] * 2 + [written.batch_serial] * 2
    assert run._choose is None
    assert all(np.array_equal(s, states[0]) for s in states[1:])
    ready = TangentMapPropagator(model, 0.05, Renorm.NONE, scheme="ABA864", parallel=False)
    ready._readiness[0] = True
    again = ready.fresh_run(1, 0, np.array([10, 20]), np.empty((1, 0, 0)))
    again(X0[None].copy(), np.empty((1, 4, 0)))
    assert again._stepper is written.batch_serial and again._choose is None
    assert np.array_equal(np.concatenate([again.x.ravel(), again.snapshots.x.ravel()]),
                          states[0])

"""The stepping skeleton (varint.kernels.interval) with a step body of its
own: a new method is a step body and its records; the skeleton's
end-of-interval contract (checks, record, renormalisation with its
bookkeeping, accumulator, overflow checks, failures) holds for it exactly
as stated, against values worked out by hand."""

import pickle
from collections import namedtuple

import numpy as np
from numba import njit

from varint.kernels.checks import CHECK_EVERY
from varint.kernels.interval import (Call, StepBody, batch_loop, borrow, keep, orbit_loop,
                                     orbit_record)
from varint.protocol import Renorm, Status

_ESCAPED = int(Status.ESCAPED)

# A toy method: every interval the orbit moves by ``v`` and the vectors are
# stretched by diag(2, ½) — exactly representable, so every number the
# skeleton keeps is known in closed form.
Toy = orbit_record("Toy", ("record",))
ToySetup = namedtuple("ToySetup", ("v",))
_Work = namedtuple("_Work", ("d", "k", "xe"))


@njit(inline="always")
def _begin(state, setup, call):
    return _Work(2, state.W.shape[1], state.x), 0


@njit(inline="always")
def _step(state, setup, ws, carry, s, call):
    x, W = state.x, state.W
    x[0] += setup.v
    for j in range(ws.k):
        W[0, j] *= 2.0
        W[1, j] *= 0.5
    state.counters[0] += 1
    return 0, carry + 1


@njit(inline="always")
def _check(state, setup, ws, xe, call):
    # Escape on |q|² as the real checks do (here q = x[0]).
    return _ESCAPED if xe[0] * xe[0] > call.escape_r2 else 0


TOY = StepBody(begin=_begin, step=_step, check=_check)


@njit
def _times(aux, r, x, W, flow, t):
    """An accumulator that keeps the time and the stretching it was given."""
    for j in range(aux.shape[0]):
        aux[j, 0] = t
        aux[j, 1] += np.log(r[j])


def _orbit(k, n, renorm, escape=np.inf, record=True, v=0.0, step0=0, chunks=None, W=None):
    W = np.eye(2)[:, :k].copy() if W is None else W
    state = Toy(np.zeros(2), W, np.ones(k), np.zeros(k, dtype=np.int64), np.zeros((k, 2)),
                np.zeros(1, dtype=np.int64), np.full((n, 2), np.nan))
    orbit = orbit_loop(TOY, _times, record=record)
    done, out = 0, None
    for m in chunks or [n]:
        out = orbit(Toy(*state[:6], state.record[done:]), ToySetup(v),
                    Call(m, step0 + done, 0.25, int(renorm), escape ** 2))
        done += out[1]
        if out[0] != 0:
            break
    return state, out, done


def test_renormalisation_bookkeeping_and_accumulator_times():
    """QR every interval: the stretching 2 and ½ of each interval goes into
    the mantissa/exponent accumulators exactly (2^±n), the vectors stay
    orthonormal, the accumulator sees t = (step0 + s + 1)·τ and r each time,
    and the record holds the orbit after every interval."""
    n = 1200    # 2^1200 overflows a double: the exponent must carry it
    state, (status, steps), _ = _orbit(2, n, Renorm.QR, v=0.5, step0=7)
    assert (status, steps) == (0, n)
    growth = np.log(state.acc_m) + state.acc_e * np.log(2.0)
    np.testing.assert_allclose(growth, [n * np.log(2.0), -n * np.log(2.0)], rtol=1e-14)
    assert state.acc_m[0] * 2.0 ** (state.acc_e[0] - 1000) == 2.0 ** (n - 1000)
    np.testing.assert_array_equal(state.W, np.eye(2))
    assert state.aux[0, 0] == (7 + n) * 0.25
    np.testing.assert_allclose(state.aux[:, 1], [n * np.log(2.0), -n * np.log(2.0)])
    np.testing.assert_array_equal(state.record[:, 0], 0.5 * np.arange(1, n + 1))
    assert state.counters[0] == n


def test_chunks_give_the_same_bits():
    a = _orbit(2, 300, Renorm.NORMALIZE, v=0.1)[0]
    b = _orbit(2, 300, Renorm.NORMALIZE, v=0.1, chunks=[1, 17, 100, 182])[0]
    for name in ("x", "W", "acc_m", "acc_e", "aux", "record"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))


def test_failures_stop_where_the_contract_says():
    """Escape: the interval in which |q| passed the radius, the orbit left at
    its end. Unrenormalised vectors: checked every CHECK_EVERY intervals
    (2^s passes 1e300 in interval 997, seen at the next check) and once
    more at the end of a call."""
    state, (status, steps), _ = _orbit(1, 50, Renorm.QR, escape=3.0, v=0.5)
    assert (status, steps) == (Status.ESCAPED, 6) and state.x[0] == 3.5
    assert np.isnan(state.record[6:]).all() and state.record[5, 0] == 3.0
    _, (status, steps), _ = _orbit(1, 2000, Renorm.NONE)
    first = int(np.ceil(np.log2(1e300)))          # 2^997 > 1e300
    assert status == Status.TANGENT_OVERFLOW
    assert steps == next(s for s in range(first - 1, 2000) if s % CHECK_EVERY == CHECK_EVERY - 1)
    # A short call that ends past the limit between checks reports it at its end.
    _, (status, steps), _ = _orbit(1, first + 1, Renorm.NONE)
    assert (status, steps) == (Status.TANGENT_OVERFLOW, first)


def test_degenerate_vectors_fail_the_renormalisation():
    W = np.array([[1.0, 2.0], [0.0, 0.0]])                    # parallel columns
    _, (status, steps), _ = _orbit(2, 10, Renorm.QR, W=W)
    assert (status, steps) == (Status.TANGENT_DEGENERATE, 0)


def test_batch_skips_failed_orbits_and_runs_the_others():
    m, k = 3, 1
    states = Toy(np.zeros((m, 2)), np.tile(np.eye(2)[:, :1], (m, 1, 1)), np.ones((m, k)),
                 np.zeros((m, k), dtype=np.int64), np.zeros((m, k, 2)),
                 np.zeros((m, 1), dtype=np.int64), np.zeros((m, 0, 2)))
    status = np.array([0, int(Status.ESCAPED), 0])
    done = np.full(m, -1)
    batch_loop(TOY, False, _times)(states, ToySetup(1.0), Call(5, 0, 1.0, int(Renorm.QR), np.inf),
                                  status, done)
    assert done.tolist() == [5, 0, 5] and status.tolist() == [0, int(Status.ESCAPED), 0]
    assert states.x[:, 0].tolist() == [5.0, 0.0, 5.0]


Pair = namedtuple("Pair", ("a", "b"))


@njit(inline="always")
def _fill(pair, value):
    for i in range(pair.a.shape[0]):
        pair.a[i] = value
    pair.b[0] = pair.a[0] + 1.0


@njit
def _borrowed_writes(n):
    owner = Pair(np.zeros(n), np.zeros(1))
    view = borrow(owner)
    for s in range(3):
        _fill(view, float(s))
    out = view.b[0] + owner.a[n - 1]
    keep(owner)
    return out


def test_borrowed_records_write_through_to_their_owner():
    """A borrowed record (views without reference counting) is the same
    memory as its owner, also when passed to inlined functions in a loop."""
    assert _borrowed_writes(4) == 3.0 + 2.0


def test_every_orbit_record_is_found_by_name_where_it_is_defined():
    """numba's on-disk cache keys a kernel by its argument types and pickles
    a record's class: one not importable by name is pickled by value, a new
    class in every process, so a cached kernel (the generated steppers'
    StepperOrbit) was compiled again in every new process."""
    from baselines.blocks import BlockOrbit
    from baselines.dop853_kernel import DOPOrbit
    from varint.codegen.interval import StepperOrbit
    from varint.kernels.map_stepper import MapOrbit
    from varint.kernels.parts import PartsOrbit
    from varint.kernels.tm import TMOrbit
    from varint.kernels.two_particle import TPOrbit
    from varint.tdh._kernels import TDHOrbit

    for cls in (StepperOrbit, TMOrbit, PartsOrbit, MapOrbit, TPOrbit, TDHOrbit, BlockOrbit,
                DOPOrbit):
        assert pickle.loads(pickle.dumps(cls)) is cls, cls.__module__

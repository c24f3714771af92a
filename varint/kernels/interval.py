"""The stepping skeleton: the loop over intervals τ of one orbit, the
end-of-interval contract, and the batch wrapper over orbits — written once
for every compiled method.

A method supplies a :class:`StepBody` (how to advance one interval, and
where its orbit and vectors are) and keeps its state in one record per
orbit; the skeleton does everything else, identically for every method, so
an orbit fails for the same reasons with the same status codes
(:class:`~varint.protocol.Status`) whatever advanced it.

The end-of-interval contract
----------------------------
After the step body advanced interval ``s`` (0-based within the call; the
run's interval ``step0 + s + 1`` ends at t = (step0 + s + 1)·τ):

1. a failure the body reports stops the orbit where the body left it;
2. the body's ``check`` of the orbit at the interval's end (escape,
   non-finite state, :mod:`varint.kernels.checks`);
3. the orbit is written to ``record[s]`` (a kernel built with ``record``:
   how the TDH and two-particle methods and the section finder read the
   orbit after every step);
4. the vectors are renormalised (:func:`~varint.kernels.checks.renormalize`,
   the stretching multiplied into the mantissa/exponent accumulators) and
   the indicator's accumulator updated at t, with the phase-space velocity
   from the body's ``flow`` if it reads one — or, with ``renorm`` NONE, the
   raw vectors are checked for overflow every ``check_every`` intervals
   (and once more at the end of the call);
5. the body's ``after`` hook (two-particle: neighbours put back; the
   baselines' blocks: the virtual renormalisation).

A failure in 2–5 leaves the orbit at the interval's end (the body's end
point is copied into ``state.x``) and returns ``(status, s)``; a call that
completes returns ``(OK, n_steps)``. Counting is the body's: it adds its
work to ``state.counters``.

Records
-------
The orbit's record is a namedtuple of arrays whose first fields are
:data:`ORBIT_FIELDS` — ``x`` (2N,), ``W`` (2N, k), ``acc_m``, ``acc_e``
(k,), ``aux`` (the accumulator's array, (k, columns); (0, 0) for none),
``counters`` — followed by the method's own (e.g. ``pt``, the momentum
conjugate to time; ``Y``, the two-particle neighbours). A batch passes the
same record with one more leading axis (orbits) on every field, and the
skeleton takes orbit m's row of each. What does not change along a call
(scheme tables, the model's parameters) is the method's ``setup`` record;
the call's own numbers are :class:`Call`. The model's kernels and the
accumulator's update are compiled into the kernel (closures), never passed
in records: numba types a record holding a function ~10× slower per call.
The closures are cached on disk across processes under a key naming what
they are compiled from (:mod:`varint.kernels.closures`).

A new method is therefore a step body and its records; a new
end-of-interval check is one edit here.
"""

from __future__ import annotations

import sys
from collections import namedtuple
from dataclasses import dataclass
from functools import cache
from typing import Any

import numpy as np
from numba import njit, types
from numba.core.extending import intrinsic, overload

from ..protocol import Renorm, Status
from ..threads import orbits_in_threads, parallel_by_default
from .checks import CHECK_EVERY, renormalize, tangent_overflow
from .closures import cache_on_disk
from .inlining import defer

__all__ = ["StepBody", "Call", "ORBIT_FIELDS", "orbit_record", "orbit_loop", "batch_loop",
           "serial_batch", "ThreadedBatch",
           "no_accumulator", "no_check", "no_flow", "no_after", "no_end", "own_vectors",
           "borrow", "keep", "row", "use_parallel", "next_interval", "EARLY",
           "SPARSE_NORM_LOG", "SPARSE_COND_LOG", "SPARSE_MAX_STEPS", "SPARSE_QR_MAX_STEPS"]

_OK = int(Status.OK)
_OVERFLOW = int(Status.TANGENT_OVERFLOW)
_NONE = int(Renorm.NONE)

#: The numbers of one call: intervals to advance, the run's interval count
#: at the start, τ, the renormalisation (a :class:`~varint.protocol.Renorm`)
#: and the squared escape radius.
Call = namedtuple("Call", ("n_steps", "step0", "tau", "renorm", "escape_r2"))

#: Sparse renormalisation (the generated steppers,
#: :mod:`varint.codegen.interval`) keeps the growth of every vector between
#: two renormalisations below e^SPARSE_NORM_LOG (1e50: far from overflow)
#: and, for QR, the spread of the stretchings below e^SPARSE_COND_LOG (32:
#: the ill-conditioning modified Gram–Schmidt then sees costs at most ~32 ε
#: in the smallest exponent's R_kk; with 1e3, the sum of C1's exponents, 0
#: in exact arithmetic, was off by 5e-12 at t = 1e3), and renormalises at
#: least every SPARSE_MAX_STEPS steps. The interval at most doubles from one
#: renormalisation to the next, so a sudden stronger stretching cannot
#: overflow before it is seen.
SPARSE_NORM_LOG = 115.0
SPARSE_COND_LOG = 3.47
SPARSE_MAX_STEPS = 1 << 16
#: With QR of several vectors, at most this many steps between
#: renormalisations: the spread of the last interval can underestimate the
#: next one's after a sticky episode (C1: the exponents' sum, 0 in exact
#: arithmetic, was off by 1.4e-10 at t = 1.6e3 without this bound).
SPARSE_QR_MAX_STEPS = 64
#: Vectors beyond this size are renormalised at the next check, whatever the
#: schedule (checked every CHECK_EVERY steps).
EARLY = 1e100
# As plain floats for the compiled schedule.
_NORM_LOG, _COND_LOG, _MAX_STEPS = SPARSE_NORM_LOG, SPARSE_COND_LOG, float(SPARSE_MAX_STEPS)
_QR_MAX_STEPS = float(SPARSE_QR_MAX_STEPS)

#: The fields every orbit record starts with.
ORBIT_FIELDS = ("x", "W", "acc_m", "acc_e", "aux", "counters")


def orbit_record(name, fields=()):
    """A namedtuple class for a method's orbit record: :data:`ORBIT_FIELDS`
    and then ``fields``, defined in the calling module (the class must be
    found there by name: numba's on-disk cache keys a kernel by its argument
    types, and pickles a class it cannot import by value, which makes a new
    class, and so a cache miss, in every process)."""
    module = sys._getframe(1).f_globals["__name__"]
    return namedtuple(name, ORBIT_FIELDS + tuple(fields), module=module)


@njit(cache=True)
def next_interval(interval, growth, spread):
    """The next renormalisation interval (steps) of the sparse schedule.

    Parameters
    ----------
    interval : int
        The interval just completed.
    growth : float
        max_j ln r_j over it (the largest log-stretching).
    spread : float
        max_j ln r_j − min_j ln r_j (0 unless QR with k ≥ 2).

    Returns
    -------
    int
        At most twice ``interval``, at least 1, and short enough that, at the
        same rates, growth stays below ``SPARSE_NORM_LOG`` and spread below
        ``SPARSE_COND_LOG``.
    """
    allowed = interval * 2.0
    if growth > 0.0:
        allowed = min(allowed, interval * _NORM_LOG / growth)
    if spread > 0.0:
        # QR of several vectors: the spread seen over the last interval
        # predicts the next one's conditioning only while the dynamics stay
        # alike; after a quiet (sticky) episode it does not, so the
        # interval is also kept short in absolute terms.
        allowed = min(allowed, interval * _COND_LOG / spread, _QR_MAX_STEPS)
    return int(max(1.0, min(allowed, _MAX_STEPS)))


@njit
def no_accumulator(aux, r, x, W, flow, t):
    """The accumulator of indicators that accumulate nothing."""


@njit(inline="always")
def no_check(state, setup, ws, xe, call):
    """For bodies whose orbit was checked as it was advanced."""
    return _OK


@njit(inline="always")
def no_flow(state, setup, ws, carry, xe, s, call, out):
    """For bodies without a phase-space velocity (maps)."""
    return carry


@njit(inline="always")
def no_after(state, setup, ws, s, call):
    return _OK


@njit(inline="always")
def no_end(state, ws):
    pass


@njit(inline="always")
def own_vectors(state, ws):
    """The vectors the skeleton renormalises: the record's ``W``."""
    return state.W


@dataclass(frozen=True)
class StepBody:
    """What a method supplies to the skeleton: compiled functions (numba
    dispatchers, normally ``inline="always"``), called as follows. ``ws``
    is the body's work space, a namedtuple with at least ``d``, the length
    of a vector, and ``k``, the number of vectors (compile-time constants
    where the body specialises them), and ``xe``, the array that holds the
    orbit at the end of each interval (``state.x`` itself for most bodies;
    the TDH methods copy a row of their record there); ``carry`` is a
    tuple of scalars the body threads from one interval to the next (kept
    in registers). The step returns no array: numba would then count
    references to every array it touches, in every step (~5× slower in a
    small system).

    Attributes
    ----------
    begin : ``begin(state, setup, call) -> (ws, carry)``
        Allocate the work space of one orbit for one call.
    step : ``step(state, setup, ws, carry, s, call) -> (status, carry)``
        Advance interval ``s``, leaving the orbit at its end in ``ws.xe``.
        A failure status stops the orbit; the body leaves ``state`` as it
        must be found then.
    check : ``check(state, setup, ws, xe, call) -> status``
        The orbit's end-of-interval check (:func:`no_check` if the body
        checked it already).
    flow : ``flow(state, setup, ws, carry, xe, s, call, out) -> carry``
        Write the phase-space velocity at ``xe`` to ``out`` (2N,), for an
        accumulator that reads it.
    vectors : ``vectors(state, ws) -> W``
        The (d, k) vectors to renormalise (:func:`own_vectors`: ``state.W``).
    after : ``after(state, setup, ws, s, call) -> status``
        After the vectors are settled.
    end : ``end(state, ws)``
        At the end of every call, however it ends.
    check_every : int
        Intervals between the overflow checks of unrenormalised vectors.
    error_model : str
        numba's: "python" (a division by zero raises) or "numpy" (it gives
        inf or NaN, which the body's checks catch).
    """

    begin: Any
    step: Any
    check: Any = no_check
    flow: Any = no_flow
    vectors: Any = own_vectors
    after: Any = no_after
    end: Any = no_end
    check_every: int = CHECK_EVERY
    error_model: str = "python"

    def __post_init__(self):
        # The helpers the hooks call are inlined into the kernel, not into
        # them (varint.kernels.inlining).
        defer(self.begin, self.step, self.check, self.flow, self.vectors, self.after,
              self.end)


@cache
def orbit_loop(body, accumulate=no_accumulator, flow=False, record=False):
    """The one-orbit kernel ``orbit(state, setup, call) -> (status, steps)``
    of ``body`` (see the module docstring for the contract).

    Parameters
    ----------
    body : StepBody
    accumulate : numba dispatcher
        The indicator's update (:class:`~varint.protocol.Accumulator`),
        called after every renormalisation when ``state.aux`` has rows.
    flow : bool
        Pass it the phase-space velocity (the body's ``flow``).
    record : bool
        Write the orbit after every interval to ``state.record[s]``.
    """
    begin, step, check, velocity = body.begin, body.step, body.check, body.flow
    vectors, after, end = body.vectors, body.after, body.end
    every = body.check_every
    FLOW, RECORD = bool(flow), bool(record)
    # Hooks left at their defaults are not called (numba prunes the branch
    # before it inlines: less to compile).
    CHECK, AFTER, END = check is not no_check, after is not no_after, end is not no_end
    OWN = vectors is own_vectors

    @njit(error_model=body.error_model)
    def orbit(state_owner, setup_owner, call):
        ws_owner, carry = begin(state_owner, setup_owner, call)
        # Unowned views of the records (see borrow): no reference counting
        # in the loop. Their owners live until the keep() at the end.
        state, setup, ws = borrow(state_owner), borrow(setup_owner), borrow(ws_owner)
        d, k, xe = ws.d, ws.k, ws.xe
        if OWN:  # noqa: SIM108 (a statement numba prunes before it inlines)
            W = state.W
        else:
            W = vectors(state, ws)
        x, aux = state.x, state.aux
        r = np.empty(k if aux.shape[0] > 0 else 0)   # stretching, for the accumulator
        out = np.empty(d if FLOW else 0)
        renorm = call.renorm
        status = _OK
        steps = call.n_steps
        for s in range(call.n_steps):
            status, carry = step(state, setup, ws, carry, s, call)
            if status == _OK:
                if CHECK:
                    status = check(state, setup, ws, xe, call)
                if status == _OK:
                    if RECORD:
                        for i in range(d):
                            state.record[s, i] = xe[i]
                    if renorm != _NONE:
                        status = renormalize(W, renorm, state.acc_m, state.acc_e, r, d, k)
                        if status == _OK and aux.shape[0] > 0:
                            if FLOW:
                                carry = velocity(state, setup, ws, carry, xe, s, call, out)
                            # The time from the integer step: it does not depend on chunking.
                            accumulate(aux, r, xe, W, out, (call.step0 + s + 1) * call.tau)
                    elif k > 0 and s % every == every - 1 and tangent_overflow(W):
                        status = _OVERFLOW
                if AFTER:  # noqa: SIM102 (pruned before inlining, as above)
                    if status == _OK:
                        status = after(state, setup, ws, s, call)
                if status != _OK:
                    # A failure at the end of the interval: the orbit is left there.
                    for i in range(d):
                        x[i] = xe[i]
            if status != _OK:
                steps = s
                break
        if status == _OK and every > 1 and renorm == _NONE and k > 0 and tangent_overflow(W):
            status, steps = _OVERFLOW, call.n_steps - 1
        if END:
            end(state, ws)
        keep(ws_owner)
        return status, steps

    return cache_on_disk(orbit)


@intrinsic
def keep(typingctx, owner):
    """A use of ``owner`` that numba does not remove: the record and its
    arrays live at least until here (so views :func:`borrow` took of them
    stay valid)."""

    def codegen(context, builder, sig, args):
        return context.get_dummy_value()

    return types.none(owner), codegen


@intrinsic
def borrow(typingctx, record):
    """``record`` with every array replaced by a view without an owner
    (compiled code only; keep the record alive while the views are used).

    Numba counts the references to every array a function binds; an array
    bound in a loop — a step body's ``x = state.x`` — costs an atomic
    increment and decrement per pass unless its control flow is simple
    enough for numba to prove them redundant, which a step with early exits
    and model kernel calls is not (the generic TM step on Hénon–Heiles took
    2–3× as long). Unowned views make every such count a no-op that LLVM
    removes.
    """
    if not isinstance(record, types.BaseTuple):
        return None

    def codegen(context, builder, sig, args):
        out = args[0]
        for i, ty in enumerate(record.types):
            item = builder.extract_value(args[0], i)
            if isinstance(ty, types.Array):
                src = context.make_array(ty)(context, builder, item)
                view = context.make_array(ty)(context, builder)
                context.populate_array(view, data=src.data, shape=src.shape,
                                       strides=src.strides, itemsize=src.itemsize, meminfo=None)
                out = builder.insert_value(out, view._getvalue(), i)
            else:
                # Anything else is shared: the new record holds a reference.
                context.nrt.incref(builder, ty, item)
        return out

    return record(record), codegen


def row(states, m):
    """Orbit ``m``'s record from a batch record: every field indexed by m
    (compiled code only)."""
    raise NotImplementedError("row() is for compiled code")


@overload(row)
def _row(states, m):
    cls = states.instance_class
    names = [f"states[{i}][m]" for i in range(len(states))]
    scope = {"cls": cls}
    exec(f"def impl(states, m):\n    return cls({', '.join(names)})\n", scope)
    return scope["impl"]


@cache
def batch_loop(body, parallel, accumulate=no_accumulator, flow=False):
    """The batch kernel ``batch(states, setup, call, status, done)`` of
    ``body``: every orbit m whose ``status[m]`` is OK is advanced by
    ``call.n_steps`` intervals by :func:`orbit_loop` (``accumulate`` and
    ``flow`` as there), in parallel over orbits if ``parallel``;
    ``status[m]`` receives its status and ``done[m]`` the intervals it
    completed (0 for orbits skipped). ``states`` is a batch record: every
    field has a leading axis of orbits.

    Parallel is the serial kernel on Python threads over slices of the
    orbits (:class:`ThreadedBatch`): one kernel compiled for both."""
    kernel = serial_batch(body, accumulate, flow)
    return ThreadedBatch(kernel) if parallel else kernel


@cache
def serial_batch(body, accumulate=no_accumulator, flow=False):
    """:func:`batch_loop`'s kernel, one orbit after the other, compiled
    with ``nogil=True`` so that threads can run it side by side."""
    orbit = orbit_loop(body, accumulate, flow)

    @njit(error_model=body.error_model, nogil=True)
    def batch(states, setup, call, status, done):
        for m in range(status.shape[0]):
            if status[m] != _OK:
                done[m] = 0
                continue
            st, steps = orbit(row(states, m), setup, call)
            status[m] = st
            done[m] = steps

    return cache_on_disk(batch)


class ThreadedBatch:
    """A serial batch kernel called as ``batch(states, setup, call, status,
    done)`` on threads over slices of the orbits
    (:func:`varint.threads.orbits_in_threads`): the bits of the serial
    call."""

    def __init__(self, kernel):
        #: The serial kernel (a numba dispatcher).
        self.kernel = kernel

    def __call__(self, states, setup, call, status, done):
        orbits_in_threads(self.kernel, (states, setup, call), status, done)


def use_parallel(parallel, n_orbits):
    """Whether a batch runs its orbits on all cores: as asked, or by default
    when there is more than one orbit, more than one numba thread and a
    core free for the second (:func:`varint.threads.parallel_by_default`)."""
    if parallel is None:
        return parallel_by_default(n_orbits)
    return bool(parallel)

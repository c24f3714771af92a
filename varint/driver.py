"""The loop every run shares: advance to each output time in chunks, record,
show progress, save checkpoints, stop cleanly on Ctrl-C, and turn orbit
failures into errors that say when and why.

Chunks are sized to take about 0.2 s of wall time, which keeps progress and
Ctrl-C responsive; since propagators are chunk-invariant (rule 3 of
:class:`varint.protocol.Propagator`) the chunking never changes a result, and neither does
stopping between chunks and resuming from a checkpoint.
"""

from __future__ import annotations

import _signal
import contextlib
import signal
import sys
import threading
import time
import warnings

import numpy as np

from .accuracy import user_stacklevel
from .protocol import REASONS, STATUS_OK, Status, is_failure
from .records import Records
from .state import Rows

#: SIGINT as the C module ``_signal`` takes it (:func:`_sigint_to_flag`).
_SIGINT = int(signal.SIGINT)

__all__ = ["CHUNK_SECONDS", "SNAPSHOT_BYTES", "IntegrationError", "Pace", "drive",
           "failure_message", "progress_bar"]

#: The wall time a chunk of steps aims at (:class:`Pace`): progress and
#: Ctrl-C are seen between chunks.
CHUNK_SECONDS = 0.2
#: Chunks shorter than this may grow faster (:class:`Pace`).
_QUICK_CHUNK = 1e-3
#: A progress bar appears only once a run has lasted this many seconds.
_PROGRESS_DELAY = 1.0


class IntegrationError(RuntimeError):
    """An orbit failed during a run.

    Attributes
    ----------
    t : float
        Time at the end of the interval in which it failed.
    step : int
        That interval's index (1-based, in units of τ).
    orbit : int
        Index of the (first) failed orbit in the batch.
    reason : str
    partial : result or None
        Everything recorded before the failure, as a result object.
    """

    def __init__(self, message, *, t, step, orbit, reason, partial=None):
        super().__init__(message)
        self.t, self.step, self.orbit, self.reason, self.partial = t, step, orbit, reason, partial


def failure_message(state, tau, single):
    """The first failure in ``state`` as (message, details) or None."""
    failed = np.flatnonzero(is_failure(state.status))
    if failed.size == 0:
        return None
    m = failed[np.argmin(state.fail_step[failed])]
    step = int(state.fail_step[m])
    code = int(state.status[m])
    reason = REASONS.get(code) or f"status {code}"
    who = "the orbit" if single else f"orbit {m}"
    msg = f"{who} failed at t = {step * tau:.10g} (step {step} of tau = {tau:g}): {reason}"
    return msg, {"t": step * tau, "step": step, "orbit": int(m), "reason": reason}


class _Flag:
    """A flag set by the Ctrl-C handler and read between chunks: the part
    of :class:`threading.Event` the driver uses (the handler runs in the
    main thread, between bytecodes, so a plain attribute is enough), at a
    fraction of an Event's cost to build (its lock and condition)."""

    __slots__ = ("_set",)

    def __init__(self):
        self._set = False

    def set(self):
        self._set = True

    def is_set(self):
        return self._set


@contextlib.contextmanager
def _sigint_to_flag():
    """First Ctrl-C sets a flag (the run stops at the next chunk and returns
    what it has); a second one interrupts at once."""
    flag = _Flag()
    if threading.current_thread() is not threading.main_thread():
        yield flag
        return
    def handler(signum, frame):
        if flag.is_set():
            _signal.signal(_SIGINT, previous)
            raise KeyboardInterrupt
        flag.set()

    # The C module's signal() returns the handler it replaces, which is put
    # back as it was: signal.signal would convert numbers and handlers to
    # and from enums at every call (~10 µs of a short run).
    previous = _signal.signal(_SIGINT, handler)
    try:
        yield flag
    finally:
        _signal.signal(_SIGINT, previous)


def progress_bar(progress, done, total, desc, unit="step"):
    """A tqdm bar on stderr counting ``unit`` from ``done`` to ``total``
    (after a second, so that short work shows none), or a null context:
    shown when ``progress`` is true, or by default (None) on a terminal.
    The one bar of varint: runs count steps, maps and ensembles their
    orbits and realisations (:mod:`varint.fanout`)."""
    if progress is None:
        progress = sys.stderr.isatty()
    if not progress:
        return contextlib.nullcontext(None)
    from tqdm.auto import tqdm

    # Counts over the whole work, so resumed work starts part-way.
    return tqdm(initial=int(done), total=int(total), desc=desc, unit=unit, unit_scale=True,
                delay=_PROGRESS_DELAY, leave=False, dynamic_ncols=True)


def drive(prop, state, out_steps, record, *, records=None, progress=None, desc="varint",
          errors="raise", checkpoint=None, decide=None, renorm=0, cancelled=None,
          stack=True):
    """Advance ``state`` to each step of ``out_steps`` and record there.

    A propagator that takes snapshots (``prop.takes_snapshots(state)``: it copies
    the state at given output steps inside its compiled loop) is advanced in
    chunks that span many outputs, and all their records are read at once,
    so outputs cost no more than the steps between them. Other propagators,
    and runs that stop orbits early (``decide``), stop at every output.

    Parameters
    ----------
    prop : propagator (see :class:`varint.protocol.Propagator`)
    state : RunState
    out_steps : ndarray of int
        Increasing output steps.
    record : callable
        ``record(rows) -> dict`` of arrays with one row per row of the
        :class:`~varint.state.Rows` it is given (the orbits at one output,
        or at several outputs, output-major).
    records : varint.records.Records, optional
        Records of the first ``len(records)`` output steps, made before
        (when resuming); extended in place.
    progress : bool or None
        Progress bar on stderr; by default only when it is a terminal;
        ``False``: nothing is printed.
    errors : {"raise", "flag"}
        Whether the first failing orbit ends the run; with "flag" it is
        frozen and its later records are NaN.
    checkpoint : varint.checkpoint.Checkpoint, optional
        Saved whenever it is due (between chunks) and when the run stops:
        finished, failed or interrupted by Ctrl-C. Not on any other
        exception (a second Ctrl-C, an error in a propagator), when the
        state may be half-updated; the last checkpoint written is then kept.
    decide : callable, optional
        Early stopping: ``decide(rec) -> bool array (M,)`` on each output's
        record; orbits it marks get status ``DECIDED`` (``fail_step`` = the
        step) and are not advanced again. Not a failure. Applied at output
        steps only, so where an orbit stops does not depend on chunking.
    renorm : Renorm
        How snapshots taken between renormalisations are renormalised
        before they are read.
    cancelled : callable, optional
        ``cancelled() -> bool``, asked between chunks: True stops the run
        as Ctrl-C does (a chunk of a chaos map on a Dask worker whose task
        was cancelled, where no signal reaches the thread that runs it).
    stack : bool
        False: the records are returned as the
        :class:`~varint.records.Records` themselves, their blocks not
        joined (a chaos map reads one output per orbit from them: joining
        copied every output of every orbit: 0.55 CPU s of a 1e6-orbit GPU
        map's host work on the CUDA simulator,
        ``studies/results/gpu23/stages_1e6_warm1.md``).

    Returns
    -------
    records : dict of str -> ndarray, shape (n_done, M, ...)
        Stacked records of the output steps reached (``stack=False``: the
        :class:`~varint.records.Records`).
    stop : None, "interrupted" or "failed"
    wall : float
        Seconds spent.
    """
    records = Records() if records is None else records
    start = time.perf_counter()
    # Outputs are recorded in order, so the records say which remain; a
    # checkpoint may hold a state at an output step not yet recorded.
    todo = np.asarray(out_steps[len(records):], dtype=np.int64)
    stop = None
    if errors == "raise" and is_failure(state.status).any():
        stop, todo = "failed", todo[:0]  # resumed from a checkpoint written at a failure
    takes = getattr(prop, "takes_snapshots", None)
    batched = decide is None and takes is not None and takes(state)
    pace = Pace()
    with _sigint_to_flag() as interrupted, \
            progress_bar(progress, state.step, out_steps[-1], desc) as bar:
        while stop is None and todo.size:
            if batched:
                n, outs = _batch(state, todo, pace.chunk)
                t0 = time.perf_counter()
                snaps = prop.advance(state, n, outputs=outs)
                pace.took(n, time.perf_counter() - t0)
                # Every output of the chunk is recorded, also after a failure
                # (the failed orbit's values NaN): the state has passed them.
                records.extend(_read_snapshots(snaps, state, record, renorm), len(outs))
                todo = todo[len(outs):]
                if errors == "raise" and is_failure(state.status).any():
                    stop = "failed"
            else:
                target = int(todo[0])
                n = min(pace.chunk, target - state.step)
                t0 = time.perf_counter()
                prop.advance(state, n)
                pace.took(n, time.perf_counter() - t0)
                if errors == "raise" and is_failure(state.status).any():
                    stop = "failed"
                elif state.step == target:
                    records.append(_record_now(prop, state, record, decide, renorm))
                    todo = todo[1:]
            if bar is not None:
                bar.update(n)
            if stop is None and (interrupted.is_set()
                                 or (cancelled is not None and cancelled())):
                stop = "interrupted"
            if stop is None and checkpoint is not None and checkpoint.due():
                checkpoint.save(state, records)
        # Inside the Ctrl-C guard: a Ctrl-C now only sets the flag.
        saved = checkpoint is not None and checkpoint.save(state, records)
    if stop == "interrupted":
        where = (f"; saved to {checkpoint.path}, run the same call again to resume"
                 if saved else "")
        warnings.warn(f"interrupted at t = {state.step * prop.tau:g}: returning the "
                      f"{len(records)} outputs recorded so far{where}", RuntimeWarning,
                      stacklevel=user_stacklevel())
    return (records.stacked() if stack else records), stop, time.perf_counter() - start


class Pace:
    """Chunks of steps sized to take about ``CHUNK_SECONDS``: progress and
    Ctrl-C stay responsive, and the chunking never changes a result
    (rule 3 of the propagator protocol).

    A call costs a fixed part (transfers, packing: on a GPU, for many
    orbits, it may exceed ``CHUNK_SECONDS``) and a part per step. Sized by
    its mean cost per step alone, a chunk whose fixed part exceeds the
    target would shrink at every call, to one step, and the run would
    pay the fixed part at every step (a GPU map of 1e5 orbits on the CUDA
    simulator, its kernel doing no step: 864 calls; the likely reason why
    the H100's GPU map of 1e6 orbits did not end within its run).
    So where two calls of different lengths show the marginal cost of a
    step to be smaller than the mean, the chunk is sized by the marginal
    cost: shrinking a chunk cannot make a call faster than its fixed part.
    """

    def __init__(self):
        self.chunk = 64
        self.last = None   # (steps, seconds) of the last call that set the pace

    def took(self, n, seconds):
        if n >= self.chunk:
            per_step = max(seconds, 1e-6) / n
            if self.last is not None and self.last[0] != n:
                marginal = (seconds - self.last[1]) / (n - self.last[0])
                if marginal > 0.0:
                    per_step = min(per_step, marginal)
            self.last = (n, seconds)
            grown = CHUNK_SECONDS / per_step
            # A chunk grows at most 8-fold, so that one unrepresentative
            # chunk cannot make the next last for minutes; a chunk of under
            # 1 ms (mostly the fixed cost of a call) may grow 64-fold, since
            # the next then lasts at most ~64 ms at this rate.
            most = 64 if seconds < _QUICK_CHUNK else 8
            # (np.clip's value, without its ~5 µs on Python floats)
            self.chunk = max(1, int(min(max(grown, n / 8), n * most)))


#: Most bytes of snapshots taken in one chunk of a batched run.
SNAPSHOT_BYTES = 1 << 26


def _batch(state, todo, chunk):
    """Steps of the next chunk and the output steps inside it."""
    m, d, k = state.W.shape
    per_output = 8 * m * (d * (k + 1) + 2 * k) + sum(
        a[0].nbytes * m for a in state.extra.values() if a.ndim and a.shape[0] == m)
    most = max(1, SNAPSHOT_BYTES // max(per_output, 1))
    end = min(state.step + chunk, int(todo[-1]))
    inside = todo[:int(np.searchsorted(todo, end, side="right"))][:most]
    if inside.size and len(inside) == most:
        end = int(inside[-1])
    return end - state.step, inside


def _record_now(prop, state, record, decide, renorm):
    """The record of every orbit at the current step (frozen ones NaN). A
    propagator that renormalises sparsely may hold raw vectors: they are
    read renormalised (copies), as its snapshots are."""
    rows = state.renormalized(renorm) if getattr(prop, "sparse", 0) else Rows.of(state)
    rec = record(rows)
    _blank(rec, is_failure(state.status))
    if decide is not None:
        settled = np.asarray(decide(rec), dtype=bool) & (state.status == STATUS_OK)
        state.status[settled] = Status.DECIDED
        state.fail_step[settled] = state.step
    return rec


def _read_snapshots(snaps, state, record, renorm):
    """The records of every snapshot step, read in one call of ``record``:
    a dict of arrays with a leading output axis (empty without snapshots)."""
    s = len(snaps.steps)
    if s == 0:
        return {}
    m = state.n_orbits
    failed = is_failure(state.status)
    # Rows of orbits that had failed by an output were never written: show
    # them the frozen state (then blank their values), so no reader sees NaN.
    # (Nothing to find without a failure, the common case.)
    blank = bool(failed.any())
    if blank:
        dead = failed[None, :] & (state.fail_step[None, :] <= snaps.steps[:, None])
        blank = bool(dead.any())
    if blank:
        out, orb = np.nonzero(dead)
        snaps.x[out, orb] = state.x[orb]
        snaps.W[out, orb] = state.W[orb]
        snaps.acc_m[out, orb] = state.acc_m[orb]
        snaps.acc_e[out, orb] = state.acc_e[orb]
        for key, arr in snaps.extra.items():
            arr[out, orb] = state.extra[key][orb]
    flat = record(snaps.rows(renorm))
    # One copy per key for the whole chunk (the record may hold views of
    # the snapshot buffers), blanked at once and kept as one block: no work
    # per output (nothing to blank in a run without failures).
    shaped = {}
    for key, arr in flat.items():
        block = np.array(arr).reshape((s, m) + np.shape(arr)[1:])
        if blank and np.issubdtype(block.dtype, np.floating):
            block[dead] = np.nan
        shaped[key] = block
    return shaped


def _blank(rec, dead):
    """NaN for the floating-point values of ``dead`` orbits."""
    if dead.any():
        for arr in rec.values():
            if np.issubdtype(arr.dtype, np.floating):
                arr[dead] = np.nan

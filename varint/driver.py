"""The loop every run shares: advance to each output time in chunks, record,
show progress, save checkpoints, stop cleanly on Ctrl-C, and turn orbit
failures into errors that say when and why.

Chunks are sized to take about 0.2 s of wall time, which keeps progress and
Ctrl-C responsive; since propagators are chunk-invariant (rule 3 of
:class:`varint.protocol.Propagator`) the chunking never changes a result, and neither does
stopping between chunks and resuming from a checkpoint.
"""

from __future__ import annotations

import contextlib
import signal
import sys
import threading
import time
import warnings

import numpy as np

from .protocol import REASONS, Status, is_failure

__all__ = ["IntegrationError", "drive", "failure_message"]

_CHUNK_SECONDS = 0.2
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


@contextlib.contextmanager
def _sigint_to_flag():
    """First Ctrl-C sets a flag (the run stops at the next chunk and returns
    what it has); a second one interrupts at once."""
    flag = threading.Event()
    if threading.current_thread() is not threading.main_thread():
        yield flag
        return
    previous = signal.getsignal(signal.SIGINT)

    def handler(signum, frame):
        if flag.is_set():
            signal.signal(signal.SIGINT, previous)
            raise KeyboardInterrupt
        flag.set()

    signal.signal(signal.SIGINT, handler)
    try:
        yield flag
    finally:
        signal.signal(signal.SIGINT, previous)


def _progress_bar(progress, done, total, desc):
    if progress is None:
        progress = sys.stderr.isatty()
    if not progress:
        return contextlib.nullcontext(None)
    from tqdm.auto import tqdm

    # Counts steps of τ over the whole run, so a resumed run starts part-way.
    return tqdm(initial=int(done), total=int(total), desc=desc, unit="step", unit_scale=True,
                delay=_PROGRESS_DELAY, leave=False, dynamic_ncols=True)


def drive(prop, state, out_steps, record, *, records=None, progress=None, desc="varint",
          errors="raise", checkpoint=None, decide=None):
    """Advance ``state`` to each step of ``out_steps`` and record there.

    Parameters
    ----------
    prop : propagator (see :mod:`varint.methods`)
    state : RunState
    out_steps : ndarray of int
        Increasing output steps.
    record : callable
        ``record(state) -> dict`` of arrays with leading orbit axis, called
        at each output step.
    records : list of dict, optional
        Records of the first ``len(records)`` output steps, made before
        (when resuming); the list is extended in place.
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

    Returns
    -------
    records : dict of str -> ndarray, shape (n_done, M, ...)
        Stacked records of the output steps reached.
    stop : None, "interrupted" or "failed"
    wall : float
        Seconds spent.
    """
    records = [] if records is None else records
    stop = None
    start = time.perf_counter()
    chunk = 64
    # Outputs are recorded in order, so the records say which remain; a
    # checkpoint may hold a state at an output step not yet recorded.
    todo = [int(s) for s in out_steps[len(records):]]
    if errors == "raise" and is_failure(state.status).any():
        stop, todo = "failed", []  # resumed from a checkpoint written at a failure
    with _sigint_to_flag() as interrupted, \
            _progress_bar(progress, state.step, out_steps[-1], desc) as bar:
        for target in todo:
            while state.step < target:
                n = min(chunk, target - state.step)
                t0 = time.perf_counter()
                prop.advance(state, n)
                dt = time.perf_counter() - t0
                if n == chunk:
                    chunk = int(np.clip(n * _CHUNK_SECONDS / max(dt, 1e-6), n / 8, n * 8))
                    chunk = max(chunk, 1)
                if bar is not None:
                    bar.update(n)
                if errors == "raise" and is_failure(state.status).any():
                    stop = "failed"
                    break
                if interrupted.is_set():
                    stop = "interrupted"
                    break
                if checkpoint is not None and checkpoint.due():
                    checkpoint.save(state, records)
            if stop is not None:
                break
            rec = record(state)
            dead = is_failure(state.status)
            if dead.any():
                for arr in rec.values():
                    if np.issubdtype(arr.dtype, np.floating):
                        arr[dead] = np.nan
            records.append(rec)
            if decide is not None:
                settled = np.asarray(decide(rec), dtype=bool) & (state.status == Status.OK)
                state.status[settled] = Status.DECIDED
                state.fail_step[settled] = state.step
        # Inside the Ctrl-C guard: a Ctrl-C now only sets the flag.
        saved = checkpoint is not None and checkpoint.save(state, records)
    if stop == "interrupted":
        where = (f"; saved to {checkpoint.path}, run the same call again to resume"
                 if saved else "")
        warnings.warn(f"interrupted at t = {state.step * prop.tau:g}: returning the "
                      f"{len(records)} outputs recorded so far{where}", RuntimeWarning,
                      stacklevel=4)
    stacked = {key: np.stack([r[key] for r in records]) if records else None
               for key in (records[0] if records else {})}
    return stacked, stop, time.perf_counter() - start

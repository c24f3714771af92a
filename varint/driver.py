"""The loop every run shares: advance to each output time in chunks, record,
show progress, stop cleanly on Ctrl-C, and turn orbit failures into errors
that say when and why.

Chunks are sized to take about 0.2 s of wall time, which keeps progress and
Ctrl-C responsive; since propagators are chunk-invariant (rule 3 of
:mod:`varint.methods`) the chunking never changes a result.
"""

from __future__ import annotations

import contextlib
import signal
import sys
import threading
import time
import warnings

import numpy as np

from . import _kernels as K

__all__ = ["IntegrationError", "drive", "failure_message"]

_REASONS = {
    K.ORBIT_NONFINITE: "the orbit became non-finite (overflow or NaN)",
    K.ESCAPED: "the orbit escaped: |q| exceeded the model's escape_radius",
    K.TANGENT_DEGENERATE: "a deviation vector became zero or non-finite",
    K.TANGENT_OVERFLOW: (f"the unrenormalised deviation vectors exceeded {K.TANGENT_LIMIT:g}; "
                         "renormalise them (lyapunov_spectrum, gali) or shorten the run"),
}

_CHUNK_SECONDS = 0.2


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
    failed = np.flatnonzero(state.status != K.OK)
    if failed.size == 0:
        return None
    m = failed[np.argmin(state.fail_step[failed])]
    step = int(state.fail_step[m])
    reason = _REASONS.get(int(state.status[m]), f"status {int(state.status[m])}")
    who = "the orbit" if single else f"orbit {m}"
    msg = f"{who} failed at t = {step * tau:.10g} (step {step} of tau = {tau:g}): {reason}"
    if failed.size > 1:
        msg += f" ({failed.size} orbits failed; pass errors='flag' to keep the others)"
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


def _progress_bar(progress, total, desc):
    if progress is None:
        progress = sys.stderr.isatty()
    if not progress:
        return contextlib.nullcontext(None)
    from tqdm.auto import tqdm

    # Shown only for runs longer than a second; unit is steps of τ.
    return tqdm(total=int(total), desc=desc, unit="step", unit_scale=True, delay=1.0,
                leave=False, dynamic_ncols=True)


def drive(prop, state, out_steps, record, *, progress=None, desc="varint", errors="raise"):
    """Advance ``state`` to each step of ``out_steps`` and record there.

    Parameters
    ----------
    prop : propagator (see :mod:`varint.methods`)
    state : RunState
    out_steps : ndarray of int
        Increasing output steps; those already reached are skipped.
    record : callable
        ``record(state) -> dict`` of arrays with leading orbit axis, called
        at each output step.
    progress : bool or None
        Progress bar on stderr; by default only when it is a terminal.
    errors : {"raise", "flag"}
        Whether the first failing orbit ends the run; with "flag" it is
        frozen and its later records are NaN.

    Returns
    -------
    records : dict of str -> ndarray, shape (n_done, M, ...)
        Stacked records of the output steps reached.
    stop : None, "interrupted" or "failed"
    wall : float
        Seconds spent.
    """
    records, stop = [], None
    start = time.perf_counter()
    chunk = 64
    todo = [int(s) for s in out_steps if s > state.step]
    with _sigint_to_flag() as interrupted, \
            _progress_bar(progress, todo[-1] - state.step if todo else 0, desc) as bar:
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
                if errors == "raise" and (state.status != K.OK).any():
                    stop = "failed"
                    break
                if interrupted.is_set():
                    stop = "interrupted"
                    break
            if stop is not None:
                break
            rec = record(state)
            dead = state.status != K.OK
            if dead.any():
                for arr in rec.values():
                    if np.issubdtype(arr.dtype, np.floating):
                        arr[dead] = np.nan
            records.append(rec)
    if stop == "interrupted":
        warnings.warn(f"interrupted at t = {state.step * prop.tau:g}: returning the "
                      f"{len(records)} outputs recorded so far", RuntimeWarning, stacklevel=3)
    stacked = {key: np.stack([r[key] for r in records]) if records else None
               for key in (records[0] if records else {})}
    return stacked, stop, time.perf_counter() - start

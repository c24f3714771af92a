"""Compilation, measured and announced.

The first run of a new model, method or scheme compiles its kernels with
numba, which takes seconds (cached on disk for the next process, see
:mod:`varint.codegen.stepper`); later runs take milliseconds. So that
neither the wait nor the timings mislead:

* every compilation is timed through numba's event API
  (:mod:`numba.core.event`, the ``"numba:compile"`` events), outermost
  compilations only (a kernel compiled while compiling the stepper that
  calls it is not counted twice);
* a run keeps its compile time apart from its pilot and run time
  (:class:`Clock`; ``result.provenance.timing``);
* a compilation that lasts longer than :data:`ANNOUNCE_AFTER` seconds
  announces itself once per call, on stderr, with the time it is expected
  to take: the median of the compilations this cache directory has seen
  (``compile_times.json`` beside the cached kernels), or "seconds" before
  the first.

The announcement is shown when stderr is a terminal or a notebook (as the
progress bars, :mod:`varint.driver`), always with ``progress=True`` and
never with ``progress=False``.
"""

from __future__ import annotations

import contextvars
import json
import math
import sys
import threading
import time

from numba.core import event

from . import cachedir
from .files import atomic_write

__all__ = ["Clock", "compile_seconds", "ANNOUNCE_AFTER"]

#: Seconds a compilation may take before it announces itself.
ANNOUNCE_AFTER = 1.0
#: The file of measured compile times, in the cache directory.
_TIMES = "compile_times.json"
#: How many measured compile times are kept.
_KEEP = 64


class _Listener(event.Listener):
    """Sums the seconds of outermost ``numba:compile`` events, per process,
    and tells the active :class:`Clock` when one starts and ends."""

    def __init__(self):
        self.lock = threading.Lock()
        self.total = 0.0
        self.local = threading.local()

    def on_start(self, ev):
        depth = getattr(self.local, "depth", 0)
        self.local.depth = depth + 1
        if depth == 0:
            self.local.start = time.perf_counter()
            clock = _ACTIVE.get()
            if clock is not None:
                clock.compile_started()

    def on_end(self, ev):
        self.local.depth -= 1
        if self.local.depth == 0:
            seconds = time.perf_counter() - self.local.start
            with self.lock:
                self.total += seconds
            clock = _ACTIVE.get()
            if clock is not None:
                clock.compile_ended(seconds)


_LISTENER = _Listener()
event.register("numba:compile", _LISTENER)
#: The outermost Clock of the current call (inner calls defer to it).
_ACTIVE: contextvars.ContextVar = contextvars.ContextVar("varint_compile_clock", default=None)


def compile_seconds():
    """Seconds this process has spent compiling with numba (outermost
    compilations), since varint was imported."""
    return _LISTENER.total


class Clock:
    """The time of one call split into compilation and the rest, and the
    announcement of a long compilation.

    Use it as a context manager around each part of the call
    (``with clock.part("pilot"):``); ``timing`` then holds the seconds of
    each part without the compilations inside it, and ``"compile"`` their
    sum. A Clock entered while another is active (a chaos map's runs)
    measures its parts but leaves the announcement to the outer one.

    Parameters
    ----------
    what : str
        What is being compiled for, for the announcement (e.g. "lyapunov
        of HenonHeiles by tm (SBAB2C)").
    progress : bool or None
        Announce: always (True), never (False), or when stderr is a
        terminal or a notebook (None).
    """

    def __init__(self, what, progress=None):
        self.what = what
        self.progress = progress
        self.timing = {"compile": 0.0}
        self._announced = False
        self._timer = None
        self._outer = None

    # -- parts -------------------------------------------------------------
    def part(self, name):
        """Context manager timing the part ``name`` (seconds without its
        compilations; those go to ``"compile"``)."""
        return _Part(self, name)

    def _enter(self):
        self._outer = _ACTIVE.get()
        return _ACTIVE.set(self if self._outer is None else self._outer)

    # -- announcement --------------------------------------------------------
    def compile_started(self):
        if self._announced or not self._shows():
            return
        self._timer = threading.Timer(ANNOUNCE_AFTER, self._announce)
        self._timer.daemon = True
        self._timer.start()

    def compile_ended(self, seconds):
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None
        _remember(seconds)

    def _shows(self):
        if self.progress is not None:
            return bool(self.progress)
        try:
            return sys.stderr.isatty() or "ipykernel" in sys.modules
        except (AttributeError, ValueError):
            return False

    def _announce(self):
        if self._announced:
            return
        self._announced = True
        expected = _expected()
        about = (f"about {expected:.0f} s" if expected is not None and expected >= 1
                 else "some seconds")
        print(f"varint: compiling kernels for {self.what}, first use; cached for next time "
              f"({about})", file=sys.stderr, flush=True)


class _Part:
    def __init__(self, clock, name):
        self.clock, self.name = clock, name

    def __enter__(self):
        self.token = self.clock._enter()
        self.start = time.perf_counter()
        self.compiled = compile_seconds()
        return self

    def __exit__(self, *exc):
        compiled = compile_seconds() - self.compiled
        wall = time.perf_counter() - self.start
        timing = self.clock.timing
        timing["compile"] += compiled
        timing[self.name] = timing.get(self.name, 0.0) + max(0.0, wall - compiled)
        if self.clock._timer is not None:
            self.clock._timer.cancel()
        _ACTIVE.reset(self.token)
        return False


def _store():
    """The store's path in the private cache directory
    (:func:`varint.cachedir.private_dir`: never a directory that others
    could write, which is refused for everything else too), or None."""
    base = cachedir.private_dir()
    return None if base is None else base / _TIMES


def _read():
    """The measured compile times: a list of positive finite numbers (an
    unreadable or foreign file counts as none; it only sets a message)."""
    path = _store()
    if path is None:
        return []
    try:
        values = json.loads(path.read_text())
    except (OSError, ValueError):
        return []
    if not isinstance(values, list):
        return []
    return [float(v) for v in values if isinstance(v, (int, float)) and not isinstance(v, bool)
            and math.isfinite(v) and v > 0][-_KEEP:]


def _expected():
    """The median of the measured compile times longer than the
    announcement's threshold, or None."""
    long = sorted(v for v in _read() if v > ANNOUNCE_AFTER)
    return long[len(long) // 2] if long else None


def _remember(seconds):
    """Add a compilation's time to the store (long ones only: they are
    what the announcement predicts); a store that cannot be written is
    skipped silently, since it only refines a message."""
    if seconds <= ANNOUNCE_AFTER:
        return
    path = _store()
    if path is None:
        return
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write(path, json.dumps((_read() + [round(seconds, 3)])[-_KEEP:]))
    except OSError:
        pass

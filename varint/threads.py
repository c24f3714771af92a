"""Whether a batch runs on several threads by default: only where a core
is free for the second thread.

numba's parallel kernels share a batch's orbits (or blocks of SIMD lanes)
among numba's threads, and a call returns when its last thread is done. On
a machine whose cores other processes keep busy, the operating system
deschedules one of those threads now and then and the whole call waits for
it: on the two busy cores of our shared machine, two threads took 1/0.49
and 1/0.61 of one thread's time on the Hénon–Heiles SALI and MEGNO maps
(issue 28; ``studies/threads.py`` measures it). So a batch goes parallel by default
only when the cores this process may use, less the load the *other*
processes put on them, leave room for a second thread.

The load of the others is the 1-minute load average less this process's
own share of it: one core (the calling thread, running now) until it has
been measured, then its CPU time per wall second averaged the way the
kernel averages the load (an exponential with a 1-minute time constant), so
that a process that ran on two threads does not read its own load as
someone else's and fall back to one. Threads change no bit of a result (the
orbits are independent), so the choice is free to follow the machine.

A parallel batch is the serial kernel, compiled with ``nogil=True``, run by
Python threads over contiguous slices of its orbits or blocks
(:func:`in_threads`, :func:`orbits_in_threads`): each orbit's arithmetic
is the serial kernel's, so the bits are those of the serial run, and a
process that runs a batch both ways compiles one kernel, not two. (numba's
``parallel=True`` kernels, their parfor lowering typing and optimising the
inlined body again, cost 2.1–5.7 CPU s each to compile cold after the
serial one, and the always-parallel section finder 17.6 s against 11.7 s
serial: ``studies/suite_threads.py``,
``results/suite21/suite_threads_base.json`` and ``…_new.json``.)
"""

from __future__ import annotations

import math
import os
import threading
import time
from concurrent.futures import ThreadPoolExecutor, wait

import numba
import numpy as np

__all__ = ["parallel_by_default", "free_cores", "in_threads", "orbits_in_threads",
           "SPARE_CORES", "SLICES_PER_THREAD", "SKIP"]

#: The free cores (beyond the calling thread's) a batch needs to go
#: parallel by default: half a core, so that a second thread gets at least
#: half of one.
SPARE_CORES = 0.5
#: Seconds between two readings of the load (a reading costs a few µs).
_READ_EVERY = 0.5
#: The time constant of the kernel's 1-minute load average (s).
_LOAD_WINDOW = 60.0
#: Slices per thread of a batch of orbits: threads take the slices one at a
#: time, so a thread the operating system deschedules holds up one slice,
#: not a whole share of the orbits (and orbits that stop early leave no
#: thread idle for long).
SLICES_PER_THREAD = 4
#: The status that makes a batch kernel skip an orbit (any status but OK
#: does; this one is no status a kernel sets).
SKIP = -1


class _Load:
    """The last reading: when, this process's CPU time then, its averaged
    share of the load and the free cores."""

    wall = -math.inf
    cpu = 0.0
    own = 1.0
    free = 0.0


def _cores():
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):   # not on Linux
        return os.cpu_count() or 1


def free_cores():
    """Cores of this process's affinity mask that neither the other
    processes' load nor the calling thread take (may be negative: an
    overloaded machine). Read at most every :data:`_READ_EVERY` seconds."""
    now, cpu = time.monotonic(), time.process_time()
    if now - _Load.wall < _READ_EVERY:
        return _Load.free
    if math.isfinite(_Load.wall):
        dt = now - _Load.wall
        decay = math.exp(-dt / _LOAD_WINDOW)
        _Load.own = _Load.own * decay + (cpu - _Load.cpu) / dt * (1.0 - decay)
    try:
        load = os.getloadavg()[0]
    except (AttributeError, OSError):   # no load average: assume the cores are ours
        load = 0.0
    others = max(0.0, load - _Load.own)
    _Load.wall, _Load.cpu, _Load.free = now, cpu, _cores() - others - 1.0
    return _Load.free


def parallel_by_default(n_items):
    """Whether a batch of ``n_items`` independent pieces (orbits, blocks of
    lanes) runs on numba's threads when the caller did not say: more than
    one piece, more than one numba thread, and at least
    :data:`SPARE_CORES` free beyond the calling thread (:func:`free_cores`)."""
    if n_items <= 1 or numba.get_num_threads() <= 1:
        return False
    return free_cores() >= SPARE_CORES


class _Pool:
    """The threads that help the calling thread: made on first use, as many
    as numba may use less one (each call takes ``numba.get_num_threads()``
    of them at most, as numba's own parallel kernels do)."""

    executor = None
    lock = threading.Lock()

    @classmethod
    def get(cls):
        with cls.lock:
            if cls.executor is None:
                cls.executor = ThreadPoolExecutor(
                    max(1, numba.config.NUMBA_NUM_THREADS - 1),
                    thread_name_prefix="varint-batch")
            return cls.executor


def in_threads(work, n_items, slice_size=None):
    """Call ``work(lo, hi)`` for contiguous slices ``[lo, hi)`` that cover
    ``range(n_items)`` once, on ``numba.get_num_threads()`` threads (the
    calling one and helpers of a pool), each thread taking the next slice
    when it is done with one.

    ``work`` must release the GIL to run in parallel (a numba kernel
    compiled with ``nogil=True``) and touch only its own slice's items.
    Slices hold ``slice_size`` items, by default about ``n_items`` /
    (threads · :data:`SLICES_PER_THREAD`). The call returns when every
    slice is done. An exception in any thread stops the handing out of
    slices and is raised here once the running slices are done (the
    calling thread's own first); so is a Ctrl-C that arrives while the
    calling thread waits (a compiled kernel cannot be interrupted, so the
    other threads finish their slices first, as numba's threads do).
    """
    n_items = int(n_items)
    threads = min(numba.get_num_threads(), n_items)
    if threads <= 1:
        if n_items:
            work(0, n_items)
        return
    size = slice_size or -(-n_items // (threads * SLICES_PER_THREAD))
    slices = iter([(lo, min(lo + size, n_items)) for lo in range(0, n_items, size)])
    lock, stop = threading.Lock(), threading.Event()

    def run():
        while not stop.is_set():
            with lock:
                piece = next(slices, None)
            if piece is None:
                return
            try:
                work(*piece)
            except BaseException:
                stop.set()
                raise

    helpers = [_Pool.get().submit(run) for _ in range(threads - 1)]
    interrupted = None
    try:
        run()
    finally:
        while True:
            try:
                wait(helpers)
                break
            except KeyboardInterrupt as exc:   # let the running slices end first
                stop.set()
                interrupted = exc
    if interrupted is not None:
        raise interrupted
    for helper in helpers:
        helper.result()


def orbits_in_threads(kernel, args, status, done):
    """Run the batch kernel ``kernel(*args, status, done)`` over slices of
    its orbits with :func:`in_threads`. Each slice's call gets a copy of
    ``status`` in which the orbits of the other slices are :data:`SKIP`
    (a batch kernel steps only the orbits whose status is OK and writes
    nothing of the others but ``done``, 0), and its own slice of
    ``status`` and ``done`` is copied back: every orbit is stepped once, by
    the serial kernel's arithmetic."""
    def work(lo, hi):
        mine = np.full_like(status, SKIP)
        mine[lo:hi] = status[lo:hi]
        steps = np.zeros_like(done)
        kernel(*args, mine, steps)
        status[lo:hi] = mine[lo:hi]
        done[lo:hi] = steps[lo:hi]

    in_threads(work, status.shape[0])

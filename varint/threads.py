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
"""

from __future__ import annotations

import math
import os
import time

import numba

__all__ = ["parallel_by_default", "free_cores", "SPARE_CORES"]

#: The free cores (beyond the calling thread's) a batch needs to go
#: parallel by default: half a core, so that a second thread gets at least
#: half of one.
SPARE_CORES = 0.5
#: Seconds between two readings of the load (a reading costs a few µs).
_READ_EVERY = 0.5
#: The time constant of the kernel's 1-minute load average (s).
_LOAD_WINDOW = 60.0


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

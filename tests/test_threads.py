"""The default thread choice: a batch goes parallel only where a core is
free for the second thread, counting the load of the other processes, not
this one's (varint.threads); and the threads a parallel batch runs on:
every item once, on several threads at a time, errors and Ctrl-C raised in
the caller once no thread runs. That the threads change no bit is tested
with the steppers (test_generated_stepper, test_chaos_map,
test_stepsize_orbits, test_planetary_runs, test_tdh)."""

import math
import threading
import time

import numba
import numpy as np
import pytest
from numba import njit

from varint import threads
from varint.kernels.interval import use_parallel


@pytest.fixture
def machine(monkeypatch):
    """A 2-core machine whose load average, CPU time and clock the test
    sets; the last reading forgotten."""
    now = {"wall": 100.0, "cpu": 0.0, "load": 1.0}
    monkeypatch.setattr(threads.os, "sched_getaffinity", lambda pid: {0, 1})
    monkeypatch.setattr(threads.os, "getloadavg", lambda: (now["load"], 0.0, 0.0))
    monkeypatch.setattr(threads.time, "monotonic", lambda: now["wall"])
    monkeypatch.setattr(threads.time, "process_time", lambda: now["cpu"])
    monkeypatch.setattr(numba, "get_num_threads", lambda: 2)
    for name, value in (("wall", -math.inf), ("cpu", 0.0), ("own", 1.0), ("free", 0.0)):
        monkeypatch.setattr(threads._Load, name, value)
    return now


def test_alone_on_the_machine_a_batch_goes_parallel(machine):
    # Load 1: this process's running thread; the second core is free.
    assert threads.free_cores() == pytest.approx(1.0)
    assert threads.parallel_by_default(100)
    assert use_parallel(None, 100)


def test_other_processes_keep_a_batch_on_one_thread(machine):
    # Load 3 on 2 cores: two other processes besides this one.
    machine["load"] = 3.0
    assert threads.free_cores() == pytest.approx(-1.0)
    assert not threads.parallel_by_default(100)
    assert not use_parallel(None, 100)
    # Asked for, it runs as asked.
    assert use_parallel(True, 100) and not use_parallel(False, 100)


def test_its_own_two_threads_are_not_read_as_someone_elses_load(machine):
    threads.free_cores()
    # A minute on two threads: 2 s of CPU per second, and the load follows.
    machine["wall"] += 60.0
    machine["cpu"] += 120.0
    machine["load"] = 2.0
    own = 1.0 * math.exp(-1.0) + 2.0 * (1.0 - math.exp(-1.0))
    assert threads._Load.own == 1.0
    assert threads.free_cores() == pytest.approx(2.0 - (2.0 - own) - 1.0)
    assert threads.parallel_by_default(100)


def test_one_piece_or_one_thread_runs_serially(machine, monkeypatch):
    assert not threads.parallel_by_default(1)
    monkeypatch.setattr(numba, "get_num_threads", lambda: 1)
    assert not threads.parallel_by_default(100)


def test_the_load_is_read_at_most_every_half_second(machine):
    assert threads.parallel_by_default(100)
    machine["load"] = 5.0
    machine["wall"] += threads._READ_EVERY / 2
    assert threads.parallel_by_default(100)       # the last reading
    machine["wall"] += threads._READ_EVERY
    assert not threads.parallel_by_default(100)


@pytest.fixture
def two_threads(monkeypatch):
    """numba may use two threads here (whatever the machine's load)."""
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("numba has one thread")
    monkeypatch.setattr(numba, "get_num_threads", lambda: 2)


def test_every_item_runs_once_in_contiguous_slices_on_two_threads(two_threads):
    """Slices cover the items once; the two threads run at the same time
    (each waits in its first slice for the other, the GIL released as a
    nogil kernel releases it: a barrier that breaks after 10 s unless both
    threads are in a slice at once)."""
    seen, idents, lock = [], set(), threading.Lock()
    meet = threading.Barrier(2, timeout=10.0)

    def work(lo, hi):
        with lock:
            first = threading.get_ident() not in idents
            idents.add(threading.get_ident())
        if first:
            meet.wait()
        with lock:
            seen.extend(range(lo, hi))

    threads.in_threads(work, 37)
    assert sorted(seen) == list(range(37))
    assert len(idents) == 2


def test_an_error_in_a_helper_thread_is_raised_once_every_slice_stopped(two_threads):
    """The error of a helper thread reaches the caller after the caller's
    running slice has ended, and no slice starts after it."""
    started, running = [], [0]
    lock, failed = threading.Lock(), threading.Event()

    def work(lo, hi):
        with lock:
            started.append(lo)
            running[0] += 1
        try:
            if threading.current_thread() is threading.main_thread():
                assert failed.wait(10.0)            # the helper fails meanwhile
                time.sleep(0.01)
            else:
                failed.set()
                raise ValueError(f"slice {lo} failed")
        finally:
            with lock:
                running[0] -= 1

    with pytest.raises(ValueError, match=r"slice \d+ failed"):
        threads.in_threads(work, 40, slice_size=1)
    # The helper's one slice, and the caller's until it saw the stop (a
    # loaded machine may deschedule the helper between failing and saying so).
    assert running[0] == 0 and 2 <= len(started) < 40


def test_a_ctrl_c_in_the_caller_ends_after_the_running_slices(two_threads):
    """A KeyboardInterrupt in the calling thread's slice stops the handing
    out and is raised once the helper's running slice is done."""
    started, running = [], [0]
    lock = threading.Lock()

    def work(lo, hi):
        with lock:
            started.append(lo)
            running[0] += 1
        try:
            time.sleep(0.01)
            if threading.current_thread() is threading.main_thread() and lo >= 2:
                raise KeyboardInterrupt
        finally:
            with lock:
                running[0] -= 1

    with pytest.raises(KeyboardInterrupt):
        threads.in_threads(work, 1000, slice_size=1)
    assert running[0] == 0 and len(started) < 1000


@njit(nogil=True)
def _toy_batch(x, factor, status, done):
    """A batch kernel's contract: orbits with status 0 are stepped (here
    x[m] *= factor, failing where it passes 100), the others skipped."""
    for m in range(status.shape[0]):
        if status[m] != 0:
            done[m] = 0
            continue
        x[m] *= factor
        status[m] = 3 if x[m] > 100.0 else 0
        done[m] = 1


def test_orbits_in_threads_steps_each_orbit_once_as_the_serial_kernel(two_threads):
    """Skipped orbits stay skipped with done 0; the others are stepped once
    with the serial kernel's arithmetic, their status and done written
    back: the serial call's arrays exactly."""
    x0 = np.linspace(1.0, 60.0, 101)
    status0 = np.where(np.arange(101) % 7 == 0, 5, 0)
    want = [x0.copy(), status0.copy(), np.full(101, -9)]
    _toy_batch(want[0], 1.7, want[1], want[2])
    got = [x0.copy(), status0.copy(), np.full(101, -9)]
    threads.orbits_in_threads(_toy_batch, (got[0], 1.7), got[1], got[2])
    for a, b in zip(got, want, strict=True):
        assert np.array_equal(a, b)
    assert (want[1] == 3).any() and (want[2] == 0).any()

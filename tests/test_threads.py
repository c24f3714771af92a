"""The default thread choice: a batch goes parallel only where a core is
free for the second thread, counting the load of the other processes, not
this one's (varint.threads). That the threads change no bit is tested with
the steppers (test_generated_stepper, test_chaos_map, test_stepsize_orbits)."""

import math

import numba
import pytest

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

"""Ctrl-C and progress: the first Ctrl-C ends the run at the next chunk
boundary, returns the outputs so far (``interrupted=True``, with a warning)
and saves the checkpoint; a second one stops at once. Progress bars appear
only on a terminal, or when asked."""

import json
import os
import signal
import subprocess
import sys
import time
import warnings

import numpy as np
import pytest

import varint
from varint import checkpoint as ckpt
from varint import driver
from tests.helpers import assert_bitwise_equal, hook_advance

T_END = 200.0


def ctrl_c():
    os.kill(os.getpid(), signal.SIGINT)


def lyapunov(c1, **kw):
    return varint.lyapunov_spectrum(*c1, T_END, **kw)


def test_ctrl_c_returns_the_outputs_so_far_and_saves_them(c1, tmp_path, monkeypatch):
    path = tmp_path / "run.ckpt"
    reference = lyapunov(c1)
    handler = signal.getsignal(signal.SIGINT)
    with monkeypatch.context() as patch:
        hook_advance(patch, "tm", 2, ctrl_c)
        with pytest.warns(RuntimeWarning, match=f"interrupted at t = .*saved to {path}"):
            partial = lyapunov(c1, checkpoint=path)
    assert signal.getsignal(signal.SIGINT) is handler  # restored
    assert partial.interrupted
    n = len(partial.t)
    assert 0 < n < len(reference.t)
    # What was recorded is exactly what the full run records there.
    assert partial.exponents.tobytes() == reference.exponents[:n].tobytes()
    saved = ckpt.read(path)
    assert len(saved.records) == n and saved.state.x.tobytes() == partial.state.tobytes()
    resumed = lyapunov(c1, checkpoint=path)
    assert not resumed.interrupted
    assert_bitwise_equal(resumed, reference)


def test_ctrl_c_without_a_checkpoint_still_returns_the_partial_result(c1, monkeypatch):
    hook_advance(monkeypatch, "tm", 2, ctrl_c)
    with pytest.warns(RuntimeWarning, match="returning the [0-9]+ outputs recorded so far$"):
        partial = varint.gali(*c1, T_END)
    assert partial.interrupted and len(partial.t) > 0
    assert np.isfinite(partial.gali[4]).all()


def test_a_second_ctrl_c_stops_at_once_keeping_the_last_checkpoint(c1, tmp_path, monkeypatch):
    """The second KeyboardInterrupt may land anywhere, so nothing is saved
    then; the checkpoint written after the previous chunk resumes."""
    path = tmp_path / "run.ckpt"
    with monkeypatch.context() as patch:
        hook_advance(patch, "tm", 2, lambda: (ctrl_c(), ctrl_c()))
        with pytest.raises(KeyboardInterrupt):
            lyapunov(c1, checkpoint=path, checkpoint_interval=0)
    assert ckpt.read(path).state.step > 0
    assert_bitwise_equal(lyapunov(c1, checkpoint=path), lyapunov(c1))


def test_ctrl_c_on_a_running_process(tmp_path):
    """SIGINT from outside (as a terminal sends it): the script gets the
    partial result, the process exits normally, no traceback; the
    checkpoint holds exactly what the partial result holds."""
    path = tmp_path / "run.ckpt"
    code = f"""
import json, varint
model, x0 = varint.paper_orbit("C1")
r = varint.lyapunov_spectrum(model, x0, 1e7, checkpoint={str(path)!r}, checkpoint_interval=0)
print(json.dumps({{"interrupted": r.interrupted, "n": len(r.t), "x": r.state.tolist()}}))
"""
    child = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while True:  # until the run is under way (past the initial checkpoint)
        assert child.poll() is None and time.monotonic() < deadline
        try:
            if ckpt.read(path).state.step > 0:
                break
        except (FileNotFoundError, varint.CheckpointError):
            pass
        time.sleep(0.02)
    child.send_signal(signal.SIGINT)
    out, err = child.communicate(timeout=60)
    assert child.returncode == 0, err
    assert "Traceback" not in err and "interrupted at t =" in err
    got = json.loads(out)
    assert got["interrupted"]
    saved = ckpt.read(path)
    assert len(saved.records) == got["n"] and saved.state.x[0].tolist() == got["x"]


@pytest.fixture
def instant_bar(monkeypatch):
    # Bars normally wait a second before appearing; show them at once so
    # that a short run shows whether one would appear.
    monkeypatch.setattr(driver, "_PROGRESS_DELAY", 0.0)


@pytest.mark.parametrize("progress, terminal, shown", [
    (None, False, False),   # default, output to a file or pipe: silent
    (None, True, True),     # default on a terminal: a bar
    (False, True, False),   # asked for silence: silent even on a terminal
    (True, False, True),    # asked for a bar: shown anywhere
])
def test_progress_bar_only_on_a_terminal_or_when_asked(progress, terminal, shown, c1, capfd,
                                                       monkeypatch, instant_bar):
    monkeypatch.setattr(sys.stderr, "isatty", lambda: terminal)
    varint.sali(*c1, T_END, progress=progress)
    out, err = capfd.readouterr()
    assert out == ""
    assert ("step" in err) == shown
    if not shown:
        assert err == ""


def test_an_interrupted_dask_map_cancels_the_chunks_still_running(monkeypatch):
    """Ctrl-C while a Dask map's chunks run: the map returns at once with
    what finished (nothing here), and the chunks still running on the
    workers stop at their next sub-chunk, because their tasks are cancelled
    and they poll that (``varint.fanout._cancel_check``). Before, a worker ran
    its chunk to its end and closing the cluster waited for it; this chunk
    is ~10^10 steps (hours), so a worker that goes idle at all shows the
    chunk stopped."""
    distributed = pytest.importorskip("distributed")
    hh = varint.models.HenonHeiles()
    grid = varint.section_grid(hh, 0.125, np.linspace(-0.2, 0.2, 2), np.linspace(-0.2, 0.2, 2))

    def wait_for(condition, what, seconds=600):
        # A bound on a hang, not a timing: the chunk would run for hours.
        deadline = time.monotonic() + seconds
        while not condition():
            assert time.monotonic() < deadline, f"{what} after {seconds} s"
            time.sleep(0.02)

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        cluster = distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                                           dashboard_address=None)
    with cluster, distributed.Client(cluster) as client:
        worker = next(iter(cluster.workers.values()))

        def ctrl_c_once_running(futures):
            # The Ctrl-C reaches the loop that waits for the chunks.
            wait_for(lambda: worker.state.executing_count > 0, "the chunk did not start")
            raise KeyboardInterrupt
            yield  # a generator, as distributed.as_completed is iterated

        monkeypatch.setattr(distributed, "as_completed", ctrl_c_once_running)
        # Not pytest.warns: the chunk's worker thread shares this process's
        # warning filters (warnings.catch_warnings is not thread-safe). The
        # filter stays until the worker has stopped: its chunk says
        # "interrupted" when it stops, after the map has returned.
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            r = varint.chaos_map(hh, grid, "sali", t_end=1e9, tau=0.05, client=client,
                                 progress=False, threshold=None)
            assert r.interrupted and np.isnan(r.values).all()
            wait_for(lambda: worker.state.executing_count == 0,
                     "the cancelled chunk still runs on its worker")

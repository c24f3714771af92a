"""Faults, tried: a process killed while it writes a checkpoint, a disk that
fills up during a run, checkpoint paths that cannot be written, truncated and
corrupted checkpoints and cache entries. Each ends in a correct result or a
clear error, and nothing written before is lost."""

import json
import os
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

import varint
from varint import checkpoint as ckpt
from tests.helpers import assert_bitwise_equal, hook_advance

T_END = 200.0


class Stop(Exception):
    pass


def stop():
    raise Stop


def lyapunov(c1, **kw):
    return varint.lyapunov_spectrum(*c1, T_END, **kw)


def start_child(code, **env):
    """A Python process running ``code`` (dedented) with varint imported."""
    script = "import os, sys, time, json\nimport numpy as np\nimport varint\n" + \
        textwrap.dedent(code)
    return subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=dict(os.environ, **env))


def wait_for(path, proc, timeout=120.0):
    deadline = time.monotonic() + timeout
    while not os.path.exists(path):
        if proc.poll() is not None:
            raise AssertionError(f"child ended early:\n{proc.stderr.read()}")
        if time.monotonic() > deadline:
            proc.kill()
            raise AssertionError("child did not get there in time")
        time.sleep(0.02)


def test_sigkill_while_writing_a_checkpoint_then_resume(c1, tmp_path):
    """The child is killed half-way through writing its fifth checkpoint
    (its temporary file holds a few bytes); the fourth is intact and the
    run resumes from it to the bits of an uninterrupted run."""
    path, mark = tmp_path / "run.ckpt", tmp_path / "writing"
    child = start_child(f"""
        import varint.checkpoint as C
        import varint.driver as D
        # Chunks of 16 steps, so the run writes many checkpoints.
        D.Pace.__init__ = lambda self: setattr(self, "chunk", 16)
        D.Pace.took = lambda self, n, seconds: None
        real, writes = C._write_npz, []
        def stalled(stream, arrays):
            writes.append(1)
            if len(writes) == 5:
                stream.write(b"half a checkpoint")
                stream.flush()
                open({str(mark)!r}, "w").close()
                time.sleep(600)
            real(stream, arrays)
        C._write_npz = stalled
        model, x0 = varint.paper_orbit("C1")
        varint.lyapunov_spectrum(model, x0, {T_END}, checkpoint={str(path)!r},
                                 checkpoint_interval=0)
    """)
    wait_for(mark, child)
    child.send_signal(signal.SIGKILL)
    assert child.wait(timeout=60) == -signal.SIGKILL
    debris = [p for p in os.listdir(tmp_path) if p.endswith(".tmp")]
    assert len(debris) == 1  # the write in flight
    saved = ckpt.read(path)  # the previous checkpoint, intact
    assert saved.state.step > 0 and len(saved.records) > 0

    resumed = lyapunov(c1, checkpoint=path)
    assert_bitwise_equal(resumed, lyapunov(c1))
    assert sorted(os.listdir(tmp_path)) == ["run.ckpt", "writing"]  # debris removed


def test_disk_full_during_a_run_keeps_the_last_checkpoint_and_the_result(c1, tmp_path):
    """RLIMIT_FSIZE makes every write beyond a size fail with EFBIG, as a
    full disk fails with ENOSPC, even for root. Checkpoints grow with the
    records, so after a few writes they no longer fit: the run warns, goes
    on and returns the correct result; the last checkpoint that fitted
    stays on disk and resumes to the same bits."""
    path = tmp_path / "run.ckpt"
    child = start_child(f"""
        import resource, signal
        import varint.checkpoint as C
        import varint.driver as D
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # get EFBIG, not death
        # Chunks of 16 steps: many checkpoint writes (the stepper would
        # otherwise take a few long chunks).
        D.Pace.__init__ = lambda self: setattr(self, "chunk", 16)
        D.Pace.took = lambda self, n, seconds: None
        real, writes = C.write, []
        def write(p, snapshot):
            real(p, snapshot)
            writes.append(1)
            if len(writes) == 2:
                # Room for a few more records: later writes no longer fit.
                limit = os.path.getsize(p) + 300
                resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
        C.write = write
        model, x0 = varint.paper_orbit("C1")
        r = varint.lyapunov_spectrum(model, x0, {T_END}, checkpoint={str(path)!r},
                                     checkpoint_interval=0)
        print(json.dumps([v.hex() for v in r.exponents.ravel()]))
    """)
    out, err = child.communicate(timeout=300)
    assert child.returncode == 0, err
    assert "could not write checkpoint" in err and "File too large" in err
    assert "Traceback" not in err
    reference = lyapunov(c1)
    got = np.array([float.fromhex(v) for v in json.loads(out)]).reshape(reference.exponents.shape)
    assert got.tobytes() == reference.exponents.tobytes()
    saved = ckpt.read(path)  # intact, from before the disk filled up
    assert 0 < len(saved.records) < len(reference.t)
    assert os.listdir(tmp_path) == ["run.ckpt"]  # no temporary files left
    assert_bitwise_equal(lyapunov(c1, checkpoint=path), reference)


def unwritable_paths(tmp_path):
    blocker = tmp_path / "a_file"
    blocker.write_text("not a directory")
    yield "parent is a file", blocker / "run.ckpt", "is not a directory"
    yield "missing directory", tmp_path / "nowhere" / "run.ckpt", "does not exist"
    try:  # sysfs refuses new files even to root
        open("/sys/varint-probe", "w").close()
    except OSError:
        yield "read-only file system", "/sys/varint-run.ckpt", "cannot write checkpoint"


@pytest.mark.parametrize("case", ["parent is a file", "missing directory",
                                  "read-only file system"])
def test_an_unwritable_checkpoint_path_fails_before_any_work(case, c1, tmp_path,
                                                              monkeypatch):
    paths = {name: (p, msg) for name, p, msg in unwritable_paths(tmp_path)}
    if case not in paths:
        pytest.skip(f"no {case} to try on this machine")
    path, message = paths[case]
    calls = hook_advance(monkeypatch, "tm", 10 ** 9, lambda: None)
    with pytest.raises(varint.CheckpointError, match=message) as err:
        lyapunov(c1, checkpoint=path)
    assert str(path) in str(err.value) and not calls


def damaged(data):
    """Ways a checkpoint file can be damaged: truncations and flipped bytes."""
    n, head = len(data), len(ckpt.MAGIC)
    yield "empty", b"", "is empty"
    yield "cut in its first line", data[:head - 5], "truncated"
    yield "cut after the first line", data[:head], "truncated or corrupt"
    yield "cut in half", data[: n // 2], "truncated or corrupt"
    yield "last byte missing", data[:-1], "truncated or corrupt"
    for where in (head + 10, n // 2, n - 10):
        flipped = bytearray(data)
        flipped[where] ^= 0x01
        yield f"bit flipped at byte {where}", bytes(flipped), "corrupt"
    yield "another file", b"x0,y0,px0,py0\n0,0.1,0.2,0\n", "not a varint checkpoint"


def test_damaged_checkpoints_are_refused_and_kept(c1, tmp_path, monkeypatch):
    """Every damage is detected (never used, never silently replaced); after
    the user deletes the file the run starts over and is correct."""
    path = tmp_path / "run.ckpt"
    with monkeypatch.context() as patch:
        hook_advance(patch, "tm", 2, stop)
        with pytest.raises(Stop):
            lyapunov(c1, checkpoint=path, checkpoint_interval=0)
    data = path.read_bytes()
    for what, bad, message in damaged(data):
        path.write_bytes(bad)
        with pytest.raises(varint.CheckpointError, match=message) as err:
            lyapunov(c1, checkpoint=path)
        assert str(path) in str(err.value) and "delete it" in str(err.value), what
        assert path.read_bytes() == bad, what
    path.unlink()
    assert_bitwise_equal(lyapunov(c1, checkpoint=path), lyapunov(c1))


def test_damaged_cache_entries_are_reported_and_recomputed(c1, tmp_path, monkeypatch):
    """The reference cache (varint.cache) never uses a damaged entry: it
    warns naming the file, and recomputes the correct result."""
    cache = pytest.importorskip("varint.cache")
    monkeypatch.setenv("VARINT_CACHE_DIR", str(tmp_path))
    parts = {"test": "faults", "t_end": 10.0}

    def compute():
        return varint.integrate(*c1, 10.0)

    reference = cache.cached(parts, compute)
    (entry,) = (tmp_path / "results").iterdir()
    data = entry.read_bytes()
    for what, bad in [("truncated", data[: len(data) // 2]),
                      ("bit flipped", data[:-20] + bytes([data[-20] ^ 1]) + data[-19:]),
                      ("empty", b"")]:
        entry.write_bytes(bad)
        with pytest.warns(cache.CacheWarning, match="unreadable") as warned:
            again = cache.cached(parts, compute)
        assert str(entry) in str(warned[0].message), what
        assert_bitwise_equal(again, reference)
        assert_bitwise_equal(cache.cached(parts, stop), reference)  # rewritten, usable

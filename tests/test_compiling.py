"""Compilation measured and announced (varint.compiling): a long compile
says so once, with the expected time; provenance keeps compile, pilot and
run time apart, so that a first call's compilation does not pass for the
method's speed."""

import numba
import numpy as np

import varint
from varint import compiling


def _fresh_function():
    # A new function each call: numba compiles it on its first call.
    return numba.njit(lambda x: np.sin(x) + 1.0)


def test_a_long_compile_announces_itself_once(capsys, monkeypatch, tmp_path):
    monkeypatch.setenv("VARINT_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(compiling, "ANNOUNCE_AFTER", 0.0)
    clock = compiling.Clock("a test", progress=True)
    with clock.part("run"):
        _fresh_function()(1.0)
        _fresh_function()(1.0)
    err = capsys.readouterr().err
    assert err.count("varint: compiling kernels for a test, first use; cached for next time") \
        == 1, err
    assert clock.timing["compile"] > 0 and set(clock.timing) == {"compile", "run"}


def test_a_short_compile_and_progress_false_say_nothing(capsys, monkeypatch, tmp_path):
    monkeypatch.setenv("VARINT_CACHE_DIR", str(tmp_path))
    with compiling.Clock("quick", progress=True).part("run"):
        _fresh_function()(1.0)           # well under ANNOUNCE_AFTER = 1 s
    monkeypatch.setattr(compiling, "ANNOUNCE_AFTER", 0.0)
    with compiling.Clock("silenced", progress=False).part("run"):
        _fresh_function()(1.0)
    assert "compiling" not in capsys.readouterr().err


def test_the_expected_time_is_the_median_of_the_measured_ones(capsys, monkeypatch, tmp_path):
    monkeypatch.setenv("VARINT_CACHE_DIR", str(tmp_path))
    (tmp_path / "compile_times.json").write_text("[3.0, 9.0, 12.0, 0.5, -1, \"x\", true]")
    assert compiling._expected() == 9.0
    monkeypatch.setattr(compiling, "ANNOUNCE_AFTER", 0.0)
    with compiling.Clock("again", progress=True).part("run"):
        _fresh_function()(1.0)
    assert "(about 9 s)" in capsys.readouterr().err
    # A damaged store only loses the estimate.
    (tmp_path / "compile_times.json").write_text("{not json")
    assert compiling._expected() is None


def test_an_inner_clock_leaves_the_announcement_to_the_outer(capsys, monkeypatch, tmp_path):
    monkeypatch.setenv("VARINT_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(compiling, "ANNOUNCE_AFTER", 0.0)
    outer = compiling.Clock("the map", progress=True)
    with outer.part("run"):
        inner = compiling.Clock("one chunk", progress=False)
        with inner.part("run"):
            _fresh_function()(1.0)
    err = capsys.readouterr().err
    assert "for the map" in err and "one chunk" not in err
    assert inner.timing["compile"] > 0 and outer.timing["compile"] >= inner.timing["compile"]


def test_provenance_keeps_compile_pilot_and_run_apart(tmp_path, monkeypatch):
    """A potential no run has compiled: its first call compiles (seconds),
    the second does not, and only the compile time differs much; the
    parts are disjoint, so they add up to at most the call's time."""
    import time

    import sympy as sp

    # An empty cache: nothing compiled by an earlier run of this test.
    monkeypatch.setenv("VARINT_CACHE_DIR", str(tmp_path / "cache"))
    x = sp.Symbol("x")
    # A coefficient of this test's own: kernels no other test has built.
    model = varint.models.from_potential(x**2 / 2 + sp.Rational(7, 13) * x**4, [x])
    first_start = time.perf_counter()
    first = varint.lyapunov_spectrum(model, [0.1, 0.2], 50.0)
    first_wall = time.perf_counter() - first_start
    second = varint.lyapunov_spectrum(model, [0.1, 0.2], 50.0)
    t1, t2 = first.provenance.timing, second.provenance.timing
    assert set(t1) == {"compile", "pilot", "setup", "run"}
    assert t1["compile"] > 0.2 and t2["compile"] == 0.0
    assert sum(t1.values()) <= first_wall
    # Without its compilation the first run is no slower than ten times the
    # second (the same work; a generous factor for a shared machine).
    assert t1["run"] < 10 * t2["run"] + 0.05
    # Saved and loaded with the result.
    first.save(tmp_path / "r.npz")
    assert varint.load_result(tmp_path / "r.npz").provenance.timing == t1
    grid = varint.phase_grid(varint.models.StandardMap(1.3), [0.5, 1.0], [0.2])
    assert set(varint.chaos_map(varint.models.StandardMap(1.3), grid, "x1", t_end=10.0)
               .provenance.timing) >= {"compile", "run"}


def test_compile_seconds_grows_only_when_numba_compiles():
    before = compiling.compile_seconds()
    _fresh_function()(1.0)
    middle = compiling.compile_seconds()
    assert middle > before
    f = _fresh_function()
    f(1.0)
    after_first = compiling.compile_seconds()
    f(2.0)                                    # already compiled for float64
    assert compiling.compile_seconds() == after_first


def test_no_announcement_when_stderr_is_not_a_terminal(capsys, monkeypatch, tmp_path):
    monkeypatch.setenv("VARINT_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(compiling, "ANNOUNCE_AFTER", 0.0)
    with compiling.Clock("captured", progress=None).part("run"):
        _fresh_function()(1.0)
    assert "compiling" not in capsys.readouterr().err

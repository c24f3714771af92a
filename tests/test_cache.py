"""The reference cache: keyed by everything that determines a result,
atomic, and never using a damaged entry."""

import numpy as np
import pytest

import varint
from varint import cache
from varint.cache import CacheWarning, cache_dir, cache_key, cached, reference


@pytest.fixture
def tmp_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("VARINT_CACHE_DIR", str(tmp_path / "c"))
    return tmp_path / "c"


@pytest.fixture(scope="module")
def small_result():
    model, x0 = varint.paper_orbit("R1")
    return varint.lyapunov_spectrum(model, x0, 1.0, n_exponents=2, t_out=4)


class Counter:
    def __init__(self, result):
        self.result, self.calls = result, 0

    def __call__(self):
        self.calls += 1
        return self.result


def test_cache_directory_follows_the_environment(tmp_path, monkeypatch):
    monkeypatch.setenv("VARINT_CACHE_DIR", str(tmp_path / "v"))
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "x"))
    assert cache_dir() == tmp_path / "v"
    monkeypatch.delenv("VARINT_CACHE_DIR")
    assert cache_dir() == tmp_path / "x" / "varint"
    monkeypatch.delenv("XDG_CACHE_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert cache_dir() == tmp_path / "home" / ".cache" / "varint"


def test_key_depends_on_every_part():
    model, x0 = varint.paper_orbit("R1")
    base = {"model": model, "x0": x0, "tau": 0.05, "options": {"rtol": 1e-10}}
    same = {"options": {"rtol": 1e-10}, "tau": 0.05, "x0": x0.copy(),
            "model": varint.models.HenonHeiles()}
    assert cache_key(base) == cache_key(same)
    x1 = x0.copy()
    x1[1] = np.nextafter(x1[1], 1)  # one ulp
    for change in ({"x0": x1}, {"tau": 0.025}, {"options": {"rtol": 1e-11}},
                   {"model": varint.models.ThreeDof()}):
        assert cache_key({**base, **change}) != cache_key(base), change
    with pytest.raises(TypeError, match="cache key"):
        cache_key({"f": object()})


def test_a_result_is_computed_once_and_read_back_equal(tmp_cache, small_result):
    compute = Counter(small_result)
    first = cached({"a": 1}, compute)
    again = cached({"a": 1}, compute)
    assert compute.calls == 1 and first is small_result
    assert np.array_equal(again.exponents, small_result.exponents)
    assert again.provenance == small_result.provenance
    cached({"a": 2}, compute)
    assert compute.calls == 2
    # Written atomically: nothing but the two entries is left behind.
    assert sorted(p.suffix for p in (tmp_cache / "results").iterdir()) == [".bin", ".bin"]


@pytest.mark.parametrize("damage", ["flip", "truncate", "empty", "garbage"])
def test_a_damaged_entry_is_reported_and_recomputed(tmp_cache, small_result, damage):
    compute = Counter(small_result)
    cached({"a": 1}, compute)
    (path,) = (tmp_cache / "results").iterdir()
    blob = path.read_bytes()
    path.write_bytes({"flip": blob[:-100] + bytes([blob[-100] ^ 1]) + blob[-99:],
                      "truncate": blob[: len(blob) // 2], "empty": b"",
                      "garbage": b"not a cache entry\n" * 10}[damage])
    with pytest.warns(CacheWarning, match=str(path.name)):
        again = cached({"a": 1}, compute)
    assert compute.calls == 2
    assert np.array_equal(again.exponents, small_result.exponents)
    assert cache._read(path) is not None  # rewritten whole


def test_a_failed_computation_leaves_no_entry(tmp_cache):
    def fail():
        raise RuntimeError("boom")

    with pytest.raises(RuntimeError, match="boom"):
        cached({"a": 1}, fail)
    assert not (tmp_cache / "results").exists() or not any((tmp_cache / "results").iterdir())


def test_reference_runs_the_extended_taylor_integration_once(tmp_cache, monkeypatch):
    calls = []
    integrate = varint.integrate

    def counting(*args, **kwargs):
        calls.append(kwargs)
        return integrate(*args, **kwargs)

    monkeypatch.setattr(varint, "integrate", counting)
    model, x0 = varint.paper_orbit("R1")
    a = reference(model, x0, 1.0, tau=0.5, deviations=np.eye(4))
    b = reference(model, x0, 1.0, tau=0.5, deviations=np.eye(4))
    assert len(calls) == 1 and calls[0]["method"] == "taylor"
    assert a.provenance.method_options["precision"] == "extended"
    assert np.array_equal(a.deviations, b.deviations)
    reference(model, x0, 1.0, tau=0.5, deviations=np.eye(4)[:, :2])
    assert len(calls) == 2
    with pytest.raises(ValueError, match="unknown kind 'orbit'"):
        reference(model, x0, 1.0, kind="orbit")


def test_an_unwritable_cache_still_returns_the_result(tmp_path, monkeypatch, small_result):
    """A cache directory that cannot be made costs the cache, not the
    result: a private fallback is used or, if none can be, nothing is
    cached (one warning says which)."""
    from varint import cachedir

    blocker = tmp_path / "file"
    blocker.write_text("not a directory")
    monkeypatch.setenv("VARINT_CACHE_DIR", str(blocker / "c"))
    monkeypatch.setattr(cachedir, "_WARNED", set())
    monkeypatch.setattr(cachedir, "_FALLBACK", {"dir": None})
    compute = Counter(small_result)
    with pytest.warns(cachedir.CacheDirWarning, match="cannot be created.*nothing is cached"):
        assert cached({"a": 1}, compute) is small_result
    assert cached({"a": 1}, compute) is small_result and compute.calls == 2
    monkeypatch.setattr(cachedir, "_FALLBACK", {"dir": tmp_path / "fallback"})
    (tmp_path / "fallback").mkdir(mode=0o700)
    assert cached({"a": 1}, compute) is small_result and compute.calls == 3
    assert cached({"a": 1}, compute).provenance == small_result.provenance
    assert compute.calls == 3 and len(list((tmp_path / "fallback" / "results").iterdir())) == 1

"""The cache directory and what varint reads back from it, tried as a hostile
local user and an unlucky one would: a directory someone else prepared, code
or data planted or edited in it, damaged numba files, a full disk.

Every case runs in a private cache directory of its own, and every planted
payload would create a marker file: the marker must never appear, and the
results must stay bitwise those of a clean cache."""

import json
import os
import pickle
import shutil
import stat
import subprocess
import sys

import numpy as np
import pytest
import sympy as sp

import varint
from varint import cache, cachedir, codecache
from varint.cachedir import CacheDirWarning
from varint.codegen import expressions as X
from varint.codegen import stepper as G
from varint.models import HenonHeiles, from_map, from_potential
from varint.models import symbolic as S

R1 = np.array([0.0, 0.558, 0.23337397, 0.0])


@pytest.fixture
def private(tmp_path, monkeypatch):
    """A cache directory of this test's own, a fallback of its own, and
    varint's in-process memory of loaded kernels emptied (as in a new
    process). Returns (cache dir, marker path)."""
    monkeypatch.setenv("VARINT_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setattr(cachedir, "_WARNED", set())
    monkeypatch.setattr(cachedir, "_FALLBACK", {"dir": tmp_path / "fallback"})
    new_process(monkeypatch)
    return tmp_path / "cache", tmp_path / "MARKER"


@pytest.fixture(scope="module")
def _filled_cache(tmp_path_factory):
    """A private cache directory after one run of :func:`orbit`: its generated
    stepper, facts and numba cache, compiled once for this file."""
    path = tmp_path_factory.mktemp("filled") / "cache"
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("VARINT_CACHE_DIR", str(path))
        mp.setattr(cachedir, "_WARNED", set())
        mp.setattr(cachedir, "_FALLBACK", {"dir": path.parent / "fallback"})
        new_process(mp)
        orbit()
    return path


@pytest.fixture
def filled(private, _filled_cache):
    """``private`` holding a copy (modes and times kept) of the cache one
    run of :func:`orbit` filled, as a new process finds what an earlier one
    left: a test whose subject is what happens to the files afterwards
    loads the stepper instead of compiling it again. Returns (cache dir, marker path)."""
    cache_dir, marker = private
    shutil.copytree(_filled_cache, cache_dir)
    return cache_dir, marker


@pytest.fixture(scope="module")
def _refused_fallback(tmp_path_factory):
    return tmp_path_factory.mktemp("refused") / "fallback"


@pytest.fixture
def refused(private, _refused_fallback, monkeypatch):
    """``private``, with the private fallback that replaces a refused cache
    directory shared by this file's tests (as by the processes of one
    user): the first compiles its stepper there, the others load it, and
    each finds nothing written to the directory it refused. Returns the
    fallback."""
    monkeypatch.setattr(cachedir, "_FALLBACK", {"dir": _refused_fallback})
    return _refused_fallback


def new_process(monkeypatch):
    """Forget the kernels and facts loaded in this process."""
    monkeypatch.setattr(G, "_LOADED", {})
    monkeypatch.setattr(X, "_FACTS", {})
    monkeypatch.setattr(S, "_LOADED", {})
    monkeypatch.setattr(cachedir, "_WARNED", set())


def orbit(t_end=20.0):
    """The orbit of R1 on a new model object (a model remembers its
    steppers), by the generated stepper that is quickest to compile: SABA1
    with no deviation vectors (2-3 s of CPU, an indicator's twice that).
    What the cache must protect, a signed module of generated code and
    numba's files of it, is the same for every stepper."""
    r = varint.integrate(HenonHeiles(), R1, t_end, tau=0.05, scheme="SABA1", t_out=[t_end])
    return r.state.tobytes()


def payload(marker):
    return f"\nopen({str(marker)!r}, 'w').write('pwned')\n"


def stepper_file(cache_dir):
    (path,) = (cache_dir / "kernels").glob("varint_stepper_*.py")
    return path


def test_the_cache_directory_and_its_secret_are_private(_filled_cache):
    """What one run leaves in a cache directory it made (this file's
    filled one, whose run had none)."""
    cache_dir = _filled_cache
    assert stat.S_IMODE(cache_dir.stat().st_mode) == 0o700
    assert stat.S_IMODE((cache_dir / "kernels").stat().st_mode) == 0o700
    secret = cache_dir / cachedir.SECRET_FILE
    assert stat.S_IMODE(secret.stat().st_mode) == 0o600 and secret.stat().st_size == 32
    # Every file varint reads back from the cache is signed.
    for path in (cache_dir / "kernels").rglob("*"):
        if path.is_file():
            assert path.read_bytes().startswith(codecache.HEADER), path


@pytest.mark.parametrize("edit", ["payload appended", "coefficient changed", "truncated",
                                  "emptied", "signature line removed", "another user's"])
def test_an_edited_generated_stepper_never_runs_and_is_rebuilt(filled, monkeypatch, edit):
    """A payload added to a cached stepper would run at import, a changed
    force coefficient would move the orbit: the file fails its
    signature, is discarded with a warning, rebuilt, and the result is
    bitwise that of a clean cache."""
    cache_dir, marker = filled
    clean = orbit()
    path = stepper_file(cache_dir)
    text = path.read_text()
    header, body = text.split("\n", 1)
    assert "H0_1" in body or "q0" in body
    edited = {
        "payload appended": text + payload(marker),
        "coefficient changed": header + "\n" + body.replace("2*q0", "2.4*q0", 1)
        .replace("2.0*q0", "2.4*q0", 1),
        "truncated": text[: len(text) // 2],
        "emptied": "",
        "signature line removed": body + payload(marker),
        "another user's": "# varint-signed " + "0" * 64 + "\n" + body + payload(marker),
    }[edit]
    assert edited != text
    path.write_text(edited)
    new_process(monkeypatch)
    with pytest.warns(CacheDirWarning, match="generated kernel file .* is not used"):
        again = orbit()
    assert again == clean and not marker.exists()
    assert path.read_text() == text          # rebuilt, signed again
    new_process(monkeypatch)
    assert orbit() == clean                  # and used without a warning


def test_code_planted_beside_the_steppers_is_never_imported(filled, monkeypatch):
    """A .pyc or a module planted in the kernels folder is not what varint
    executes: it runs the verified bytes of its own file only."""
    cache_dir, marker = filled
    clean = orbit()
    path = stepper_file(cache_dir)
    pycache = path.parent / "__pycache__"
    code = compile(payload(marker), str(path), "exec")
    import importlib.util
    pyc = pycache / f"{path.stem}.cpython-{sys.version_info[0]}{sys.version_info[1]}.pyc"
    pyc.write_bytes(importlib.util.MAGIC_NUMBER + b"\0" * 12 + __import__("marshal").dumps(code))
    (path.parent / "numba.py").write_text(payload(marker))
    new_process(monkeypatch)
    assert orbit() == clean and not marker.exists()


def code_file(cache_dir):
    """The signed code object kept beside the generated stepper."""
    path = stepper_file(cache_dir)
    return path.with_name(f"{path.stem}.{sys.implementation.cache_tag}.code")


def counting_compiles(monkeypatch, path):
    """Count, in a list, the compilations of the source of ``path``."""
    seen = []

    def compile_(source, filename, *args, **kwargs):
        if filename == str(path):
            seen.append(filename)
        return compile(source, filename, *args, **kwargs)

    monkeypatch.setattr(codecache, "compile", compile_, raising=False)
    return seen


def test_a_generated_steppers_code_is_read_back_not_compiled(filled, monkeypatch):
    """A new process executes the stepper's code object from its signed code
    file instead of compiling the source again, with the same bits; without
    that file it compiles the source and writes the file again."""
    cache_dir, _ = filled
    clean = orbit()
    assert code_file(cache_dir).read_bytes().startswith(codecache.HEADER)
    new_process(monkeypatch)
    seen = counting_compiles(monkeypatch, stepper_file(cache_dir))
    assert orbit() == clean and seen == []
    written = code_file(cache_dir).read_bytes()
    code_file(cache_dir).unlink()
    new_process(monkeypatch)
    assert orbit() == clean and seen == [str(stepper_file(cache_dir))]
    assert code_file(cache_dir).read_bytes() == written


@pytest.mark.parametrize("damage", ["payload, unsigned", "payload, another key", "truncated",
                                    "garbage", "empty"])
def test_a_tampered_code_file_never_runs_and_is_rebuilt(filled, monkeypatch, damage):
    """The code file is marshalled code that would run at import: one that
    fails its signature is never unmarshalled; it is discarded with a
    warning, the verified source compiled and the file written again."""
    cache_dir, marker = filled
    clean = orbit()
    path = code_file(cache_dir)
    blob = path.read_bytes()
    tag = blob.split(b"\n")[1]
    evil = tag + b"\n" + __import__("marshal").dumps(compile(payload(marker), "x", "exec"))
    path.write_bytes({
        "payload, unsigned": evil,
        "payload, another key": codecache.HEADER + b"0" * 64 + b"\n" + evil,
        "truncated": blob[: len(blob) // 2],
        "garbage": b"not code" * 20,
        "empty": b"",
    }[damage])
    new_process(monkeypatch)
    with pytest.warns(CacheDirWarning, match="compiled kernel file .* is not used"):
        assert orbit() == clean
    assert not marker.exists() and path.read_bytes() == blob


@pytest.mark.parametrize("other", ["source", "file name"])
def test_a_signed_code_file_serves_only_its_own_source(filled, monkeypatch, other):
    """A code file signed by the user's own secret but compiled from another
    source (the module rebuilt) or for another file name (the cache
    directory moved: numba keeps a kernel's cache beside the file its code
    names) is not executed: the source is compiled again, no warning."""
    cache_dir, marker = filled
    clean = orbit()
    path = code_file(cache_dir)
    source = stepper_file(cache_dir).read_bytes().split(b"\n", 1)[1]
    tag = {"source": codecache._code_tag(source + payload(marker).encode(), stepper_file(cache_dir)),
           "file name": codecache._code_tag(source, cache_dir / "elsewhere.py")}[other]
    evil = compile(payload(marker), str(stepper_file(cache_dir)), "exec")
    codecache.write_signed(path, tag + b"\n" + __import__("marshal").dumps(evil))
    new_process(monkeypatch)
    seen = counting_compiles(monkeypatch, stepper_file(cache_dir))
    assert orbit() == clean and not marker.exists() and len(seen) == 1


@pytest.mark.parametrize("damage", ["garbage", "truncated", "pickle payload", "empty"])
def test_damaged_numba_cache_files_are_discarded_and_rebuilt(filled, monkeypatch, damage):
    """numba's cache files are pickles that numba loads: one that does not
    carry varint's signature is never unpickled (a pickle that would
    create the marker stays inert), it is deleted with a warning and
    compiled again; later runs use the new, signed file."""
    cache_dir, marker = filled
    clean = orbit()
    files = sorted((cache_dir / "kernels" / "__pycache__").glob("*"))
    assert files and all(f.suffix in (".nbi", ".nbc") for f in files)

    class Payload:
        def __reduce__(self):
            return (open, (str(marker), "w"))

    for f in files:
        blob = f.read_bytes()
        f.write_bytes({"garbage": b"not a pickle" * 10, "truncated": blob[: len(blob) // 3],
                       "pickle payload": pickle.dumps(Payload()), "empty": b""}[damage])
    new_process(monkeypatch)
    with pytest.warns(CacheDirWarning, match="numba cache file"):
        again = orbit()
    assert again == clean and not marker.exists()
    new_process(monkeypatch)
    assert orbit() == clean and not marker.exists()
    assert all(f.read_bytes().startswith(codecache.HEADER)
               for f in (cache_dir / "kernels" / "__pycache__").glob("*"))


def test_symbolic_facts_are_data_never_code(filled, monkeypatch):
    """The cached facts of a built-in model hold a flag and a key, signed;
    text in them is never evaluated (SymPy's sympify would eval it), not
    even when someone who holds the secret signs it."""
    cache_dir, marker = filled
    clean = orbit()
    (facts,) = (cache_dir / "kernels").glob("varint_model_*.json")
    evil = f"__import__('os').system('touch {marker}')"
    for content in ([True, evil], [True, [evil, [], 2]], {"fits": True}, [True, "0" * 31],
                    [False, "0" * 32]):
        facts.write_text(json.dumps(content))         # unsigned
        new_process(monkeypatch)
        with pytest.warns(CacheDirWarning, match="symbolic facts"):
            assert orbit() == clean
        codecache.write_signed(facts, json.dumps(content))   # signed by the user's secret
        new_process(monkeypatch)
        assert orbit() == clean and not marker.exists()
        assert json.loads(facts.read_bytes().split(b"\n", 1)[1])[1] != evil


def test_a_from_potential_kernel_file_is_verified_too(private, monkeypatch):
    """The kernels of a from_potential model are generated code in the cache
    as well: an edited file is discarded and rebuilt."""
    cache_dir, marker = private
    q = sp.symbols("q0:2")
    V = (q[0] ** 2 + q[1] ** 2) / 2 + q[0] ** 2 * q[1] - q[1] ** 3 / 3
    first = from_potential(V, q)
    clean = first.gradient([0.1, 0.2]).tobytes()
    (path,) = (cache_dir / "models").glob("varint_potential_*.py")
    path.write_text(path.read_text().replace("g[0] =", "g[0] = 1.0 +", 1) + payload(marker))
    new_process(monkeypatch)
    with pytest.warns(CacheDirWarning, match="generated kernel file"):
        again = from_potential(V, q)
    assert again.gradient([0.1, 0.2]).tobytes() == clean and not marker.exists()


@pytest.mark.parametrize("mode", [0o777, 0o775, 0o757])
def test_a_cache_directory_writable_by_others_is_refused(tmp_path, monkeypatch, refused, mode):
    """A directory another user could write (a 0777 shared scratch path) is
    not used: one warning names it and why, and a private fallback takes
    its place; nothing is written to the refused one."""
    shared = tmp_path / "shared"
    shared.mkdir()
    shared.chmod(mode)
    monkeypatch.setenv("VARINT_CACHE_DIR", str(shared))
    with pytest.warns(CacheDirWarning, match=f"writable by .*{mode:04o}.*using") as warned:
        orbit()
    assert len([w for w in warned if "is not used" in str(w.message)]) == 1
    assert list(shared.iterdir()) == []
    assert stepper_file(refused).exists()


def test_a_cache_directory_of_another_user_is_refused(tmp_path, monkeypatch, refused):
    if os.getuid() != 0:
        pytest.skip("only root can give a directory to another user")
    other = tmp_path / "theirs"
    other.mkdir(mode=0o700)
    os.chown(other, 65534, 65534)
    monkeypatch.setenv("VARINT_CACHE_DIR", str(other))
    with pytest.warns(CacheDirWarning, match="belongs to user id 65534"):
        orbit()
    assert list(other.iterdir()) == []


def test_a_planted_kernels_link_is_refused(tmp_path, monkeypatch, private):
    """kernels/ as a symbolic link to someone's directory is not followed:
    the generated code is compiled in memory (one warning each)."""
    cache_dir, marker = private
    cache_dir.mkdir(mode=0o700)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (cache_dir / "kernels").symlink_to(elsewhere)
    with pytest.warns(CacheDirWarning, match="symbolic link"):
        orbit()
    assert list(elsewhere.iterdir()) == []


def test_a_secret_others_can_read_is_replaced(filled, monkeypatch):
    """A secret file readable by others may have leaked: it is replaced by a
    new one (one warning), and what it signed is rebuilt (one warning per
    file signed with the old secret, which is not used)."""
    cache_dir, _ = filled
    clean = orbit()
    secret = cache_dir / cachedir.SECRET_FILE
    old = secret.read_bytes()
    secret.chmod(0o644)
    new_process(monkeypatch)
    monkeypatch.setattr(cachedir, "_SECRETS", {})
    # No ``match=``: pytest re-emits the warnings a match leaves out, and the
    # rebuilt files' warnings are expected here too (checked below).
    with pytest.warns(CacheDirWarning) as warned:
        assert orbit() == clean
    messages = [str(w.message) for w in warned]
    assert len([m for m in messages if "not private" in m]) == 1
    rebuilt = [m for m in messages if "not private" not in m]
    assert rebuilt and all("is not used: its signature does not match" in m for m in rebuilt)
    assert secret.read_bytes() != old and stat.S_IMODE(secret.stat().st_mode) == 0o600


def test_a_full_cache_compiles_in_memory_with_one_warning(filled, monkeypatch):
    """No space for the generated source: the kernels are compiled in
    memory (numba's disk caching off), the run's result is unchanged, one
    warning says so."""
    cache_dir, _ = filled
    clean = orbit()
    new_process(monkeypatch)
    for path in (cache_dir / "kernels").glob("varint_stepper_*.py"):
        path.unlink()

    def full(path, data):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(codecache, "atomic_write", full)
    with pytest.warns(CacheDirWarning, match="No space left.*compiled in memory") as warned:
        assert orbit() == clean
    assert len([w for w in warned if "compiled in memory" in str(w.message)]) == 1
    assert not list((cache_dir / "kernels").glob("varint_stepper_*.py"))


def test_a_full_disk_when_numba_writes_its_cache_costs_a_warning(filled, monkeypatch):
    """numba's own cache write hitting a full disk raised a raw OSError
    [Errno 28] that lost the run: now it is one warning."""
    cache_dir, _ = filled
    clean = orbit()
    new_process(monkeypatch)
    for f in (cache_dir / "kernels" / "__pycache__").glob("*"):
        f.unlink()

    def full(self, path, data):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(codecache._SignedCacheFile, "_write", full)
    with pytest.warns(CacheDirWarning, match="No space left"):
        assert orbit() == clean


def test_an_unusable_cache_leaves_no_debris_in_tmp(tmp_path):
    """Processes whose cache directory is unusable share one private
    fallback, <tmp>/varint-<uid>; if that name is taken by a directory that
    is not private, each uses a fresh one removed when it exits."""
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    blocker = tmp_path / "file"
    blocker.write_text("")
    env = dict(os.environ, VARINT_CACHE_DIR=str(blocker / "cache"), TMPDIR=str(tmp))
    script = ("import warnings; warnings.simplefilter('ignore'); from varint import cachedir; "
              "print(cachedir.private_dir())")
    runs = [subprocess.run([sys.executable, "-c", script], env=env, capture_output=True,
                           text=True, check=True).stdout.strip() for _ in range(2)]
    assert runs[0] == runs[1] == str(tmp / f"varint-{os.getuid()}")
    assert sorted(os.listdir(tmp)) == [f"varint-{os.getuid()}"]
    (tmp / f"varint-{os.getuid()}").chmod(0o777)        # taken, not private
    out = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True,
                         text=True, check=True).stdout.strip()
    assert out != runs[0] and out.startswith(str(tmp))
    assert sorted(os.listdir(tmp)) == [f"varint-{os.getuid()}"]   # removed at exit


def test_reference_cache_entries_carry_their_key(filled, monkeypatch):
    """Two entries swapped (or one copied to another's name) are not used
    for each other's call: each is reported and recomputed. (The runs are
    the filled cache's stepper.)"""
    cache_dir, _ = filled

    def run(x0):
        return lambda: varint.integrate(HenonHeiles(), x0, 1.0, tau=0.05, scheme="SABA1")

    r1 = cache.cached({"orbit": "R1"}, run(R1))
    c1 = cache.cached({"orbit": "C1"}, run(varint.paper_orbit("C1")[1]))
    a, b = (cache_dir / "results" / f"{cache.cache_key({'orbit': o})}.bin" for o in ("R1", "C1"))
    blob_a, blob_b = a.read_bytes(), b.read_bytes()
    a.write_bytes(blob_b)
    b.write_bytes(blob_a)
    with pytest.warns(cache.CacheWarning, match="unreadable"):
        again = cache.cached({"orbit": "R1"}, run(R1))
    assert np.array_equal(again.state, r1.state) and not np.array_equal(again.state, c1.state)


def test_numbers_given_as_text_are_refused_never_parsed(private):
    """SymPy would evaluate text as Python: periods and inverse masses given
    as strings are refused, and nothing runs."""
    _, marker = private
    x, p = sp.symbols("x p")
    evil = f"__import__('os').system('touch {marker}') or 6.28"
    with pytest.raises(ValueError, match="period of x must be a number"):
        from_map([x + p, p], [x, p], periods={x: evil})
    with pytest.raises(ValueError, match="period of x must be a number"):
        from_map([x + p, p], [x, p], periods=[evil, 0])
    with pytest.raises(ValueError, match=r"inverse_mass\[0\] must be a number"):
        from_potential(x ** 2, [x], inverse_mass=[evil])
    assert not marker.exists()
    # Numbers, NumPy and SymPy numbers still are.
    assert from_map([x + p, p], [x, p], periods={x: 2 * sp.pi}).periods[0] == pytest.approx(
        2 * np.pi)
    assert from_map([x + p, p], [x, p], periods=[np.float64(6.5), 0]).periods[0] == 6.5


def test_numba_writing_the_cache_of_varints_own_kernels_on_a_full_disk_warns(monkeypatch):
    """varint's package kernels are cached by numba beside the package: a
    full disk there raised a raw OSError from inside the compilation. Every
    varint kernel's cache is wrapped so that it costs one warning."""
    from numba.core.dispatcher import Dispatcher

    from varint.kernels import checks

    kernels = [v for v in vars(checks).values() if isinstance(v, Dispatcher)]
    assert kernels and all(isinstance(k._cache, codecache._TolerantCache) for k in kernels
                           if k._cache.__class__.__name__ != "NullCache")

    class Full:
        cache_path = "/nowhere/__pycache__"

        def save_overload(self, sig, data):
            raise OSError(28, "No space left on device")

    monkeypatch.setattr(cachedir, "_WARNED", set())
    with pytest.warns(CacheDirWarning, match="No space left"):
        codecache._TolerantCache(Full()).save_overload(None, None)


@pytest.mark.parametrize("damage", ["a link", "truncated", "empty"])
def test_a_secret_that_is_not_a_private_file_is_replaced(private, tmp_path, damage):
    """The secret planted as a link (to a key someone else knows), or cut
    short, is replaced by a new private one; a missing one is created once
    even by processes racing to make it."""
    cache_dir, _ = private
    cache_dir.mkdir(mode=0o700)
    first = cachedir.secret(cache_dir)
    path = cache_dir / cachedir.SECRET_FILE
    path.unlink()
    known = tmp_path / "known.key"
    known.write_bytes(b"k" * 32)
    if damage == "a link":
        path.symlink_to(known)
    else:
        path.write_bytes(first[: {"truncated": 16, "empty": 0}[damage]])
    cachedir._SECRETS.clear()
    with pytest.warns(CacheDirWarning, match="not private"):
        new = cachedir.secret(cache_dir)
    assert new not in (first, b"k" * 32) and not path.is_symlink()
    assert path.read_bytes() == new and known.read_bytes() == b"k" * 32
    # Two makers at once: the second reads the first's.
    path.unlink()
    a = cachedir._new_secret(path)
    b = cachedir._new_secret(path)
    assert a == b == path.read_bytes()
    assert sorted(p.name for p in cache_dir.iterdir()) == [cachedir.SECRET_FILE]

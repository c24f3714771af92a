"""Code identity and machine in every result (varint.identity)."""

import hashlib
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import varint
from varint import checkpoint as ckpt
from varint import codecache
from varint import identity

ROOT = Path(varint.__file__).resolve().parent.parent
T_END = 2.0


def _digest_of(package, baselines):
    """SHA-256 of the sources as the docstring defines it, computed here
    without varint's code."""
    h = hashlib.sha256()
    for name, folder in (("varint", package), ("varint.baselines", baselines)):
        for path in sorted(folder.rglob("*.py")):
            rel = path.relative_to(folder)
            if name == "varint" and "baselines" in rel.parts:
                continue
            h.update(f"{name}/{rel}".encode() + path.read_bytes())
    return h.hexdigest()


@pytest.fixture(scope="module")
def result():
    return varint.lyapunov_spectrum(*varint.paper_orbit("C1"), T_END, tau=0.05, seed=0)


def test_a_result_names_the_digest_of_the_sources_that_ran(result):
    from varint import baselines

    expected = _digest_of(Path(varint.__file__).resolve().parent,
                          Path(baselines.__file__).resolve().parent)
    assert result.provenance.code["source"] == expected


@pytest.mark.skipif(not (ROOT / ".git").exists() or shutil.which("git") is None,
                    reason="varint is not run from a git checkout")
def test_from_a_checkout_the_commit_is_that_of_git():
    head = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "HEAD"], capture_output=True,
                          text=True, check=True).stdout.strip()
    changed = subprocess.run(["git", "-C", str(ROOT), "status", "--porcelain", "--", "varint",
                              "baselines"], capture_output=True, text=True,
                             check=True).stdout.strip()
    code = identity.code_identity()
    assert code["commit"] == head and code["modified"] is bool(changed)


def test_an_installed_copy_has_the_same_digest_and_an_edit_changes_it(tmp_path):
    """Copied as a wheel installs it (baselines inside the package), the
    digest is the checkout's; one changed byte gives another."""
    from varint import baselines

    package = Path(varint.__file__).resolve().parent
    copy = tmp_path / "site" / "varint"
    shutil.copytree(package, copy, ignore=shutil.ignore_patterns("__pycache__"))
    if not (copy / "baselines").exists():
        shutil.copytree(Path(baselines.__file__).resolve().parent, copy / "baselines",
                        ignore=shutil.ignore_patterns("__pycache__"))
    script = "from varint import identity; print(identity.code_identity())"
    env = dict(os.environ, PYTHONPATH=str(tmp_path / "site"))

    def ask():
        out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                             env=env, cwd=tmp_path, check=True).stdout
        return eval(out)  # a dict literal of str, bool and None

    first = ask()
    assert first["source"] == identity.source_digest()
    assert first["commit"] is None and first["modified"] is None  # no checkout there
    with open(copy / "identity.py", "a") as f:
        f.write("\n")
    assert ask()["source"] != first["source"]


def test_the_machine_is_recorded_with_its_load_at_the_start(result):
    m = result.provenance.machine
    assert m["cores"] >= 1 and m["cpu"] == identity.cpu_model()
    assert m["load"] is None or m["load"] >= 0.0
    assert m["system"]


def test_the_load_is_read_again_once_a_second_has_passed(monkeypatch):
    # Linux recomputes the load average every 5 s: a reading under a second
    # old serves the next runs (a prepared run's short calls), an older one
    # does not, and each machine() is a new dict.
    reads = []

    def load():
        reads.append(None)
        return (0.125 * len(reads), 0.0, 0.0)

    monkeypatch.setattr(identity.os, "getloadavg", load)
    monkeypatch.setattr(identity, "_LAST_LOAD", (float("-inf"), None))
    first, second = identity.machine(), identity.machine()
    assert len(reads) == 1 and first == second and first is not second
    assert first["load"] == round(0.125, 2)
    # A reading almost a second old still serves; one a second old does not.
    read_at = identity.time.monotonic() - 0.9 * identity.LOAD_FRESH_SECONDS
    monkeypatch.setattr(identity, "_LAST_LOAD", (read_at, 0.5))
    assert identity.machine()["load"] == 0.5 and len(reads) == 1
    read_at = identity.time.monotonic() - identity.LOAD_FRESH_SECONDS
    monkeypatch.setattr(identity, "_LAST_LOAD", (read_at, 0.5))
    assert identity.machine()["load"] == round(0.25, 2) and len(reads) == 2


def test_a_checkpoint_from_other_code_is_refused(tmp_path):
    """Bitwise resumption holds only for the same code: the checkpoint
    records the digest and a run of other sources does not resume it."""
    path = tmp_path / "c.ckpt"
    c1 = varint.paper_orbit("C1")
    varint.lyapunov_spectrum(*c1, T_END, tau=0.05, seed=0, checkpoint=path)
    snap = ckpt.read(path)
    assert snap.parameters["code"] == identity.source_digest()
    snap.parameters["code"] = "0" * 64
    ckpt.write(path, snap)
    with pytest.raises(varint.CheckpointError, match=r"parameters: code \(other values\)"):
        varint.lyapunov_spectrum(*c1, T_END, tau=0.05, seed=0, checkpoint=path)


def test_code_and_machine_survive_save_and_load(result, tmp_path):
    result.save(tmp_path / "r.npz")
    back = varint.load_result(tmp_path / "r.npz")
    assert back.provenance.code == result.provenance.code
    assert back.provenance.machine == result.provenance.machine
    np.testing.assert_array_equal(back.exponents, result.exponents)


def test_a_result_saved_before_code_was_recorded_loads_with_none(result, tmp_path):
    """An older file must not be stamped with the code that loads it."""
    import json

    path = tmp_path / "old.npz"
    result.save(path)
    with np.load(path, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    meta = json.loads(str(arrays["__meta__"]))
    for name in ("code", "machine"):
        meta["provenance"].pop(name)
    arrays["__meta__"] = np.array(json.dumps(meta))
    np.savez(path, **arrays)
    back = varint.load_result(path)
    assert back.provenance.code == {} and back.provenance.machine == {}


@pytest.fixture
def sources(tmp_path, monkeypatch):
    """A copy of varint's sources settled for 0.1 s (the time a status must
    lie back to vouch for a file here, instead of 2 s), a private cache
    directory of its own, and the digest of the copy computed without
    varint's code. Returns (folders as :func:`identity._digest` takes them,
    record folder, digest)."""
    from varint import baselines, cachedir

    monkeypatch.setenv("VARINT_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setattr(cachedir, "_WARNED", set())
    monkeypatch.setattr(identity, "_SETTLED_NS", 50_000_000)
    copies = []
    for name, folder in (("varint", Path(varint.__file__).resolve().parent),
                         ("varint.baselines", Path(baselines.__file__).resolve().parent)):
        copies.append((name, tmp_path / name))
        shutil.copytree(folder, tmp_path / name, ignore=shutil.ignore_patterns("__pycache__"))
    time.sleep(0.1)
    return tuple(copies), tmp_path / "cache" / identity._RECORDS, _digest_of(copies[0][1],
                                                                            copies[1][1])


def test_the_digest_is_recorded_signed_and_read_back_while_the_files_are_unchanged(
        sources, monkeypatch):
    """A recorded digest is what a later process gets, without reading the
    sources; the record is signed."""
    folders, records, digest = sources
    assert identity._digest(folders) == digest
    (record,) = records.glob("sources_*.json")
    assert record.read_bytes().startswith(codecache.HEADER)
    stored = json.loads(record.read_bytes().split(b"\n", 1)[1])
    stored["digest"] = "f" * 64   # as if the record were read: nothing else says this
    codecache.write_signed(record, json.dumps(stored))
    monkeypatch.setattr("builtins.open", None)     # and no source is read
    assert identity._digest(folders) == "f" * 64


@pytest.mark.parametrize("edit", ["one byte, same size and times", "a file added",
                                  "a file removed", "renamed over"])
def test_any_change_to_a_source_changes_the_digest_despite_the_record(sources, edit):
    """Edits the status of a file cannot hide: one byte changed with its
    size and modification time put back (its change time moves), a file
    added or removed, a file replaced by a rename (its inode changes)."""
    folders, records, digest = sources
    assert identity._digest(folders) == digest and list(records.glob("sources_*.json"))
    package = folders[0][1]
    target = package / "identity.py"
    before = target.stat()
    if edit == "one byte, same size and times":
        data = bytearray(target.read_bytes())
        data[-2] = ord("#") if data[-2] != ord("#") else ord(" ")
        target.write_bytes(bytes(data))
        os.utime(target, ns=(before.st_atime_ns, before.st_mtime_ns))
        assert target.stat().st_size == before.st_size
    elif edit == "a file added":
        (package / "added.py").write_text("")
    elif edit == "a file removed":
        (package / "demo.py").unlink()
    else:
        (package / "new.tmp").write_bytes(target.read_bytes() + b"#")
        os.replace(package / "new.tmp", target)
    assert identity._digest(folders) == _digest_of(package, folders[1][1]) != digest


def test_a_file_changed_just_before_is_hashed_again_by_the_next_process(sources, monkeypatch):
    """A status younger than the settling time does not vouch for its file
    (a write in the same tick of the file system's clock would keep it):
    no record is kept until every file has settled."""
    folders, records, digest = sources
    monkeypatch.setattr(identity, "_SETTLED_NS", 10**12)
    assert identity._digest(folders) == digest and not list(records.glob("sources_*.json"))


def test_a_forged_or_damaged_record_is_discarded(sources):
    """A record not signed with the user's secret is discarded with a
    warning and the digest computed from the sources."""
    from varint.cachedir import CacheDirWarning

    folders, records, digest = sources
    identity._digest(folders)
    (record,) = records.glob("sources_*.json")
    stored = json.loads(record.read_bytes().split(b"\n", 1)[1])
    stored["digest"] = "f" * 64
    record.write_bytes(codecache.HEADER + b"0" * 64 + b"\n" + json.dumps(stored).encode())
    with pytest.warns(CacheDirWarning, match="source digest record"):
        assert identity._digest(folders) == digest

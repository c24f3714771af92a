"""Code identity and machine in every result (varint.identity)."""

import hashlib
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import varint
from varint import checkpoint as ckpt
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

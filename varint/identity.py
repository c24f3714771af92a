"""Which code and which machine produced a result.

A version number names a release, not the code that ran: between two
releases every edit keeps "0.1.0". A result, a checkpoint and a stored
study output therefore carry

* :func:`source_digest`: the SHA-256 of varint's installed sources (every
  ``.py`` file of ``varint`` and ``varint.baselines``, with its path), so
  two results name the same code exactly when the digests agree;
* :func:`code_identity`: that digest, and where the package is run from a
  git checkout, the commit and whether the sources differ from it;
* :func:`machine`: the CPU model, the number of cores and the load average
  when the run started, since a time measured on a shared machine means
  little without them.

The digest and the commit are worked out once per process (one git process
~5 ms); the load is read at every call. Reading and hashing the 1.6 MB of
sources cost ~11 ms of every process, so the digest is kept in a signed
record with each file's status, and read again only while every status
matches (:func:`source_digest`).
"""

from __future__ import annotations

import functools
import hashlib
import os
import platform
import subprocess
import time
from pathlib import Path

from . import codecache

__all__ = ["source_digest", "code_identity", "machine", "cpu_model"]

#: Seconds git may take to answer before the commit is left unknown.
_GIT_TIMEOUT = 10.0


#: How long before the sources are read a file's last change must lie for
#: its status to vouch for its content (ns): a file changed again within one
#: tick of the file system's clock can keep its times (git's "racily
#: clean" entries), and the clock that stamps them may lag the one read here.
_SETTLED_NS = 2_000_000_000

#: The cache directory's folder of the signed records of source digests.
_RECORDS = "identity"


@functools.cache
def source_digest():
    """SHA-256 (hex) of the sources of the installed ``varint``.

    Every ``.py`` file of ``varint`` and of ``varint.baselines`` (installed
    from the repository's ``baselines/`` folder) is hashed in sorted order
    with its path relative to its package, so a renamed, added or edited
    file changes the digest, and a copy of the same sources anywhere on
    disk gives the same one.

    The digest is read from a record signed in the cache directory when the
    list of files and each one's status (device, inode, size, times of the
    last modification and of the last status change) are those it was
    recorded with, and computed from the contents otherwise. This is sound
    because the status is taken before the contents are read, and a file is
    recorded only if its last change lies :data:`_SETTLED_NS` before that:
    any write to a file after that moment (an edit, a copy over it, a
    rename onto its path) gives it a change time (``st_ctime_ns``, which
    no one but the superuser can set back) or an inode other than the
    recorded one, so its content is read again. The record is signed
    (:func:`varint.codecache.write_json`): a record that another user
    planted, or that was edited, is discarded with a warning.
    """
    from . import baselines

    return _digest((("varint", Path(__file__).resolve().parent),
                    ("varint.baselines", Path(baselines.__file__).resolve().parent)))


def _digest(folders):
    """:func:`source_digest` of the packages ``folders`` ((name, folder)
    pairs), from its record when every file's status matches."""
    files = []
    for name, folder in folders:
        for parts in _python_files(folder):
            if name == "varint" and "baselines" in parts:
                continue  # an installed copy, hashed as varint.baselines
            files.append((f"{name}/{os.sep.join(parts)}", os.path.join(folder, *parts)))
    started = time.time_ns()
    status = [[label, *_status(path)] for label, path in files]
    record_name = "sources_" + hashlib.sha256(
        "|".join(str(folder) for _, folder in folders).encode()).hexdigest()[:24] + ".json"
    record = codecache.read_json(_RECORDS, record_name, "source digest record")
    if isinstance(record, dict) and record.get("files") == status and \
            isinstance(record.get("digest"), str):
        return record["digest"]
    h = hashlib.sha256()
    for label, path in files:
        h.update(label.encode())
        with open(path, "rb") as f:
            h.update(f.read())
    digest = h.hexdigest()
    if all(max(mtime, ctime) < started - _SETTLED_NS for *_, mtime, ctime in status):
        codecache.write_json(_RECORDS, record_name, {"files": status, "digest": digest})
    return digest


def _python_files(folder):
    """The relative paths (tuples of names) of the ``.py`` files under
    ``folder``, in the order of ``sorted(folder.rglob("*.py"))`` (folders
    reached through a symbolic link not entered, as there), without
    pathlib's cost per file (≈ 8 ms of every process)."""
    found, stack = [], [()]
    while stack:
        parts = stack.pop()
        with os.scandir(os.path.join(folder, *parts)) as entries:
            for entry in entries:
                if entry.name.endswith(".py"):
                    found.append((*parts, entry.name))
                if entry.is_dir() and not entry.is_symlink():
                    stack.append((*parts, entry.name))
    return sorted(found, key=lambda parts: tuple(map(os.path.normcase, parts)))


def _status(path):
    """[device, inode, size, mtime_ns, ctime_ns] of the file ``path``."""
    st = os.stat(path)
    return [st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns]


def _git(root, *args):
    out = subprocess.run(["git", "-C", str(root), *args], capture_output=True, text=True,
                         timeout=_GIT_TIMEOUT, check=True)
    return out.stdout


@functools.cache
def _checkout():
    """(commit, modified) of the git checkout varint runs from, or
    (None, None) when it is installed (no ``.git`` beside the package) or
    git cannot say."""
    root = Path(__file__).resolve().parent.parent
    if not (root / ".git").exists() or not (root / "pyproject.toml").exists():
        return None, None
    try:
        # One git process says both (each costs ~5 ms of a first run): the
        # header "# branch.oid <commit>" ("(initial)" before the first
        # commit), then a line per changed or new file; tracked edits and
        # new files alike change the code that runs.
        lines = _git(root, "status", "--porcelain=v2", "--branch", "--", "varint",
                     "baselines").splitlines()
    except (OSError, subprocess.SubprocessError):
        return None, None
    commit = next((line.split()[2] for line in lines if line.startswith("# branch.oid ")), None)
    if commit is None or commit == "(initial)":
        return None, None
    return commit, any(not line.startswith("#") for line in lines)


def code_identity():
    """The code that runs: ``{"source": digest, "commit": str or None,
    "modified": bool or None}``.

    ``source`` is :func:`source_digest`. ``commit`` is the git commit of the
    checkout varint is imported from (None for an installed package), and
    ``modified`` whether its ``varint/`` or ``baselines/`` differ from that
    commit (uncommitted edits or new files): only ``source`` identifies
    the code exactly; the commit says where to find it.
    """
    commit, modified = _checkout()
    return {"source": source_digest(), "commit": commit, "modified": modified}


@functools.cache
def cpu_model():
    """The CPU's model name (``/proc/cpuinfo`` on Linux, else what
    :func:`platform.processor` says; "" if neither knows)."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor()


def machine():
    """The machine now: ``{"cpu": model, "cores": logical CPUs the process
    may use, "load": 1-minute load average (None where the system has
    none), "system": OS and architecture}``.

    The load is that of the moment of the call (read at most
    :data:`LOAD_FRESH_SECONDS` before it): call it when a run starts.
    """
    cpu, cores, system = _fixed_machine()
    return {"cpu": cpu, "cores": cores, "load": _load(), "system": system}


#: How long a reading of the load average serves later calls, in seconds:
#: Linux recomputes the average every 5 s, so a reading this recent is the
#: one a new reading would give, or the sample before it (a prepared run's
#: short calls, ~100 µs each, would otherwise read it at every call).
LOAD_FRESH_SECONDS = 1.0

#: (time.monotonic() of the last reading, its load).
_LAST_LOAD: tuple[float, float | None] = (float("-inf"), None)


def _load():
    """The 1-minute load average, rounded to 0.01 (None where the system
    has none), read again once :data:`LOAD_FRESH_SECONDS` have passed."""
    global _LAST_LOAD
    now = time.monotonic()
    read_at, load = _LAST_LOAD
    if now - read_at < LOAD_FRESH_SECONDS:
        return load
    try:
        load = round(os.getloadavg()[0], 2)
    except (AttributeError, OSError):  # not on Windows
        load = None
    _LAST_LOAD = (now, load)
    return load


@functools.cache
def _fixed_machine():
    """(CPU model, logical CPUs the process may use, OS and architecture):
    read once per process (~8 µs of every run otherwise)."""
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # not on macOS or Windows
        cores = os.cpu_count()
    return cpu_model(), cores, f"{platform.system()} {platform.machine()}"

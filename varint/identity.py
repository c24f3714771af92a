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

The digest and the commit are worked out once per process (reading the
sources takes a few milliseconds, one git process ~5 ms); the load is read at
every call.
"""

from __future__ import annotations

import functools
import hashlib
import os
import platform
import subprocess
import time
from pathlib import Path

__all__ = ["source_digest", "code_identity", "machine", "cpu_model"]

#: Seconds git may take to answer before the commit is left unknown.
_GIT_TIMEOUT = 10.0


@functools.cache
def source_digest():
    """SHA-256 (hex) of the sources of the installed ``varint``.

    Every ``.py`` file of ``varint`` and of ``varint.baselines`` (installed
    from the repository's ``baselines/`` folder) is hashed in sorted order
    with its path relative to its package, so a renamed, added or edited
    file changes the digest, and a copy of the same sources anywhere on
    disk gives the same one.
    """
    from . import baselines

    h = hashlib.sha256()
    for name, folder in (("varint", Path(__file__).resolve().parent),
                         ("varint.baselines", Path(baselines.__file__).resolve().parent)):
        for path in sorted(folder.rglob("*.py")):
            if name == "varint" and "baselines" in path.relative_to(folder).parts:
                continue  # an installed copy, hashed as varint.baselines
            h.update(f"{name}/{path.relative_to(folder)}".encode())
            h.update(path.read_bytes())
    return h.hexdigest()


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

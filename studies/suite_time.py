"""How long the default test suite takes, run as CI runs it
(``python -m pytest`` in a fresh process): cold, with empty numba and varint
caches as a fresh CI checkout has them, or warm, on the caches a cold run
left. Stores wall and CPU time (pytest and its workers together), the
machine's cores and load before and after, pytest's summary line and its
slowest tests, under ``cold`` or ``warm`` of ``suite_time.json`` (the other
entry is kept; a run given pytest arguments, e.g. some files, under
``cold ARGS``, its profile merged into the stored one); pytest's whole
report is left in ``CACHE/pytest.log``. README states the figures through
``studies/quotes.py``.
The run carries the ``studies.suite_profile`` plugin: a cold run also
leaves the per-file table of where the time went (CPU seconds, compile
share, functions compiled) as ``suite_profile.json`` (a warm run keeps the
cold table).

Usage: ``python studies/suite_time.py [--warm] [--cache DIR] [--out DIR]
[-- PYTEST ARGS]``
"""

from __future__ import annotations

import json
import os
import re
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

try:
    from common import parse_args, provenance, save_json
    from suite_profile import main as profile_main
except ImportError:  # imported as studies.suite_time
    from .common import parse_args, provenance, save_json
    from .suite_profile import main as profile_main

ROOT = Path(__file__).resolve().parent.parent
#: pytest's closing line: "1470 passed, 60 deselected in 512.3s" (failures,
#: when there are any, come first: "1 failed, 1469 passed ...").
SUMMARY = re.compile(r"^=*\s*(\d+ (?:failed|passed|error).*?) in [\d.]+s", re.M)
#: one line of ``--durations``: "12.34s setup tests/x.py::test_y".
DURATION = re.compile(r"^([\d.]+)s (call|setup|teardown)\s+(\S+)", re.M)


def _extra(parser):
    parser.add_argument("--warm", action="store_true",
                        help="keep the caches a previous (cold) run left")
    parser.add_argument("--cache", type=Path,
                        default=Path(tempfile.gettempdir()) / f"varint-suite-time-{os.getuid()}",
                        help="folder of the varint cache the suite runs with")
    parser.add_argument("pytest_args", nargs="*", help="extra arguments after --")


def run_suite(cache, warm, pytest_args=()):
    """Run the default suite once in a subprocess; its wall and CPU time,
    load, summary and slowest steps (a dict)."""
    if not warm:
        shutil.rmtree(cache, ignore_errors=True)
        # numba's own caches of the package's functions, beside their
        # sources as CI has them (NUMBA_CACHE_DIR would move them, and the
        # cache-security tests check where they are).
        for path in ROOT.glob("**/__pycache__/*.nb[ic]"):
            path.unlink()
    cache.mkdir(parents=True, exist_ok=True)
    # Each process's per-test rows (studies/suite_profile.py), fresh.
    shutil.rmtree(cache / "rows", ignore_errors=True)
    (cache / "rows").mkdir()
    env = {**os.environ, "VARINT_CACHE_DIR": str(cache / "varint"),
           "VARINT_SUITE_PROFILE": str(cache / "rows")}
    command = [sys.executable, "-m", "pytest", "-p", "no:cacheprovider",
               "-p", "studies.suite_profile", "--durations=30", *pytest_args]
    load_start = os.getloadavg()
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    proc = subprocess.run(command, cwd=ROOT, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    out = proc.stdout + proc.stderr
    # pytest's whole report, for the failures and warnings the summary names.
    (cache / "pytest.log").write_text(out)
    summary = SUMMARY.search(out)
    return {"mode": "warm" if warm else "cold",
            "command": " ".join(["python", "-m", "pytest", *command[3:]]),
            "returncode": proc.returncode,
            "summary": summary.group(1) if summary else (out.strip().splitlines() or [""])[-1],
            "wall_s": round(wall, 1),
            "cpu_s": round(after.ru_utime + after.ru_stime
                           - before.ru_utime - before.ru_stime, 1),
            "cores": os.cpu_count(),
            "load_start": [round(x, 2) for x in load_start],
            "load_end": [round(x, 2) for x in os.getloadavg()],
            "slowest": [{"s": float(s), "when": when, "test": test}
                        for s, when, test in DURATION.findall(out)[:30]],
            "provenance": provenance()}


def main(argv=None):
    args = parse_args(__doc__.splitlines()[0], argv, extra=_extra)
    out = args.out
    entry = run_suite(args.cache, args.warm, args.pytest_args)
    path = Path(out) / "suite_time.json"
    stored = json.loads(path.read_text()) if path.exists() else {}
    stored.pop("_provenance", None)
    # A run of some files only is stored beside the default suite's, under
    # its files, and merged into the profile: it must not stand for the
    # suite (README quotes ``cold``).
    label = " ".join([entry["mode"], *args.pytest_args])
    stored[label] = entry
    save_json(out, "suite_time", stored)
    if entry["mode"] == "cold":
        merge = ["--merge"] if args.pytest_args else []
        profile_main([*merge, "--rows", str(args.cache / "rows"), "--out", str(out), "--note",
                      f"the cold {' '.join(args.pytest_args) or 'default suite'} of "
                      f"suite_time.py: {entry['summary']}, "
                      f"{entry['wall_s']:.0f} s wall, {entry['cpu_s']:.0f} s CPU, load "
                      f"{entry['load_start'][0]} -> {entry['load_end'][0]}"])
    print(f"{entry['mode']}: {entry['wall_s']:.0f} s wall, {entry['cpu_s']:.0f} s CPU, "
          f"{entry['summary']} (load {entry['load_start'][0]} → {entry['load_end'][0]})")
    return entry


if __name__ == "__main__":
    main()

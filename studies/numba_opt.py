"""What LLVM's optimisation level (``NUMBA_OPT``) costs the test suite: test
files run cold (fresh varint and numba caches) in one process at each level,
the levels interleaved within each repeat; per level, the CPU seconds of the
run (process and children), the CPU seconds numba spent compiling
(:class:`suite_profile.CompileTimer`), pytest's summary, and how many
kernels numba could not cache ("Cannot cache compiled function": a kernel
that cannot be cached compiles again in every process, cold or warm).

Asks whether compiling the suite's kernels at ``-O0``/``-O1`` instead of
numba's default ``-O3`` cuts its cold time (issue 26, item 5): compiling is
94-100 % of its CPU time, but much of it is numba's own typing and lowering,
which does not depend on the level.

Usage: ``python studies/numba_opt.py [--levels 0 1 3] [--repeats N] [--out DIR]
[-- TEST FILES]``
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
from pathlib import Path

try:
    from common import parse_args, save_json
except ImportError:  # imported as studies.numba_opt
    from .common import parse_args, save_json

ROOT = Path(__file__).resolve().parent.parent
SUMMARY = re.compile(r"^=*\s*(\d+ (?:failed|passed|error).*?) in [\d.]+s", re.M)


def _extra(parser):
    parser.add_argument("--levels", type=int, nargs="+", default=[0, 1, 3],
                        help="NUMBA_OPT levels to compare (3 is numba's default)")
    parser.add_argument("--repeats", type=int, default=1,
                        help="cold runs per level (the minimum is kept)")
    parser.add_argument("--cache", type=Path,
                        default=Path(tempfile.gettempdir()) / f"varint-numba-opt-{os.getuid()}",
                        help="folder of the fresh caches, one per run")
    parser.add_argument("files", nargs="*", default=["tests/test_megno.py"],
                        help="test files after --")


def cold_run(level, files, cache):
    """One cold pytest run of ``files`` at ``NUMBA_OPT=level``, in caches of
    its own (numba's cache key omits the level); its CPU and compile
    seconds, summary and uncacheable kernels (a dict)."""
    shutil.rmtree(cache, ignore_errors=True)
    cache.mkdir(parents=True)
    rows = cache / "rows.json"
    code = (f"import sys, pytest; sys.path.insert(0, {str(ROOT / 'studies')!r}); "
            f"from suite_profile import CompileTimer; "
            f"sys.exit(pytest.main(sys.argv[1:], plugins=[CompileTimer({str(rows)!r})]))")
    env = {**os.environ, "NUMBA_OPT": str(level), "VARINT_CACHE_DIR": str(cache / "varint"),
           "NUMBA_CACHE_DIR": str(cache / "numba")}
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    proc = subprocess.run([sys.executable, "-c", code, "-n", "0", "-p", "no:cacheprovider",
                           "-q", *files], cwd=ROOT, env=env, capture_output=True, text=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    out = proc.stdout + proc.stderr
    summary = SUMMARY.search(out)
    compile_s = sum(r["compile_s"] for r in json.loads(rows.read_text()).values()) \
        if rows.exists() else None
    return {"level": level, "returncode": proc.returncode,
            "summary": summary.group(1) if summary else out.strip().splitlines()[-1:],
            "cpu_s": round(after.ru_utime + after.ru_stime
                           - before.ru_utime - before.ru_stime, 1),
            "compile_s": None if compile_s is None else round(compile_s, 1),
            "uncacheable": out.count("Cannot cache compiled function")}


def main(argv=None):
    args = parse_args(__doc__.splitlines()[0], argv, extra=_extra)
    runs = []
    for repeat in range(args.repeats):
        # Interleaved, the order reversed every other repeat: a load that
        # changes during the study weighs on every level alike.
        levels = args.levels if repeat % 2 == 0 else args.levels[::-1]
        for level in levels:
            run = cold_run(level, args.files, args.cache / f"opt{level}")
            run["load"] = [round(x, 2) for x in os.getloadavg()]
            runs.append(run)
            print(run, flush=True)
    best = {level: min((r for r in runs if r["level"] == level), key=lambda r: r["cpu_s"])
            for level in args.levels}
    top = max(args.levels)
    summary = {str(level): {"cpu_s": r["cpu_s"], "compile_s": r["compile_s"],
                            f"cpu_ratio_to_O{top}": round(r["cpu_s"] / best[top]["cpu_s"], 3),
                            "summary": r["summary"], "uncacheable": r["uncacheable"]}
               for level, r in best.items()}
    save_json(args.out, "numba_opt", {"files": args.files, "repeats": args.repeats,
                                      "best": summary, "runs": runs})
    return summary


if __name__ == "__main__":
    main()

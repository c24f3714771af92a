"""Where a rotating bar's first run goes (issue 29, bar23): the cold
compile of its generated steppers, this code against a baseline copy of
varint.

The suite's profile (``studies/results/suite_profile_stop56.json``) gave
one test 70 CPU s for a single compile of the bar's stepper (the full
spectrum, six vectors, ``tests/test_remembered.py``'s "bar seeded") and 32 s
for one vector. Cases (:data:`CASES`), each a first call in a new
interpreter with empty varint and numba caches, measured by
:mod:`studies.compile_cost`'s child (numba's event API, exclusive seconds
per dispatcher and per compiler pass, the time under LLVM's lock):

* ``bar 1 vector``: ``lyapunov_spectrum`` of the chaotic orbit to t = 1,
  τ = 0.1, one deviation vector (the hamiltonians study's call);
* ``bar seeded``: the same with the default vectors (the full spectrum).

Per code and case the median over ``--repeats`` runs, the codes
interleaved (a worker per code with its directory first on ``sys.path``).

Usage::

    git worktree add /tmp/base a96e0b7
    python studies/bar_compile_cost.py --baseline /tmp/base [--repeats N]
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from studies.common import parse_args, save_json  # noqa: E402
from studies.compile_cost import CHILD, largest, median_of  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]

_ORBIT = "from varint.models.bar import bar_orbit; m, x = bar_orbit('chaotic'); "

#: The first call of each case, in a new process with empty caches.
CASES = {
    "bar 1 vector": (_ORBIT + "r = varint.lyapunov_spectrum(m, x, 1.0, tau=0.1, "
                     "deviations=np.full((6, 1), 6 ** -0.5)); value = r.exponents"),
    "bar seeded": _ORBIT + "r = varint.lyapunov_spectrum(m, x, 1.0, tau=0.1); value = r.exponents",
}


def child(code_dir, case):
    """One new interpreter with empty caches running ``case`` on the code
    in ``code_dir``: :mod:`studies.compile_cost`'s measurements."""
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, VARINT_CACHE_DIR=os.path.join(cache, "varint"),
                   NUMBA_CACHE_DIR=os.path.join(cache, "numba"))
        code = (f"import sys\nsys.path.insert(0, {str(code_dir)!r})\n"
                f"CASE = {CASES[case]!r}\nPROFILE = False\n" + CHILD)
        done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                              text=True, cwd=code_dir)
    if done.returncode:
        raise RuntimeError(f"case {case!r} failed on {code_dir}:\n{done.stderr[-3000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def summarise(runs):
    """The medians of one code's and case's repeats."""
    return {
        "median compile s": round(statistics.median(r["compile"] for r in runs), 2),
        "median process CPU s": round(statistics.median(r["cpu"] for r in runs), 2),
        "median dispatchers compiled": statistics.median(len(r["compiles"]) for r in runs),
        "event kinds, exclusive median s": largest(median_of(runs, "kinds"), 6),
        "passes, exclusive median s (largest)": largest(median_of(runs, "passes"), 6),
        "dispatchers, exclusive median s (largest)": largest(median_of(runs, "compiles"), 8),
    }


def main(argv=None):
    def extra(parser):
        parser.add_argument("--baseline", type=Path, required=True,
                            help="a worktree of the code to compare with")
        parser.add_argument("--repeats", type=int, default=2)
        parser.add_argument("--cases", nargs="+", default=list(CASES), choices=list(CASES))

    args = parse_args(__doc__.splitlines()[0], argv, extra)
    load = os.getloadavg()
    codes = {"baseline": args.baseline.resolve(), "this": ROOT}
    raw: dict = {}
    for _ in range(args.repeats):
        for case in args.cases:
            for label, code_dir in codes.items():
                raw.setdefault(case, {}).setdefault(label, []).append(child(code_dir, case))
    rows = {case: {label: summarise(runs) for label, runs in per.items()}
            for case, per in raw.items()}
    for case, row in rows.items():
        print(case, json.dumps(row, indent=1), flush=True)
    save_json(args.out, "bar_compile_cost", {
        "summary": rows, "repeats": args.repeats, "baseline": str(codes["baseline"]),
        "load": load, "load_end": os.getloadavg()})


if __name__ == "__main__":
    main()

"""Where a generated stepper's compile time goes, and what calling the
logarithm of the sparse schedule instead of inlining it changes (issue 26
leftover: the fixed compile of every generated stepper).

``compile``: for each source tree given (``--tree LABEL=PATH``, copies of a
varint checkout), interleaved, ``--repeats`` new interpreters each with an
empty cache directory run the first Hénon–Heiles Lyapunov spectrum (the
generated one-orbit stepper, four vectors, the default adaptive schedule)
and report the seconds numba spent compiling
(:func:`varint.compiling.compile_seconds`), the CPU seconds of the process,
and numba's per-pass times of the one-orbit kernel (its
``pipeline_times``): the median of each is stored.

``speed``: in one process, the one-orbit stepper as generated now (the
schedule's logarithm called, ``vlog_called``) against the same source with
it inlined (``vlog``, as before), the same run (R1, four vectors, t = 20000,
τ = 0.05, adaptive schedule), and a chaos map of 64 orbits as SIMD lanes
(X1 to t = 500, the generated ``lanes``), interleaved, minimum of
``--repeats`` (CPU time; run it with ``NUMBA_NUM_THREADS=1``), their
ratios and spread; the results must be the same bits.

Run: ``python studies/stepper_compile.py compile --tree after=<copy>
--tree before=<copy>`` and ``python studies/stepper_compile.py speed``.
"""

from __future__ import annotations

import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

try:
    from common import interleaved, parse_args, ratio_spread, save_json
except ImportError:  # imported as studies.stepper_compile
    from .common import interleaved, parse_args, ratio_spread, save_json

R1 = [0.0, 0.558, 0.23337397, 0.0]

#: The child of ``compile``: the first run of a new process, cold cache.
CHILD = """
import json, sys, time
import numpy as np
import varint
from varint import compiling
m = varint.models.HenonHeiles()
r = varint.lyapunov_spectrum(m, np.array([0.0, 0.558, 0.23337397, 0.0]), t_end=10.0, tau=0.05, progress=False)
passes = {}
for name, module in list(sys.modules.items()):
    if name.startswith("varint_stepper_"):
        orbit = module.orbit
        for sig in orbit.signatures:
            times = (orbit.get_metadata(sig) or {}).get("pipeline_times", {}).get("nopython", {})
            for key, t in times.items():
                passes[key.split("_", 1)[-1]] = t.init + t.run + t.finalize
print(json.dumps({"compile": compiling.compile_seconds(), "cpu": time.process_time(),
                  "passes": passes, "values": r.exponents.tobytes().hex()}))
"""


def compile_times(args, trees):
    runs = {label: [] for label in trees}
    scratch = Path(tempfile.mkdtemp(prefix="varint-stepper-compile-"))
    try:
        for rep in range(1 if args.quick else args.repeats):
            for label, tree in trees.items():
                for path in Path(tree, "varint").rglob("__pycache__/*.nb[ic]"):
                    path.unlink()
                env = dict(os.environ, PYTHONPATH=str(tree),
                           VARINT_CACHE_DIR=str(scratch / f"{label}-{rep}"))
                done = subprocess.run([sys.executable, "-c", CHILD], env=env, check=True,
                                      capture_output=True, text=True, cwd=scratch)
                runs[label].append(json.loads(done.stdout.strip().splitlines()[-1]))
                print(label, rep, {k: v for k, v in runs[label][-1].items() if k != "passes"},
                      flush=True)
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    summary = {}
    for label, rs in runs.items():
        keys = sorted({k for r in rs for k in r["passes"]})
        passes = {k: statistics.median(r["passes"].get(k, 0.0) for r in rs) for k in keys}
        summary[label] = {
            "median compile s": statistics.median(r["compile"] for r in rs),
            "median process CPU s": statistics.median(r["cpu"] for r in rs),
            "orbit kernel passes, median s (largest)": dict(
                sorted(passes.items(), key=lambda kv: -kv[1])[:8]),
            "values": sorted({r["values"] for r in rs})}
    print(json.dumps(summary, indent=1))
    save_json(args.out, "stepper_compile", {"summary": summary, "runs": runs,
                                            "trees": sorted(trees)})


def speed(args):
    import numpy as np

    import varint
    from varint.codegen import stepper
    from varint.kernels import logarithm

    x = np.array(R1)

    grid = x + 1e-3 * np.arange(64)[:, None] * np.array([0.0, 1.0, 0.0, 0.0])

    def run(model):
        return varint.lyapunov_spectrum(model, x, t_end=20000.0, tau=0.05, progress=False)

    def lanes(model):
        return varint.chaos_map(model, grid, "x1", t_end=500.0, tau=0.05, progress=False)

    now = varint.models.HenonHeiles()
    first = run(now)                                     # compiled: vlog called
    # The same generated source with the schedule's logarithm inlined (as
    # before): a new module, in a cache directory of its own.
    scratch = tempfile.mkdtemp(prefix="varint-stepper-inline-")
    called = logarithm.vlog_called
    try:
        os.environ["VARINT_CACHE_DIR"] = scratch
        stepper._LOADED.clear()
        logarithm.vlog_called = logarithm.vlog
        inlined = varint.models.HenonHeiles()
        second = run(inlined)
        lanes(inlined)
    finally:
        logarithm.vlog_called = called
    lanes(now)
    assert first.exponents.tobytes() == second.exponents.tobytes()
    tasks = {"called": lambda: run(now), "inlined": lambda: run(inlined),
             "lanes called": lambda: lanes(now), "lanes inlined": lambda: lanes(inlined)}
    turns: dict = {}
    best, outputs = interleaved(tasks, 1 if args.quick else args.repeats,
                                clock=time.process_time, turns=turns)
    assert outputs["called"].exponents.tobytes() == outputs["inlined"].exponents.tobytes()
    assert outputs["lanes called"].values.tobytes() == outputs["lanes inlined"].values.tobytes()
    result = {"best CPU s": best, "ratio called/inlined": best["called"] / best["inlined"],
              "spread": ratio_spread(turns, "inlined", "called"),
              "lanes ratio called/inlined": best["lanes called"] / best["lanes inlined"],
              "lanes spread": ratio_spread(turns, "lanes inlined", "lanes called"),
              "bitwise": True, "load": os.getloadavg()}
    print(json.dumps(result, indent=1))
    shutil.rmtree(scratch, ignore_errors=True)
    save_json(args.out, "stepper_compile_speed", result)


def main(argv=None):
    def extra(parser):
        parser.add_argument("mode", choices=("compile", "speed"))
        parser.add_argument("--tree", action="append", default=[],
                            help="LABEL=PATH of a varint source tree (compile; a copy: its "
                                 "numba cache files are deleted)")
        parser.add_argument("--repeats", type=int, default=3)

    args = parse_args(__doc__.splitlines()[0], argv, extra)
    if args.mode == "compile":
        compile_times(args, dict(item.split("=", 1) for item in args.tree))
    else:
        speed(args)


if __name__ == "__main__":
    main()

"""What one step body costs to compile per indicator and per process, and
what calling it (instead of inlining it into each indicator's loop) costs
per step (issue 26 item 5, issue 28).

``compile``: for each source tree given (``--tree LABEL=PATH``, copies of a
varint checkout), interleaved, ``--repeats`` times: a new interpreter with
an empty cache directory runs TDHes on Hénon–Heiles (R1) for four
indicators in turn — Lyapunov spectrum (k = 4), GALI₄ (k = 4, another
accumulator), MEGNO (k = 1), integrate with four deviation vectors — and
reports the seconds numba spent compiling for each
(:func:`varint.compiling.compile_seconds`) and the process's CPU seconds;
then a second interpreter on the same (now warm) cache directory runs the
same four: what a later process, or the other xdist worker, pays.

``speed``: for each tree, alternating processes on a warm cache, the time
per interval of TDHes on Hénon–Heiles (k = 4, τ = 0.05, t = 4000) and of
the part stepper on a disordered Klein–Gordon lattice (N = 64, k = 4,
τ = 0.1, t = 400), each the minimum over ``--repeats`` processes of the
best of three calls; the values must be the same bits in every tree.

Run: ``python studies/step_body_compile.py compile --tree after=<tree>
--tree before=<tree>`` and ``python studies/step_body_compile.py speed
--tree after=<tree> --tree before=<tree>``.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

try:
    from common import save_json
except ImportError:  # imported as studies.step_body_compile
    from .common import save_json

#: The child of ``compile``: the four indicator variants in one process.
COMPILE_CHILD = """
import json, time
import numpy as np
import varint
from varint import compiling
m, x = varint.paper_orbit("R1")
kw = dict(t_end=2.0, tau=0.05, method="tdhes", progress=False)
runs = {"lyapunov k=4": lambda: varint.lyapunov_spectrum(m, x, **kw).exponents,
        "gali k=4": lambda: varint.gali(m, x, k=4, **kw).gali[4],
        "megno k=1": lambda: varint.megno(m, x, **kw).megno,
        "integrate k=4": lambda: varint.integrate(m, x, deviations=np.eye(4), **kw).deviations}
out = {}
for name, run in runs.items():
    c0, p0 = compiling.compile_seconds(), time.process_time()
    values = run()
    out[name] = {"compile s": compiling.compile_seconds() - c0,
                 "CPU s": time.process_time() - p0,
                 "values": np.ascontiguousarray(values).tobytes().hex()}
print(json.dumps(out))
"""

#: The child of ``speed``: seconds per interval, best of three calls.
SPEED_CHILD = """
import json, time
import numpy as np
import varint
m, x = varint.paper_orbit("R1")
kg = varint.models.DisorderedKG(64, seed=1)
xk = kg.initial_block(width=8, seed=1)
cases = {
    "TDHes HH k=4": (lambda: varint.lyapunov_spectrum(m, x, t_end=4000.0, tau=0.05,
                                                      method="tdhes", progress=False), 80000),
    "parts KG N=64 k=4": (lambda: varint.lyapunov_spectrum(kg, xk, t_end=400.0, tau=0.1, n_exponents=4,
                                                           progress=False), 4000)}
out = {}
for name, (run, steps) in cases.items():
    r = run()
    best = float("inf")
    for _ in range(3):
        t0 = time.process_time()
        r = run()
        best = min(best, time.process_time() - t0)
    out[name] = {"ns/interval": best / steps * 1e9, "values": r.exponents.tobytes().hex()}
print(json.dumps(out))
"""


def child(tree, code, cache):
    env = dict(os.environ, PYTHONPATH=str(tree), VARINT_CACHE_DIR=str(cache),
               NUMBA_CACHE_DIR=str(Path(cache) / "numba"))
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                          text=True, cwd=cache)
    if done.returncode:
        raise RuntimeError(f"the child failed:\n{done.stderr[-3000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def load():
    with open("/proc/loadavg") as f:
        return float(f.read().split()[0])


def compile_times(args, trees, scratch):
    runs = {label: [] for label in trees}
    for rep in range(args.repeats):
        for label, tree in trees.items():
            cache = scratch / f"{label}-{rep}"
            cache.mkdir()
            before = load()
            first = child(tree, COMPILE_CHILD, cache)
            second = child(tree, COMPILE_CHILD, cache)
            runs[label].append({"load": [before, load()], "first process": first,
                                "second process": second})
            for name in first:
                print(f"{label:8s} {rep} {name:14s} compile s: first process "
                      f"{first[name]['compile s']:6.1f}, second {second[name]['compile s']:6.1f}"
                      f" (CPU {first[name]['CPU s']:6.1f}, {second[name]['CPU s']:6.1f})",
                      flush=True)
    values = {label: {name: sorted({r[p][name]["values"] for r in rs
                                    for p in ("first process", "second process")})
                      for name in rs[0]["first process"]} for label, rs in runs.items()}
    same = len({json.dumps(v, sort_keys=True) for v in values.values()}) == 1
    summary = {label: {name: {f"min {p} {what}": min(r[p][name][what] for r in rs)
                              for p in ("first process", "second process")
                              for what in ("compile s", "CPU s")}
                       for name in rs[0]["first process"]} for label, rs in runs.items()}
    print(json.dumps(summary, indent=1), "\nsame bits in every tree:", same)
    save_json(args.out, "step_body_compile", {"summary": summary, "same bits": same,
                                              "runs": runs, "trees": sorted(trees)})


def speed(args, trees, scratch):
    for label, tree in trees.items():        # warm each tree's cache first
        (scratch / label).mkdir()
        child(tree, SPEED_CHILD.replace("4000.0", "4.0").replace("400.0", "4.0"),
              scratch / label)
    runs = {label: [] for label in trees}
    for rep in range(args.repeats):
        for label, tree in trees.items():
            before = load()
            runs[label].append(dict(child(tree, SPEED_CHILD, scratch / label),
                                    load=[before, load()]))
            print(label, rep, {k: v["ns/interval"] for k, v in runs[label][-1].items()
                               if k != "load"}, flush=True)
    cases = [k for k in runs[next(iter(runs))][0] if k != "load"]
    best = {label: {c: min(r[c]["ns/interval"] for r in rs) for c in cases}
            for label, rs in runs.items()}
    same = all(len({r[c]["values"] for rs in runs.values() for r in rs}) == 1 for c in cases)
    labels = list(trees)
    ratios = {c: best[labels[0]][c] / best[labels[-1]][c] for c in cases}
    print(json.dumps({"min ns/interval": best, f"{labels[0]}/{labels[-1]}": ratios}, indent=1),
          "\nsame bits in every tree:", same)
    save_json(args.out, "step_body_speed", {"min ns/interval": best,
                                            f"ratio {labels[0]}/{labels[-1]}": ratios,
                                            "same bits": same, "runs": runs,
                                            "trees": labels})


def tree_study(doc, compile_times, speed, prefix, argv=None):
    """The command line of a study that races source trees in fresh
    processes (this one, ``dop853_compile.py``): ``compile`` or ``speed``,
    each ``--tree LABEL=PATH``, ``--repeats``, ``--quick``, ``--out``; the
    part runs as ``part(args, trees, scratch)`` with a scratch folder
    (``prefix``) removed afterwards."""
    parser = argparse.ArgumentParser(description=doc.split("\n\n")[0])
    parser.add_argument("what", choices=("compile", "speed"))
    parser.add_argument("--tree", action="append", required=True,
                        help="LABEL=PATH of a varint source tree (repeatable)")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--quick", action="store_true", help="one repeat")
    parser.add_argument("--out", default=str(Path(__file__).parent / "results"))
    args = parser.parse_args(argv)
    if args.quick:
        args.repeats = 1
        args.out = str(Path(args.out) / "quick")
    trees = dict(t.split("=", 1) for t in args.tree)
    Path(args.out).mkdir(parents=True, exist_ok=True)
    scratch = Path(tempfile.mkdtemp(prefix=prefix))
    try:
        (compile_times if args.what == "compile" else speed)(args, trees, scratch)
    finally:
        shutil.rmtree(scratch, ignore_errors=True)


def main(argv=None):
    tree_study(__doc__, compile_times, speed, "varint-step-body-", argv)


if __name__ == "__main__":
    main()

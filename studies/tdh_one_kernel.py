"""What one TDH kernel for the three methods costs per interval: TDHcc,
TDHes (LAPACK's and the analytic eigensolver) and TDHeps on the paper's
regular orbit R1 (Hénon–Heiles, τ = 0.05, four vectors, QR), each method
read from the setup at run time by one kernel (this tree) against a kernel
per method (the tree given by ``--base``, e.g. a worktree of the commit
before).

Each tree runs in child processes (``PYTHONPATH``), alternately, on its own
numba and varint caches (the first child of each compiles, and its CPU
seconds to the end of the first call of each method are stored as the cold
compile cost; the others load). Per child, per method: the minimum CPU time
of ``--repeats`` calls of ``--steps`` intervals; per tree the minimum over
its children; the ratio this tree / base per method. The load average at
start and end is stored.

Usage: ``python studies/tdh_one_kernel.py --base TREE [--rounds 3]
[--steps 20000] [--repeats 5] [--out DIR]`` (stored as
``tdh_one_kernel.json``).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

try:
    from common import parse_args, save_json
except ImportError:  # imported as studies.tdh_one_kernel
    from .common import parse_args, save_json

ROOT = Path(__file__).resolve().parent.parent

#: The runs timed: (label, method, options).
RUNS = (("tdhcc", "tdhcc", {}), ("tdhes", "tdhes", {}),
        ("tdhes/analytic", "tdhes", {"eigensolver": "analytic"}), ("tdheps", "tdheps", {}))

#: What a child runs: per run, the CPU seconds of its first call (compile
#: included) and the minimum over repeated calls, as JSON on stdout.
CHILD = """
import json, sys, time
import numpy as np
import varint
from varint.methods import make_propagator
from varint.state import RunState
runs, steps, repeats = json.loads(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3])
model, x0 = varint.paper_orbit("R1")
out = {}
for label, method, options in runs:
    prop = make_propagator(method, model, 0.05, "qr", **options)
    state = RunState.start(x0[None], np.eye(4)[None])
    t0 = time.process_time()
    prop.advance(state, 1)
    first = time.process_time() - t0
    best = float("inf")
    for _ in range(repeats):
        state = RunState.start(x0[None], np.eye(4)[None])
        t0 = time.process_time()
        prop.advance(state, steps)
        best = min(best, time.process_time() - t0)
    out[label] = {"first_call_s": first, "per_interval_ns": best / steps * 1e9}
print(json.dumps(out))
"""


def _extra(parser):
    parser.add_argument("--base", type=Path, required=True, help="the tree to compare with")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--steps", type=int, default=20000)
    parser.add_argument("--repeats", type=int, default=5)


def child(tree, cache, steps, repeats):
    """One child process on ``tree`` with its caches under ``cache``."""
    env = {**os.environ, "PYTHONPATH": str(tree), "NUMBA_CACHE_DIR": str(cache / "numba"),
           "VARINT_CACHE_DIR": str(cache / "varint")}
    proc = subprocess.run([sys.executable, "-c", CHILD, json.dumps(RUNS), str(steps),
                           str(repeats)], cwd=tree, env=env, capture_output=True, text=True,
                          check=True)
    return json.loads(proc.stdout.strip().splitlines()[-1])


def main(argv=None):
    args = parse_args(__doc__.splitlines()[0], argv, extra=_extra)
    load_start = os.getloadavg()
    trees = {"base": args.base.resolve(), "this": ROOT}
    caches = {name: Path(tempfile.mkdtemp(prefix=f"tdh_one_kernel_{name}_")) for name in trees}
    children = {name: [] for name in trees}
    for _ in range(args.rounds):
        for name, tree in trees.items():
            children[name].append(child(tree, caches[name], args.steps, args.repeats))
    table = {}
    for label, _, _ in RUNS:
        row = {name: {"per_interval_ns": min(c[label]["per_interval_ns"] for c in runs),
                      "cold_first_call_s": runs[0][label]["first_call_s"]}
               for name, runs in children.items()}
        row["ratio"] = row["this"]["per_interval_ns"] / row["base"]["per_interval_ns"]
        table[label] = row
        print(f"{label:16s} base {row['base']['per_interval_ns']:9.1f} ns  this "
              f"{row['this']['per_interval_ns']:9.1f} ns  ratio {row['ratio']:.3f}   cold first "
              f"call base {row['base']['cold_first_call_s']:.1f} s, this "
              f"{row['this']['cold_first_call_s']:.1f} s")
    for name in trees:
        print(f"cold CPU s to the end of every first call, {name}: "
              f"{sum(r[name]['cold_first_call_s'] for r in table.values()):.1f}")
    save_json(args.out, "tdh_one_kernel", {
        "runs": table, "children": children, "steps": args.steps, "repeats": args.repeats,
        "rounds": args.rounds, "base": str(args.base),
        "load_start": [round(x, 2) for x in load_start],
        "load_end": [round(x, 2) for x in os.getloadavg()]})


if __name__ == "__main__":
    main()

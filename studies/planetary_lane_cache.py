"""The first planetary MEGNO map of a new process, its kernels' cache cold
and warm (issue 28 item 2: every compiled kernel cached across processes;
the SIMD-lane kernels of :mod:`varint.kernels.planetary_batch`).

Each measurement is a new interpreter that imports varint and runs one
small map of Saturn's (a, e) (the grid of studies/bench_planetary.py, 2 × 4
points, which the planetary propagator steps as SIMD lanes) and reports
the wall time of ``import varint`` plus the map, the seconds numba spent
compiling (:func:`varint.compiling.compile_seconds`) and a SHA-256 of the
map's values:

* ``cold``: an empty varint cache directory and no numba cache files in the
  source tree (as a first run after installing);
* ``warm``: the cache directory and source tree the previous cold process
  left.

Trees given with ``--tree LABEL=PATH`` (copies of a varint checkout, whose
``__pycache__`` numba files a cold process deletes) are measured
interleaved, cold then warm, ``--repeats`` times; the median of each is
stored, with every run and the load. The values must be the same bits in
every process of one tree.

Run: ``python studies/planetary_lane_cache.py --tree after=<copy> [--tree before=<copy>]``.
"""

from __future__ import annotations

import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

try:
    from common import parse_args, save_json
except ImportError:  # imported as studies.planetary_lane_cache
    from .common import parse_args, save_json

#: The child: one map in a new process (the grid of bench_planetary.py's
#: Saturn, 2 × 4 points, short enough that compiling is most of its time).
CHILD = """
import hashlib, json, time, warnings
t0 = time.perf_counter()
import varint
from varint import compiling
from varint.models import Planetary
model = Planetary([1.0, 0.000954, 0.000285])
jupiter = dict(a=5.204, M=0.600, omega=0.257, e=0.048)
grid = varint.element_grid(model, [jupiter, dict(a=9.0, e=0.05, M=0.871, omega=1.616)], 2,
                           [7.0, 8.0, 9.0, 10.0], [0.05, 0.25])
with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    r = varint.chaos_map(model, grid, "megno", t_end=200.0, tau=1.0,
                         scheme=varint.get_scheme("SABA1").repeated(10), progress=False)
wall = time.perf_counter() - t0
print(json.dumps({"wall": wall, "compile": compiling.compile_seconds(),
                  "values": hashlib.sha256(r.values.tobytes()).hexdigest()}))
"""


def _clear_numba_files(tree):
    for path in Path(tree, "varint").rglob("__pycache__/*.nb[ic]"):
        path.unlink()


def run_child(tree, cache_dir):
    env = dict(os.environ, PYTHONPATH=str(tree), VARINT_CACHE_DIR=str(cache_dir),
               NUMBA_NUM_THREADS="1")
    done = subprocess.run([sys.executable, "-c", CHILD], env=env, check=True,
                          capture_output=True, text=True, cwd=tempfile.gettempdir())
    return json.loads(done.stdout.strip().splitlines()[-1])


def main(argv=None):
    def extra(parser):
        parser.add_argument("--tree", action="append", required=True,
                            help="LABEL=PATH of a varint source tree (a copy: its numba "
                                 "cache files are deleted)")
        parser.add_argument("--repeats", type=int, default=3)

    args = parse_args(__doc__.splitlines()[0], argv, extra)
    trees = dict(item.split("=", 1) for item in args.tree)
    runs = {f"{label} {state}": [] for label in trees for state in ("cold", "warm")}
    scratch = Path(tempfile.mkdtemp(prefix="varint-lane-cache-"))
    try:
        for rep in range(1 if args.quick else args.repeats):
            for label, tree in trees.items():
                cache_dir = scratch / f"{label}-{rep}"
                _clear_numba_files(tree)
                runs[f"{label} cold"].append(run_child(tree, cache_dir))
                runs[f"{label} warm"].append(run_child(tree, cache_dir))
                print(label, rep, runs[f"{label} cold"][-1], runs[f"{label} warm"][-1],
                      flush=True)
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    summary = {name: {"median wall s": statistics.median(r["wall"] for r in rs),
                      "median compile s": statistics.median(r["compile"] for r in rs),
                      "values": sorted({r["values"] for r in rs})}
               for name, rs in runs.items()}
    for label in trees:
        both = summary[f"{label} cold"]["values"] + summary[f"{label} warm"]["values"]
        summary[f"{label} bitwise cold = warm"] = len(set(both)) == 1
    print(json.dumps(summary, indent=1))
    save_json(args.out, "planetary_lane_cache", {"summary": summary, "runs": runs,
                                                 "trees": sorted(trees)})


if __name__ == "__main__":
    main()

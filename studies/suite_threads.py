"""What a parallel batch costs to compile and how fast it runs: numba's
``parallel=True`` kernels (``prange``) against the serial ``nogil`` kernel
on Python threads (:mod:`varint.threads`), on two trees side by side.

Per tree (``--tree``: a checkout; the first is the reference), in a fresh
process with fresh numba and varint caches (cold, as the suite and CI
start), numba's compile CPU seconds
(process CPU time, numba's ``numba:compile`` events, outermost only) of
four steps in turn, each run serial then parallel (the second is what a
parallel run costs on top of a serial one in the same process):

1. ``lanes``: a FLI map of 64 Hénon–Heiles orbits (blocks of SIMD lanes,
   the generated stepper's ``blocks_*``);
2. ``orbits``: a FLI run of 4 orbits (fewer than a block: one orbit at a
   time, ``batch_*``);
3. ``map``: a FLI map of 64 standard-map orbits (``batch_loop``);
4. ``sections``: a surface of section of 4 orbits (always parallel).

Then the orbits per second (wall, best of ``--repeats``) of a FLI map of
Hénon–Heiles orbits on the x = 0 section at E = 1/8 (``bench_stepper.py``'s
case 5, ``parallel=True`` so that the load does not choose one thread) on
1 and 2 threads, and whether every value is bitwise the serial run's.
Timings are wall time on a shared machine: the load at start and end is
stored.

Usage: ``python studies/suite_threads.py --tree DIR [--tree DIR] [--side N]
[--t-end T] [--repeats R] [--name SUFFIX] [--out DIR]``
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
except ImportError:  # imported as studies.suite_threads
    from .common import parse_args, save_json

#: Runs in the child: prints one JSON line.
CHILD = r"""
import json, sys, time
import numpy as np
import numba
from numba.core import event
import varint
from varint.models.maps import StandardMap


# Process CPU seconds of numba's outermost compiles (wall time would count
# the other processes of a loaded machine).
class Compiles(event.Listener):
    depth, total = 0, 0.0

    def on_start(self, ev):
        if self.depth == 0:
            self.started = time.process_time()
        self.depth += 1

    def on_end(self, ev):
        self.depth -= 1
        if self.depth == 0:
            self.total += time.process_time() - self.started


compiles = Compiles()
event.register("numba:compile", compiles)

side, t_end, repeats = int(sys.argv[1]), float(sys.argv[2]), int(sys.argv[3])
hh = varint.models.HenonHeiles()
grid8 = varint.section_grid(hh, 0.125, np.linspace(-0.3, 0.5, 8), np.linspace(-0.3, 0.3, 8))
four = grid8.states[:4]
std = StandardMap(1.2)
X = np.random.default_rng(0).uniform(0.0, 1.0, (64, 2))
steps = {
    "lanes": lambda p: varint.chaos_map(hh, grid8, "fli", t_end=10.0, progress=False,
                                        parallel=p).values,
    "orbits": lambda p: varint.megno(hh, four, 10.0, progress=False, parallel=p).fli,
    "map": lambda p: varint.chaos_map(std, X, "fli", t_end=50, progress=False,
                                      parallel=p).values,
}
out = {"compile_s": {}, "same_bits": {}}
for name, step in steps.items():
    values = []
    for parallel in (False, True):
        before = compiles.total
        values.append(np.asarray(step(parallel), dtype=float))
        out["compile_s"][f"{name} {'parallel' if parallel else 'serial'}"] = round(
            compiles.total - before, 2)
    out["same_bits"][name] = bool(np.array_equal(*values, equal_nan=True))
before = compiles.total
varint.surface_of_section(hh, four, 50.0, tau=0.05)
out["compile_s"]["sections"] = round(compiles.total - before, 2)

grid = varint.section_grid(hh, 0.125, np.linspace(-0.45, 0.65, side),
                           np.linspace(-0.45, 0.45, side))
rates, maps = {}, {}
for threads in (1, 2):
    numba.set_num_threads(threads)
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        r = varint.chaos_map(hh, grid, "fli", t_end=t_end, progress=False, parallel=True)
        best = min(best, time.perf_counter() - t0)
    maps[threads] = np.asarray(r.values, dtype=float)
    rates[threads] = round(int(np.isfinite(maps[threads]).sum()) / best, 1)
out["orbits_per_s"] = rates
out["ratio_2_to_1"] = round(rates[2] / rates[1], 3)
out["map_same_bits"] = bool(np.array_equal(maps[1], maps[2], equal_nan=True))
print(json.dumps(out))
"""


def run_tree(tree, side, t_end, repeats):
    """The child's measurements on ``tree`` (fresh caches), with the load."""
    tree = Path(tree).resolve()
    with tempfile.TemporaryDirectory(prefix="suite_threads_") as cache:
        env = {**os.environ, "PYTHONPATH": str(tree), "NUMBA_CACHE_DIR": f"{cache}/nc",
               "VARINT_CACHE_DIR": f"{cache}/vc"}
        load = [round(x, 2) for x in os.getloadavg()]
        proc = subprocess.run([sys.executable, "-c", CHILD, str(side), str(t_end),
                               str(repeats)], cwd=tree, env=env, capture_output=True,
                              text=True, check=True)
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    out["load"] = {"start": load, "end": [round(x, 2) for x in os.getloadavg()]}
    return out


def main(argv=None):
    def extra(parser):
        parser.add_argument("--tree", action="append", required=True,
                            help="a checkout to measure (repeatable; the first is the reference)")
        parser.add_argument("--side", type=int, default=30, help="map grid side (orbits: side²)")
        parser.add_argument("--t-end", type=float, default=200.0)
        parser.add_argument("--repeats", type=int, default=3)
        parser.add_argument("--name", default="", help="suffix of the stored file's name")

    args = parse_args(__doc__.splitlines()[0], argv, extra=extra)
    trees = {}
    for tree in args.tree:
        trees[tree] = run_tree(tree, args.side, args.t_end, args.repeats)
        r = trees[tree]
        print(f"{tree}: load {r['load']['start'][0]} -> {r['load']['end'][0]}")
        for step, seconds in r["compile_s"].items():
            print(f"  compile {step:18s} {seconds:7.2f} s CPU")
        print(f"  FLI map {r['orbits_per_s']['1']:.0f} orbits/s on 1 thread, "
              f"{r['orbits_per_s']['2']:.0f} on 2 ({r['ratio_2_to_1']:.2f}x); bits equal: "
              f"{r['map_same_bits']}, serial = parallel: {r['same_bits']}")
    save_json(args.out, f"suite_threads{args.name}",
              {"trees": trees, "side": args.side, "t_end": args.t_end, "repeats": args.repeats})
    return trees


if __name__ == "__main__":
    main()

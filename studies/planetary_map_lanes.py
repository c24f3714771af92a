"""The MEGNO map of the planetary race with its points stepped as SIMD
lanes (the default) against one orbit at a time (``lanes=False``): what
the lanes change in a whole map — the end of every interval, early
stopping and refilled lanes included (issue 30).

The system, grid, step and verdict are studies/bench_planetary.py's (the
Sun, Jupiter and a Saturn-mass planet on (a, e) ∈ [7, 10] × [0, 0.5], the
WH map ten steps of dt = 1 per interval, MEGNO, escape beyond |q| = 20),
with early stopping (Ȳ > 4 at a check time) and without. One numba
thread, CPU time of this process, minimum of interleaved repeats
(:func:`common.interleaved`); both maps are checked bit for bit alike; the
load is recorded.

Run: ``python studies/planetary_map_lanes.py [--quick] [--grid 16]
[--periods 200]``.
"""

from __future__ import annotations

import math
import os
import sys
import time

import numba
import numpy as np

from varint.kernels.planetary_batch import LANES
from varint.models import Planetary

try:
    from bench_planetary import DT, MASSES, SUBSTEPS, THRESHOLD, grid, varint_map
    from common import interleaved, parse_args, save_json
except ImportError:  # imported as studies.planetary_map_lanes
    from .bench_planetary import DT, MASSES, SUBSTEPS, THRESHOLD, grid, varint_map
    from .common import interleaved, parse_args, save_json

#: Jupiter's period (a = 5.204, G = 1, solar masses), the horizon's unit.
INNER_PERIOD = 2 * math.pi * 5.204 ** 1.5


def main(argv=None):
    def extra(parser):
        parser.add_argument("--grid", type=int, default=16, metavar="N",
                            help="an N × N grid (default 16: 256 points)")
        parser.add_argument("--periods", type=float, default=200.0, metavar="P",
                            help="the horizon in orbits of the inner planet (default 200)")

    args = parse_args(__doc__.split("\n\n")[0], argv, extra)
    n_grid, periods, repeats = (4, 5.0, 1) if args.quick else (args.grid, args.periods, 3)
    numba.set_num_threads(1)
    model = Planetary(MASSES)
    X = grid(model, n_grid).states
    t_end = periods * INNER_PERIOD
    tasks = {}
    for stopping in (True, False):
        for lanes in (True, False):
            label = (f"{'lanes' if lanes else 'one orbit at a time'}, "
                     f"{'early stopping' if stopping else 'no early stopping'}")
            tasks[label] = (lambda lanes=lanes, stopping=stopping: varint_map(
                model, X, t_end, THRESHOLD if stopping else None, lanes=lanes))
    load_start = os.getloadavg()[0]
    for lanes in (True, False):                             # compile
        varint_map(model, X[:LANES], 20 * DT * SUBSTEPS, THRESHOLD, lanes=lanes)
    best, out = interleaved(tasks, repeats, clock=time.process_time)
    load_end = os.getloadavg()[0]
    labels = list(tasks)
    bitwise = {kind: all(np.array_equal(a, b, equal_nan=True) for a, b in
                         zip(out[f"lanes, {kind}"], out[f"one orbit at a time, {kind}"],
                             strict=True))
               for kind in ("early stopping", "no early stopping")}
    speedup = {kind: best[f"one orbit at a time, {kind}"] / best[f"lanes, {kind}"]
               for kind in ("early stopping", "no early stopping")}
    print(f"MEGNO map, {len(X)} points, {periods:g} inner orbits (t = {t_end:.4g}), one thread; "
          f"load {load_start:.1f} → {load_end:.1f}")
    for label in labels:
        print(f"  {label:40} {best[label]:8.2f} s CPU")
    for kind, s in speedup.items():
        print(f"  {kind}: lanes {s:.2f}× one orbit at a time; bitwise equal: {bitwise[kind]}")
    result = {"cpu_seconds": best, "lanes_speedup": speedup, "bitwise_equal": bitwise,
              "grid_points": len(X), "inner_periods": periods, "t_end": t_end, "dt": DT,
              "substeps": SUBSTEPS, "threshold": THRESHOLD, "lanes": LANES, "repeats": repeats,
              "threads": 1, "load_average": [load_start, load_end], "cores": os.cpu_count()}
    save_json(args.out, "planetary_map_lanes", result,
              times="measured: CPU time of this process (one numba thread), min of "
                    "interleaved repeats")
    return result


if __name__ == "__main__":
    main()
    sys.exit(0)

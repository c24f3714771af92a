"""The race of issue 30: a MEGNO stability map of a two-planet system on
≥ 1000 grid points, varint against REBOUND WHFast + variational particles
driven as its users drive a grid — one ``Simulation`` per point,
``init_megno()``, a ``multiprocessing`` pool over the points — with the
classification of both checked against a tight reference.

The system, grid, step and verdict are studies/bench_planetary.py's (the
Sun, Jupiter and a Saturn-mass planet on (a, e) ∈ [7, 10] × [0, 0.5],
Jacobi coordinates, dt = 1 = Jupiter's period / 75, MEGNO Ȳ > 4 or a
failure is chaotic, an escape beyond |q| = 20 ends an orbit as unstable).
The horizon is counted in orbits of the inner planet (Jupiter, period
2π·5.204^1.5 ≈ 74.6), or with ``--outer`` in orbits of the outer planet at
the grid's middle (a = 8.5, period 2π·8.5^1.5 ≈ 155.7), the unit of the
issue's target (1e4 orbits of the outer planet).

* varint: ``chaos_map(..., "megno")``, the WH map ten steps per
  renormalisation interval, on ``--workers`` numba threads, its grid
  points stepped as SIMD lanes (:mod:`varint.kernels.planetary_batch`);
  with early stopping (Ȳ > 4 at a check time) and without.
* REBOUND 5: ``integrator = "whfast"``, ``dt = 1``, ``init_megno(seed)``,
  ``exit_max_distance = 20``, ``integrate(t_end, exact_finish_time=0)``,
  ``megno()``, one simulation per point in a ``multiprocessing.Pool`` of
  ``--workers`` processes (each returns its point's CPU time). WHFast runs
  in its default safe mode: REBOUND refuses MEGNO with ``safe_mode = 0``
  ("MEGNO is not compatible with WHFast's safe_mode=0", REBOUND 5.2.2).
* The reference: heyoka's Taylor integrator at tolerance 1e-15 on the same
  model and MEGNO code, on a seeded random sample of the grid.

The grid runs in blocks of 128 points, the contenders taking turns and
alternating which goes first in each block. The figure of merit is CPU
time per thread: the CPU time of all of varint's threads (this process),
against the sum of the CPU times of REBOUND's simulations in its workers
(so that neither a loaded machine nor the pool's start-up enters it); the
wall time of each is stored beside it, with the load average. The whole
grid runs once (its cost): the ratio is that of sums over the blocks, and
the spread of the per-block ratios is stored.

Run: ``python studies/race_planetary.py [--quick] [--grid 32]
[--periods 1e4] [--outer] [--sample 32] [--workers 2]``.
"""

from __future__ import annotations

import math
import multiprocessing
import os
import sys
import time

import numba
import numpy as np

import varint
from varint.kernels.planetary_batch import LANES
from varint.models import Planetary

try:
    from bench_planetary import DT, MASSES, OUTER_PERIOD, SUBSTEPS, THRESHOLD, agreement, \
        chaotic, grid, rebound_megno, varint_map
    from common import Claims, parse_args, save_json
except ImportError:  # imported as studies.race_planetary
    from .bench_planetary import DT, MASSES, OUTER_PERIOD, SUBSTEPS, THRESHOLD, agreement, \
        chaotic, grid, rebound_megno, varint_map
    from .common import Claims, parse_args, save_json

#: Jupiter's period (a = 5.204, G = 1, solar masses).
INNER_PERIOD = 2 * math.pi * 5.204 ** 1.5
BLOCK = 128
_MODEL = None


def _timed_point(task):
    """One grid point in a worker: (Ȳ, CPU seconds)."""
    global _MODEL
    if _MODEL is None:
        _MODEL = Planetary(MASSES)
    x0, t_end, seed = task
    t0 = time.process_time()
    value = rebound_megno(_MODEL, x0, t_end, seed)
    return value, time.process_time() - t0


def race(model, X, t_end, pool):
    """The grid in blocks, the three contenders taking turns (module
    docstring); returns values, statuses, CPU and wall seconds per block."""
    names = ("varint", "varint, no early stopping", "REBOUND")
    values = {k: [] for k in names}
    status = {k: [] for k in names[:2]}
    cpu = {k: [] for k in names}
    wall = {k: [] for k in names}
    for b, start in enumerate(range(0, len(X), BLOCK)):
        block = X[start:start + BLOCK]
        order = names if b % 2 == 0 else names[::-1]
        for name in order:
            w0, c0 = time.perf_counter(), time.process_time()
            if name == "REBOUND":
                out = pool.map(_timed_point, [(x, t_end, start + i) for i, x in
                                              enumerate(block)], chunksize=4)
                values[name].append(np.array([v for v, _ in out]))
                cpu[name].append(sum(s for _, s in out))
            else:
                v, st, _ = varint_map(model, block, t_end,
                                      THRESHOLD if name == "varint" else None)
                values[name].append(v)
                status[name].append(st)
                cpu[name].append(time.process_time() - c0)
            wall[name].append(time.perf_counter() - w0)
    return ({k: np.concatenate(v) for k, v in values.items()},
            {k: np.concatenate(v) for k, v in status.items()},
            {k: np.array(v) for k, v in cpu.items()}, {k: np.array(v) for k, v in wall.items()})


def main(argv=None):
    def extra(parser):
        parser.add_argument("--grid", type=int, default=32, metavar="N",
                            help="an N × N grid (default 32: 1024 points)")
        parser.add_argument("--periods", type=float, default=1e4, metavar="P",
                            help="the horizon in orbits of the inner planet (default 1e4)")
        parser.add_argument("--outer", action="store_true",
                            help="count --periods in orbits of the outer planet at a = 8.5")
        parser.add_argument("--sample", type=int, default=32, metavar="N",
                            help="grid points checked against the reference (default 32)")
        parser.add_argument("--workers", type=int, default=2, metavar="W",
                            help="REBOUND's processes and varint's threads (default 2)")

    args = parse_args(__doc__.split("\n\n")[0], argv, extra)
    n_grid, periods, n_sample = (4, 20.0, 4) if args.quick else (args.grid, args.periods,
                                                                 args.sample)
    n_sample = min(n_sample, n_grid * n_grid)
    unit = "outer" if args.outer and not args.quick else "inner"
    t_end = periods * (OUTER_PERIOD if unit == "outer" else INNER_PERIOD)
    numba.set_num_threads(min(args.workers, numba.config.NUMBA_NUM_THREADS))
    model = Planetary(MASSES)
    g = grid(model, n_grid)
    X = g.states
    load_start = os.getloadavg()[0]
    # The workers are forked before numba starts its threads.
    with multiprocessing.get_context("fork").Pool(args.workers) as pool:
        t0 = time.perf_counter()
        # Compile once per process (the lanes too: a block's worth of points).
        varint_map(model, X[:LANES], 20 * DT * SUBSTEPS, THRESHOLD)
        varint_map(model, X[:LANES], 20 * DT * SUBSTEPS, None)
        compile_seconds = time.perf_counter() - t0
        values, status, cpu, wall = race(model, X, t_end, pool)
    sample = np.sort(np.random.default_rng(2026).choice(len(X), n_sample, replace=False))
    t0 = time.perf_counter()
    ref_values, ref_status, _ = varint_map(model, X[sample], t_end, None, method="taylor",
                                           tol=1e-15)
    ref_seconds = time.perf_counter() - t0
    load_end = os.getloadavg()[0]
    reference = chaotic(ref_values, ref_status)
    verdict = {k: chaotic(v, status.get(k)) for k, v in values.items()}
    rows = []
    for name in values:
        per_block = cpu[name] / cpu["varint"]
        rows.append({"code": name, "grid_points": len(X), "cpu_seconds": float(cpu[name].sum()),
                     "wall_seconds": float(wall[name].sum()),
                     "cpu_ms_per_point": 1e3 * float(cpu[name].sum()) / len(X),
                     "time_over_varint": float(cpu[name].sum() / cpu["varint"].sum()),
                     "time_over_varint_per_block": [float(per_block.min()),
                                                    float(per_block.max())],
                     "wall_over_varint": float(wall[name].sum() / wall["varint"].sum()),
                     "agreement_with_reference": agreement(verdict[name][sample], reference),
                     "agreement_with_rebound": agreement(verdict[name], verdict["REBOUND"]),
                     "chaotic_fraction": float(verdict[name].mean())})
    speed = rows[2]["time_over_varint"]
    plain = rows[2]["cpu_seconds"] / rows[1]["cpu_seconds"]
    print(f"MEGNO map race, {n_grid}×{n_grid} grid, {periods:g} {unit} orbits (t = {t_end:.4g}), "
          f"dt = {DT}, {args.workers} workers; load {load_start:.1f} → {load_end:.1f}; "
          f"compile {compile_seconds:.0f} s")
    for row in rows:
        print(f"  {row['code']:28} {row['cpu_seconds']:8.1f} s CPU ({row['wall_seconds']:.1f} s "
              f"wall)  {row['time_over_varint']:.2f}× varint's  agreement with the reference "
              f"{row['agreement_with_reference']:.1%}, with REBOUND "
              f"{row['agreement_with_rebound']:.1%}")
    print(f"  reference (heyoka, tol 1e-15) on {n_sample} points: {ref_seconds:.0f} s wall")
    result = {"grid": n_grid, "grid_points": len(X), "periods": periods, "periods_of": unit,
              "inner_periods": t_end / INNER_PERIOD, "t_end": t_end,
              "dt": DT, "substeps": SUBSTEPS, "threshold": THRESHOLD, "workers": args.workers,
              "sample": int(n_sample), "rows": rows, "reference_seconds": ref_seconds,
              "reference_chaotic_fraction": float(reference.mean()),
              "compile_seconds": compile_seconds, "load_average": [load_start, load_end],
              "cores": os.cpu_count(), "rebound_safe_mode": 1,
              "versions": varint.results.package_versions("rebound", "heyoka"),
              "rebound_over_varint": speed, "rebound_over_varint_no_early_stopping": plain}
    save_json(args.out, "race_planetary", result,
              times="measured: CPU seconds (varint: this process, all threads; REBOUND: the sum "
                    "of each simulation's CPU time in its worker) and wall seconds, summed over "
                    "blocks; one pass over the grid")
    np.savez(args.out / "race_planetary_map.npz", a=g.u, e=g.v, sample=sample,
             reference=ref_values, **{k.replace(" ", "_").replace(",", ""): v
                                      for k, v in values.items()})
    agree = {row["code"]: row["agreement_with_reference"] for row in rows}
    claims = Claims("race_planetary", args.out, source="own")
    claims.add(f"MEGNO map of a two-planet system ({len(X)} grid points, {periods:g} orbits of "
               f"the {unit} planet), varint against REBOUND WHFast + variational particles "
               f"({args.workers} processes) per thread, at least REBOUND's classification "
               "agreement with a tight reference: ≥ 3×", "≥ 3× (issue target)",
               f"{speed:.1f}× with early stopping ({plain:.1f}× without); agreement with heyoka "
               f"(tol 1e-15) on {n_sample} points: varint {agree['varint']:.1%}, REBOUND "
               f"{agree['REBOUND']:.1%}",
               None if args.quick else bool(speed >= 3 and agree["varint"] >= agree["REBOUND"]),
               note=f"CPU time per thread; load average {load_start:.1f} → {load_end:.1f} on "
                    f"{os.cpu_count()} shared cores; REBOUND in safe mode (it refuses MEGNO "
                    "with safe_mode = 0); one pass over the grid"
                    + ("" if periods >= 1e4 else f"; scaled: {periods:g} {unit} orbits, not 1e4"))
    claims.save()
    result["claims"] = claims.items
    return result


if __name__ == "__main__":
    main()
    sys.exit(0)

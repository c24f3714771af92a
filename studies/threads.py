"""Threads that never hurt: chaos maps of the Hénon–Heiles section on one
thread and on two, by default and forced.

For the FLI, SALI and MEGNO maps of the x = 0 section at E = 1/8 (a
``side`` × ``side`` grid, t = ``t_end``), wall seconds of three contenders
taken in turn (:func:`studies.common.interleaved`, the minimum of
repeats): numba on one thread; numba on two with varint's default choice
(:func:`varint.threads.parallel_by_default`: parallel only when a core is
free of the other processes' load); numba on two with ``parallel=True``
(the default before that rule). The ratios are one thread's time over the
others' (≥ 1: the two threads did not hurt). The load average and the
free cores the rule read are stored with the figures: on a busy machine
the default stays on one thread, on an idle one it takes both.

Usage: ``python studies/threads.py [--quick] [--out DIR]``
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numba
import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import varint  # noqa: E402
from studies.common import interleaved, parse_args, save_json  # noqa: E402
from varint import threads  # noqa: E402

INDICATORS = ("fli", "sali", "megno")


def map_task(model, grid, indicator, t_end, n_threads, parallel):
    """A chaos map on ``n_threads`` numba threads (``parallel`` as given;
    None: varint's default); returns the number of finite values."""

    def task():
        before = numba.get_num_threads()
        numba.set_num_threads(n_threads)
        try:
            r = varint.chaos_map(model, grid, indicator, t_end=t_end, tau=0.05,
                                 parallel=parallel, progress=False)
        finally:
            numba.set_num_threads(before)
        return int(np.isfinite(np.asarray(r.values, dtype=float)).sum())

    return task


def main(argv=None):
    args = parse_args(__doc__.splitlines()[0], argv)
    side, t_end, repeats = (8, 20.0, 1) if args.quick else (45, 1e3, 3)
    model = varint.models.HenonHeiles()
    grid = varint.section_grid(model, 0.125, np.linspace(-0.45, 0.65, side),
                               np.linspace(-0.45, 0.45, side))
    two = min(2, numba.config.NUMBA_NUM_THREADS)
    rows = []
    for ind in INDICATORS:
        tasks = {"1 thread": map_task(model, grid, ind, t_end, 1, None),
                 "2 threads, default": map_task(model, grid, ind, t_end, two, None),
                 "2 threads, parallel=True": map_task(model, grid, ind, t_end, two, True)}
        for task in tasks.values():
            task()                       # compile (or load the cached kernels)
        load = os.getloadavg()[0]
        free = threads.free_cores()
        best, out = interleaved(tasks, repeats)
        one = best["1 thread"]
        row = {"indicator": ind, "orbits": out["1 thread"], "t_end": t_end,
               "load_before": load, "load_after": os.getloadavg()[0], "free_cores": free,
               "default_parallel": threads.parallel_by_default(len(grid)),
               **{f"{k} s": v for k, v in best.items()},
               "default_over_1": one / best["2 threads, default"],
               "forced_over_1": one / best["2 threads, parallel=True"]}
        rows.append(row)
        print(f"{ind.upper():6s} {row['orbits']} orbits, load {load:.1f}, free cores "
              f"{free:.2f}: 1 thread {one:.3f} s; 2 threads default "
              f"{row['default_over_1']:.2f}x (parallel: {row['default_parallel']}), "
              f"forced {row['forced_over_1']:.2f}x", flush=True)
    save_json(args.out, "threads", {"rows": rows, "side": side, "repeats": repeats,
                                    "cpus": len(os.sched_getaffinity(0))})
    return rows


if __name__ == "__main__":
    main()

"""The LH lanes' pool on the cored map (issue 27, lh21): how many of the
lanes' passes run an orbit, with and without the pool shrinking to its live
lanes once no orbit waits (:mod:`varint.codegen.lh_lanes`, "Pool").

The map's orbits (``studies/ladder_rule.py``'s ``case``: the quick race
maps of ``studies/map_steps.py``; ``core`` by default) are run as the
defaults' map runs them: the δ and h the defaults chose (one
``chaos_map(model, X, "fli", t_end=...)``), the map's chunk order and
vectors, over lanes (:meth:`varint.time_transform.LogHamiltonian.outputs`).
From each orbit's LH steps, the lanes' passes: a pool of
:data:`~varint.codegen.lh_lanes.LANE_WIDTH` lanes fed in order (a lane
takes the next orbit when its own ends) runs ``passes × width`` lane steps
without shrinking, and only the orbits' own steps with it. Counts, the same
on any machine and load; the kernel's CPU seconds on this tree (min of
``--repeats``, one thread) are for reading with the load (recorded).

Stored run (``studies/results/lh21/lh_pool.json``, lh21, 3 repeats, load
15.4 → 17.2): the cored map (defaults δ = 0.25, h = 0.0247), 120 orbits of
60 280–60 477 LH steps each: a fixed pool of 16 lanes makes 482 838 passes,
7 725 408 lane steps for 7 243 284 orbit steps, 6.2 % of them idle (the
last 8 orbits in a pool of 16); the shrinking pool runs the orbits' own
steps only. The map's values from this run equal the defaults' map's.
The same study run alternately in a worktree of 3556484 (fixed pool) and
this tree (``lh_pool_base_{1,2}.json``, ``lh_pool_this_{1,2}.json``, 4
repeats each, load 18.2 → 18.5): the map's kernel 713.2, 673.6 ms CPU
before, 631.5, 640.2 ms after; min against min 1.07×, as the idle share
predicts (read at this load as a ratio, not as seconds).

Usage: ``python studies/lh_pool.py [--maps core] [--repeats 3]``; result
``lh_pool.json``.
"""

from __future__ import annotations

import os
import sys
import time
import warnings
from pathlib import Path

import numba
import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import varint
from studies.common import parse_args, save_json
from studies.ladder_rule import case
from varint import maps
from varint.codegen.lh_lanes import LANE_WIDTH
from varint.state import initial_deviations


def passes(steps, width=LANE_WIDTH):
    """The passes of a pool of ``width`` lanes over orbits of ``steps`` LH
    steps each, fed in order: each lane takes the next orbit when its own
    ends; the run lasts until its last lane's orbits end."""
    lanes = np.zeros(min(width, len(steps)), dtype=np.int64)
    for s in steps:
        lanes[int(np.argmin(lanes))] += int(s)
    return int(lanes.max())


def measure(name, repeats):
    """One map's pool counts and kernel seconds."""
    model, X, t_end = case(name)
    numba.set_num_threads(1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = varint.chaos_map(model, X, "fli", t_end=t_end, progress=False)
        choice = out.provenance.tau_choice
        if out.provenance.method != "tm+log":
            return {"map": name, "method": out.provenance.method}
        h = float(choice["h"])
        lh = maps._log_hamiltonian(model, maps.LOG_MAP_OPTIONS["scheme"], None).with_offset(
            choice.get("offset"))
        order = np.random.default_rng(20100927).permutation(len(X))
        W0 = initial_deviations(model.dim, 1, len(X), 0, order)[:, :, 0]
        seconds = []
        for _ in range(repeats):
            start = time.process_time()
            run = lh.outputs(X[order], W0, t_end, h, every=maps.LOG_MAP_OPTIONS["every"])
            seconds.append(time.process_time() - start)
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    steps = run.counts[:, 0]
    n = passes(steps)
    width = min(LANE_WIDTH, len(X))
    row = {"map": name, "orbits": len(X), "t_end": t_end, "h": h, "offset": choice.get("offset"),
           "lane_width": LANE_WIDTH, "steps": int(steps.sum()),
           "steps_per_orbit": [int(steps.min()), float(steps.mean()), int(steps.max())],
           "passes": n, "lane_steps_fixed_pool": n * width,
           "idle_share_fixed_pool": 1.0 - float(steps.sum()) / (n * width),
           "kernel_cpu_seconds": min(seconds),
           "map_values_same": bool(np.array_equal(run.fli, out.values[order], equal_nan=True))}
    print(f"{name}: {len(X)} orbits, LH steps per orbit {steps.min()}–{steps.max()} (mean "
          f"{steps.mean():.0f}); a fixed pool of {width} lanes: {n} passes, "
          f"{n * width} lane steps for {steps.sum()} orbit steps "
          f"({100 * row['idle_share_fixed_pool']:.1f} % idle); kernel "
          f"{1e3 * row['kernel_cpu_seconds']:.1f} ms CPU here; the map's values "
          f"{'the same' if row['map_values_same'] else 'DIFFERENT'}", flush=True)
    return row


def main(argv=None):
    def extra(parser):
        parser.add_argument("--maps", default="core")
        parser.add_argument("--repeats", type=int, default=3)

    args = parse_args(__doc__.split("\n\n")[0], argv, extra)
    result = {"load": list(os.getloadavg()), "repeats": args.repeats,
              "maps": [measure(name, args.repeats) for name in args.maps.split(",") if name]}
    result["load_end"] = list(os.getloadavg())
    save_json(args.out, "lh_pool", result)
    return result


if __name__ == "__main__":
    main()

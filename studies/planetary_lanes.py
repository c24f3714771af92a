"""Planetary flows over SIMD lanes against one orbit at a time: the WH map
(ten steps per interval) with one deviation vector on a block of grid
points, per point and step of dt (issue 30: lanes over grid points).

The block is the 8 × 8 grid of studies/bench_planetary.py (Saturn's
(a, e) ∈ [7, 10] × [0, 0.5]). Contenders, both without renormalisation or
indicator (the flows alone, what the lanes change):

* ``one orbit at a time``: the part stepper's batch kernel
  (:func:`varint.kernels.parts.parts_batch`, one thread), the orbits one
  after the other, each step through the generated one-orbit flows;
* ``lanes``: :func:`varint.kernels.planetary_lanes.lane_steps`, the block
  as one structure of arrays, every flow one loop over the lanes.

Both end bit for bit alike (checked here on the timed runs, and by
tests/test_planetary_lanes.py). CPU time of this process, minimum of
interleaved repeats (:func:`common.interleaved`); the load is recorded.

Run: ``python studies/planetary_lanes.py [--quick]``.
"""

from __future__ import annotations

import os
import sys
import time

import numba
import numpy as np

import varint
from varint.kernels import parts as K
from varint.kernels.interval import Call
from varint.kernels.planetary_lanes import lane_steps
from varint.methods.parts import _tables
from varint.models import Planetary
from varint.protocol import Renorm

try:
    from bench_planetary import DT, MASSES, SUBSTEPS, grid
    from common import interleaved, parse_args, save_json
except ImportError:  # imported as studies.planetary_lanes
    from .bench_planetary import DT, MASSES, SUBSTEPS, grid
    from .common import interleaved, parse_args, save_json


def one_at_a_time(model, X, W, parts, h, par, n_work, n_steps):
    """``n_steps`` steps of every orbit of X (M, 2N) and W (M, 2N, k) by
    the part stepper's batch kernel, one thread, no renormalisation."""
    m, k = len(X), W.shape[2]
    kernel = K.parts_batch(model.parts.apply, model.parts.field, k, False)
    status = np.zeros(m, dtype=np.int64)
    done = np.zeros(m, dtype=np.int64)
    record = K.PartsOrbit(X, W, np.ones((m, k)), np.zeros((m, k), dtype=np.int64),
                          np.empty((m, 0, 0)), np.zeros((m, len(model.parts.names)),
                                                        dtype=np.int64))
    kernel(record, K.PartsSetup(parts, h, par, n_work),
           Call(int(n_steps), 0, DT * SUBSTEPS, int(Renorm.NONE), np.inf), status, done)
    return X, W


def main(argv=None):
    args = parse_args(__doc__.split("\n\n")[0], argv)
    n_steps, repeats = (20, 2) if args.quick else (500, 5)
    numba.set_num_threads(1)
    model = Planetary(MASSES)
    X0 = grid(model, 8).states
    W0 = np.random.default_rng(30).standard_normal((len(X0), model.dim, 1))
    scheme = varint.get_scheme("SABA1").repeated(SUBSTEPS)
    parts, h, par, n_work = _tables(model, scheme, DT * SUBSTEPS)
    steps = lane_steps(model.n_planets, True, 1, model.parts.apply, len(X0))
    alone = []

    def lanes():
        Xl = np.ascontiguousarray(X0.T)
        Vl = np.ascontiguousarray(W0.transpose(2, 1, 0))
        alone.append(steps(Xl, Vl, parts, h, par, n_work, n_steps))
        return Xl.T, Vl.transpose(2, 1, 0)

    def orbits():
        return one_at_a_time(model, X0.copy(), W0.copy(), parts, h, par, n_work, n_steps)

    tasks = {"one orbit at a time": orbits, "lanes": lanes}
    load_start = os.getloadavg()[0]
    for task in tasks.values():
        task()                                       # compile
    best, out = interleaved(tasks, repeats, clock=time.process_time)
    load_end = os.getloadavg()[0]
    bitwise = all(np.array_equal(a, b) for a, b in zip(out["lanes"], out["one orbit at a time"],
                                                       strict=True))
    per_step = {k: 1e9 * v / (len(X0) * n_steps * SUBSTEPS) for k, v in best.items()}
    speedup = best["one orbit at a time"] / best["lanes"]
    print(f"WH x{SUBSTEPS}, k = 1, {len(X0)} points, {n_steps} intervals; load "
          f"{load_start:.1f} → {load_end:.1f}")
    for k, v in per_step.items():
        print(f"  {k:22} {v:7.1f} CPU ns per point and step of dt")
    print(f"  lanes {speedup:.2f}× one orbit at a time; bitwise equal: {bitwise}; drifts stepped "
          f"alone per call: {alone[-1]}")
    result = {"ns_per_point_step": per_step, "lanes_speedup": speedup, "bitwise_equal": bitwise,
              "drifts_alone_per_call": int(alone[-1]), "points": len(X0), "intervals": n_steps,
              "substeps": SUBSTEPS, "dt": DT, "repeats": repeats,
              "load_average": [load_start, load_end], "cores": os.cpu_count(),
              "numba_cpu": numba.config.CPU_NAME or "host"}
    save_json(args.out, "planetary_lanes", result,
              times="measured: CPU time of this process, min of interleaved repeats")
    return result


if __name__ == "__main__":
    main()
    sys.exit(0)

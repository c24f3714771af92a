"""What calling the planetary Kepler drift costs the part stepper: the
one-orbit part stepper of a two-planet system (Jacobi coordinates, the WH
map) with the model's flows ``apply`` — whose drift is called
(:func:`varint.kernels.nbody_unrolled.drift_kernel`: compiled once per
process and number of vectors, not into every stepper configuration) —
against the same ``apply`` with the drift inlined (numba's
``inline="always"``, as it was built before).

For one deviation vector (normalised every interval), the CPU time of a
step of each (the minimum of interleaved repeats; the load average before
and after is stored), their ratio, and whether the two end bit for bit in
the same state and vectors (they must: the same operations in the same
order, only called). The cold compile CPU seconds of each stepper are
stored beside them (the inlined one first, so its nested compiles, e.g.
the Kepler solver's fallback, are counted there and not in the other's).

Usage: ``python studies/planetary_parts_call.py [--quick] [--out DIR]``.
"""

from __future__ import annotations

import os
import time
import types

import numba
import numpy as np

from varint.kernels import parts as K
from varint.kernels.nbody_unrolled import drift_kernel
from varint.kernels.interval import Call
from varint.methods.parts import _tables
from varint.models import Planetary
from varint.protocol import Renorm
from varint.schemes import get_scheme

try:
    from common import parse_args, save_json
except ImportError:  # imported as studies.planetary_parts_call
    from .common import parse_args, save_json


def stepper(model, apply, k):
    """A call ``run(x, W, n)`` of the one-orbit part stepper with flows
    ``apply``: n intervals of the WH map (τ = 0.05) from copies of x, W;
    returns the end state, vectors and the CPU seconds of the call."""
    kinds, h, par, n_work = _tables(model, get_scheme("SABA1"), 0.05)
    kernel = K.parts_batch(apply, model.parts.field, k, False)
    setup = K.PartsSetup(kinds, h, par, n_work)

    def run(x, W, n):
        X, Ws = x[None].copy(), np.ascontiguousarray(W[None].copy())
        record = K.PartsOrbit(X, Ws, np.ones((1, k)), np.zeros((1, k), dtype=np.int64),
                              np.empty((1, 0, 0)),
                              np.zeros((1, len(model.parts.names)), dtype=np.int64))
        status, done = np.zeros(1, dtype=np.int64), np.zeros(1, dtype=np.int64)
        t0 = time.process_time()
        kernel(record, setup, Call(int(n), 0, 0.05, int(Renorm.NORMALIZE), np.inf), status, done)
        return X[0], Ws[0], time.process_time() - t0

    return run


def drift_inlined(apply, n):
    """``apply`` (a numba function of :func:`varint.kernels.nbody_unrolled.flows`)
    rebuilt with its drift inlined: the same Python function, its closure's
    drift replaced by one compiled with ``inline="always"``."""
    func = apply.py_func
    drift = drift_kernel(n)
    inline = numba.njit(error_model="numpy", inline="always")(drift.py_func)
    cells = tuple(types.CellType(inline if c.cell_contents is drift else c.cell_contents)
                  for c in func.__closure__)
    rebuilt = types.FunctionType(func.__code__, func.__globals__, func.__name__,
                                 func.__defaults__, cells)
    return numba.njit(error_model="numpy", inline="always")(rebuilt)


def main(argv=None):
    args = parse_args(__doc__.splitlines()[0], argv)
    load = [os.getloadavg()[0]]
    model = Planetary([1.0, 1e-3, 3e-4])
    x0 = model.from_elements([dict(a=1.0, e=0.05), dict(a=1.6, e=0.1, M=2.0, inc=0.1)])
    called = model.parts.apply
    inlined = drift_inlined(called, model.n_planets)
    n, repeats = (20_000, 3) if args.quick else (200_000, 7)
    rows = {}
    for k in (1,):
        W = np.eye(12)[:, :k].copy()
        runs, compile_s = {}, {}
        for name, apply in (("inlined", inlined), ("called", called)):
            runs[name] = stepper(model, apply, k)
            t0 = time.process_time()
            runs[name](x0, W, 1)
            compile_s[name] = round(time.process_time() - t0, 1)
        best = {name: np.inf for name in runs}
        ends = {}
        for _ in range(repeats):
            for name, run in runs.items():
                x, Wn, seconds = run(x0, W, n)
                best[name] = min(best[name], seconds)
                ends[name] = x.tobytes() + Wn.tobytes()
        rows[f"k={k}"] = {
            "ns_per_step": {name: round(1e9 * s / n, 1) for name, s in best.items()},
            "called_over_inlined": round(best["called"] / best["inlined"], 3),
            "bitwise_equal": ends["called"] == ends["inlined"],
            "compile_cpu_s": compile_s}
        print(f"k={k}: {rows[f'k={k}']}", flush=True)
    load.append(os.getloadavg()[0])
    save_json(args.out, "planetary_parts_call", {"steps": n, "repeats": repeats, "rows": rows,
                                              "load": load})


if __name__ == "__main__":
    main()

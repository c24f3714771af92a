"""The GPU call as it was before the state stayed on the device (main
93ccc3a), for ``studies/bench_gpu.py``'s before/after ratio in one run on
one machine: every call packs the active orbits into new arrays, copies
them to newly allocated device arrays from pageable memory, and back.

Used only by the benchmark, which puts :func:`advance_cuda` in the place of
``varint.gpu.advance.advance_cuda`` for its ``gpu_before`` contender (the
TM propagator looks the name up at each GPU call). The kernel is the same;
the results are the same bits (the benchmark compares them).
"""

from __future__ import annotations

import time

import numpy as np

from varint.gpu.advance import STATS, _put
from varint.gpu.emit import cuda_stepper
from varint.protocol import COUNTERS
from varint.schemes import DRIFT


def _soa(a, rows):
    """(M, ...) -> (..., len(rows)), contiguous: the orbit index innermost."""
    view = np.moveaxis(a, 0, -1)
    return np.ascontiguousarray(view if rows is None else view[..., rows])


def advance_cuda(prop, module, state, n, snaps, active):
    """Advance the ``active`` orbits of ``state`` by ``n`` steps on the GPU
    (as ``varint.gpu.advance.advance_cuda`` did at main 93ccc3a)."""
    from numba import cuda

    t0 = time.perf_counter()
    m, d, k = state.W.shape
    a = len(active)
    kinds = prop._kinds
    kernel = cuda_stepper(prop.model, kinds, (prop._hc != 0.0) & (kinds != DRIFT), k,
                          prop.accumulator)
    sched = prop._schedule(state)
    # All rows (no orbit decided or failed yet): views, no gathering.
    rows = None if a == m else active
    extra_start = {key: arr[active] for key, arr in state.extra.items()}
    aux = prop._accumulator(state)
    # Arrays the kernel does not touch (no accumulator columns, no output
    # steps: the sentinel −1 lies before every call) get one element, not
    # none: a zero-size array is not allocated on every device alike.
    lane_aux = np.ascontiguousarray(aux[active]) if aux.size else np.zeros((a, 1, 1))
    s = len(snaps.steps)
    outs = np.ascontiguousarray(snaps.steps, np.int64) if s else np.array([-1], np.int64)
    host = {"X": _soa(state.x, rows), "W": _soa(state.W, rows), "am": _soa(state.acc_m, rows),
            "ae": _soa(state.acc_e, rows), "st": np.zeros(a, np.int64),
            "fs": np.zeros(a, np.int64), "nxt": np.ascontiguousarray(sched[active, 0]),
            "itv": np.ascontiguousarray(sched[active, 1]), "aux": lane_aux}
    # The call's start, for the orbits that fail: the host's copies.
    start = {"x": np.moveaxis(host["X"], -1, 0), "W": np.moveaxis(host["W"], -1, 0),
             "acc_m": np.moveaxis(host["am"], -1, 0), "acc_e": np.moveaxis(host["ae"], -1, 0)}
    dev = {name: cuda.to_device(arr) for name, arr in host.items()}
    rows_out = max(s, 1)
    snap = {"x": cuda.device_array((rows_out, d, a)), "W": cuda.device_array((rows_out, d, k, a)),
            "m": cuda.device_array((rows_out, k, a)),
            "e": cuda.device_array((rows_out, k, a), np.int64),
            "aux": cuda.device_array((rows_out,) + lane_aux.shape)}
    t1 = time.perf_counter()
    kernel.launch(a, dev["X"], dev["W"], dev["am"], dev["ae"], dev["st"], dev["fs"], dev["nxt"],
                  dev["itv"], int(n), int(state.step), prop.tau,
                  cuda.to_device(prop._h), cuda.to_device(prop._hc), prop._escape_r2,
                  int(prop.renorm), prop.sparse, dev["aux"],
                  cuda.to_device(outs),
                  snap["x"], snap["W"], snap["m"], snap["e"], snap["aux"])
    cuda.synchronize()
    t2 = time.perf_counter()
    out = {name: arr.copy_to_host() for name, arr in dev.items()}
    _put(state.x, rows, out["X"])
    _put(state.W, rows, out["W"])
    _put(state.acc_m, rows, out["am"])
    _put(state.acc_e, rows, out["ae"])
    sched[active, 0], sched[active, 1] = out["nxt"], out["itv"]
    if aux.size:
        aux[active] = out["aux"]
    if s:
        # Snapshots (S, M, ...): the orbit index is the second.
        for name, key in (("x", "x"), ("W", "W"), ("m", "acc_m"), ("e", "acc_e")):
            _put(getattr(snaps, key), rows, snap[name].copy_to_host(), axis=1)
        if aux.size:
            snaps.extra[prop.accumulator.key][:, active] = snap["aux"].copy_to_host()
    per, first = prop._step_counts(k)
    done = np.zeros(m, dtype=np.int64)
    counters = np.zeros((m, len(COUNTERS)), dtype=np.int64)
    done[active], counters[active] = n, per * int(n) + first
    failed = active[out["st"] != 0]
    STATS["launches"] += 1
    STATS["kernel_s"] += t2 - t1
    STATS["host_s"] += time.perf_counter() - t2 + t1 - t0
    prop._rerun_failed(module, state, n, snaps, active, failed, start, extra_start, done,
                       counters)

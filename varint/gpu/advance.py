"""One call of the TM propagator on the GPU: the active orbits, packed.

The run state holds one row per orbit, (M, ...). A call takes only the
orbits still active (status OK: not decided, not failed), so after every
check time of a chaos map with early stopping the orbits that decided are
gone from the launch: the packed arrays keep every warp full of live
orbits (compaction between launches). Each quantity goes to the GPU as one
array with the orbit index innermost (structure of arrays, so that loads
coalesce), the kernel (:mod:`varint.gpu.emit`) advances every orbit by
``n`` steps in one launch, and the state, the snapshots at output steps and
the status come back.

An orbit that failed on the GPU is recomputed on the CPU by the one-orbit
stepper from the call's start (exactly as after the CPU's SIMD lanes), so it
is left where and as the CPU leaves it.
"""

from __future__ import annotations

import time

import numpy as np

from ..protocol import COUNTERS
from ..schemes import DRIFT
from .emit import cuda_stepper

__all__ = ["advance_cuda", "STATS"]

#: Launches in this process and their seconds (kernel alone, synchronised;
#: transfers and repacking on the host), for benchmarks: how much of a
#: map's time the GPU computes.
STATS = {"launches": 0, "kernel_s": 0.0, "host_s": 0.0}


def _soa(a):
    """(M, ...) -> (..., M), contiguous: the orbit index innermost."""
    return np.ascontiguousarray(np.moveaxis(a, 0, -1))


def advance_cuda(prop, module, state, n, snaps, active):
    """Advance the ``active`` orbits of ``state`` by ``n`` steps on the GPU.

    Parameters
    ----------
    prop : TangentMapPropagator
    module : module
        The CPU's generated stepper for the same model, scheme and k (it
        recomputes failed orbits).
    state : RunState
    n : int
    snaps : Snapshots
        Filled at their output steps.
    active : ndarray of int
        Rows of ``state`` to advance (status OK), at least one.
    """
    from numba import cuda

    t0 = time.perf_counter()
    m, d, k = state.W.shape
    a = len(active)
    kinds = prop._kinds
    kernel = cuda_stepper(prop.model, kinds, (prop._hc != 0.0) & (kinds != DRIFT), k,
                          prop.accumulator)
    sched = prop._schedule(state)
    start = {"x": state.x[active], "W": state.W[active], "acc_m": state.acc_m[active],
             "acc_e": state.acc_e[active]}
    extra_start = {key: arr[active] for key, arr in state.extra.items()}
    aux = prop._accumulator(state)
    # Arrays the kernel does not touch (no accumulator columns, no output
    # steps: the sentinel −1 lies before every call) get one element, not
    # none: a zero-size array is not allocated on every device alike.
    lane_aux = np.ascontiguousarray(aux[active]) if aux.size else np.zeros((a, 1, 1))
    s = len(snaps.steps)
    outs = np.ascontiguousarray(snaps.steps, np.int64) if s else np.array([-1], np.int64)
    host = {"X": _soa(start["x"]), "W": _soa(start["W"]), "am": _soa(start["acc_m"]),
            "ae": _soa(start["acc_e"]), "st": np.zeros(a, np.int64), "fs": np.zeros(a, np.int64),
            "nxt": np.ascontiguousarray(sched[active, 0]),
            "itv": np.ascontiguousarray(sched[active, 1]), "aux": lane_aux}
    dev = {name: cuda.to_device(arr) for name, arr in host.items()}
    rows = max(s, 1)
    snap = {"x": cuda.device_array((rows, d, a)), "W": cuda.device_array((rows, d, k, a)),
            "m": cuda.device_array((rows, k, a)), "e": cuda.device_array((rows, k, a), np.int64),
            "aux": cuda.device_array((rows,) + lane_aux.shape)}
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
    state.x[active] = np.moveaxis(out["X"], -1, 0)
    state.W[active] = np.moveaxis(out["W"], -1, 0)
    state.acc_m[active] = np.moveaxis(out["am"], -1, 0)
    state.acc_e[active] = np.moveaxis(out["ae"], -1, 0)
    sched[active, 0], sched[active, 1] = out["nxt"], out["itv"]
    if aux.size:
        aux[active] = out["aux"]
    if s:
        snaps.x[:, active] = np.moveaxis(snap["x"].copy_to_host(), -1, 1)
        snaps.W[:, active] = np.moveaxis(snap["W"].copy_to_host(), -1, 1)
        snaps.acc_m[:, active] = np.moveaxis(snap["m"].copy_to_host(), -1, 1)
        snaps.acc_e[:, active] = np.moveaxis(snap["e"].copy_to_host(), -1, 1)
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

"""The GPU call as it was at main a875246, before the snapshots' energies
were computed on the device (issue 33): the host computes every snapshot's
energy with NumPy, and the state's bookkeeping makes arrays of all M
orbits at every call.

Used only by the benchmarks (``studies/bench_gpu.py``'s ``gpu_main``
contender, ``studies/gpu_stages.py --compare``), which put
:func:`advance_cuda` in the place of ``varint.gpu.advance.advance_cuda``
(the TM propagator looks the name up at each GPU call), for the
before/after ratio in one run on one machine. The kernel and the state
kept on the device are today's; the values are the same bits (the
benchmarks compare them), the energy errors the host's.
"""

from __future__ import annotations

import time

import numpy as np

from varint.gpu.advance import STATS, _put
from varint.gpu.emit import cuda_stepper
from varint.gpu.resident import STAGES, Resident, _Clock, resident_for
from varint.protocol import COUNTERS
from varint.schemes import DRIFT


def advance_cuda(prop, module, state, n, snaps, active):
    """Advance the ``active`` orbits of ``state`` by ``n`` steps on the GPU
    (as ``varint.gpu.advance.advance_cuda`` did at main a875246).

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
        Rows of ``state`` to advance (status OK), at least one, increasing.
    """
    from numba import cuda

    t0 = time.perf_counter()
    m, d, k = state.W.shape
    a = len(active)
    kinds = prop._kinds
    kernel = cuda_stepper(prop.model, kinds, (prop._hc != 0.0) & (kinds != DRIFT), k,
                          prop.accumulator)
    res = resident_for(state)
    if res is None or not res.usable(prop, state, active):
        res = Resident(prop, state, active)
    elif len(res.rows) != a:
        res.compact(active)
    # Valid again only once the call has ended (an exception half-way
    # leaves host and device apart: the next call uploads).
    res.step = None
    # All rows (no orbit decided or failed yet): views, no gathering.
    rows = None if a == m else active
    sel = slice(None) if rows is None else active
    s = len(snaps.steps)
    # The kernel's sentinel −1 lies before every call: no output step.
    outs = np.ascontiguousarray(snaps.steps, np.int64) if s else np.array([-1], np.int64)
    snap = res.snapshots(s, d, k)
    clock = _Clock()
    outs_dev = cuda.to_device(outs)
    clock.mark("h2d")
    t1 = time.perf_counter()
    kernel.launch(a, *res.kernel_args(), int(n), int(state.step), prop.tau, *res.constants,
                  prop._escape_r2, int(prop.renorm), prop.sparse, res.aux_arg(), outs_dev,
                  snap["x"], snap["W"], snap["m"], snap["e"], snap["aux"])
    cuda.synchronize()
    t2 = time.perf_counter()
    clock.mark("kernel")
    out = res.download(["st", "X", "W", "am", "ae", "nxt", "itv"]
                       + (["aux"] if res.has_aux else []))
    names = ["x", "W", "m", "e"] + (["aux"] if res.has_aux else [])
    # An output at the call's last step (where a chunk of a map usually
    # ends) is the state the kernel leaves: the same numbers, written at
    # that step and after the loop. It is read from the state copied back,
    # not copied from the device a second time.
    last = bool(s) and int(snaps.steps[-1]) == int(state.step) + int(n)
    head = s - 1 if last else s
    snap_host = res.download_snapshots(snap, names, head) if head else {}
    clock.mark("d2h")
    failed = active[out["st"] != 0]
    # The call's start, for the orbits that fail (rare): the host's rows,
    # not yet overwritten.
    start, extra_start = {}, {}
    if failed.size:
        start = {name: getattr(state, name)[active] for name in ("x", "W", "acc_m", "acc_e")}
        extra_start = {key: arr[active] for key, arr in state.extra.items()}
    _put(state.x, rows, out["X"])
    _put(state.W, rows, out["W"].reshape(d, k, a))
    _put(state.acc_m, rows, out["am"])
    _put(state.acc_e, rows, out["ae"])
    sched = prop._schedule(state)
    _put(sched[:, :1], rows, out["nxt"])
    _put(sched[:, 1:], rows, out["itv"])
    aux = prop._accumulator(state)
    if res.has_aux:
        aux[sel] = out["aux"].reshape((a,) + aux.shape[1:])
    # Snapshots (S, M, ...): the orbit index is the second.
    if head:
        for name, key in (("x", "x"), ("W", "W"), ("m", "acc_m"), ("e", "acc_e")):
            _put(getattr(snaps, key)[:head], rows, snap_host[name], axis=1)
        if res.has_aux:
            snaps.extra[prop.accumulator.key][:head, sel] = snap_host["aux"]
    if last:
        for key in ("x", "W", "acc_m", "acc_e"):
            getattr(snaps, key)[-1, sel] = getattr(state, key)[sel]
        if res.has_aux:
            snaps.extra[prop.accumulator.key][-1, sel] = aux[sel]
    clock.mark("unpack")
    per, first = prop._step_counts(k)
    done = np.zeros(m, dtype=np.int64)
    counters = np.zeros((m, len(COUNTERS)), dtype=np.int64)
    done[sel], counters[sel] = n, per * int(n) + first
    prop._rerun_failed(module, state, n, snaps, active, failed, start, extra_start, done,
                       counters)
    # The device copy is at the new step; a failed orbit that the CPU did
    # not fail again has host values the device lacks: upload next time.
    res.step = state.step if not (state.status[failed] == 0).any() else None
    clock.mark("rerun")
    STATS["launches"] += 1
    STAGES["launches"] += 1
    STATS["kernel_s"] += t2 - t1
    STATS["host_s"] += time.perf_counter() - t2 + t1 - t0

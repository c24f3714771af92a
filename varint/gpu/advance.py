"""One call of the TM propagator on the GPU: the active orbits, on the device.

The run state holds one row per orbit, (M, ...). A call advances only the
orbits still active (status OK: not decided, not failed). Their state lives
on the device between calls (:mod:`varint.gpu.resident`): uploaded at a
run's first call, with the orbit index innermost (structure of arrays, so
that loads coalesce), and compacted on the device when orbits stop (after a
check time of a chaos map with early stopping the orbits that decided are
gone from the launch, so every warp stays full of live orbits). The kernel
(:mod:`varint.gpu.emit`) advances every orbit by ``n`` steps in one launch;
the energies of the snapshots are computed on the device
(:mod:`varint.gpu.energy`: the host only forms the relative errors); the
state, the snapshots at output steps and the status come back
(:mod:`varint.gpu.resident`: transposed on the device and copied straight
into the host's arrays where every orbit was advanced, else through pinned
buffers written into the advanced orbits' rows).

An orbit that failed on the GPU is recomputed on the CPU by the one-orbit
stepper from the call's start (exactly as after the CPU's SIMD lanes), so it
is left where and as the CPU leaves it.
"""

from __future__ import annotations

import time

import numpy as np

from ..protocol import COUNTERS
from ..schemes import DRIFT
from . import host
from .emit import cuda_stepper
from .resident import STAGES, Resident, _Clock, resident_for

__all__ = ["advance_cuda", "STATS", "STAGES"]

#: Launches in this process and their seconds (kernel alone, synchronised;
#: the rest of a call on the host), for benchmarks: how much of a map's
#: time the GPU computes. :data:`~varint.gpu.resident.STAGES` splits the
#: host's part by stage.
STATS = {"launches": 0, "kernel_s": 0.0, "host_s": 0.0}


def _put(a, rows, soa, axis=0):
    """``soa`` (..., len(rows)), the orbit index innermost, written into the
    rows of ``a`` whose orbit index is ``axis``, in one pass."""
    view = np.moveaxis(a, axis, -1)
    if rows is None:
        view[...] = soa
    else:
        view[..., rows] = soa


def _row_targets(prop, state, snaps, sched, aux, head):
    """The host arrays a call of all orbits writes, orbit first, as 2-D
    views (an orbit's numbers in a row), or None where one is not
    C-contiguous (then a reshape would be a copy)."""
    m = state.n_orbits
    arrays = {"X": state.x, "W": state.W, "am": state.acc_m, "ae": state.acc_e,
              "sched": sched}
    if aux.size:
        arrays["aux"] = aux
        arrays["aux_snap"] = snaps.extra[prop.accumulator.key][:head]
    for j in range(head):
        arrays.update({f"x{j}": snaps.x[j], f"W{j}": snaps.W[j], f"m{j}": snaps.acc_m[j],
                       f"e{j}": snaps.acc_e[j]})
    if not all(v.flags.c_contiguous for v in arrays.values()):
        return None
    return {key: v if key == "aux_snap" else v.reshape(m, -1) for key, v in arrays.items()}


def _download_rows(res, snap, hosts, head, d, k):
    """The state and the first ``head`` snapshots of all orbits copied
    into ``hosts`` (:func:`_row_targets`), transposed on the device."""
    dev = res.dev
    pairs = [(dev["X"], hosts["X"], 0), (dev["W"], hosts["W"], 0), (dev["am"], hosts["am"], 0),
             (dev["ae"], hosts["ae"], 0), (dev["nxt"], hosts["sched"], 0),
             (dev["itv"], hosts["sched"], 1)]
    for j in range(head):
        pairs += [(snap["x"][j], hosts[f"x{j}"], 0),
                  (snap["W"][j].reshape(d * k, -1), hosts[f"W{j}"], 0),
                  (snap["m"][j], hosts[f"m{j}"], 0), (snap["e"][j], hosts[f"e{j}"], 0)]
    res.into_rows(pairs)
    if "aux" in hosts:   # orbit first on the device already: copied as it is
        dev["aux"].copy_to_host(ary=hosts["aux"])
        if head:
            snap["aux"][:head].copy_to_host(ary=hosts["aux_snap"])


def _download_and_put(res, snap, state, snaps, sched, aux, rows, sel, head, d, k, a):
    """The state and the first ``head`` snapshots of the advanced orbits
    copied into pinned buffers and written into their rows."""
    out = res.download(["X", "W", "am", "ae", "nxt", "itv"] + (["aux"] if res.has_aux else []))
    names = ["x", "W", "m", "e"] + (["aux"] if res.has_aux else [])
    snap_host = res.download_snapshots(snap, names, head) if head else {}
    _put(state.x, rows, out["X"])
    _put(state.W, rows, out["W"].reshape(d, k, a))
    _put(state.acc_m, rows, out["am"])
    _put(state.acc_e, rows, out["ae"])
    _put(sched[:, :1], rows, out["nxt"])
    _put(sched[:, 1:], rows, out["itv"])
    if res.has_aux:
        aux[sel] = out["aux"].reshape((a,) + aux.shape[1:])
    # Snapshots (S, M, ...): the orbit index is the second.
    if head:
        for name, key in (("x", "x"), ("W", "W"), ("m", "acc_m"), ("e", "acc_e")):
            _put(getattr(snaps, key)[:head], rows, snap_host[name], axis=1)
        if res.has_aux:
            snaps.extra[res.prop.accumulator.key][:head, sel] = snap_host["aux"]


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
    if s and res.energy is not None:
        # H of every snapshot, where they are: one number per orbit and
        # output comes back instead of the host's NumPy energy of the state.
        res.energy.launch(a, snap["x"], s, snap["energy"])
        cuda.synchronize()
        clock.mark("energy")
    st = res.download(["st"])["st"]
    failed = active[st != 0]
    # The call's start, for the orbits that fail (rare): the host's rows,
    # not yet overwritten.
    start, extra_start = {}, {}
    if failed.size:
        start = {name: getattr(state, name)[active] for name in ("x", "W", "acc_m", "acc_e")}
        extra_start = {key: arr[active] for key, arr in state.extra.items()}
    # An output at the call's last step (where a chunk of a map usually
    # ends) is the state the kernel leaves: the same numbers, written at
    # that step and after the loop. It is read from the state copied back,
    # not copied from the device a second time.
    last = bool(s) and int(snaps.steps[-1]) == int(state.step) + int(n)
    head = s - 1 if last else s
    sched = prop._schedule(state)
    aux = prop._accumulator(state)
    hosts = _row_targets(prop, state, snaps, sched, aux, head) if rows is None else None
    if hosts is not None:
        # Every orbit advanced: transposed on the device and copied straight
        # into the state's and the snapshots' arrays.
        _download_rows(res, snap, hosts, head, d, k)
    else:
        _download_and_put(res, snap, state, snaps, sched, aux, rows, sel, head, d, k, a)
    clock.mark("d2h")
    if last:
        for key in ("x", "W", "acc_m", "acc_e"):
            getattr(snaps, key)[-1, sel] = getattr(state, key)[sel]
        if res.has_aux:
            snaps.extra[prop.accumulator.key][-1, sel] = aux[sel]
    if s and res.energy is not None:
        # Orbits not advanced have no energy here (NaN, as their snapshots).
        energies = host.empty((s, a))
        snap["energy"][:s].copy_to_host(ary=energies)
        if rows is None:
            snaps.energy = energies
        else:
            snaps.energy = np.full((s, m), np.nan)
            snaps.energy[:, rows] = energies
    clock.mark("unpack")
    per, first = prop._step_counts(k)
    if failed.size:
        done = np.zeros(m, dtype=np.int64)
        counters = np.zeros((m, len(COUNTERS)), dtype=np.int64)
        done[sel], counters[sel] = n, per * int(n) + first
        prop._rerun_failed(module, state, n, snaps, active, failed, start, extra_start, done,
                           counters)
        if snaps.energy is not None:
            # Their snapshots are the CPU's now: so are their energies.
            with np.errstate(all="ignore"):
                snaps.energy[:, failed] = prop.model.energy(snaps.x[:, failed])
    else:
        # What RunState.after_kernel does after a call in which no orbit
        # failed, without arrays of all M orbits: every active orbit took n
        # steps and the same counts.
        state.step += int(n)
        state.add_counts(steps=np.int64(a) * int(n), **dict(zip(
            COUNTERS, np.int64(a) * (per * int(n) + first), strict=False)))
    # The device copy is at the new step; a failed orbit that the CPU did
    # not fail again has host values the device lacks: upload next time.
    res.step = state.step if not (state.status[failed] == 0).any() else None
    clock.mark("rerun")
    STATS["launches"] += 1
    STAGES["launches"] += 1
    STATS["kernel_s"] += t2 - t1
    STATS["host_s"] += time.perf_counter() - t2 + t1 - t0

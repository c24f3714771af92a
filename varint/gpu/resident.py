"""The orbits' state kept on the GPU between the launches of one run.

A chaos map calls the TM propagator once per chunk of steps (at every check
time with early stopping; per batch of output steps without). Before, every
call packed the active orbits' state into structure-of-arrays copies,
allocated device arrays, copied the state there and back, and freed them:
host work that grows with the orbits at every call (on an H100, 4.9 s of a
1e6-orbit map whose kernel took 0.08 s, ``studies/results/bench_gpu_h100.md``).

Here the state goes to the device once, as 2-D arrays with the orbit index
innermost (``(L, a)``: ``L`` numbers of one orbit, ``a`` orbits, viewed by
the kernel with its own shapes), and stays there for the state's lifetime:

* the next call of the same propagator on the same state, at the step where
  the last one left it, reuses it: no packing and no copy to the device;
* orbits that stopped between calls (decided by early stopping, or failed)
  are dropped on the device: a gather kernel copies the columns of the
  orbits still active into new arrays, in their order (compaction, so that
  warps stay full), from their column numbers — the only copy to the
  device;
* after every launch the state is copied back once per array, so every
  reader on the host (records, checkpoints, the result) sees what it saw
  before: the host copy stays the run's state of record. A call of all
  the run's orbits (a map's chunk until an orbit stops) transposes the
  state and the snapshots on the device into the host's layout (orbit
  first, :meth:`Resident.into_rows`) and copies them straight into the
  run state's and the snapshots' arrays: the host makes no pass over
  them (on an H200 writing them into the host's rows took 0.83 s of a
  1e6-orbit map, ``studies/results/bench_gpu_h200.md``). A call of some
  orbits copies into page-locked (pinned) host buffers, which copy at the
  bus's full rate and are allocated once per process (a pool: pinning
  pages is slow), and writes them into the orbits' rows.

The device copy is valid only while nothing but the propagator writes the
state's rows, which is how a run advances (``RunState`` is changed between
calls only by the propagator, and by the driver's early stopping, which
changes the status alone). It is used only if the state is the same object,
at the same step, with the same arrays, and its active orbits are among
those on the device; anything else (another state, a checkpoint read back,
a call on the CPU in between, which moves the step) uploads again. An orbit
recomputed on the CPU after failing on the GPU leaves the device copy: it is
either failed (not active again) or, if the CPU's stepper did not fail it,
the device copy is dropped and the next call uploads.
"""

from __future__ import annotations

import threading
import time
import weakref

import numpy as np

# A module global, not imported inside the kernels: numba's CUDA simulator
# runs a kernel with its own ``cuda`` put in the kernel's globals.
from numba import cuda

from . import device, energy

__all__ = ["Resident", "resident_for", "STAGES"]

#: Seconds and counts per stage of the GPU calls in this process, for the
#: benchmarks (``studies/bench_gpu.py`` prints them): ``alloc`` (page-locked
#: host buffers, where none is free for reuse), ``pack`` (the state
#: gathered into pinned buffers, at an upload), ``h2d`` (copies to the
#: device), ``compact`` (dropping stopped orbits on the device), ``kernel``
#: (the launch, synchronised), ``energy`` (the snapshots' energies on the
#: device, :mod:`varint.gpu.energy`, synchronised), ``d2h`` (copies back),
#: ``unpack`` (written into the run state and the snapshots), ``rerun``
#: (failed orbits on the CPU and the state's bookkeeping); ``uploads``,
#: ``compactions``, ``launches`` count calls.
STAGES = {"alloc": 0.0, "pack": 0.0, "h2d": 0.0, "compact": 0.0, "kernel": 0.0, "energy": 0.0,
          "d2h": 0.0, "unpack": 0.0, "rerun": 0.0, "uploads": 0, "compactions": 0,
          "launches": 0}


class _Clock:
    """Adds the seconds since the last mark to a stage of :data:`STAGES`."""

    def __init__(self):
        self.t = time.perf_counter()

    def mark(self, stage):
        now = time.perf_counter()
        STAGES[stage] += now - self.t
        self.t = now


#: The live device copies, by ``id`` of their run state (removed when the
#: state is collected: ``RunState`` is a dataclass, unhashable).
_LIVE: dict = {}


def resident_for(state):
    """The device copy of ``state``'s orbits made by an earlier call, or
    None."""
    res = _LIVE.get(id(state))
    return res if res is not None and res.state() is state else None


def _gather_columns(src, slots, dst):
    """``dst[:, j] = src[:, slots[j]]``: the columns (orbits) kept, in order."""
    j = cuda.grid(1)
    if j < dst.shape[1]:
        s = slots[j]
        for i in range(dst.shape[0]):
            dst[i, j] = src[i, s]


def _gather_rows(src, slots, dst):
    """``dst[j] = src[slots[j]]``: the rows (orbits) kept, in order."""
    j = cuda.grid(1)
    if j < dst.shape[0]:
        s = slots[j]
        for i in range(dst.shape[1]):
            dst[j, i] = src[s, i]


def _to_rows(src, dst, c0):
    """``dst[j, c0 + i] = src[i, j]``: columns with the orbit index
    innermost written as the host's rows, the orbit first."""
    j = cuda.grid(1)
    if j < src.shape[1]:
        for i in range(src.shape[0]):
            dst[j, c0 + i] = src[i, j]


_KERNELS: dict = {}


def _gather(name):
    if name not in _KERNELS:
        _KERNELS[name] = device.kernel({"columns": _gather_columns, "rows": _gather_rows,
                                        "to_rows": _to_rows}[name])
    return _KERNELS[name]


class _Pinned:
    """A page-locked host buffer of at least ``size`` numbers, handed out as
    C-contiguous views of any shape that fits (the active orbits shrink).
    Page-locking costs time (the pages are pinned one by one): a buffer
    comes from :data:`_POOL` where one fits, and goes back there when the
    run state that used it is collected."""

    def __init__(self, size, dtype, owner):
        size, dtype = max(int(size), 1), np.dtype(dtype)
        with _POOL_LOCK:
            fits = [i for i, b in enumerate(_POOL) if b.dtype == dtype and b.size >= size]
            best = min(fits, key=lambda i: _POOL[i].size) if fits else None
            self.buffer = _POOL.pop(best) if best is not None else None
        if self.buffer is None:
            clock = _Clock()
            self.buffer = cuda.pinned_array(size, dtype=dtype)
            clock.mark("alloc")
        owner.append(self.buffer)

    def view(self, shape):
        return self.buffer[:int(np.prod(shape))].reshape(shape)


#: Page-locked buffers free for the next run, the newest last (at most
#: :data:`_POOL_BYTES` in all: pinned memory is memory the system cannot
#: page out).
_POOL: list = []
_POOL_BYTES = 1 << 30
_POOL_LOCK = threading.Lock()


def _release(key, buffers):
    """A run state was collected: its device copy goes, its page-locked
    buffers return to the pool (no call can be using them any more)."""
    _LIVE.pop(key, None)
    with _POOL_LOCK:
        _POOL.extend(buffers)
        while sum(b.nbytes for b in _POOL) > _POOL_BYTES:
            del _POOL[0]


class Resident:
    """The state of a run's active orbits on the device (see the module
    docstring).

    Parameters
    ----------
    prop : TangentMapPropagator
    state : RunState
    active : ndarray of int
        The rows of ``state`` to hold (status OK), increasing.
    """

    def __init__(self, prop, state, active):
        m, d, k = state.W.shape
        aux = prop._accumulator(state)
        self.prop, self.state = prop, weakref.ref(state)
        self.step = None   # set after a launch: the step the device copy is at
        self.rows = np.asarray(active, dtype=np.int64)
        a = len(self.rows)
        # (L, orbit axis) of each array and the shape the kernel reads.
        self.aux_shape = aux.shape[1:] if aux.size else (1, 1)
        lengths = {"X": d, "W": d * k, "am": k, "ae": k, "nxt": 1, "itv": 1}
        self.lengths = lengths
        self.kernel_shape = {"X": (d,), "W": (d, k), "am": (k,), "ae": (k,), "nxt": (),
                             "itv": ()}
        self.dtype = {"X": float, "W": float, "am": float, "ae": np.int64, "nxt": np.int64,
                      "itv": np.int64}
        self.has_aux = bool(aux.size)
        # Every page-locked buffer this copy takes, returned to the pool
        # when the state is collected.
        self.buffers = []
        self.pinned = {name: _Pinned(n * a, self.dtype[name], self.buffers)
                       for name, n in lengths.items()}
        self.pinned["aux"] = _Pinned(a * int(np.prod(self.aux_shape)), float, self.buffers)
        self.pinned["st"] = _Pinned(a, np.int64, self.buffers)
        self.constants = (cuda.to_device(prop._h), cuda.to_device(prop._hc))
        # The snapshots' energies are computed on the device where the
        # model allows (varint.gpu.energy); else the host computes them.
        self.energy = energy.energy_kernel(prop.model) if energy.supported(prop.model) else None
        self.snap_cache = {}
        self.rows_cache = {}
        self.dev = {}
        self._upload(state)
        # After the upload, which makes the schedule at a run's first call.
        self.arrays = self._identity(state)
        # One copy per propagator: the chunks of a map run one after another.
        for key in [key for key, res in _LIVE.items() if res.prop is prop]:
            del _LIVE[key]
        _LIVE[id(state)] = self
        weakref.finalize(state, _release, id(state), self.buffers)

    @staticmethod
    def _identity(state):
        return (state.x, state.W, state.acc_m, state.acc_e) + tuple(
            sorted(((k, id(v)) for k, v in state.extra.items()), key=lambda kv: kv[0]))

    def usable(self, prop, state, active):
        """Whether this copy can continue ``state`` for ``active`` orbits
        (see the module docstring)."""
        if prop is not self.prop or self.step != state.step or len(active) > len(self.rows):
            return False
        ident = self._identity(state)
        if len(ident) != len(self.arrays) or any(
                a is not b if isinstance(a, np.ndarray) else a != b
                for a, b in zip(ident, self.arrays, strict=True)):
            return False
        if len(active) == len(self.rows):   # the common case: one comparison pass
            return bool(np.array_equal(active, self.rows))
        slots = np.searchsorted(self.rows, active)
        return bool(np.all(slots < len(self.rows)) and np.array_equal(
            self.rows[np.minimum(slots, len(self.rows) - 1)], active))

    def _host_views(self, name, a):
        shape = (a, int(np.prod(self.aux_shape))) if name == "aux" else (
            (a,) if name == "st" else (self.lengths[name], a))
        return self.pinned[name].view(shape)

    def _upload(self, state):
        """The active rows of ``state`` packed into the pinned buffers and
        copied to the device: one copy per array."""
        clock = _Clock()
        rows, a = self.rows, len(self.rows)
        m = state.n_orbits
        every = a == m   # all rows: transposed copies, no gathering
        sched = self.prop._schedule(state)
        sources = {"X": state.x, "W": state.W.reshape(m, -1), "am": state.acc_m,
                   "ae": state.acc_e, "nxt": sched[:, :1], "itv": sched[:, 1:]}
        host = {}
        for name, src in sources.items():
            buf = self._host_views(name, a)
            np.copyto(buf, src.T if every else src[rows].T)
            host[name] = buf
        aux = self._host_views("aux", a)
        if self.has_aux:
            src = self.prop._accumulator(state).reshape(m, -1)
            np.copyto(aux, src if every else src[rows])
        else:
            aux[...] = 0.0
        host["aux"] = aux
        clock.mark("pack")
        self.dev = {name: cuda.to_device(buf) for name, buf in host.items()}
        self.dev["st"] = cuda.device_array(a, np.int64)
        self.dev["fs"] = cuda.device_array(a, np.int64)
        clock.mark("h2d")
        STAGES["uploads"] += 1

    def compact(self, active):
        """Keep only the ``active`` orbits (a subset of :attr:`rows`) on the
        device, in their order: one copy of their column numbers to the
        device and a gather per array."""
        clock = _Clock()
        slots = cuda.to_device(np.searchsorted(self.rows, active).astype(np.int64))
        a = len(active)
        new = {}
        for name, arr in self.dev.items():
            if name in ("st", "fs"):
                new[name] = cuda.device_array(a, np.int64)
            elif name == "aux":
                new[name] = cuda.device_array((a, arr.shape[1]), arr.dtype)
                _gather("rows").launch(a, arr, slots, new[name])
            else:
                new[name] = cuda.device_array((arr.shape[0], a), arr.dtype)
                _gather("columns").launch(a, arr, slots, new[name])
        cuda.synchronize()
        self.dev, self.rows = new, np.asarray(active, dtype=np.int64)
        self.snap_cache.clear()
        self.rows_cache.clear()
        clock.mark("compact")
        STAGES["compactions"] += 1

    def kernel_args(self):
        """The state's arrays as the kernel reads them (views of the 2-D
        device arrays), in :data:`~varint.gpu.emit.ARGUMENTS` order up to
        ``itv``."""
        a = len(self.rows)
        views = {name: self.dev[name].reshape(self.kernel_shape[name] + (a,))
                 for name in self.kernel_shape}
        return (views["X"], views["W"], views["am"], views["ae"], self.dev["st"],
                self.dev["fs"], views["nxt"], views["itv"])

    def aux_arg(self):
        a = len(self.rows)
        return self.dev["aux"].reshape((a,) + tuple(self.aux_shape))

    def snapshots(self, s, d, k):
        """Device arrays for ``s`` output steps (at least one row: the
        kernel's sentinel), made once per size."""
        a = len(self.rows)
        key = (max(s, 1), a)
        if key not in self.snap_cache:
            r = key[0]
            self.snap_cache[key] = {
                "x": cuda.device_array((r, d, a)), "W": cuda.device_array((r, d, k, a)),
                "m": cuda.device_array((r, k, a)), "e": cuda.device_array((r, k, a), np.int64),
                "aux": cuda.device_array((r, a) + tuple(self.aux_shape)),
                "energy": cuda.device_array((r, a))}
        return self.snap_cache[key]

    def download(self, names):
        """The device arrays ``names`` copied into the pinned host buffers:
        {name: (L, a) view}."""
        a = len(self.rows)
        out = {}
        for name in names:
            buf = self._host_views(name, a)
            self.dev[name].copy_to_host(ary=buf)
            out[name] = buf
        return out

    def into_rows(self, pairs):
        """Device arrays with the orbit index innermost, ``(L, a)``, copied
        into host arrays with the orbit first, ``(a, L')`` (C-contiguous),
        from column ``c0`` on (``pairs``: (device array, host array, c0); the
        pairs of one host array adjacent): transposed on the device, where
        memory is fast, into an array of the host's layout, then copied once
        straight into the host array, with no pass of the host's over it."""
        for i, (src, host, c0) in enumerate(pairs):
            key = (host.shape, host.dtype)
            if key not in self.rows_cache:
                self.rows_cache[key] = cuda.device_array(host.shape, host.dtype)
            buf = self.rows_cache[key]
            _gather("to_rows").launch(src.shape[1], src, buf, c0)
            # The host array is complete after its last pair (a synchronous
            # copy: the buffer is free again for the next array).
            if i + 1 == len(pairs) or pairs[i + 1][1] is not host:
                buf.copy_to_host(ary=host)

    def download_snapshots(self, snap, names, count):
        """The first ``count`` output steps of the snapshot device arrays
        ``names``, copied into pinned host buffers."""
        out = {}
        for name in names:
            arr = snap[name][:count]
            # Page-locked buffers for snapshots only where they are needed
            # (a call of all orbits copies straight into the host's arrays).
            have = self.pinned.get("snap_" + name)
            if have is None or have.buffer.size < snap[name].size:
                self.pinned["snap_" + name] = _Pinned(snap[name].size, snap[name].dtype,
                                                      self.buffers)
            buf = self.pinned["snap_" + name].view(arr.shape)
            arr.copy_to_host(ary=buf)
            out[name] = buf
        return out

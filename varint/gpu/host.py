"""Host arrays that the GPU calls of a process reuse: the snapshots.

A GPU call of every orbit of a run copies its snapshots (the state at each
output step: 112 bytes per orbit and output for a Hénon–Heiles FLI map)
from the device into host arrays, every number of them
(:mod:`varint.gpu.advance`). Fresh NumPy arrays of that size are fresh
pages from the system at every call, filled with NaN first (a pass over
them) and written again by the copy: on the CUDA simulator the snapshot
arrays of a 1e6-orbit map took 0.65 CPU s, 0.006 s from these buffers
(``studies/results/gpu23/stages_1e6_warm1.md``, a process's second map;
its first map allocates them, and pays the first write of every page).
Against fresh arrays without the fill (``studies/gpu_host_pool.py``, a
process's later 1e6-orbit maps): the copies into them (unpack) 1.59 ->
0.45 s (wall), but the records (their energy errors 0.08 -> 0.33), whose
NumPy temporaries are then slower to come by, 0.19 -> 0.43 CPU s; the map
4.30 -> 3.99 CPU s (``studies/results/gpu23/host_pool_1000000.json``).

:func:`empty` hands out views of byte buffers kept by this module, and
hands a buffer out again only once nothing refers to it any more: no
array, view or record holds any part of it (its reference count is back
to what it was when only this module held it; every NumPy view of a
buffer refers to the buffer itself, its ``base``). A reader that keeps a
snapshot keeps its buffer from being reused, so nothing a caller holds is
ever overwritten; the driver reads a call's snapshots into records
(copies) before the next call, so a run alternates between two sets of
buffers.
"""

from __future__ import annotations

import sys
import threading

import numpy as np

__all__ = ["empty", "MOST_BYTES"]

#: The most bytes kept in buffers nothing refers to (the driver's
#: snapshots of one call are at most 64 MiB, ``varint.driver.SNAPSHOT_BYTES``).
MOST_BYTES = 1 << 30

#: [buffer, its reference count when only this list holds it], oldest first.
_BUFFERS: list = []
_LOCK = threading.Lock()


def _refs(entry):
    # The same expression at every count, so the counts compare.
    return sys.getrefcount(entry[0])


def _free(entry):
    return _refs(entry) == entry[1]


def empty(shape, dtype=float):
    """An uninitialised C-contiguous array of ``shape`` and ``dtype``, a view
    of a buffer nothing else refers to (a new one where none fits), as
    :func:`numpy.empty` but without fresh pages at every call."""
    dtype = np.dtype(dtype)
    nbytes = int(np.prod(shape, dtype=np.int64)) * dtype.itemsize
    if nbytes == 0:
        return np.empty(shape, dtype)
    with _LOCK:
        fits = [entry for entry in _BUFFERS if entry[0].nbytes >= nbytes and _free(entry)]
        if fits:
            entry = min(fits, key=lambda e: e[0].nbytes)
        else:
            _trim(MOST_BYTES - nbytes)
            entry = [np.empty(nbytes, np.uint8), 0]
            _BUFFERS.append(entry)
            entry[1] = _refs(entry)
        return entry[0][:nbytes].view(dtype).reshape(shape)


def _trim(most):
    """Drop the oldest buffers nothing refers to while those kept exceed
    ``most`` bytes (called holding the lock)."""
    free = [entry for entry in _BUFFERS if _free(entry)]
    kept = sum(entry[0].nbytes for entry in free)
    for entry in free:
        if kept <= most:
            break
        # By identity: lists holding arrays do not compare with ==.
        del _BUFFERS[next(i for i, e in enumerate(_BUFFERS) if e is entry)]
        kept -= entry[0].nbytes

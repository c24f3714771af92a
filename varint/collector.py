"""The cyclic garbage collector held off while varint loads code.

A fresh process that loads numba's registries, varint's modules and its
cached kernels creates some 10⁵ long-lived objects (functions, classes,
types, typing templates). CPython's collector counts them as new
allocations and runs *full* collections in the middle of the load, each of
which traverses every object of the process (numpy's, numba's, SciPy's) and
frees nothing: one such pass, ≈ 0.05 s of CPU, is the difference between a
first R1 run's collector time and the floor's (numpy and numba alone;
``studies/startup.py --part breakdown``, rows "gc: …"). Holding the
collector off while code is loaded (imports, kernels read back from the
cache, never a compilation) defers the full pass to a later one, where
those objects are already old. A load that made many objects ends with one
pass over the young generations, which moves them to the old one at once:
left to the young passes, the first would move them to the middle
generation and a later one traverse them all again.

Nothing is freed later than the end of the load: garbage cycles made while
the collector is held are collected at its next pass, as if they had been
made just before it. Nothing here imports the rest of varint.
"""

from __future__ import annotations

import contextlib
import gc
import threading

__all__ = ["held"]

#: A held block that leaves more than this many times the young
#: generation's threshold of new objects (gc.get_threshold()[0]) ends with
#: a collection of the young generations (:func:`held`).
_PROMOTE = 10

_LOCK = threading.Lock()
#: How many threads are loading now, and whether the collector was
#: enabled when the first of them began (it is enabled again only then:
#: a user who disabled it keeps it disabled).
_STATE = {"depth": 0, "enable": False}


@contextlib.contextmanager
def held():
    """Hold the cyclic garbage collector off for the block (re-entrant and
    shared by threads: it is enabled again when the last block ends, and
    only if it was enabled when the first began)."""
    with _LOCK:
        if _STATE["depth"] == 0:
            _STATE["enable"] = gc.isenabled()
            gc.disable()
        _STATE["depth"] += 1
    try:
        yield
    finally:
        with _LOCK:
            _STATE["depth"] -= 1
            if _STATE["depth"] == 0 and _STATE["enable"]:
                gc.enable()
                if gc.get_count()[0] > _PROMOTE * gc.get_threshold()[0]:
                    # Many objects were made, nearly all code that lives on:
                    # one pass over the young generations moves them to the
                    # old one, where the young passes no longer traverse
                    # them (else the first young pass moves them to the
                    # middle generation and the next one traverses them
                    # again).
                    gc.collect(1)

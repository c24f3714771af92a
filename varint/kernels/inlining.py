"""Where numba inlines the helpers of the compiled kernels.

A step body (:class:`~varint.kernels.interval.StepBody`) is inlined into
the skeleton's loop, and numba inlines a function by copying its IR at a
cost that grows as its size squared. Had the helpers a step body calls
(band products, checks) been inlined into it first, each body would be
copied whole, expanded: that took as long as compiling the rest of the
kernel (the generic TM step of Hénon–Heiles: 6 s of 35). So they are
inlined where the body lands instead — into the kernel — by numba's cost
model :func:`into_kernels`: same code, each piece copied once, small.

Nothing here imports the rest of varint.
"""

from __future__ import annotations

__all__ = ["into_kernels", "defer"]

#: The Python functions of step-body hooks (inlined into kernels later).
_DEFERRED: set = set()


def defer(*dispatchers):
    """Mark the functions of ``dispatchers`` as inlined into kernels later:
    helpers called from them wait until then."""
    for d in dispatchers:
        _DEFERRED.add(getattr(d, "py_func", d))


def into_kernels(expr, caller, callee):
    """numba's inline cost model of the helpers: inline into a function,
    unless it is a step-body hook (then into the kernel it lands in)."""
    return caller.func_id.func not in _DEFERRED

"""Moving orbits between the run state's layout and SIMD lanes.

The run state holds one row per orbit, (M, ...); the lane steppers of
:mod:`~varint.codegen.interval` want blocks with the orbit index innermost,
(blocks, ..., lanes). A chaos map with early stopping converts its state
both ways at every check time, for a handful of arrays: in NumPy (fancy
index, moveaxis, copy) that cost ~8 µs per array and direction, as much as
the steps between early check times. These loops do it in one pass each.
"""

from __future__ import annotations

from numba import njit

__all__ = ["gather", "scatter", "scatter_outputs"]


@njit(cache=True)
def gather(a, index, out):
    """``out[b, f, l] = a[index[b·L + l], f]`` for ``a`` (M, F) and ``out``
    (B, F, L): the rows of ``index`` as blocks of L lanes."""
    blocks, features, width = out.shape
    for b in range(blocks):
        for f in range(features):
            for lane in range(width):
                out[b, f, lane] = a[index[b * width + lane], f]


@njit(cache=True)
def scatter(src, rows, a):
    """``a[rows[i], f] = src[i // L, f, i % L]`` for ``src`` (B, F, L) and
    ``a`` (M, F): lanes back into the rows they came from (padding lanes,
    beyond ``len(rows)``, are dropped)."""
    width = src.shape[2]
    for i in range(len(rows)):
        b, lane = divmod(i, width)
        for f in range(src.shape[1]):
            a[rows[i], f] = src[b, f, lane]


@njit(cache=True)
def scatter_outputs(src, rows, a):
    """``a[s, rows[i], f] = src[i // L, s, f, i % L]`` for ``src`` (B, S, F, L)
    and ``a`` (S, M, F): the lanes' copies at S outputs back into the rows
    they came from (padding lanes dropped), as :func:`scatter` per output
    (NumPy's moveaxis, reshape and fancy assignment cost more than the
    copy for a pilot's few orbits)."""
    width = src.shape[3]
    for s in range(src.shape[1]):
        for i in range(len(rows)):
            b, lane = divmod(i, width)
            for f in range(src.shape[2]):
                a[s, rows[i], f] = src[b, s, f, lane]

"""The model's derivative kernels evaluated at many states in one compiled
pass, to refuse a start where one is not finite
(:func:`varint._validate.kernels`).

The kernels are passed as first-class functions of the protocol's
signatures (:mod:`varint.models.base`), not as numba dispatchers: one
compiled loop serves every model and is cached on disk, where a loop
specialised to each model's dispatchers would be compiled again (~1 s) in
every process. Compiled when this module is first imported (or loaded from
numba's cache).
"""

from __future__ import annotations

import numpy as np
from numba import njit, types

__all__ = ["first_nonfinite"]

_VEC = types.Array(types.float64, 1, "C")
_BAND = types.Array(types.float64, 2, "C")
#: grad(q, par, g), hess(q, par, B), third(q, par, v, B).
GRAD = types.FunctionType(types.none(_VEC, _VEC, _VEC))
HESS = types.FunctionType(types.none(_VEC, _VEC, _BAND))
THIRD = types.FunctionType(types.none(_VEC, _VEC, _VEC, _BAND))


@njit(inline="always")
def _finite(a):
    """Whether every number of the 1-D ``a`` is finite, with no temporary
    array (np.isfinite made three per state: most of the pass's time)."""
    i = 0
    while i < a.size and np.isfinite(a[i]):
        i += 1
    return i == a.size


@njit(types.int64(GRAD, HESS, THIRD, _BAND, _VEC, types.int64), cache=True)
def first_nonfinite(grad, hess, third, Q, par, rows):
    """The first row m of ``Q`` (M, N) where ∇V, D²V (``rows`` bands) or the
    third derivatives along (1, …, 1) are not all finite, or −1.

    Each state is evaluated as :func:`varint._validate.kernels` evaluates
    it from Python: the band matrices zeroed first (a banded kernel need
    not write every entry), the third derivatives along a vector of ones.
    An exception of a kernel propagates.
    """
    n = Q.shape[1]
    g = np.empty(n)
    h = np.empty((rows, n))
    t = np.empty((rows, n))
    v = np.ones(n)
    for m in range(Q.shape[0]):
        h[:] = 0.0
        t[:] = 0.0
        q = Q[m]
        grad(q, par, g)
        hess(q, par, h)
        third(q, par, v, t)
        if not (_finite(g) and _finite(h.ravel()) and _finite(t.ravel())):
            return m
    return -1

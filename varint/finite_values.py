"""A vector's numbers all finite, tested in one compiled pass (a prepared
run's short call tests its state's kernel values so: NumPy's ``isfinite``
and ``count_nonzero`` cost ~2 µs on a dozen numbers; issue 28, the fixed
cost of a call).

Apart from :mod:`varint._validate`, which imports no numba (loading a
result needs none); its :class:`~varint._validate.KernelCheck` imports
this module when it is made, for a model whose kernels numba compiled.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .kernels.resolved import Resolved

__all__ = ["ALL_FINITE"]


@njit(cache=True)
def _all_finite(values):
    """Whether every number of the vector ``values`` is finite."""
    i = 0
    while i < values.size and np.isfinite(values[i]):
        i += 1
    return i == values.size


#: :func:`_all_finite` through its compiled version (:class:`Resolved`):
#: for callers that pass C-contiguous float64 vectors only (the kept
#: buffers of :class:`varint._validate.KernelCheck`), the same array type
#: at every call.
ALL_FINITE = Resolved(_all_finite)

"""The relative energy errors of a short run and their largest value per
orbit, from T and V already evaluated, in one compiled pass (a prepared
run's short call, :mod:`varint.prepared`; issue 28: the fixed cost of a
call).

T and V stay the model's own NumPy functions (their bits are the energy
errors' bits: a compiled T or V could round differently, e.g. a power by
``pow`` against repeated products); what follows them is additions,
subtractions, absolute values, one division and comparisons, which IEEE
754 rounds the same in NumPy and in compiled code. So the errors are
:meth:`varint.accuracy.Reference.errors`' bit for bit, and the largest
error, when it was reached and the verdict those of
:func:`varint.accuracy.assess`, for orbits that did not fail (their
status 0) and errors that are all finite (``finite``; otherwise the caller
takes the general path).
"""

from __future__ import annotations

import numpy as np
from numba import njit, types

__all__ = ["energy_errors"]

_VEC = types.Array(types.float64, 1, "C")
_MAT = types.Array(types.float64, 2, "C")
_FLAGS = types.Array(types.boolean, 1, "C")


@njit(types.Tuple((_MAT, _VEC, _VEC, _FLAGS, types.boolean))(
    _VEC, _VEC, types.int64, _VEC, types.float64), cache=True, error_model="numpy")
def energy_errors(kinetic, potential, m, t, energy_tol):
    """Relative energy errors of ``m`` orbits at ``s`` outputs.

    Parameters
    ----------
    kinetic, potential : ndarray, shape (m + s·m,)
        T and V at the ``m`` initial states, then at the outputs
        (output-major: output j of orbit i at row m + j·m + i).
    m : int
    t : ndarray, shape (s,)
        The output times.
    energy_tol : float

    Returns
    -------
    errors : ndarray, shape (m, s)
        |H − H₀| / (|T₀| + |V₀|), the scale 1 where it is not positive
        (:class:`varint.accuracy.Reference`).
    largest, t_worst : ndarray, shape (m,)
        Each orbit's largest error and the first output time at which it
        was reached.
    accurate : ndarray of bool, shape (m,)
        ``largest <= energy_tol``.
    finite : bool
        Whether H₀ and every error are finite (otherwise the other results
        are meaningless).
    """
    s = (kinetic.size - m) // m
    errors = np.empty((m, s))
    largest = np.empty(m)
    t_worst = np.empty(m)
    accurate = np.empty(m, dtype=np.bool_)
    finite = True
    for i in range(m):
        h0 = kinetic[i] + potential[i]
        scale = abs(kinetic[i]) + abs(potential[i])
        if not scale > 0.0:        # (NaN too, as np.where(scale > 0, scale, 1.0))
            scale = 1.0
        finite = finite and np.isfinite(h0)
        worst, at = -np.inf, 0
        for j in range(s):
            row = m + j * m + i
            e = abs((kinetic[row] + potential[row]) - h0) / scale
            errors[i, j] = e
            finite = finite and np.isfinite(e)
            if e > worst:           # the first largest, as argmax
                worst, at = e, j
        largest[i], t_worst[i] = worst, t[at]
        accurate[i] = worst <= energy_tol
    return errors, largest, t_worst, accurate, finite

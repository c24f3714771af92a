"""The relative energy errors of a short run and their largest value per
orbit, from T and V already evaluated, in one compiled pass (a prepared
run's short call, :mod:`varint.prepared`; issue 28: the fixed cost of a
call).

V stays the model's own NumPy function (its bits are the energy errors'
bits: a compiled V could round differently, e.g. NumPy's ``y ** 3`` is
its SIMD ``pow`` (SVML, on AVX-512 machines), which differs from the C
library's ``pow`` and from ``y * y * y`` in a few per cent of the last
bits). T, where it is :class:`varint.models.base.Model`'s
``½ Σ M⁻¹ᵢ pᵢ²`` over fewer than 8 degrees of freedom, is computed here
(:func:`state_energy_errors`) by NumPy's operations in NumPy's order:
each term ``(M⁻¹ᵢ pᵢ) pᵢ``, their sum from the first to the last (what
``np.add.reduce`` does below 8 terms; from 8 on it sums pairwise, in
another order, so T is then NumPy's, :func:`energy_errors`), then
``½ ×`` the sum: products and sums that IEEE 754 rounds the same in
NumPy and in compiled code. (The terms are never −0, so the sum's start
cannot change the sign of a zero.) What follows T and V is additions,
subtractions, absolute values, one division and comparisons, rounded the
same way too. So the errors are :meth:`varint.accuracy.Reference.errors`'
bit for bit, and the largest error and when it was reached those of
:func:`varint.accuracy.assess`, for orbits that did not fail
(their status 0) and errors that are all finite (``finite``; otherwise
the caller takes the general path).
"""

from __future__ import annotations

import numpy as np
from numba import njit, types

__all__ = ["energy_errors", "state_energy_errors", "hamiltonian_errors", "SEQUENTIAL_TERMS"]

#: Below this many terms ``np.add.reduce`` adds them one after the other
#: (NumPy's ``pairwise_sum``; from 8 on, eight running sums), which
#: :func:`state_energy_errors` repeats.
SEQUENTIAL_TERMS = 8

_VEC = types.Array(types.float64, 1, "C")
_MAT = types.Array(types.float64, 2, "C")
_RESULT = types.Tuple((_VEC, types.boolean))


@njit(cache=True, error_model="numpy")
def _errors(kinetic, potential, m, t):
    # The body of energy_errors (see there), shared with state_energy_errors:
    # H₀ and the scale of each orbit, then the errors of its outputs.
    h = np.empty(kinetic.size)
    scale = np.empty(m)
    for r in range(kinetic.size):
        h[r] = kinetic[r] + potential[r]
    for i in range(m):
        scale[i] = abs(kinetic[i]) + abs(potential[i])
    return _relative(h[:m], scale, h[m:], m, t)


@njit(cache=True, error_model="numpy")
def _relative(h0, scale, h, m, t):
    # The errors |h − h0| / scale of the outputs h (output-major), the
    # scale 1 where it is not positive, and each orbit's largest.
    s = h.size // m
    found = np.empty(m * (s + 2))
    finite = True
    for i in range(m):
        h0_i, scale_i = h0[i], scale[i]
        if not scale_i > 0.0:      # (NaN too, as np.where(scale > 0, scale, 1.0))
            scale_i = 1.0
        finite = finite and np.isfinite(h0_i)
        worst, at = -np.inf, 0
        for j in range(s):
            e = abs(h[j * m + i] - h0_i) / scale_i
            found[2 * m + i * s + j] = e
            finite = finite and np.isfinite(e)
            if e > worst:           # the first largest, as argmax
                worst, at = e, j
        found[i], found[m + i] = worst, t[at]
    return found, finite


@njit(_RESULT(_VEC, _VEC, types.int64, _VEC), cache=True, error_model="numpy")
def energy_errors(kinetic, potential, m, t):
    """Relative energy errors of ``m`` orbits at ``s`` outputs.

    Parameters
    ----------
    kinetic, potential : ndarray, shape (m + s·m,)
        T and V at the ``m`` initial states, then at the outputs
        (output-major: output j of orbit i at row m + j·m + i).
    m : int
    t : ndarray, shape (s,)
        The output times.

    Returns
    -------
    found : ndarray, shape (m·(s + 2),)
        Each orbit's largest error (``found[:m]``), the first output time
        at which it was reached (``found[m:2m]``), then the errors
        (``found[2m:]``, (m, s) orbit-major): |H − H₀| / (|T₀| + |V₀|),
        the scale 1 where it is not positive
        (:class:`varint.accuracy.Reference`). One array, not three: each
        array a compiled function returns costs ~1 µs to hand to Python,
        as much as the rest of this call on a few outputs. (The verdict,
        ``largest <= energy_tol``, is NumPy's comparison, the same.)
    finite : bool
        Whether H₀ and every error are finite (otherwise ``found`` is
        meaningless).
    """
    return _errors(kinetic, potential, m, t)


@njit(_RESULT(_MAT, _VEC, _VEC, types.int64, _VEC), cache=True, error_model="numpy")
def state_energy_errors(states, potential, inverse_mass, m, t):
    """:func:`energy_errors` with T computed here from the ``states``
    (T = ½ Σᵢ M⁻¹ᵢ pᵢ², NumPy's bits for N < :data:`SEQUENTIAL_TERMS`,
    see the module's notes).

    Parameters
    ----------
    states : ndarray, shape (m + s·m, 2N)
        The ``m`` initial states, then the outputs' (output-major).
    potential : ndarray, shape (m + s·m,)
        V at those states.
    inverse_mass : ndarray, shape (N,)
        The diagonal of M⁻¹.
    m, t
        As for :func:`energy_errors`, which gives the results.
    """
    n = inverse_mass.size
    kinetic = np.empty(states.shape[0])
    for r in range(states.shape[0]):
        total = (inverse_mass[0] * states[r, n]) * states[r, n]
        for j in range(1, n):
            p = states[r, n + j]
            total += (inverse_mass[j] * p) * p
        kinetic[r] = 0.5 * total
    return _errors(kinetic, potential, m, t)


@njit(_RESULT(_VEC, _VEC, types.int64, _VEC), cache=True, error_model="numpy")
def hamiltonian_errors(h, v, m, t):
    """:func:`energy_errors` of a model whose energy is H itself (a
    :class:`~varint.models.hamiltonian.HamiltonianModel`'s, not T + V):
    from H at the ``m`` initial states and the outputs and V at the
    initial states (:meth:`~varint.models.hamiltonian.HamiltonianModel.row_energies`;
    zeros where the model's scale is |H| alone: |H₀ − 0| + |0| is |H₀|
    bit for bit). The scale |H₀ − V₀| + |V₀| (1 where it is not positive)
    and the errors |H − H₀| / scale are
    :meth:`~varint.models.hamiltonian.HamiltonianModel.energy_scale`'s and
    :func:`varint.accuracy._relative`'s operations, and the largest with
    its time :func:`varint.accuracy.assess`'s, bit for bit.

    Parameters
    ----------
    h : ndarray, shape (m + s·m,)
        H at the initial states, then at the outputs (output-major).
    v : ndarray, shape (m,)
    m, t
        As for :func:`energy_errors`, which gives the results.
    """
    scale = np.empty(m)
    for i in range(m):
        scale[i] = abs(h[i] - v[i]) + abs(v[i])
    return _relative(h[:m], scale, h[m:], m, t)

"""The constant of the logarithmic Hamiltonian's U = C − V(q) (Mikkola &
Tanikawa 1999): C = E + δ per orbit, δ = max(−E, 1) unless given
(:mod:`varint.time_transform`'s docstring gives the reasoning).

A module of its own, importing NumPy only, so that a map deciding whether
the logarithmic Hamiltonian is a candidate at all
(:func:`varint.maps._log_candidate`) reads U without loading SymPy, which
the transformation's own module needs to read a model's form.

References
----------
S. Mikkola & K. Tanikawa, MNRAS 310, 745 (1999).
"""

from __future__ import annotations

import numpy as np

__all__ = ["offset_constant"]


def offset_constant(E, offset):
    """C = E + δ of orbits of energies ``E``: δ = ``offset``, or max(−E, 1)
    where None, so that U = C − V > 0 along the orbit.

    >>> offset_constant(np.array([-0.5, 2.0]), None)
    array([0.5, 3. ])
    """
    E = np.asarray(E, dtype=float)
    return E + (np.maximum(-E, 1.0) if offset is None else offset)

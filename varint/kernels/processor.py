"""The processor of a processed scheme (:class:`varint.schemes.ProcessedScheme`)
and its tangent map, applied to orbits and their deviation vectors.

A processor is a short word of drifts and kicks (Blanes, Casas & Murua,
SIAM J. Sci. Comput. 27, 1817 (2006)), applied once where a run starts
(P⁻¹) and once where its state is read (P), never per step: one plain
compiled loop over its stages, with the TM method's flows (Skokos &
Gerlach 2010, eqs. 46–47):

* drift  q += h M⁻¹p,      δq += h M⁻¹δp
* kick   p −= h ∇V(q),     δp −= h D²V(q) δq

Its own loop rather than the stepping skeleton's: a processor is one pass
over a non-palindromic word, with nothing to check, renormalise or count
per step.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .banded import band_kick_block
from .drift import drift

__all__ = ["processor_map"]


@njit
def processor_map(x, W, rows, kinds, h, minv, par, bw, grad, hess):
    """Apply the drifts (``kinds == 0``) and kicks of lengths ``h`` to the
    orbits ``x`` (M, 2N) and vectors ``W`` (M, 2N, k) where ``rows`` is
    True, in place. ``grad(q, par, g)`` and ``hess(q, par, H)`` are the
    model's compiled kernels (Hessian in band storage of bandwidth ``bw``).
    A non-finite force leaves non-finite numbers, which the next step of
    the run's stepper reports."""
    m, d = x.shape
    n = d // 2
    k = W.shape[2]
    q, g = np.empty(n), np.empty(n)
    H, Kb = np.zeros((bw + 1, n)), np.empty((bw + 1, n))
    for o in range(m):
        if not rows[o]:
            continue
        xo, Wo = x[o], W[o]
        for st in range(kinds.shape[0]):
            hs = h[st]
            if kinds[st] == 0:
                drift(xo, Wo, minv, hs, n, k)
                continue
            for i in range(n):
                q[i] = xo[i]
            grad(q, par, g)
            for i in range(n):
                xo[n + i] -= hs * g[i]
            if k > 0:
                hess(q, par, H)
                for b in range(bw + 1):
                    for i in range(n):
                        Kb[b, i] = hs * H[b, i]
                band_kick_block(Kb, Wo, n, k, bw)

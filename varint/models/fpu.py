"""The FPU-β chain with fixed ends (Skokos & Gerlach 2010, eq. 56).

    H = Σ_{i=1}^{n} p_i²/2 + Σ_{i=0}^{n} [ r_i²/2 + β r_i⁴/4 ],
    r_i = q_{i+1} − q_i,  q_0 = q_{n+1} = 0.

It is the α-β chain :class:`~varint.models.fput.FPUT` with α = 0, whose
kernels then compute exactly what they computed before the α term existed
(the same operations in the same order: the same bits). Every derivative is
assembled bond by bond, so D²V is tridiagonal and never formed as an n×n
matrix: the kernels cost O(n) and work at n = 4096.
"""

from __future__ import annotations

import numpy as np

from .fput import FPUT, check_coupling, check_size

__all__ = ["FPUBeta"]


class FPUBeta(FPUT):
    """The Fermi–Pasta–Ulam–Tsingou β chain of ``n`` particles, fixed ends.

    Parameters
    ----------
    n : int
        Number of moving particles (degrees of freedom); 8 in the paper.
    beta : float
        Quartic coupling β; 1.5 in the paper.

    References
    ----------
    Skokos & Gerlach, Phys. Rev. E 82, 036704 (2010), eq. (56).
    """

    def __init__(self, n: int = 8, beta: float = 1.5) -> None:
        n = check_size(n)
        beta = check_coupling(beta, "beta")
        super().__init__(n, 0.0, beta, "fixed", name=f"FPUBeta(n={n}, beta={beta:g})")

    def describe(self):
        # As before FPUBeta was an FPUT: provenance and checkpoints of earlier
        # runs stay comparable.
        return {"name": self.name, "class": "FPUBeta", "n_dof": self.n_dof,
                "params": [self.beta], "inverse_mass": np.ones(self.n_dof).tolist(),
                "n": self.n_dof, "beta": self.beta}

"""The Hénon–Heiles system (Skokos & Gerlach 2010, eq. 54 and Appendix A).

    H₂ = ½(px² + py²) + ½(x² + y²) + x²y − y³/3

Bounded motion below the escape energy 1/6.
"""

from __future__ import annotations

import functools

from numba import njit

from .base import Model
from .potential_rows import rows_from

__all__ = ["HenonHeiles"]

#: Energy above which orbits can leave the potential well through its saddles.
ESCAPE_ENERGY = 1.0 / 6.0


@njit(cache=True, error_model="numpy")
def _grad(q, par, g):
    x, y = q[0], q[1]
    g[0] = x + 2.0 * x * y
    g[1] = y + x * x - y * y


@njit(cache=True, error_model="numpy")
def _hess(q, par, B):
    # Paper eq. (A.12): D²V = [[1 + 2y, 2x], [2x, 1 − 2y]].
    x, y = q[0], q[1]
    B[0, 0] = 1.0 + 2.0 * y
    B[0, 1] = 1.0 - 2.0 * y
    B[1, 0] = 2.0 * x
    B[1, 1] = 0.0


@njit(cache=True, error_model="numpy")
def _third(q, par, v, B):
    # The only non-zero third derivatives: V_xxy = 2, V_yyy = −2.
    B[0, 0] = 2.0 * v[1]
    B[0, 1] = -2.0 * v[1]
    B[1, 0] = 2.0 * v[0]
    B[1, 1] = 0.0


def _potential(q):
    return _V(q[..., 0], q[..., 1])


def _V(x, y):
    # The one expression of V: NumPy's (through _potential) and the
    # compiled one over rows (potential_rows) are both made from it.
    return 0.5 * (x * x + y * y) + x * x * y - y ** 3 / 3.0


class HenonHeiles(Model):
    """The 2-degree-of-freedom Hénon–Heiles Hamiltonian.

    Parameters
    ----------
    escape_radius : float, optional
        Stop runs whose |q| exceeds this (orbits above the escape energy 1/6
        leave to infinity). None by default: such runs end with an overflow
        error instead.

    References
    ----------
    M. Hénon & C. Heiles, Astron. J. 69, 73 (1964); Skokos & Gerlach,
    Phys. Rev. E 82, 036704 (2010), eq. (54).
    """

    escape_energy = ESCAPE_ENERGY

    def __init__(self, escape_radius: float | None = None) -> None:
        super().__init__(2, _potential, _grad, _hess, _third, bandwidth=1,
                         name="HenonHeiles", escape_radius=escape_radius)

    def describe(self):
        d = super().describe()
        d["escape_radius"] = self.escape_radius
        return d

    @property
    def potential_rows(self):
        """V compiled over rows from :func:`_V`'s expression
        (:meth:`Model.potential_rows <varint.models.base.Model.potential_rows>`):
        wholly where NumPy's power is libm's, else but for ``y ** 3``, which
        NumPy computes (:mod:`varint.models.potential_rows`)."""
        return rows_from(_V, 2)

    def symbolic(self):
        """The potential in SymPy: the one definition the Taylor reference
        integrates, and the twin the kernels above are tested against."""
        return _symbolic()


@functools.cache
def _symbolic():
    """The model in SymPy, built once per process (the expressions are
    immutable; building them costs ~0.1 ms, and every run and every chunk of a
    chaos map asks for them)."""
    import sympy as sp

    from .symbolic import SymbolicPotential

    x, y = sp.symbols("x y")
    V = (x**2 + y**2) / 2 + x**2 * y - y**3 / 3
    return SymbolicPotential(V, (x, y), (sp.Integer(1),) * 2)

"""The paper's 3-degree-of-freedom system (Skokos & Gerlach 2010, eq. 55).

    H₃ = ½(x² + px²) + (√2/2)(y² + py²) + (√3/2)(z² + pz²) + x²y + x²z

The kinetic part is ½ pᵀM⁻¹p with M⁻¹ = diag(1, √2, √3), so the paper's
coordinates are kept (GALIs depend on the coordinates in which deviation
vectors are normalised).
"""

from __future__ import annotations

import functools

import math

from numba import njit

from .base import Model

__all__ = ["ThreeDof"]

_S2, _S3 = math.sqrt(2.0), math.sqrt(3.0)


@njit(cache=True, error_model="numpy")
def _grad(q, par, g):
    x, y, z = q[0], q[1], q[2]
    g[0] = x + 2.0 * x * (y + z)
    g[1] = _S2 * y + x * x
    g[2] = _S3 * z + x * x


@njit(cache=True, error_model="numpy")
def _hess(q, par, B):
    x, y, z = q[0], q[1], q[2]
    B[0, 0] = 1.0 + 2.0 * (y + z)
    B[0, 1] = _S2
    B[0, 2] = _S3
    B[1, 0] = 2.0 * x  # (x, y)
    B[1, 1] = 0.0      # (y, z)
    B[1, 2] = 0.0
    B[2, 0] = 2.0 * x  # (x, z)
    B[2, 1] = 0.0
    B[2, 2] = 0.0


@njit(cache=True, error_model="numpy")
def _third(q, par, v, B):
    # Non-zero third derivatives: V_xxy = V_xxz = 2.
    for b in range(3):
        for i in range(3):
            B[b, i] = 0.0
    B[0, 0] = 2.0 * (v[1] + v[2])
    B[1, 0] = 2.0 * v[0]
    B[2, 0] = 2.0 * v[0]


def _potential(q):
    x, y, z = q[..., 0], q[..., 1], q[..., 2]
    return 0.5 * x * x + 0.5 * _S2 * y * y + 0.5 * _S3 * z * z + x * x * (y + z)


class ThreeDof(Model):
    """The 3D system of Contopoulos, Galgani & Giorgilli (1978), as in the
    paper, with inverse mass diag(1, √2, √3).

    References
    ----------
    Skokos & Gerlach, Phys. Rev. E 82, 036704 (2010), eq. (55).
    """

    def __init__(self) -> None:
        super().__init__(3, _potential, _grad, _hess, _third, bandwidth=2,
                         inverse_mass=(1.0, _S2, _S3), name="ThreeDof")

    def symbolic(self):
        """The potential and inverse mass in SymPy, with √2 and √3 exact."""
        return _symbolic()


@functools.cache
def _symbolic():
    """The model in SymPy, built once per process (the expressions are
    immutable; building them costs ~0.1 ms, and every run and every chunk of a
    chaos map asks for them)."""
    import sympy as sp

    from .symbolic import SymbolicPotential

    x, y, z = sp.symbols("x y z")
    s2, s3 = sp.sqrt(2), sp.sqrt(3)
    V = x**2 / 2 + s2 / 2 * y**2 + s3 / 2 * z**2 + x**2 * y + x**2 * z
    return SymbolicPotential(V, (x, y, z), (sp.Integer(1), s2, s3))

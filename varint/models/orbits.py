"""Initial conditions: momenta solved from the energy, and the paper's orbits."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from .base import Model
from .henon_heiles import HenonHeiles
from .three_dof import ThreeDof

__all__ = ["solve_momentum", "paper_orbit", "PAPER_ORBITS"]


def solve_momentum(model: Model, q: ArrayLike, p: ArrayLike, energy: float,
                   index: int = 0) -> np.ndarray:
    """The state (q, p) with ``p[index] ≥ 0`` solved from H(q, p) = energy.

    Parameters
    ----------
    model : Model
    q, p : array_like, shape (N,)
        Positions and momenta; ``p[index]`` is ignored and replaced.
    energy : float
    index : int
        Which momentum to solve for.

    Returns
    -------
    x : ndarray, shape (2N,)

    Raises
    ------
    ValueError
        If no real momentum solves the energy equation at this q.
    """
    n = model.n_dof
    q = np.asarray(q, dtype=float).reshape(-1)
    p = np.array(p, dtype=float).reshape(-1)
    if q.shape != (n,) or p.shape != (n,):
        raise ValueError(f"q and p must have shape ({n},), got {q.shape} and {p.shape}")
    if not (0 <= index < n):
        raise ValueError(f"index must be in 0..{n - 1}, got {index}")
    if not np.isfinite(energy):
        raise ValueError(f"energy must be finite, got {energy!r}")
    p[index] = 0.0
    rest = float(energy) - float(model.potential(q)) - float(model.kinetic(p))
    if rest < 0:
        raise ValueError(
            f"no real momentum p[{index}] gives energy {energy!r} at q = {q.tolist()}: "
            f"V(q) plus the other kinetic terms is already {energy - rest!r}")
    p[index] = np.sqrt(2.0 * rest / model.inverse_mass[index])
    return np.concatenate([q, p])


def _hh(y, py=0.0):
    model = HenonHeiles()
    return model, solve_momentum(model, [0.0, y], [0.0, py], 0.125, index=0)


def _fpu():
    # The lattices' kernels are imported with the first lattice built.
    from .fpu import FPUBeta

    return FPUBeta(8, 1.5), np.concatenate([np.full(8, 0.1), np.zeros(8)])


#: The orbits of Skokos & Gerlach (2010), Sect. VI: builder, nature, notes.
PAPER_ORBITS = {
    "R1": (lambda: _hh(0.558), "regular",
           "Hénon–Heiles, H = 0.125, x = 0, y = 0.558, py = 0, px ≈ 0.2334"),
    "C1": (lambda: _hh(-0.25), "chaotic",
           "Hénon–Heiles, H = 0.125, x = 0, y = −0.25, py = 0, px ≈ 0.4208; χ1 ≈ 0.045"),
    "C2": (lambda: _hh(0.335036, -0.385631), "weakly chaotic",
           "Hénon–Heiles, H = 0.125, x = 0, y = 0.335036, py = −0.385631, px ≈ 0.11879; "
           "χ1 ≈ 4e-6, sticky until t ≈ 1e6"),
    "R2": (lambda: (ThreeDof(), np.array([0.0, 0.0, 0.0, 0.1, 0.347, 0.0])), "regular",
           "3D system, x = y = z = 0, px = 0.1, py = 0.347, pz = 0; 3-torus"),
    "R3": (_fpu, "regular", "FPU-β, n = 8, β = 1.5, q_i = 0.1, p_i = 0; 4-dimensional torus"),
}


def paper_orbit(name: str) -> tuple[Model, np.ndarray]:
    """The model and initial state of one of the paper's orbits.

    Parameters
    ----------
    name : {"R1", "C1", "C2", "R2", "R3"}
        Case-insensitive.

    Returns
    -------
    model : Model
    x0 : ndarray, shape (2N,)

    Examples
    --------
    >>> model, x0 = paper_orbit("R1")
    >>> round(float(x0[2]), 4)
    0.2334
    """
    key = str(name).upper()
    if key not in PAPER_ORBITS:
        raise ValueError(f"unknown paper orbit {name!r}; expected one of: {', '.join(PAPER_ORBITS)}")
    return PAPER_ORBITS[key][0]()

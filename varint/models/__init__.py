"""Models H = ½ pᵀM⁻¹p + V(q): the protocol and the paper's systems."""

from .base import Model
from .fpu import FPUBeta
from .henon_heiles import HenonHeiles
from .orbits import PAPER_ORBITS, paper_orbit, solve_momentum
from .three_dof import ThreeDof

__all__ = ["Model", "HenonHeiles", "ThreeDof", "FPUBeta", "paper_orbit", "solve_momentum",
           "PAPER_ORBITS"]

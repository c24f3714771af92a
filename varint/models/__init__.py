"""Models H = ½ pᵀM⁻¹p + V(q) (or V(q, t)): the protocol and the paper's
systems; symplectic maps with their tangent maps (:mod:`.maps`); the
many-body lattices (:mod:`varint.models.lattice`), which also declare the
parts their Hamiltonians split into, and the T + V ones written as one
stencil (:mod:`varint.models.stencil`); and planetary systems
(:mod:`varint.models.planetary`), split into Kepler problems and their
interaction."""

from .base import Model
from .ddnls import DDNLS
from .fpu import FPUBeta
from .fput import FPUT
from .henon_heiles import HenonHeiles
from .kg import DisorderedKG
from .lattice import LatticeModel, Parts
from .maps import CoupledStandardMaps, MapModel, StandardMap
from .planetary import Planetary
from .stencil import Potential, Stencil, StencilLattice
from .orbits import PAPER_ORBITS, paper_orbit, solve_momentum
from .three_dof import ThreeDof

__all__ = ["Model", "HenonHeiles", "ThreeDof", "FPUBeta", "FPUT", "DisorderedKG", "DDNLS",
           "LatticeModel", "Parts", "Stencil", "Potential", "StencilLattice", "Planetary",
           "paper_orbit", "solve_momentum", "PAPER_ORBITS",
           "from_potential", "SymbolicModel", "SymbolicPotential",
           "MapModel", "StandardMap", "CoupledStandardMaps", "from_map", "SymbolicMap",
           "from_hamiltonian", "HamiltonianModel", "CR3BP", "cr3bp_orbit", "RotatingBar",
           "bar_orbit", "MagneticBottle", "bottle_orbit"]

# SymPy takes as long to import as the rest of varint: load it on first use.
_LAZY = {
    "from_potential": "symbolic", "SymbolicModel": "symbolic", "SymbolicPotential": "symbolic",
    "from_map": "symbolic", "SymbolicMap": "symbolic",
    "from_hamiltonian": "hamiltonian", "HamiltonianModel": "hamiltonian",
    "CR3BP": "cr3bp", "cr3bp_orbit": "cr3bp", "RotatingBar": "bar", "bar_orbit": "bar",
    "MagneticBottle": "bottle", "bottle_orbit": "bottle",
}


def __getattr__(name):
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

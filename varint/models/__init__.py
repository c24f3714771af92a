"""Models H = ½ pᵀM⁻¹p + V(q) (or V(q, t)): the protocol and the paper's
systems; symplectic maps with their tangent maps (:mod:`.maps`); the
many-body lattices (:mod:`varint.models.lattice`), which also declare the
parts their Hamiltonians split into, and the T + V ones written as one
stencil (:mod:`varint.models.stencil`); and planetary systems
(:mod:`varint.models.planetary`), split into Kepler problems and their
interaction."""

from typing import TYPE_CHECKING

from .base import Model
from .henon_heiles import HenonHeiles
from .orbits import PAPER_ORBITS, paper_orbit, solve_momentum
from .three_dof import ThreeDof

__all__ = ["Model", "HenonHeiles", "ThreeDof", "FPUBeta", "FPUT", "DisorderedKG", "DDNLS",
           "LatticeModel", "Parts", "Stencil", "Potential", "StencilLattice", "Planetary",
           "paper_orbit", "solve_momentum", "PAPER_ORBITS",
           "from_potential", "SymbolicModel", "SymbolicPotential",
           "MapModel", "StandardMap", "CoupledStandardMaps", "from_map", "SymbolicMap",
           "from_hamiltonian", "HamiltonianModel", "CR3BP", "cr3bp_orbit", "RotatingBar",
           "bar_orbit", "MagneticBottle", "bottle_orbit"]

# Loaded on first use (PEP 562): SymPy takes as long to import as the rest
# of varint, and the lattices, stencils, planetary systems and maps define
# a hundred compiled kernels that a run of another model never calls, whose
# import a fresh process's first run would wait for (issue 28).
_LAZY = {
    "DDNLS": "ddnls", "FPUBeta": "fpu", "FPUT": "fput", "DisorderedKG": "kg",
    "LatticeModel": "lattice", "Parts": "lattice",
    "CoupledStandardMaps": "maps", "MapModel": "maps", "StandardMap": "maps",
    "Planetary": "planetary",
    "Potential": "stencil", "Stencil": "stencil", "StencilLattice": "stencil",
    "from_potential": "symbolic", "SymbolicModel": "symbolic", "SymbolicPotential": "symbolic",
    "from_map": "symbolic", "SymbolicMap": "symbolic",
    "from_hamiltonian": "hamiltonian", "HamiltonianModel": "hamiltonian",
    "CR3BP": "cr3bp", "cr3bp_orbit": "cr3bp", "RotatingBar": "bar", "bar_orbit": "bar",
    "MagneticBottle": "bottle", "bottle_orbit": "bottle",
}

if TYPE_CHECKING:
    # What a type checker sees: the same names, statically.
    from .bar import RotatingBar as RotatingBar, bar_orbit as bar_orbit
    from .bottle import MagneticBottle as MagneticBottle, bottle_orbit as bottle_orbit
    from .cr3bp import CR3BP as CR3BP, cr3bp_orbit as cr3bp_orbit
    from .ddnls import DDNLS as DDNLS
    from .fpu import FPUBeta as FPUBeta
    from .fput import FPUT as FPUT
    from .hamiltonian import (
        HamiltonianModel as HamiltonianModel,
        from_hamiltonian as from_hamiltonian,
    )
    from .kg import DisorderedKG as DisorderedKG
    from .lattice import LatticeModel as LatticeModel, Parts as Parts
    from .maps import (
        CoupledStandardMaps as CoupledStandardMaps,
        MapModel as MapModel,
        StandardMap as StandardMap,
    )
    from .planetary import Planetary as Planetary
    from .stencil import Potential as Potential, Stencil as Stencil, StencilLattice as StencilLattice
    from .symbolic import (
        SymbolicMap as SymbolicMap,
        SymbolicModel as SymbolicModel,
        SymbolicPotential as SymbolicPotential,
        from_map as from_map,
        from_potential as from_potential,
    )


def __getattr__(name):
    # Called only for names not yet in the package (PEP 562).
    if name in _LAZY:
        import importlib

        value = globals()[name] = getattr(importlib.import_module(f".{_LAZY[name]}", __name__),
                                          name)
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_LAZY))

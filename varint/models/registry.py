"""The built-in models by name: one registry that the command line, the
documentation and the plots read, as :data:`varint.SCHEMES`,
:data:`varint.METHODS` and :data:`varint.INDICATORS` are read for schemes,
methods and indicators.

An entry is a factory with its parameters (name, default, one line of
documentation) and the names of the model's coordinates. ``kind`` says how
a model is used: ``"flow"`` (a Hamiltonian, ½pᵀM⁻¹p + V(q) or of another form, integrated),
``"map"`` (a symplectic map, iterated) or ``"lattice"`` (a many-body
lattice whose factory also takes ``shape``, ``boundary`` and the disorder's
``seed``). A new model is one :func:`register_model` call.

>>> from varint.models.registry import MODELS
>>> MODELS["standard"].build(K=2.0).name
'StandardMap(K=2)'
>>> [p.name for p in MODELS["fpu-beta"].parameters]
['n', 'beta']
"""

from __future__ import annotations

from dataclasses import dataclass, field
from types import MappingProxyType
from collections.abc import Callable
from typing import Any

from .ddnls import DDNLS
from .fpu import FPUBeta
from .fput import FPUT
from .henon_heiles import HenonHeiles
from .kg import DisorderedKG
from .maps import CoupledStandardMaps, StandardMap
from .planetary import Planetary
from .three_dof import ThreeDof

__all__ = ["Parameter", "ModelEntry", "MODELS", "register_model", "get_model",
           "coordinate_names", "state_names"]

KINDS = ("flow", "map", "lattice")


@dataclass(frozen=True)
class Parameter:
    """A parameter of a registered model.

    Attributes
    ----------
    name : str
        The factory's keyword.
    default : int or float
    doc : str
        One line: what it is.
    flag : str, optional
        Its command-line option (``--<flag>``); ``name`` by default.
    integer : bool
        Whether it is a count (read as an integer).
    """

    name: str
    default: Any
    doc: str
    flag: str | None = None
    integer: bool = False

    @property
    def option(self):
        """The command-line option, e.g. ``"--beta"``."""
        return "--" + (self.flag or self.name)


@dataclass(frozen=True)
class ModelEntry:
    """A built-in model: how to build it and what it takes.

    Attributes
    ----------
    name : str
        Registry key, e.g. ``"henon-heiles"``.
    kind : {"flow", "map", "lattice"}
    factory : callable
        ``factory(**parameters) -> model`` (a lattice's also takes
        ``shape``, ``boundary`` and ``seed``).
    summary : str
        One line: what it is.
    parameters : tuple of Parameter
    coordinates : tuple of str, optional
        Names of the coordinates q (a map: of every state component), in
        state order; None when they depend on the size (lattices: q_l).
    """

    name: str
    kind: str
    factory: Callable
    summary: str
    parameters: tuple = ()
    coordinates: tuple | None = None
    classes: tuple = field(default=())

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ValueError(f"model {self.name!r}: kind must be one of {', '.join(KINDS)}, "
                             f"got {self.kind!r}")

    def defaults(self):
        """``{parameter: default}``."""
        return {p.name: p.default for p in self.parameters}

    def build(self, **given):
        """The model with the ``given`` parameters, the others at their
        defaults.

        Raises
        ------
        ValueError
            For a parameter the model does not take (the message lists its
            parameters).
        """
        names = {p.name for p in self.parameters}
        extra = {"shape", "boundary", "seed"} if self.kind == "lattice" else set()
        unknown = sorted(set(given) - names - extra)
        if unknown:
            raise ValueError(f"model {self.name!r} takes no parameter {unknown[0]!r}; its "
                             f"parameters: {', '.join(sorted(names | extra)) or 'none'}")
        values = self.defaults()
        values.update({k: v for k, v in given.items() if v is not None})
        return self.factory(**values)


_REGISTRY: dict = {}
#: Name → :class:`ModelEntry`. Read-only view; add with :func:`register_model`.
MODELS = MappingProxyType(_REGISTRY)


def register_model(entry: ModelEntry) -> ModelEntry:
    """Add ``entry`` to :data:`MODELS`; returns it.

    Raises
    ------
    ValueError
        If it is not a :class:`ModelEntry` or its name is taken.
    """
    if not isinstance(entry, ModelEntry):
        raise ValueError(f"register_model takes a ModelEntry, got {type(entry).__name__}")
    if entry.name in _REGISTRY:
        raise ValueError(f"a model named {entry.name!r} is already registered")
    _REGISTRY[entry.name] = entry
    return entry


def get_model(name: str) -> ModelEntry:
    """The registered model called ``name``.

    Raises
    ------
    ValueError
        For an unknown name; the message lists the valid ones.
    """
    try:
        return _REGISTRY[name]
    except (KeyError, TypeError):
        raise ValueError(f"unknown model {name!r}; expected one of: "
                         f"{', '.join(_REGISTRY)}") from None


def coordinate_names(description: dict) -> tuple:
    """The names of the coordinates q of a model from its
    :meth:`~varint.models.base.Model.describe` (as results keep it in
    their provenance): a map's state names, a SymPy model's symbols, a
    registered model's coordinates, else q1, q2, ….

    Returns
    -------
    tuple of str
        N names for a flow, 2N for a map (every state component).
    """
    if description.get("variables"):
        return tuple(description["variables"])
    if description.get("q"):
        return tuple(description["q"])
    cls = description.get("class")
    for entry in _REGISTRY.values():
        if entry.coordinates is not None and cls in entry.classes:
            return entry.coordinates
    n = int(description.get("n_dof") or 0)
    return tuple(f"q{i + 1}" for i in range(n))


def state_names(description: dict, dim: int) -> tuple:
    """Names of the ``dim`` state components (q then p) for axis labels:
    ``("x", "y", "p_x", "p_y")`` for Hénon–Heiles, a map's own names."""
    names = coordinate_names(description)
    if len(names) == dim:          # a map names every component
        return names
    if len(names) != dim // 2:
        names = tuple(f"q{i + 1}" for i in range(dim // 2))
    return names + tuple(f"p_{name}" for name in names)


def _fput(shape, alpha, beta, boundary="fixed", seed=None):
    """The FPUT chain as the lattice command builds it: no disorder, so
    ``seed`` is ignored, and a chain only."""
    if not isinstance(shape, int):
        raise ValueError(f"the FPUT model is a chain: shape must be one integer, got {shape!r}")
    return FPUT(shape, alpha, beta, boundary=boundary)


def _planetary(m1, m2):
    """The star (mass 1, G = 1) and two planets of masses ``m1`` (inner) and
    ``m2`` in Jacobi coordinates, Wisdom–Holman split."""
    return Planetary([1.0, m1, m2])


_HH_XY = ("x", "y")
register_model(ModelEntry(
    "henon-heiles", "flow", HenonHeiles,
    "Hénon–Heiles, V = (x² + y²)/2 + x²y − y³/3 (the paper's R1, C1, C2)",
    coordinates=_HH_XY, classes=("HenonHeiles",)))
register_model(ModelEntry(
    "three-dof", "flow", ThreeDof,
    "the paper's 3-dof system with M⁻¹ = diag(1, √2, √3) (orbit R2)",
    coordinates=("x", "y", "z"), classes=("ThreeDof",)))
register_model(ModelEntry(
    "fpu-beta", "flow", FPUBeta, "the FPU-β chain with fixed ends (orbit R3)",
    (Parameter("n", 8, "FPU particles", flag="fpu-n", integer=True),
     Parameter("beta", 1.5, "FPU beta"))))
register_model(ModelEntry(
    "planetary", "flow", _planetary,
    "a star and two planets (Jupiter and Saturn by default) in Jacobi coordinates; its map is "
    "a grid of the outer planet's orbital elements",
    (Parameter("m1", 9.54e-4, "inner planet's mass (the star's is 1)"),
     Parameter("m2", 2.85e-4, "outer planet's mass (the star's is 1)")),
    coordinates=("x1", "y1", "z1", "x2", "y2", "z2"), classes=("Planetary",)))
register_model(ModelEntry(
    "standard", "map", StandardMap, "the standard map p' = p + K sin x, x' = x + p' (x mod 2π)",
    (Parameter("K", 1.2, "kick strength of the standard map"),),
    coordinates=("x", "p"), classes=("StandardMap",)))
register_model(ModelEntry(
    "coupled", "map", CoupledStandardMaps,
    "two coupled standard maps (Skokos, Bountis & Antonopoulos 2007), mod 1",
    (Parameter("K1", 1.5, "first kick strength"), Parameter("K2", 1.5, "second kick strength"),
     Parameter("beta", 0.1, "coupling")),
    coordinates=("x1", "x2", "x3", "x4"), classes=("CoupledStandardMaps",)))
register_model(ModelEntry(
    "kg", "lattice", DisorderedKG, "the disordered Klein–Gordon lattice (1D or 2D)",
    (Parameter("W", 4.0, "disorder strength"),)))
register_model(ModelEntry(
    "fput", "lattice", _fput, "the Fermi–Pasta–Ulam–Tsingou chain",
    (Parameter("alpha", 0.25, "cubic term"), Parameter("beta", 1.0, "quartic term"))))
register_model(ModelEntry(
    "ddnls", "lattice", DDNLS,
    "the disordered discrete nonlinear Schrödinger lattice (1D or 2D)",
    (Parameter("W", 4.0, "disorder strength"), Parameter("beta", 1.0, "nonlinearity"))))


# The models of any H(q, p) import SymPy: built on first use, so that reading
# the registry (the command line's help) stays as quick as before.
def _cr3bp(mu):
    from .cr3bp import CR3BP

    return CR3BP(mu)


def _rotating_bar(omega):
    from .bar import RotatingBar

    return RotatingBar(omega=omega)


def _magnetic_bottle(b0, length):
    from .bottle import MagneticBottle

    return MagneticBottle(b0, length)


#: Sun–Jupiter, as varint.models.cr3bp.SUN_JUPITER_MU (a test checks they agree).
_SUN_JUPITER_MU = 0.000954

register_model(ModelEntry(
    "cr3bp", "flow", _cr3bp,
    "the planar circular restricted three-body problem in the rotating frame (Jacobi "
    "constant checked)",
    (Parameter("mu", _SUN_JUPITER_MU, "mass ratio of the secondary (Sun–Jupiter by default)"),),
    coordinates=("x", "y"), classes=("CR3BP",)))
register_model(ModelEntry(
    "rotating-bar", "flow", _rotating_bar,
    "a rotating Ferrers bar, Miyamoto–Nagai disc and Plummer bulge (Skokos, Patsis & "
    "Athanassoula 2002)",
    (Parameter("omega", 0.054, "pattern speed of the bar"),),
    coordinates=("x", "y", "z"), classes=("RotatingBar",)))
register_model(ModelEntry(
    "magnetic-bottle", "flow", _magnetic_bottle,
    "a charged particle in the mirror field B_z = B0 (1 + z²/L²)",
    (Parameter("b0", 1.0, "field at the bottle's centre"),
     Parameter("length", 1.0, "the mirror length L")),
    coordinates=("x", "y", "z"), classes=("MagneticBottle",)))

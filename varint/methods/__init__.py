"""Integration methods behind the single ``method=`` switch.

A method is a *propagator*: an object that advances a
:class:`~varint.state.RunState` by whole intervals τ, following the rules of
:class:`varint.protocol.Propagator`. Every indicator is written once against
that protocol, so every method feeds the same indicator code.

A method is registered by name with the "module:class" that implements it
(imported on first use, so heyoka and SUNDIALS load only when asked for); a
new method is one file plus one call of :func:`register_method`.

Map models (``model.kind == "map"``, :mod:`varint.models.maps`) are not
integrated: ``"tm"`` iterates them with their own tangent map
(:class:`varint.methods.map.MapPropagator`), and only the methods in
:data:`MAP_METHODS` take them; the others refuse them with that list.

``method="tm"`` has two steppers: the generic one (:mod:`varint.methods.tm`,
H = T + V with band kernels) and, for models split into k ≥ 2 parts (the
lattices, planetary systems), the part stepper (:mod:`varint.methods.parts`),
which :func:`make_propagator` picks by :func:`varint.methods.parts.runs_parts`
(or the propagator around it a model names in ``parts_propagator``:
:mod:`varint.methods.planetary`).
"""

from __future__ import annotations

import importlib

from ..protocol import Renorm
from .options import method_options

__all__ = ["METHODS", "MAP_METHODS", "make_propagator", "register_method", "method_options",
           "propagator_class"]

#: ``method=`` name → "module:class".
METHODS = {
    "tm": "varint.methods.tm:TangentMapPropagator",
    "tdhcc": "varint.tdh.propagators:TDHccPropagator",
    "tdhes": "varint.tdh.propagators:TDHesPropagator",
    "tdheps": "varint.tdh.propagators:TDHepsPropagator",
    "taylor": "varint.baselines.taylor:TaylorPropagator",
    "cvode": "varint.baselines.cvode:CVODEPropagator",
    "dop853": "varint.baselines.dop853:DOP853Propagator",
    "two-particle": "varint.methods.two_particle:TwoParticlePropagator",
}

#: The reference methods, which integrate Hamilton's equations of any H(q, p)
#: (a model with a ∇H, D²H kernel, ``grad_hess_h``) as well as of T + V.
REFERENCE_METHODS = ("taylor", "cvode", "dop853")

#: The methods that take map models: ``method=`` name → "module:class".
MAP_METHODS = {
    "tm": "varint.methods.map:MapPropagator",
    "two-particle": "varint.methods.two_particle:TwoParticlePropagator",
}


def register_method(name: str, target: str, maps: str | None = None) -> None:
    """Make ``method=name`` available everywhere; ``target`` is
    "module:Class" of a class following :class:`varint.protocol.Propagator`,
    and ``maps`` (optional) the one that runs it on map models.

    Raises
    ------
    ValueError
        If the name is taken or a target is not of the form "module:Class".
    """
    key = str(name).lower()
    if key in METHODS:
        raise ValueError(f"a method named {name!r} is already registered")
    for t in (target,) if maps is None else (target, maps):
        if not (isinstance(t, str) and t.count(":") == 1 and all(t.split(":"))):
            raise ValueError(f"target must be 'module:Class', got {t!r}")
    METHODS[key] = target
    if maps is not None:
        MAP_METHODS[key] = maps


def _key(method):
    key = method.lower() if isinstance(method, str) else method
    if key not in METHODS:
        raise ValueError(f"unknown method {method!r}; expected one of: {', '.join(METHODS)}")
    return key


def propagator_class(method, model=None):
    """The class registered under ``method`` (case-insensitive), for
    ``model`` if given (a map model takes the methods of :data:`MAP_METHODS`).

    Raises
    ------
    ValueError
        For an unknown method (the message lists the valid ones), or one
        that does not take map models, for a map.
    """
    key = _key(method)
    target = METHODS[key]
    if getattr(model, "kind", "flow") == "map":
        if key not in MAP_METHODS:
            raise ValueError(f"method {method!r} integrates flows, but {model.name} is a map "
                             f"(iterated, not integrated); maps take: {', '.join(MAP_METHODS)} "
                             "('tm' iterates the map's own tangent map)")
        target = MAP_METHODS[key]
    return _resolve(target)


def _resolve(target):
    """The class named by "module:Class"."""
    module, _, cls = target.partition(":")
    return getattr(importlib.import_module(module), cls)


def make_propagator(method, model, tau, renorm, accumulator=None, **options):
    """Build the propagator registered under ``method``.

    Parameters
    ----------
    method : str
    model : Model
    tau : float
    renorm : Renorm or {"qr", "normalize", "none"}
    accumulator : Accumulator, optional
        Updated after every interval (rule 9 of the protocol).
    **options
        The method's own options.

    Raises
    ------
    ValueError
        For an unknown method (the message lists the valid ones) or renorm.
    TypeError
        For an option the method does not take (the message lists its
        options).
    """
    cls = propagator_class(method, model)
    # Models split into parts (the lattices) run "tm" through their fused
    # part flows (varint.methods.parts decides when), and only "tm" when
    # they have no band kernels for the other methods.
    from .parts import PartsPropagator, generated_rotating, runs_parts

    if _key(method) == "tm" and runs_parts(model, options.get("scheme")):
        # A model may name a propagator of its own around the part stepper
        # ("module:Class"; planetary systems: the correctors at outputs).
        own = getattr(model, "parts_propagator", None)
        cls = PartsPropagator if own is None else _resolve(own)
    elif not getattr(model, "band_kernels", True) and not (
            _key(method) in REFERENCE_METHODS and callable(getattr(model, "grad_hess_h", None))
    ) and not (_key(method) == "tm" and generated_rotating(model)):
        # A model of any H(q, p) gives the reference methods Hamilton's
        # equations from its ∇H, D²H kernel (baselines.rhs) and expression.
        raise ValueError(f"method {method!r} needs the band-Hessian kernels of "
                         f"varint.models.base, which {model.name} does not have (a 2D lattice, "
                         "a ring, or H not of the form T(p) + V(q)); use method='tm'")
    return cls(model, tau, Renorm.parse(renorm), accumulator=accumulator, **options)

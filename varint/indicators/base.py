"""Indicators as data: one frozen object per indicator, in one registry.

An :class:`Indicator` says everything a run needs to compute it, whatever
the method and whether for one orbit or a chaos map of millions:

* how many deviation vectors it carries and how they are renormalised every
  τ (:class:`~varint.protocol.Renorm`), and what given initial vectors must
  satisfy;
* what it accumulates after every interval (an
  :class:`~varint.protocol.Accumulator`, updated by the same compiled code
  inside every method);
* how it reads its values off the run state at an output time, how the
  stacked records become its result, and which single value per orbit a
  chaos map shows, with the default early-stopping threshold;
* its parameters (each with a default and a check), the laws it follows and
  the papers that define it, for its documentation.

A new indicator is one file that builds an :class:`Indicator` and calls
:func:`register_indicator`; :func:`varint.run` and :func:`varint.chaos_map`
then compute it with every method, with no other change. See
:mod:`varint.indicators.local_exponents` for a worked example.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from types import MappingProxyType
from collections.abc import Mapping
from typing import Any
from collections.abc import Callable

import numpy as np

from ..protocol import Accumulator, Renorm
from ..results import IndicatorResult

__all__ = ["Indicator", "Option", "INDICATORS", "register_indicator", "get_indicator",
           "indicator_names", "resolve", "as_values", "Field"]


@dataclass(frozen=True)
class Option:
    """A parameter of an indicator.

    Attributes
    ----------
    default : object
        Its value when the caller gives none (None may mean "derived", as
        the check decides).
    check : callable
        ``check(model, value) -> value``: the value validated and normalised
        (raising ``ValueError`` naming it and what was expected).
    doc : str
        One line for the documentation.
    """

    default: Any
    check: Callable
    doc: str = ""


def _no_finish(fields, options):
    return fields


@dataclass(frozen=True)
class Field:
    """A map value that is one field of the indicator's record, e.g.
    ``Field("sali")`` (a callable object rather than a lambda, so indicators
    pickle for Dask workers)."""

    name: str

    def __call__(self, record, model, options):
        return record[self.name]


def as_values(fields, options):
    """The ``finish`` of indicators whose result is
    :class:`~varint.results.IndicatorResult`: every series under ``values``."""
    return {"values": dict(fields)}


@dataclass(frozen=True, eq=False)
class Indicator:
    """One chaos indicator, as data.

    Attributes
    ----------
    name : str
        Registry key (lower case), e.g. ``"gali"``.
    summary : str
        One line: what it is.
    renorm : Renorm
        How its vectors are renormalised every τ.
    vectors : callable
        ``vectors(model, options, given) -> k``: the number of deviation
        vectors, given the options and the number of columns of
        user-supplied initial vectors (None if drawn at random); raises
        ``ValueError`` if they do not fit.
    read : callable
        ``read(rows, model, t, options) -> dict`` of arrays with a leading
        axis of rows: ``rows`` is a :class:`~varint.state.Rows` (state of
        each orbit at an output time, possibly of several output times at
        once: R rows), ``t`` (R,) the time of each row; renormalised
        vectors, accumulators in ``rows.extra``, ``rows.step`` (R,).
    result : type
        Result class built as ``result(**common, **finish(fields))``; its
        fields are the stacked records, shape ([M,] n_out, ...).
    require : {"orthonormal", "unit", None}
        What given initial vectors must satisfy (orthonormal columns; or
        independent columns, normalised before use; or nothing).
    options : mapping of str -> Option
        The indicator's parameters (passed as keyword arguments to
        :func:`varint.run`).
    accumulator : Accumulator, callable or None
        What it accumulates after every interval, or
        ``accumulator(options) -> Accumulator`` when its initial values
        depend on the options.
    finish : callable
        ``finish(fields, options) -> dict``: the stacked records (orbit
        axis first) turned into the result's fields; by default identity,
        or :func:`as_values` when ``result`` is (a subclass of)
        :class:`~varint.results.IndicatorResult`.
    scalar : callable or None
        ``scalar(record, model, options) -> ndarray (M,)``: the one value
        per orbit a chaos map shows, from a record of ``read``; None if the
        indicator has no such value.
    threshold : float, callable or None
        Default early-stopping threshold of a map (``threshold(model,
        options)`` when it depends on them); None: no early stopping.
    below : bool
        Whether values below the threshold decide an orbit (SALI, GALI) or
        above it (MEGNO, FLI).
    log_scale : bool
        Whether map values spread over decades (plots use log₁₀).
    output_times : callable or None
        ``output_times(t_end, tau, options) -> t_out``: the default output
        times when the caller gives none (log-spaced otherwise).
    count_option : str or None
        The option that states the number of vectors, if any (e.g.
        ``n_exponents``): the run records there the number actually used,
        so provenance and checkpoints name it.
    laws : str
        What the indicator does on regular and chaotic orbits (for the
        documentation).
    references : tuple of str
    map_tolerance : float or None
        The energy error a chaos map's pilot must meet when it chooses the
        step for this indicator, if its classification needs a tighter one
        than :data:`varint.maps.MAP_PILOT_TOL` (measured in
        ``studies/map_defaults.py``); None: the maps' default.
    states : callable or None
        ``states(model, x0, options)``: raises ``ValueError`` (naming the
        orbit) for initial states (M, 2N) where the indicator is not
        defined — e.g. a lattice's distribution over sites at zero energy —
        before any work; None: defined everywhere.
    """

    name: str
    summary: str
    renorm: Renorm
    vectors: Callable
    read: Callable
    result: type
    require: str | None = None
    options: Any = field(default_factory=dict)
    accumulator: Any = None
    finish: Callable = _no_finish
    scalar: Callable | None = None
    threshold: Any = None
    below: bool = True
    log_scale: bool = True
    output_times: Callable | None = None
    count_option: str | None = None
    laws: str = ""
    references: tuple = ()
    map_tolerance: float | None = None
    states: Callable | None = None

    def __post_init__(self):
        if not (isinstance(self.name, str) and re.fullmatch(r"[a-z][a-z0-9_]*", self.name)):
            raise ValueError(f"an indicator's name must be a lower-case identifier, "
                             f"got {self.name!r}")
        object.__setattr__(self, "renorm", Renorm.parse(self.renorm))
        if self.require not in (None, "orthonormal", "unit"):
            raise ValueError(f"indicator {self.name!r}: require must be 'orthonormal', 'unit' "
                             f"or None, got {self.require!r}")
        for label in ("vectors", "read", "finish"):
            if not callable(getattr(self, label)):
                raise ValueError(f"indicator {self.name!r}: {label} must be callable")
        if not isinstance(self.result, type):
            raise ValueError(f"indicator {self.name!r}: result must be a class")
        bad = [k for k, v in dict(self.options).items() if not isinstance(v, Option)]
        if bad:
            raise ValueError(f"indicator {self.name!r}: option {bad[0]!r} must be an Option")
        acc = self.accumulator
        if acc is not None and not (isinstance(acc, Accumulator) or callable(acc)):
            raise ValueError(f"indicator {self.name!r}: accumulator must be an Accumulator "
                             "or a function of the options returning one")
        if acc is not None and self.renorm == Renorm.NONE:
            raise ValueError(f"indicator {self.name!r}: an accumulator needs renormalised "
                             "vectors (renorm 'qr' or 'normalize')")
        tol = self.map_tolerance
        if tol is not None and not (isinstance(tol, (int, float)) and 0 < tol < math.inf):
            raise ValueError(f"indicator {self.name!r}: map_tolerance must be a positive "
                             f"finite energy error or None, got {tol!r}")
        if self.finish is _no_finish and issubclass(self.result, IndicatorResult):
            object.__setattr__(self, "finish", as_values)
        # A plain dict (a copy): indicators travel to Dask workers by pickle.
        object.__setattr__(self, "options", dict(self.options))

    # -- what a run asks of it ------------------------------------------------
    def configure(self, model, given):
        """The indicator's options from the caller's ``given`` ones, each
        checked, defaults filled in.

        Raises
        ------
        TypeError
            For an option it does not take (the message lists its options).
        """
        unknown = sorted(set(given) - set(self.options))
        if unknown:
            raise TypeError(f"unknown option {unknown[0]!r} for indicator {self.name!r}; its "
                            f"options: {', '.join(self.options) or 'none'}")
        return {name: opt.check(model, given.get(name, opt.default))
                for name, opt in self.options.items()}

    def check_states(self, model, x0, options):
        """Raise ``ValueError`` for initial states ``x0`` (M, 2N) where the
        indicator is undefined (see ``states``)."""
        if self.states is not None:
            self.states(model, x0, options)

    def accumulator_for(self, options):
        """The :class:`Accumulator` of a run with these options, or None."""
        acc = self.accumulator
        return acc(options) if callable(acc) and not isinstance(acc, Accumulator) else acc

    def default_threshold(self, model, options):
        """The early-stopping threshold of a map, or None."""
        t = self.threshold
        return t(model, options) if callable(t) else t

    def settled(self, values, threshold):
        """Which orbits a map value decides (NaN decides nothing)."""
        with np.errstate(invalid="ignore"):
            return values < threshold if self.below else values > threshold

    def describe(self):
        """JSON-serialisable summary (for the documentation and listings)."""
        return {"name": self.name, "summary": self.summary, "renorm": self.renorm.name.lower(),
                "options": {k: o.doc for k, o in self.options.items()},
                "accumulates": None if self.accumulator is None else "every interval",
                "map": self.scalar is not None, "laws": self.laws,
                "references": list(self.references)}


#: Name → Indicator. Read-only view; add with :func:`register_indicator`.
_REGISTRY: dict = {}
INDICATORS = MappingProxyType(_REGISTRY)

#: Shorthands: name → (indicator, fixed options), e.g. "x1" for the largest
#: Lyapunov exponent alone; "gali_3" style names are read as GALI with k.
_ALIASES: dict = {}


def register_indicator(indicator: Indicator,
                       aliases: Mapping[str, Mapping[str, Any]] | None = None) -> Indicator:
    """Add ``indicator`` to :data:`INDICATORS` (and optional shorthands
    ``{alias: options}``); returns it.

    Raises
    ------
    ValueError
        If it is not an :class:`Indicator` or its name is taken.
    """
    if not isinstance(indicator, Indicator):
        raise ValueError(f"register_indicator takes an Indicator, got "
                         f"{type(indicator).__name__} {indicator!r}")
    if indicator.name in _REGISTRY or indicator.name in _ALIASES:
        raise ValueError(f"an indicator named {indicator.name!r} is already registered")
    _REGISTRY[indicator.name] = indicator
    for alias, fixed in (aliases or {}).items():
        _ALIASES[alias] = (indicator.name, dict(fixed))
    return indicator


def indicator_names() -> list:
    """Every name :func:`resolve` takes: the registered indicators and
    their shorthands ("x1"), without the "gali_k" pattern."""
    return list(_REGISTRY) + [a for a in _ALIASES if a not in _REGISTRY]


def get_indicator(name: str | Indicator) -> Indicator:
    """The indicator of :func:`resolve` among those registered so far
    (:func:`varint.indicators.get_indicator` loads a built-in's module
    first); a ValueError lists the valid names."""
    return resolve(name)[0]


def resolve(name):
    """``(indicator, fixed options)`` for a name, a shorthand ("x1",
    "gali_3") or an Indicator."""
    if isinstance(name, Indicator):
        return name, {}
    key = name.lower() if isinstance(name, str) else name
    if key in _REGISTRY:
        return _REGISTRY[key], {}
    if key in _ALIASES:
        target, fixed = _ALIASES[key]
        return _REGISTRY[target], dict(fixed)
    match = re.fullmatch(r"gali_?(\d+)", key) if isinstance(key, str) else None
    if match and "gali" in _REGISTRY:
        return _REGISTRY["gali"], {"k": int(match.group(1))}
    names = list(_REGISTRY) + list(_ALIASES) + ["gali_k"]
    raise ValueError(f"unknown indicator {name!r}; expected one of: {', '.join(names)}")

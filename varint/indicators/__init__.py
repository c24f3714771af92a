"""Chaos indicators as data: one :class:`Indicator` per indicator in the
registry :data:`INDICATORS` (see :mod:`varint.indicators.base` for what an
indicator declares and how to add one).

Built in: ``"lyapunov"`` (alias ``"x1"`` for X_1 alone), ``"gali"`` (and
``"gali_k"``), ``"sali"``, ``"megno"``, ``"fli"``, ``"ofli"``,
``"local_exponents"``, ``"integrate"`` (the orbit itself), and for lattices
``"spreading"`` and ``"dvd"`` (:mod:`varint.indicators.lattice`).

A built-in indicator's module is imported, and the indicator registered,
the first time its name is asked for (:data:`BUILT_IN`): a process that
computes Lyapunov exponents imports none of the others (issue 28, a first
run's start-up). Listing the registry, an unknown name, or registering a
new indicator imports them all first, so the list is complete and a new
name cannot take a built-in's.
"""

from __future__ import annotations

import importlib
import re
from collections.abc import Iterator, Mapping
from typing import TYPE_CHECKING

from . import base
from .base import Field, Indicator, Option, as_values

if TYPE_CHECKING:
    from .alignment import gali_from_vectors, sali_from_vectors

__all__ = ["INDICATORS", "Indicator", "Option", "Field", "register_indicator", "get_indicator",
           "indicator_names", "resolve", "as_values", "gali_from_vectors", "sali_from_vectors",
           "BUILT_IN"]

#: Each built-in indicator's name and shorthand → the module of this package
#: that defines and registers it.
BUILT_IN = {"lyapunov": "lyapunov", "x1": "lyapunov", "lyapunov_spectrum": "lyapunov",
            "gali": "alignment", "sali": "alignment", "megno": "megno", "fli": "megno",
            "ofli": "megno", "local_exponents": "local_exponents", "integrate": "orbit",
            "spreading": "lattice", "dvd": "lattice"}

#: Names this package gives from its modules when first asked for.
_FROM_MODULES = {"gali_from_vectors": "alignment", "sali_from_vectors": "alignment"}


def _load(name):
    """Import the module that registers the built-in indicator ``name``
    (a name, a shorthand or a "gali_k" name, any case), if there is one."""
    if not isinstance(name, str):
        return
    key = name.lower()
    module = BUILT_IN.get(key) or ("alignment" if re.fullmatch(r"gali_?\d+", key) else None)
    if module is not None:
        importlib.import_module(f".{module}", __name__)


def _load_all():
    for module in sorted(set(BUILT_IN.values())):
        importlib.import_module(f".{module}", __name__)


class _Registry(Mapping):
    """Name → :class:`Indicator`: the read-only registry of
    :mod:`varint.indicators.base`, which imports a built-in indicator's
    module when its name is looked up, and all of them when it is listed."""

    def __getitem__(self, name):
        _load(name)
        return base.INDICATORS[name]

    def __contains__(self, name):
        _load(name)
        return name in base.INDICATORS

    def __iter__(self) -> Iterator[str]:
        _load_all()
        return iter(base.INDICATORS)

    def __len__(self):
        _load_all()
        return len(base.INDICATORS)

    def __repr__(self):
        _load_all()
        return f"INDICATORS({dict(base.INDICATORS)!r})"


#: Name → Indicator. Read-only view; add with :func:`register_indicator`.
INDICATORS: Mapping[str, Indicator] = _Registry()


def register_indicator(indicator, aliases=None):
    """:func:`varint.indicators.base.register_indicator`, after the built-in
    indicators are registered (a new one may not take their names)."""
    _load_all()
    return base.register_indicator(indicator, aliases)


def indicator_names():
    """:func:`varint.indicators.base.indicator_names`, built-ins included."""
    _load_all()
    return base.indicator_names()


def resolve(name):
    """``(indicator, fixed options)`` for a name, a shorthand ("x1",
    "gali_3") or an Indicator (:func:`varint.indicators.base.resolve`); an
    unknown name's error lists every indicator."""
    _load(name)
    try:
        return base.resolve(name)
    except ValueError:
        _load_all()
        return base.resolve(name)


def get_indicator(name):
    """The registered :class:`Indicator` called ``name`` (case-insensitive),
    or ``name`` itself if it is an Indicator.

    Raises
    ------
    ValueError
        For an unknown name; the message lists the valid ones.
    """
    return resolve(name)[0]


def __getattr__(name):
    # Called only for names not yet in the package (PEP 562): a function of
    # an indicator's module, or the module itself.
    module = _FROM_MODULES.get(name, name if name in BUILT_IN.values() else None)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = importlib.import_module(f".{module}", __name__)
    return value if module == name else getattr(value, name)

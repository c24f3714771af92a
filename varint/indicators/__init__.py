"""Chaos indicators as data: one :class:`Indicator` per indicator in the
registry :data:`INDICATORS` (see :mod:`varint.indicators.base` for what an
indicator declares and how to add one).

Built in: ``"lyapunov"`` (alias ``"x1"`` for X_1 alone), ``"gali"`` (and
``"gali_k"``), ``"sali"``, ``"megno"``, ``"fli"``, ``"ofli"``,
``"local_exponents"``, ``"integrate"`` (the orbit itself), and for lattices
``"spreading"`` and ``"dvd"`` (:mod:`varint.indicators.lattice`).
"""

from . import alignment, lattice, local_exponents, lyapunov, megno, orbit  # noqa: F401  (registers them)
from .alignment import gali_from_vectors, sali_from_vectors
from .base import (INDICATORS, Field, Indicator, Option, as_values, get_indicator,
                   indicator_names, register_indicator, resolve)

__all__ = ["INDICATORS", "Indicator", "Option", "Field", "register_indicator", "get_indicator",
           "indicator_names", "resolve", "as_values", "gali_from_vectors", "sali_from_vectors"]

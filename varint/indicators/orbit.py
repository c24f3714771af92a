"""Plain integration as an indicator: the orbit at the output times, and
(if given) the deviation vectors carried along, never renormalised.

For ``method="tm"`` the final vectors are exactly the derivative of the
numerical orbit map applied to the initial ones (Skokos & Gerlach 2010,
Sect. V.C). Without given vectors no tangent work is done at all.
"""

from __future__ import annotations

from ..protocol import Renorm
from ..results import IntegrationResult
from .base import Indicator, register_indicator

__all__ = ["ORBIT"]


def _vectors(model, options, given):
    return 0 if given is None else given


def _read(rows, model, t, options):
    return {"states": rows.x.copy()}


def _only_the_end(t_end, tau, options):
    return 1


ORBIT = register_indicator(Indicator(
    name="integrate",
    summary="the orbit (and raw deviation vectors, if given) at the output times",
    renorm=Renorm.NONE,
    vectors=_vectors,
    read=_read,
    result=IntegrationResult,
    output_times=_only_the_end,
    laws="the tangent map of the whole run applied to the initial vectors",
))

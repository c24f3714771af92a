"""The alignment indices: GALI_k and SALI.

max(k) deviation vectors are normalised to unit length every τ. GALI_k is
the volume spanned by the first k of them, the product of the singular
values of the 2N × k matrix (Skokos & Gerlach 2010, Sect. IV, eq. 18); SALI
is min(‖ŵ₁ + ŵ₂‖, ‖ŵ₁ − ŵ₂‖), which behaves like GALI_2.

References
----------
Ch. Skokos, J. Phys. A 34, 10029 (2001) — SALI.
Ch. Skokos, T. Bountis & Ch. Antonopoulos, Physica D 231, 30 (2007) and
Eur. Phys. J. ST 165, 5 (2008) — GALI.
"""

from __future__ import annotations

import numbers

import numpy as np

from .. import _validate as check
from ..protocol import Renorm
from ..results import GALIResult, SALIResult
from .base import Field, Indicator, Option, register_indicator

__all__ = ["GALI", "SALI", "gali_from_vectors", "sali_from_vectors"]

#: Below this an alignment index is decided "chaotic" by a map's early
#: stopping: well under any value a regular orbit reaches in practice, and
#: above the round-off floor (~1e-16) where the indices stop falling.
DECIDED = 1e-8


def gali_from_vectors(W, orders):
    """GALI_k of the first k columns of unit vectors ``W`` (M, 2N, K), for
    each k in ``orders``: the product of the singular values (paper eq. 18).

    Returns a dict k -> ndarray of shape (M,).
    """
    return {k: np.prod(np.linalg.svd(W[:, :, :k], compute_uv=False), axis=-1) for k in orders}


def sali_from_vectors(W):
    """SALI = min(‖ŵ₁ + ŵ₂‖, ‖ŵ₁ − ŵ₂‖) of the first two columns of unit
    vectors ``W`` (M, 2N, K), shape (M,)."""
    w1, w2 = W[:, :, 0], W[:, :, 1]
    return np.minimum(np.linalg.norm(w1 + w2, axis=1), np.linalg.norm(w1 - w2, axis=1))


def _orders(model, k):
    if k is None:
        k = tuple(range(2, min(4, model.dim) + 1))
    orders = (k,) if isinstance(k, numbers.Integral) and not isinstance(k, bool) else k
    try:
        orders = tuple(orders)
    except TypeError:
        raise ValueError(f"k must be an integer or a sequence of integers, got {k!r}") from None
    if not orders:
        raise ValueError("k must name at least one GALI order")
    orders = tuple(check.n_vectors(o, model.dim, "GALI order k", minimum=2) for o in orders)
    if len(set(orders)) != len(orders):
        raise ValueError(f"GALI orders must be distinct, got {orders}")
    return tuple(sorted(orders))


def _gali_vectors(model, options, given):
    k = options["k"][-1]
    if given is not None and given < k:
        raise ValueError(f"GALI_{k} needs {k} deviation vectors, {given} were given")
    return k


def _read_gali(rows, model, t, options):
    return {f"gali_{o}": v for o, v in gali_from_vectors(rows.W, options["k"]).items()}


def _finish_gali(fields, options):
    return {"gali": {o: fields[f"gali_{o}"] for o in options["k"]}}


def _map_order(model, orders):
    """The order a map shows: the largest k ≤ N, for which GALI_k stays
    constant on an N-torus and falls exponentially on chaotic orbits (paper
    eqs. 16–17); the smallest order if all exceed N."""
    low = [k for k in orders if k <= model.n_dof]
    return low[-1] if low else orders[0]


def _gali_scalar(record, model, options):
    return record[f"gali_{_map_order(model, options['k'])}"]


def _gali_threshold(model, options):
    # For k > N the regular values fall as power laws too: no safe default.
    return DECIDED if _map_order(model, options["k"]) <= model.n_dof else None


GALI = register_indicator(Indicator(
    name="gali",
    summary="generalised alignment indices GALI_k(t): the volume of k unit deviation "
            "vectors (paper eq. 18)",
    renorm=Renorm.NORMALIZE,
    vectors=_gali_vectors,
    read=_read_gali,
    result=GALIResult,
    require="unit",
    options={"k": Option(None, _orders, "GALI orders, each in 2..2N; GALI_N by default")},
    finish=_finish_gali,
    scalar=_gali_scalar,
    threshold=_gali_threshold,
    laws="regular orbit on an s-torus: GALI_k ≈ const for k ≤ s, ∝ t^{−2(k−s)} for k > s "
         "(paper eq. 17, s = N for a generic torus); chaotic: "
         "∝ exp(−[(χ1−χ2) + … + (χ1−χk)] t) (eq. 16)",
    references=("Skokos, Bountis & Antonopoulos, Physica D 231, 30 (2007)",
                "Skokos, Bountis & Antonopoulos, Eur. Phys. J. ST 165, 5 (2008)"),
))


def _sali_vectors(model, options, given):
    if given is not None and given != 2:
        raise ValueError(f"SALI needs exactly 2 deviation vectors, {given} were given")
    return 2


def _read_sali(rows, model, t, options):
    return {"sali": sali_from_vectors(rows.W)}


SALI = register_indicator(Indicator(
    name="sali",
    summary="smaller alignment index SALI(t) = min(‖ŵ₁ + ŵ₂‖, ‖ŵ₁ − ŵ₂‖)",
    renorm=Renorm.NORMALIZE,
    vectors=_sali_vectors,
    read=_read_sali,
    result=SALIResult,
    require="unit",
    scalar=Field("sali"),
    threshold=DECIDED,
    laws="regular orbits (2 dof): SALI fluctuates about a positive value; chaotic: "
         "∝ exp(−(χ1−χ2) t)",
    references=("Skokos, J. Phys. A 34, 10029 (2001)",),
    # Its maps classify like a tight reference at least as often as heyoka's
    # batch mode at tol 1e-6 only from this pilot tolerance on (98.2 % against
    # 98.0 %; 97.6 % at the maps' 1e-7): a SALI falling below 1e-8 late, on a
    # sticky orbit, is decided by small errors (studies/map_defaults.py).
    map_tolerance=1e-8,
))

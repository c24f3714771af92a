"""A model's potential as the expressions a generated stepper evaluates:
∇V, D²V and the corrector's ∇C and D²C (C = ∇VᵀM⁻¹∇V, Skokos & Gerlach
2010, eq. 26), in the symbols q0 … q{N−1}; and which models get a
generated stepper at all (:func:`symbolic_fits`).

The symbolic work costs far more than anything else in building a stepper,
so it is cached: the expressions per potential and process, and for a
built-in model even whether it fits and the key of its potential, on disk
beside the steppers (a new process then builds no SymPy expression).
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np
import sympy as sp  # type: ignore[import-untyped]

from ..files import atomic_write, canonical_json
from ..models.symbolic import SymbolicModel
from ..paths import cache_dir

__all__ = ["Expressions", "expressions", "symbolic_fits", "model_key", "SYMBOLIC_MAX_N",
           "SYMBOLIC_MAX_VALUES"]

#: Largest N and largest 2N(1 + k) (orbit and vectors held in local
#: variables) for which straight-line code is generated; beyond, the generic
#: stepper is used. The code grows as stages × 2N(1 + k) and LLVM's compile
#: time faster: FPU n = 5 with 10 vectors (110 values) took 50 s to
#: compile, the 3-dof model's full spectrum (42 values) a few seconds.
SYMBOLIC_MAX_N = 16
SYMBOLIC_MAX_VALUES = 48


@dataclass(frozen=True)
class Expressions:
    """∇V, D²V, ∇C and D²C of a symbolic model in the symbols q0 … q{N−1}."""

    n: int
    minv: tuple
    g: tuple       # ∇V_i
    H: dict        # (i, j), i ≤ j -> D²V_ij (non-zero entries only)
    gc: tuple      # ∇C_i
    HC: dict       # (i, j), i ≤ j -> D²C_ij (non-zero entries only)
    q: tuple       # the symbols


@lru_cache(maxsize=32)
def expressions(V_srepr, minv_srepr, n):
    """The expressions of a potential given by its SymPy ``srepr`` (cached
    by it: the symbolic work costs far more than the rest)."""
    q = sp.symbols(f"q0:{n}")
    V = sp.sympify(V_srepr)
    minv = tuple(sp.sympify(m) for m in minv_srepr)
    g = tuple(sp.diff(V, qi) for qi in q)
    H = {}
    for i in range(n):
        for j in range(i, n):
            e = sp.diff(g[i], q[j])
            if e != 0:
                H[i, j] = e

    def h(i, j):
        return H.get((min(i, j), max(i, j)), sp.Integer(0))

    # C = Σ_k m_k g_k²: ∇C_i = 2 Σ_k m_k g_k H_ki and
    # D²C_ij = 2 Σ_k m_k (H_ki H_kj + g_k ∂_j H_ki)  (paper eq. 26 with M⁻¹).
    gc = tuple(2 * sp.Add(*[minv[k] * g[k] * h(k, i) for k in range(n)]) for i in range(n))
    HC = {}
    for i in range(n):
        for j in range(i, n):
            e = 2 * sp.Add(*[minv[k] * (h(k, i) * h(k, j) + g[k] * sp.diff(h(k, i), q[j]))
                             for k in range(n)])
            if e != 0:
                HC[i, j] = e
    return Expressions(n=n, minv=tuple(float(m) for m in minv), g=g, H=H, gc=gc, HC=HC, q=q)


@lru_cache(maxsize=256)
def _symbolic_key(s):
    """The arguments of :func:`expressions` for a model's (frozen,
    hashable) symbolic form: printed once per process, not once per chunk
    of a chaos map (~0.4 ms each)."""
    n = len(s.q)
    V = s.V.xreplace(dict(zip(s.q, sp.symbols(f"q0:{n}"), strict=True)))
    return sp.srepr(V), tuple(sp.srepr(m) for m in s.inverse_mass), n


def symbolic_fits(model, k):
    """Whether ``model`` gets a generated straight-line stepper for ``k``
    vectors (an autonomous flow that knows its potential symbolically and
    is small; a time-dependent V takes the generic stepper's extended phase
    space)."""
    if getattr(model, "time_dependent", False) or getattr(model, "kind", "flow") != "flow":
        return False
    if not callable(getattr(model, "symbolic", None)) or model.n_dof > SYMBOLIC_MAX_N:
        return False
    if 2 * model.n_dof * (1 + k) > SYMBOLIC_MAX_VALUES:
        return False
    return _facts(model)[0]


def model_key(model):
    """The arguments of :func:`expressions` for ``model``."""
    return _facts(model)[1]


def _facts(model):
    """(whether the model's symbolic form has its coordinates and masses,
    the form's :func:`_symbolic_key` or None).

    For a built-in model they are kept in the kernels' cache directory,
    named after the model's description (:meth:`~varint.models.base.Model.describe`,
    "enough to rebuild the model") and the code of ``varint.models``: a new
    process that runs it on cached steppers then builds no SymPy
    expression, whose first costs ~0.1 s (SymPy imports its tensor
    module). Other models are asked directly: one made from an expression
    (``from_potential``) holds it already, and the code behind a user's
    own class is not known.
    """
    cls = type(model)
    if isinstance(model, SymbolicModel) or not cls.__module__.startswith("varint.models."):
        return _facts_now(model)
    name = _description_id(cls, canonical_json(model.describe()))
    if name in _FACTS:
        return _FACTS[name]
    path = cache_dir() / "kernels" / f"varint_model_{name}.json"
    try:
        fits, key = json.loads(path.read_text())
        facts = (bool(fits), None if key is None else (key[0], tuple(key[1]), int(key[2])))
    except (OSError, ValueError, TypeError, IndexError):
        facts = _facts_now(model)
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            atomic_write(path, json.dumps(facts))
        except OSError:
            pass            # an unwritable cache costs SymPy's time, not the run
    _FACTS[name] = facts
    return facts


#: :func:`_facts` of the models run in this process, by description id.
_FACTS: dict[str, tuple] = {}


def _facts_now(model):
    """:func:`_facts` from the model's SymPy form."""
    try:
        s = model.symbolic()
    except (NotImplementedError, ValueError):
        return False, None
    return _facts_of(s, model.n_dof, tuple(float(m) for m in model.inverse_mass))


@lru_cache(maxsize=256)
def _facts_of(s, n_dof, inverse_mass):
    """:func:`_facts` of the symbolic form ``s`` for a model of ``n_dof``
    coordinates and these masses (once per form and process)."""
    fits = len(s.q) == n_dof and np.allclose([float(m) for m in s.inverse_mass],
                                             inverse_mass, rtol=1e-15, atol=0)
    return bool(fits), _symbolic_key(s) if fits else None


@lru_cache(maxsize=256)
def _description_id(cls, description):
    """A name for a built-in model's symbolic facts: its class and
    description and the code they come from (``varint.models`` and this
    module, which prints the key), so that a change of either names new
    facts."""
    digest = hashlib.sha256(f"{cls.__module__}.{cls.__qualname__}|{description}".encode())
    digest.update(Path(__file__).read_bytes())
    for path in sorted((Path(__file__).parent.parent / "models").glob("*.py")):
        digest.update(path.read_bytes())
    return digest.hexdigest()[:24]

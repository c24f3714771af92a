"""A model's potential as the expressions a generated stepper evaluates:
∇V, D²V and the corrector's ∇C and D²C (C = ∇VᵀM⁻¹∇V, Skokos & Gerlach
2010, eq. 26), in the symbols q0 … q{N−1}; and which models get a
generated stepper at all (:func:`symbolic_fits`).

Two kinds of model qualify: H = ½pᵀM⁻¹p + V(q) (every built-in potential
and :func:`~varint.models.from_potential`), whose drift is free motion, and
H = A + V(q) with A the solvable quadratic of a rotating frame or a uniform
magnetic field (:class:`~varint.models.hamiltonian.IntegrableHamiltonian`:
the restricted three-body problem), whose drift is A's exact linear flow
(:attr:`Expressions.planar`, emitted by :class:`~varint.codegen.tm.TMBody`).
For the latter M⁻¹ is A's diagonal of ∂²A/∂p² (a, a, a_i): A's rotation
term is linear in p, so the corrector C = {V,{V,A}} = ∇Vᵀ diag(a) ∇V is the
same as for ½pᵀM⁻¹p.

A model whose potential is a closed form plus a term that has none (the
Ferrers bar of :class:`~varint.models.bar.RotatingBar`: λ is a root, the
W_ijk elliptic integrals) declares that term as an :class:`ExtraForce`
(``model.extra_force``) and its closed part's form by
``model.closed_symbolic()``: the stepper is generated for the closed part
and every kick adds the term's gradient and Hessian by calling its compiled
kernel (:attr:`Expressions.extra`). Its corrector would need the term's
third derivatives, so such a model runs no corrector scheme on it.

The symbolic work costs far more than anything else in building a stepper,
so it is cached: the expressions per potential and process, and for a
built-in model even whether it fits and the key of its potential, on disk
beside the steppers (a new process then builds no SymPy expression, and
does not even import SymPy). That file is signed and holds only a flag and
a key (:mod:`varint.codecache`); the expressions are only ever built from a
model's own SymPy form, never from text read back from disk.
"""

from __future__ import annotations

import hashlib
import importlib.util
import re
import weakref
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from .. import cachedir, codecache
from ..files import canonical_json

__all__ = ["Expressions", "ExtraForce", "expressions", "symbolic_fits", "model_key",
           "ensure_form", "planar_key", "SYMBOLIC_MAX_N", "SYMBOLIC_MAX_VALUES"]

#: Largest N and largest 2N(1 + k) (orbit and vectors held in local
#: variables) for which straight-line code is generated; beyond, the generic
#: stepper is used. The code grows as stages × 2N(1 + k) and LLVM's compile
#: time faster: FPU n = 5 with 10 vectors (110 values) took 50 s to
#: compile, the 3-dof model's full spectrum (42 values) a few seconds.
SYMBOLIC_MAX_N = 16
SYMBOLIC_MAX_VALUES = 48


@dataclass(frozen=True)
class ExtraForce:
    """A compiled term of the potential that a generated stepper's kicks add
    to the closed part's ∇V and D²V (module docstring).

    Attributes
    ----------
    function : numba dispatcher
        ``function(q, g, D, hessian, *constants)``, compiled with
        ``cache=True`` at the top level of its module: adds the term's
        gradient at the positions ``q`` (N,) to ``g`` (N,) and, if
        ``hessian``, its Hessian to ``D`` (N, N), in place (both hold the
        closed part's values when it is called).
    constants : tuple
        Its further arguments: floats, or tuples of floats (passed as
        arrays). They are written into the stepper's source as literals.
    callees : tuple of modules
        The modules of the compiled functions ``function`` calls (e.g. the
        parts of a potential inlined into it), whose files name the stepper
        as its own module's does.
    """

    function: object
    constants: tuple
    callees: tuple = ()

    def identity(self):
        """What the stepper's code depends on: the function's module, name
        and the hash of its module's file, the constants' exact values,
        then the hash of each callee's file (numba's cache of a stepper
        does not follow a changed callee)."""
        py = getattr(self.function, "py_func", self.function)
        digest = _file_digest(py.__code__.co_filename)
        callees = "".join(f" {_file_digest(m.__file__)}" for m in self.callees)
        return f"{py.__module__}:{py.__qualname__}:{digest} {self.constants!r}{callees}"


def _file_digest(path):
    """The first 16 hex digits of the SHA-256 of the file at ``path``."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()[:16]


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
    #: A rotating frame's drift (:func:`planar_key`), or None for free motion.
    planar: tuple | None = None
    #: A compiled term added to ∇V and D²V in every kick (:class:`ExtraForce`);
    #: then ``H`` holds every entry i ≤ j, zeros included.
    extra: ExtraForce | None = None


#: The symbolic forms met in this process, by :func:`_symbolic_key`: (V in
#: q0 … q{N−1}, inverse masses, N, the rotating frame's :func:`planar_key`
#: or None, the :class:`ExtraForce` or None). Only ever filled from a model's own SymPy form, never from a
#: file.
_FORMS: dict = {}


@lru_cache(maxsize=32)
def expressions(key):
    """The expressions of the potential of ``key`` (:func:`model_key`;
    cached by it: the symbolic work costs far more than the rest)."""
    import sympy as sp  # type: ignore[import-untyped]  # (see _symbolic_key)

    V, minv, n, planar, extra = _FORMS[key]
    q = sp.symbols(f"q0:{n}")
    g = tuple(sp.diff(V, qi) for qi in q)
    H = {}
    for i in range(n):
        for j in range(i, n):
            e = sp.diff(g[i], q[j])
            # The extra term may fill any entry (its kernel adds to all).
            if e != 0 or extra is not None:
                H[i, j] = sp.Float(0.0) if e == 0 else e

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
    return Expressions(n=n, minv=tuple(float(m) for m in minv), g=g, H=H, gc=gc, HC=HC, q=q,
                       planar=planar, extra=extra)


def potential_form(key):
    """The potential V of ``key`` (:func:`model_key`) as the SymPy
    expression in q0 … q{N−1} the steppers' ∇V and D²V are made from
    (a model's own form, never read from a file)."""
    return _FORMS[key][0]


def planar_key(planar, n):
    """A rotating frame's drift as a hashable tuple ``(u, v, a, b, Ω,
    ((a_i, b_i) for every i))`` from the ``planar`` dict of
    :class:`~varint.models.hamiltonian.IntegrableHamiltonian` (A =
    ½a|p_⊥|² + ½b|q_⊥|² − Ω(q_u p_v − q_v p_u) + Σ_i ½a_i p_i² + ½b_i q_i²;
    :func:`varint.flows.split.planar_params`); the plane's own entries
    repeat (a, b)."""
    u, v = (int(c) for c in planar["plane"])
    a, b = float(planar["a"]), float(planar["b"])
    pairs = tuple((a, b) if i in (u, v) else tuple(float(c) for c in planar["others"][i])
                  for i in range(n))
    return (u, v, a, b, float(planar["omega"]), pairs)


@lru_cache(maxsize=256)
def _symbolic_key(s, planar=None, extra=None):
    """A name (32 hex digits) for a model's (frozen, hashable) symbolic form:
    the hash of its exact SymPy text (``srepr``) in the symbols q0 …
    q{N−1}, worked out once per process, not once per chunk of a chaos map
    (~0.4 ms each). The form itself is kept in ``_FORMS``: a stepper's
    source is only ever emitted from a model's own expressions.

    SymPy is imported here and in :func:`expressions`, where a form is
    worked on, not with this module: a process whose steppers and facts
    are all cached never needs it (importing it costs ~0.35 s)."""
    import sympy as sp  # type: ignore[import-untyped]

    n = len(s.q)
    V = s.V.xreplace(dict(zip(s.q, sp.symbols(f"q0:{n}"), strict=True)))
    # A rotating frame's masses are A's coefficients a of p² (module docstring).
    minv = tuple(s.inverse_mass) if planar is None else tuple(sp.Rational(a)
                                                               for a, _ in planar[5])
    text = "|".join([sp.srepr(V), *(sp.srepr(m) for m in minv), str(n)])
    if planar is not None:
        text += f"|planar {planar!r}"
    if extra is not None:
        text += f"|extra {extra.identity()}"
    key = hashlib.sha256(text.encode()).hexdigest()[:32]
    _FORMS[key] = (V, minv, n, planar, extra)
    return key


def symbolic_fits(model, k):
    """Whether ``model`` gets a generated straight-line stepper for ``k``
    vectors (an autonomous flow that knows its potential symbolically and
    is small, H = ½pᵀM⁻¹p + V or a rotating frame's A + V; a time-dependent
    V takes the generic stepper's extended phase space)."""
    if getattr(model, "time_dependent", False) or getattr(model, "kind", "flow") != "flow":
        return False
    if not callable(getattr(model, "symbolic", None)) or model.n_dof > SYMBOLIC_MAX_N:
        return False
    if 2 * model.n_dof * (1 + k) > SYMBOLIC_MAX_VALUES:
        return False
    return _facts(model)[0]


def model_key(model):
    """The :func:`_symbolic_key` of ``model``'s form (the argument of
    :func:`expressions`)."""
    return _facts(model)[1]


def ensure_form(model, key):
    """Make sure the form of ``key`` is known in this process, from
    ``model``'s own SymPy form (the stored facts named the key; the model
    must give the same one).

    Raises
    ------
    RuntimeError
        If the model's form has another key than its cached facts say.
    """
    if key not in _FORMS and _facts_now(model)[1] != key:
        raise RuntimeError(f"the cached symbolic facts of {model.name} do not match its form; "
                           f"delete {cachedir.location()} and run again")


#: A stored symbolic key: 32 hex digits.
_KEY = re.compile(r"[0-9a-f]{32}\Z")


def _facts(model):
    """(whether the model's symbolic form has its coordinates and masses,
    the form's :func:`_symbolic_key` or None).

    For a built-in model they are kept in the kernels' cache directory,
    named after the model's description (:meth:`~varint.models.base.Model.describe`,
    "enough to rebuild the model"), the code of ``varint.models`` and
    SymPy's version: a new process that runs it on cached steppers then
    builds no SymPy expression, whose first costs ~0.1 s (SymPy imports its
    tensor module). The file is signed and holds only a flag and a key
    (:mod:`varint.codecache`): a file that fails its check or holds
    anything else is discarded. Other models are asked directly: one made
    from an expression (``from_potential``) holds it already, and the code
    behind a user's own class is not known.
    """
    # A model whose form is fixed when it is built (``frozen_form``: an
    # H(q, p) model) has the same facts all its life: asked once, not at
    # every call (its description and the hash of it cost ~0.1 ms, asked
    # four times a run).
    if getattr(model, "frozen_form", False):
        try:
            return _INSTANCE_FACTS[model]
        except KeyError:
            facts = _INSTANCE_FACTS[model] = _facts_by_description(model)
            return facts
    return _facts_by_description(model)


#: :func:`_facts` of the models with a ``frozen_form``, per instance.
_INSTANCE_FACTS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _facts_by_description(model):
    """:func:`_facts`, asked of the model's form or of the stored facts
    named after its description."""
    cls = type(model)
    # The models of varint.models.symbolic (from_potential) hold their form.
    if cls.__module__ == "varint.models.symbolic" or not cls.__module__.startswith(
            "varint.models."):
        return _facts_now(model)
    description = canonical_json(model.describe())
    extra = getattr(model, "extra_force", None)
    if extra is not None:
        # Its key names the extra force; a description need not.
        description += f"|extra {extra.identity()}"
    name = _description_id(cls, description)
    if name in _FACTS:
        return _FACTS[name]
    file = f"varint_model_{name}.json"
    facts = _stored_facts(codecache.read_json("kernels", file, "symbolic facts file"))
    if facts is None:
        facts = _facts_now(model)
        # An unwritable cache costs SymPy's time, not the run.
        codecache.write_json("kernels", file, list(facts))
    _FACTS[name] = facts
    return facts


def _stored_facts(value):
    """``value`` read from a facts file as (fits, key), or None unless it is
    exactly what :func:`_facts` writes."""
    if not (isinstance(value, list) and len(value) == 2 and isinstance(value[0], bool)):
        return None
    fits, key = value
    if fits and isinstance(key, str) and _KEY.match(key):
        return True, key
    return (False, None) if not fits and key is None else None


#: :func:`_facts` of the models run in this process, by description id.
_FACTS: dict[str, tuple] = {}


def _facts_now(model):
    """:func:`_facts` from the model's SymPy form (with an
    :class:`ExtraForce`, its closed part's)."""
    extra = getattr(model, "extra_force", None)
    try:
        s = model.symbolic() if extra is None else model.closed_symbolic()
    except (NotImplementedError, ValueError):
        return False, None
    # An H(q, p) model (varint.models.hamiltonian) qualifies only as a
    # rotating frame's A + V; its other forms have no straight-line drift.
    planar = None
    if getattr(s, "structure", None) == "integrable":
        planar = planar_key(model.planar, model.n_dof)
    elif not hasattr(s, "inverse_mass"):
        return False, None
    return _facts_of(s, model.n_dof, tuple(float(m) for m in model.inverse_mass), planar,
                     extra)


@lru_cache(maxsize=256)
def _facts_of(s, n_dof, inverse_mass, planar=None, extra=None):
    """:func:`_facts` of the symbolic form ``s`` for a model of ``n_dof``
    coordinates and these masses (once per form and process); a rotating
    frame's (``planar``) masses are its A's; ``extra``: the model's
    :class:`ExtraForce`."""
    fits = len(s.q) == n_dof and (planar is not None or np.allclose(
        [float(m) for m in s.inverse_mass], inverse_mass, rtol=1e-15, atol=0))
    return bool(fits), _symbolic_key(s, planar, extra) if fits else None


@lru_cache(maxsize=256)
def _description_id(cls, description):
    """A name for a built-in model's symbolic facts: its class and
    description and the code they come from (``varint.models``, this
    module, which names the key, and SymPy, which prints it), so that a
    change of either names new facts."""
    sympy_version = _sympy_version()
    digest = hashlib.sha256(f"{cls.__module__}.{cls.__qualname__}|{sympy_version}|"
                            f"{description}".encode())
    digest.update(Path(__file__).read_bytes())
    for path in sorted((Path(__file__).parent.parent / "models").glob("*.py")):
        digest.update(path.read_bytes())
    return digest.hexdigest()[:24]


def _sympy_version():
    """SymPy's version without importing SymPy, which would cost what the
    stored facts save: the ``__version__`` that ``sympy/release.py`` of the
    copy an import would load assigns, else the installed metadata's
    (importlib.metadata takes ~15 ms to import)."""
    spec = importlib.util.find_spec("sympy")
    for folder in (spec.submodule_search_locations or []) if spec else []:
        try:
            text = (Path(folder) / "release.py").read_text(encoding="utf-8")
        except OSError:
            continue
        found = re.search(r'^__version__\s*=\s*"([^"]+)"', text, re.M)
        if found:
            return found.group(1)
    from importlib import metadata

    return metadata.version("sympy")

"""Tangent-map steppers generated per model and scheme, cached on disk.

For a model that knows its potential symbolically (every built-in model and
every :func:`~varint.models.from_potential` model) and has few degrees of
freedom, the stepper is written out as Python source and compiled by numba:

* the scheme's stages are unrolled; each kick evaluates ∇V, D²V and, for a
  corrector, ∇C and D²C (C = ∇VᵀM⁻¹∇V, Skokos & Gerlach 2010 eq. 26) as
  straight-line expressions of q with common subexpressions eliminated, and
  applies the orbit kick and the tangent kick (eqs. 47, 53) in one go;
  drifts and kicks are written as fused multiply–adds
  (:mod:`varint.kernels.fma`), which halves the latency of a step;
* the orbit, the deviation vectors and the stretching accumulators live in
  local variables (registers) for the whole loop — the code a person would
  write in C for this model and scheme;
* the end-of-step work is that of :mod:`varint.kernels.checks` (escape,
  non-finite state, a singular derivative, degenerate or overflowing
  vectors; the same status codes), unrolled;
* an indicator's accumulator is called after every renormalisation, and the
  state is copied at the requested output steps (*snapshots*), so a run with
  many outputs costs no more than its steps (:mod:`varint.driver`);
* with ``sparse`` renormalisation the vectors are renormalised only when
  needed (:func:`next_interval`), which gives the same exponents as
  renormalising every step, to round-off.

The source goes to ``<cache dir>/kernels/`` under a name that hashes the
generator's code, the model's potential and the plan, and numba caches its
compilation beside it, so a new process (or a new varint version, or
another model) finds or builds exactly the kernel it needs; the first run
in a new process loads it instead of compiling it, without emitting the
source again.

Models without a symbolic definition, or too large for straight-line code,
use the generic stepper of :mod:`varint.kernels.tm`.
"""

from __future__ import annotations

import hashlib
import re
import sys
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np
import sympy as sp

from numba import njit

from .. import cachedir, codecache
from ..protocol import TANGENT_LIMIT, Renorm, Status
from ..schemes import DRIFT
from .checks import CHECK_EVERY, HUGE_Q2

__all__ = ["symbolic_stepper", "generated_source", "SYMBOLIC_MAX_N", "SYMBOLIC_MAX_VALUES",
           "next_interval", "SPARSE_NORM_LOG", "SPARSE_COND_LOG", "SPARSE_MAX_STEPS",
           "SPARSE_QR_MAX_STEPS"]

#: Largest N and largest 2N(1 + k) (orbit and vectors held in local
#: variables) for which straight-line code is generated; beyond, the generic
#: stepper is used. The code grows as stages × 2N(1 + k) and LLVM's compile
#: time faster: FPU n = 5 with 10 vectors (110 values) took 50 s to
#: compile, the 3-dof model's full spectrum (42 values) a few seconds.
SYMBOLIC_MAX_N = 16
SYMBOLIC_MAX_VALUES = 48

#: Sparse renormalisation keeps the growth of every vector between two
#: renormalisations below e^SPARSE_NORM_LOG (1e50: far from overflow) and,
#: for QR, the spread of the stretchings below e^SPARSE_COND_LOG (32: the
#: ill-conditioning modified Gram–Schmidt then sees costs at most ~32 ε in
#: the smallest exponent's R_kk; with 1e3, the sum of C1's exponents, 0 in
#: exact arithmetic, was off by 5e-12 at t = 1e3), and renormalises at least every
#: SPARSE_MAX_STEPS steps. The interval at most doubles from one
#: renormalisation to the next, so a sudden stronger stretching cannot
#: overflow before it is seen.
SPARSE_NORM_LOG = 115.0
SPARSE_COND_LOG = 3.47
SPARSE_MAX_STEPS = 1 << 16
#: With QR of several vectors, at most this many steps between
#: renormalisations: the spread of the last interval can underestimate the
#: next one's after a sticky episode (C1: the exponents' sum, 0 in exact
#: arithmetic, was off by 1.4e-10 at t = 1.6e3 without this bound).
SPARSE_QR_MAX_STEPS = 64
#: Vectors beyond this size are renormalised at the next check, whatever the
#: schedule (checked every CHECK_EVERY steps).
_EARLY = 1e100
# As plain floats for the compiled schedule.
_NORM_LOG, _COND_LOG, _MAX_STEPS = SPARSE_NORM_LOG, SPARSE_COND_LOG, float(SPARSE_MAX_STEPS)
_QR_MAX_STEPS = float(SPARSE_QR_MAX_STEPS)


@njit(cache=True)
def next_interval(interval, growth, spread):
    """The next renormalisation interval (steps) of the sparse schedule.

    Parameters
    ----------
    interval : int
        The interval just completed.
    growth : float
        max_j ln r_j over it (the largest log-stretching).
    spread : float
        max_j ln r_j − min_j ln r_j (0 unless QR with k ≥ 2).

    Returns
    -------
    int
        At most twice ``interval``, at least 1, and short enough that, at the
        same rates, growth stays below ``SPARSE_NORM_LOG`` and spread below
        ``SPARSE_COND_LOG``.
    """
    allowed = interval * 2.0
    if growth > 0.0:
        allowed = min(allowed, interval * _NORM_LOG / growth)
    if spread > 0.0:
        # QR of several vectors: the spread seen over the last interval
        # predicts the next one's conditioning only while the dynamics stay
        # alike; after a quiet (sticky) episode it does not, so the
        # interval is also kept short in absolute terms.
        allowed = min(allowed, interval * _COND_LOG / spread, _QR_MAX_STEPS)
    return int(max(1.0, min(allowed, _MAX_STEPS)))


# -- the model's expressions -----------------------------------------------------

@dataclass(frozen=True)
class _Expressions:
    """∇V, D²V, ∇C and D²C of a symbolic model in the symbols q0 … q{N−1}."""

    n: int
    minv: tuple
    g: tuple       # ∇V_i
    H: dict        # (i, j), i ≤ j -> D²V_ij (non-zero entries only)
    gc: tuple      # ∇C_i
    HC: dict       # (i, j), i ≤ j -> D²C_ij (non-zero entries only)
    q: tuple       # the symbols


#: The symbolic forms met in this process, by :func:`_symbolic_key`: (V in
#: q0 … q{N−1}, inverse masses, N). Only ever filled from a model's own
#: SymPy form, never from a file.
_FORMS: dict = {}


@lru_cache(maxsize=32)
def _expressions(key):
    """The expressions of the potential of ``key`` (:func:`_symbolic_key`;
    cached by it: the symbolic work costs far more than the rest)."""
    V, minv, n = _FORMS[key]
    q = sp.symbols(f"q0:{n}")
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
    return _Expressions(n=n, minv=tuple(float(m) for m in minv), g=g, H=H, gc=gc, HC=HC, q=q)


@lru_cache(maxsize=256)
def _symbolic_key(s):
    """A name (32 hex digits) for a model's (frozen, hashable) symbolic form:
    the hash of its exact SymPy text (``srepr``) in the symbols q0 …
    q{N−1}, worked out once per process, not once per chunk of a chaos map
    (~0.4 ms each). The form itself is kept in ``_FORMS``: a stepper's
    source is only ever emitted from a model's own expressions."""
    n = len(s.q)
    V = s.V.xreplace(dict(zip(s.q, sp.symbols(f"q0:{n}"), strict=True)))
    text = "|".join([sp.srepr(V), *(sp.srepr(m) for m in s.inverse_mass), str(n)])
    key = hashlib.sha256(text.encode()).hexdigest()[:32]
    _FORMS[key] = (V, tuple(s.inverse_mass), n)
    return key


@lru_cache(maxsize=64)
def _source(key, plan):
    """The stepper's source for the model of ``key`` (:func:`_model_key`)
    and ``plan``, written once per process: each chunk of a chaos map makes
    its own propagator, and emitting the source (SymPy's common
    subexpressions, printing) costs ~60 ms."""
    return generated_source(_expressions(key), plan)


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


def _model_key(model):
    """The :func:`_symbolic_key` of ``model``'s form."""
    return _facts(model)[1]


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
    from ..models.symbolic import SymbolicModel

    cls = type(model)
    if isinstance(model, SymbolicModel) or not cls.__module__.startswith("varint.models."):
        return _facts_now(model)
    name = _description_id(cls, _canonical_description(model))
    if name in _FACTS:
        return _FACTS[name]
    file = f"varint_model_{name}.json"
    stored = codecache.read_json("kernels", file, "symbolic facts file")
    facts = _stored_facts(stored)
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
_FACTS: dict = {}


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


def _canonical_description(model):
    """``model.describe()`` as canonical JSON text."""
    from ..files import canonical_json

    return canonical_json(model.describe())


@lru_cache(maxsize=256)
def _description_id(cls, description):
    """A name for a built-in model's symbolic facts: its class and
    description and the code they come from (``varint.models``, this
    module, which names the key, and SymPy, which prints it), so that a
    change of either names new facts."""
    digest = hashlib.sha256(f"{_generator_id()}|{cls.__module__}.{cls.__qualname__}|"
                            f"{sp.__version__}|{description}".encode())
    for path in sorted((Path(__file__).parent.parent / "models").glob("*.py")):
        digest.update(path.read_bytes())
    return digest.hexdigest()[:24]


# -- source emission ------------------------------------------------------------------

@dataclass(frozen=True)
class Plan:
    """What one generated stepper is specialised to.

    Attributes
    ----------
    kinds : tuple of int
        Stage kinds (``DRIFT`` or kick), as :func:`varint.schemes.stage_arrays`.
    corrected : tuple of bool
        Which kick stages carry a corrector.
    k : int
        Deviation vectors.
    accumulator : str
        ``"module:name"`` of the indicator's accumulator update, or "".
    flow : bool
        Pass the accumulator the phase-space velocity.
    inline : str
        A built-in accumulator that ``lanes`` writes out in its loop
        (a key of ``_INLINE_COLUMNS``), or "": any other is called.
    """

    kinds: tuple
    corrected: tuple
    k: int
    accumulator: str
    flow: bool
    inline: str = ""


_OK, _ESCAPED, _NONFINITE = int(Status.OK), int(Status.ESCAPED), int(Status.ORBIT_NONFINITE)
_DEGENERATE, _OVERFLOW = int(Status.TANGENT_DEGENERATE), int(Status.TANGENT_OVERFLOW)
_GRAD, _HESS, _THIRD = (int(Status.GRADIENT_NONFINITE), int(Status.HESSIAN_NONFINITE),
                        int(Status.THIRD_NONFINITE))

#: Orbits per block of ``lanes`` at most (its work arrays' width).
LANE_WIDTH = 64

#: Built-in accumulators whose update ``lanes`` writes out inside its
#: vectorised loop (calling an update per lane and step would keep that loop
#: scalar): the columns each keeps, as in :mod:`varint.indicators.megno`.
_INLINE_COLUMNS = {"fli": ("log", "fli", "peak", "peak_exp"),
                   "megno": ("log", "weighted", "megno_sum", "fli", "ofli")}
#: The columns each one updates every step (FLI's others are read off the
#: peak and the stretching accumulators when the state is copied out).
_INLINE_LIVE = {"fli": (2, 3), "megno": (0, 1, 2, 3, 4)}
_LN2 = 0.6931471805599453


def _inline_kind(accumulator):
    """The key of ``_INLINE_COLUMNS`` that ``accumulator`` is, or ""."""
    from ..indicators.megno import FLI_ACCUMULATOR, MEGNO_ACCUMULATOR

    for key, builtin in (("fli", FLI_ACCUMULATOR), ("megno", MEGNO_ACCUMULATOR)):
        if accumulator is not None and accumulator.update is builtin.update \
                and tuple(accumulator.columns) == _INLINE_COLUMNS[key]:
            return key
    return ""


class _Emitter:
    """Writes the source of one stepper: ``orbit`` (one orbit, state in
    locals) and ``batch_serial``/``batch_parallel`` (over a batch)."""

    def __init__(self, E, plan):
        from ..models.symbolic import _KernelPrinter

        self.E, self.plan = E, plan
        self.n, self.k = E.n, plan.k
        n, k = self.n, self.k
        self.q = [f"q{i}" for i in range(n)]
        self.p = [f"p{i}" for i in range(n)]
        # δq_i and δp_i of vector j.
        self.a = [[f"a{i}_{j}" for j in range(k)] for i in range(n)]
        self.b = [[f"b{i}_{j}" for j in range(k)] for i in range(n)]
        self.printer = _KernelPrinter()
        self.lines = []
        self.level = 0

    # -- plumbing ------------------------------------------------------------------
    def __call__(self, *lines):
        for line in lines:
            self.lines.append("    " * self.level + line if line else "")

    def indent(self):
        self.level += 1

    def dedent(self):
        self.level -= 1

    def vectors(self):
        """Every δq and δp local, vector by vector."""
        return [v for i in range(self.n) for j in range(self.k)
                for v in (self.a[i][j], self.b[i][j])]

    def fail(self, status):
        """Leave the loop with ``status``; the locals are stored after it, so
        the state is left where the failure was seen."""
        self.indent()
        if status in (_GRAD, _HESS, _THIRD):
            # At an enormous |q| the derivatives overflow before the state
            # does: that is the orbit running away, not a singular potential.
            rq = " + ".join(f"{v} * {v}" for v in self.q)
            self(f"status = {status} if {rq} < HUGE else {_NONFINITE}")
        else:
            self(f"status = {status}")
        self("break")
        self.dedent()

    def store(self):
        n, k = self.n, self.k
        for i in range(n):
            self(f"x[{i}] = {self.q[i]}", f"x[{n + i}] = {self.p[i]}")
        for i in range(n):
            for j in range(k):
                self(f"W[{i}, {j}] = {self.a[i][j]}", f"W[{n + i}, {j}] = {self.b[i][j]}")
        for j in range(k):
            self(f"acc_m[{j}] = am{j}", f"acc_e[{j}] = ae{j}")
            if self.plan.inline == "fli":
                self.fli_readout(f"aux[{j}, {{}}]", f"am{j}", f"ae{j}", f"pk{j}", f"pe{j}")
        self("counters[0] += c_grad", "counters[1] += c_hess", "counters[2] += c_third",
             "counters[3] += c_tan", "rsched[0] = next_renorm", "rsched[1] = interval")

    # -- the pieces of a step -----------------------------------------------------------
    def derivatives(self, label, what, lane=False):
        """Evaluate ∇V and, as ``what`` asks, D²V, ∇C, D²C at the current q,
        with a singular value caught before it is used.

        The orbit's quantities (∇V, ∇C) and the tangent ones (D²V, D²C) are
        simplified separately, so the orbit gets the same bits whether or
        not deviation vectors are carried. With ``lane``, a singular value
        marks the lane (``code``, ``fstep``; see :meth:`lane_fail`) instead
        of leaving the loop, and nothing is counted.
        """
        E = self.E
        orbit = [("g", [f"g{i}" for i in range(self.n)], list(E.g), _GRAD, "c_grad")]
        if "gc" in what:
            orbit.append(("gc", [f"gc{i}" for i in range(self.n)], list(E.gc), _THIRD, None))
        tangent = []
        if "H" in what:
            tangent.append(("H", [f"H{i}_{j}" for i, j in E.H], list(E.H.values()), _HESS,
                            "c_hess"))
        if "HC" in what:
            tangent.append(("HC", [f"HC{i}_{j}" for i, j in E.HC], list(E.HC.values()), _THIRD,
                            "c_third"))
        for part, groups in (("o", orbit), ("w", tangent)):
            if not groups:
                continue
            targets = [t for g in groups for t in g[1]]
            exprs = [e for g in groups for e in g[2]]
            temps, reduced = sp.cse(exprs, symbols=sp.numbered_symbols(f"t{label}{part}_"))
            for t, e in temps:
                self(f"{t} = {self.printer.doprint(e)}")
            for t, e in zip(targets, reduced):
                self(f"{t} = {self.printer.doprint(e)}")
            for _, names, _, status, counter in groups:
                if counter and not lane:
                    self(f"{counter} += 1")
                if names and lane:
                    self(f"fin = {' + '.join(names)}")
                    self.lane_fail("fin - fin != 0.0", status)
                elif names:
                    self(f"fin = {' + '.join(names)}", "if fin - fin != 0.0:")
                    self.fail(status)

    # Drifts and kicks are chains of fused multiply–adds (varint.kernels.fma).
    def drift(self, st):
        for i in range(self.n):
            m = self.E.minv[i]
            h = f"h{st}" if m == 1.0 else f"(h{st} * {m!r})"
            self(f"{self.q[i]} = fma({h}, {self.p[i]}, {self.q[i]})")
            for j in range(self.k):
                self(f"{self.a[i][j]} = fma({h}, {self.b[i][j]}, {self.a[i][j]})")

    def kick(self, st, corrected, count=True):
        """p −= h ∇V + hc ∇C and δp −= (h D²V + hc D²C) δq (paper eqs. 47, 53)."""
        E, n, k = self.E, self.n, self.k
        for i in range(n):
            p = self.p[i]
            if corrected:
                p = f"fma(-hc{st}, gc{i}, {p})"
            self(f"{self.p[i]} = fma(-h{st}, g{i}, {p})")
        if not k:
            return
        if count:
            self("c_tan += 1")
        entries = set(E.H) | (set(E.HC) if corrected else set())
        for key in sorted(entries):
            name = f"{key[0]}_{key[1]}"
            if key in E.H and corrected and key in E.HC:
                self(f"K{name} = fma(hc{st}, HC{name}, h{st} * H{name})")
            elif key in E.H:
                self(f"K{name} = h{st} * H{name}")
            else:
                self(f"K{name} = hc{st} * HC{name}")
        for j in range(k):
            for i in range(n):
                acc = self.b[i][j]
                for l in range(n):
                    key = (min(i, l), max(i, l))
                    if key in entries:
                        acc = f"fma(-K{key[0]}_{key[1]}, {self.a[l][j]}, {acc})"
                if acc != self.b[i][j]:
                    self(f"{self.b[i][j]} = {acc}")

    def needs(self, corrected):
        """What a kick stage evaluates: ∇V; D²V with vectors; ∇C (and D²C
        with vectors) with a corrector."""
        k = self.k
        return {"g"} | ({"H"} if k else set()) | ({"gc"} if corrected else set()) \
            | ({"HC"} if corrected and k else set())

    def orthogonalize(self, j):
        """Modified Gram–Schmidt of vector ``j`` against the earlier ones (QR
        only), in the locals; returns the expression of its squared norm."""
        n, a, b = self.n, self.a, self.b
        if j:
            self("if mode == QR:")
            self.indent()
            for c in range(j):
                dot = " + ".join([f"{a[i][c]} * {a[i][j]}" for i in range(n)]
                                 + [f"{b[i][c]} * {b[i][j]}" for i in range(n)])
                self(f"rr = {dot}")
                for i in range(n):
                    self(f"{a[i][j]} -= rr * {a[i][c]}", f"{b[i][j]} -= rr * {b[i][c]}")
            self.dedent()
        return " + ".join([f"{a[i][j]} * {a[i][j]}" for i in range(n)]
                          + [f"{b[i][j]} * {b[i][j]}" for i in range(n)])

    def renormalize(self):
        """Modified Gram–Schmidt (QR) or normalisation in the locals; the
        stretching r{j} is multiplied into am{j}/ae{j} (mantissa, exponent;
        :mod:`varint.kernels.checks`)."""
        n, k, a, b = self.n, self.k, self.a, self.b
        for j in range(k):
            sq = self.orthogonalize(j)
            self(f"r{j} = math.sqrt({sq})", f"if not (r{j} > 0.0 and r{j} < np.inf):")
            self.fail(_DEGENERATE)
            # The mantissa rescaled by exact powers of two (as in lanes).
            self(f"aa = am{j} * r{j}",
                 f"ae{j} += 500 if aa > ACC_BIG else (-500 if aa < ACC_SMALL else 0)",
                 f"am{j} = aa * ACC_SMALL if aa > ACC_BIG else "
                 "(aa * ACC_BIG if aa < ACC_SMALL else aa)",
                 f"inv = 1.0 / r{j}")
            for i in range(n):
                self(f"{a[i][j]} *= inv", f"{b[i][j]} *= inv")

    def schedule(self):
        """The next renormalisation step of the sparse schedule: the
        adaptive rule's (:func:`next_interval`), at most ``every`` steps
        when one is given. Every-step renormalisation (``every == 0``)
        keeps no schedule (as the lanes do)."""
        k = self.k
        logs = [f"math.log(r{j})" for j in range(k)]
        self("if every != 0:")
        self.indent()
        self(f"lmax = max({', '.join(logs)})" if k > 1 else f"lmax = {logs[0]}")
        if k > 1:
            self(f"spread = lmax - min({', '.join(logs)}) if mode == QR else 0.0")
        else:
            self("spread = 0.0")
        self("interval = next_interval(max(step - (next_renorm - interval), 1), lmax, spread)",
             "if every > 0 and interval > every:", "    interval = every",
             "next_renorm = step + interval")
        self.dedent()

    def fli_peak(self, j, pk, pe, ok=None):
        """The largest ‖w_j‖ so far, as the (mantissa, exponent) pair
        (pk, pe) of the step where it was reached, compared exactly with
        the current (am, ae): the exponents are multiples of 500, so
        am · 2^(ae − pe) is exact where it matters and otherwise decides
        by its exponent alone. FLI = ln pk + pe ln 2 is taken only when
        the state is copied out — no logarithm per step, so the loop over
        lanes vectorises (the arithmetic of Froeschlé et al.'s sup, not of
        :func:`varint.indicators.megno._update_fli`'s running sum)."""
        self(f"d = ae{j} - {pe}",
             f"v = am{j} if d == 0.0 else (am{j} * ACC_BIG if d == 500.0 else "
             f"(am{j} * ACC_SMALL if d == -500.0 else (np.inf if d > 0.0 else 0.0)))")
        up = f"v > {pk}" if ok is None else f"{ok} and v > {pk}"
        self(f"up = {up}", f"{pk} = am{j} if up else {pk}",
             f"{pe} = float(ae{j}) if up else {pe}")

    def fli_readout(self, target, am, ae, pk, pe):
        """``target`` (a format string of the column) = FLI's columns."""
        self(f"{target.format(0)} = math.log({am}) + {ae} * LN2",
             f"{target.format(1)} = math.log({pk}) + {pe} * LN2",
             f"{target.format(2)} = {pk}", f"{target.format(3)} = {pe}")

    def accumulate(self, kinds):
        n, k = self.n, self.k
        if self.plan.inline == "fli":
            for j in range(k):
                self.fli_peak(j, f"pk{j}", f"pe{j}")
            return
        for j in range(k):
            self(f"rbuf[{j}] = r{j}")
        for i in range(n):
            self(f"xbuf[{i}] = {self.q[i]}", f"xbuf[{n + i}] = {self.p[i]}")
            for j in range(k):
                self(f"Wbuf[{i}, {j}] = {self.a[i][j]}", f"Wbuf[{n + i}, {j}] = {self.b[i][j]}")
        if self.plan.flow:
            if kinds[-1] == DRIFT:
                self.derivatives("f", {"g"})  # the flow needs ∇V at the end of the step
            for i in range(n):
                m = self.E.minv[i]
                self(f"flowbuf[{i}] = {self.p[i]}" if m == 1.0
                     else f"flowbuf[{i}] = {m!r} * {self.p[i]}", f"flowbuf[{n + i}] = -g{i}")
        # The time from the integer step: it does not depend on chunking.
        self("accumulate(aux, rbuf, xbuf, Wbuf, flowbuf, step * tau)")

    def snapshot(self):
        """Copy the state at an output step; check raw vectors there too."""
        n, k = self.n, self.k
        self("if jo < outs.shape[0] and step == outs[jo]:")
        self.indent()
        if k:
            big = " or ".join(f"not (abs({v}) < TANGENT_LIMIT)" for v in self.vectors())
            self(f"if mode == NONE and ({big}):")
            self.fail(_OVERFLOW)
        for i in range(n):
            self(f"snap_x[jo, {i}] = {self.q[i]}", f"snap_x[jo, {n + i}] = {self.p[i]}")
            for j in range(k):
                self(f"snap_W[jo, {i}, {j}] = {self.a[i][j]}",
                     f"snap_W[jo, {n + i}, {j}] = {self.b[i][j]}")
        for j in range(k):
            self(f"snap_m[jo, {j}] = am{j}", f"snap_e[jo, {j}] = ae{j}")
        if self.plan.inline == "fli":
            for j in range(k):
                self.fli_readout(f"snap_aux[jo, {j}, {{}}]", f"am{j}", f"ae{j}", f"pk{j}",
                                 f"pe{j}")
        elif self.plan.accumulator:
            self("for jj in range(aux.shape[0]):",
                 "    for cc in range(aux.shape[1]):",
                 "        snap_aux[jo, jj, cc] = aux[jj, cc]")
        self("jo += 1")
        self.dedent()

    # -- the whole source ------------------------------------------------------------------
    def source(self):
        E, plan, n, k = self.E, self.plan, self.n, self.k
        kinds = plan.kinds
        self('"""Generated by varint.kernels.generate; do not edit."""',
             f"# accumulator: {plan.accumulator or 'none'}",
             "import math", "import numpy as np",
             "from numba import njit, prange, set_parallel_chunksize",
             "from varint.kernels.fma import fma", "",
             f"ACC_BIG = {2.0 ** 500!r}", f"ACC_SMALL = {2.0 ** -500!r}",
             f"TANGENT_LIMIT = {TANGENT_LIMIT!r}", f"EARLY = {_EARLY!r}", f"HUGE = {HUGE_Q2!r}",
             f"CHECK_EVERY = {CHECK_EVERY}", f"LANE_WIDTH = {LANE_WIDTH}", f"LN2 = {_LN2!r}",
             f"NONE, QR = {int(Renorm.NONE)}, {int(Renorm.QR)}", "", "",
             "@njit(cache=True, error_model='numpy', nogil=True)",
             "def orbit(x, W, acc_m, acc_e, n_steps, step0, tau, h, hc, escape_r2, counters, aux,"
             " rsched, outs, snap_x, snap_W, snap_m, snap_e, snap_aux, mode, every):")
        self.indent()
        for st in range(len(kinds)):
            self(f"h{st} = h[{st}]")
            if plan.corrected[st]:
                self(f"hc{st} = hc[{st}]")
        for i in range(n):
            self(f"q{i} = x[{i}]", f"p{i} = x[{n + i}]")
            for j in range(k):
                self(f"{self.a[i][j]} = W[{i}, {j}]", f"{self.b[i][j]} = W[{n + i}, {j}]")
        for j in range(k):
            self(f"am{j} = acc_m[{j}]", f"ae{j} = acc_e[{j}]", f"r{j} = 1.0")
            if plan.inline == "fli":
                self(f"pk{j} = aux[{j}, 2]", f"pe{j} = aux[{j}, 3]")
        self("c_grad = 0", "c_hess = 0", "c_third = 0", "c_tan = 0",
             "next_renorm = rsched[0]", "interval = rsched[1]")
        if plan.accumulator:
            self(f"rbuf = np.empty({k})", f"xbuf = np.empty({2 * n})",
                 f"Wbuf = np.empty(({2 * n}, {k}))", f"flowbuf = np.empty({2 * n if plan.flow else 0})")
        # Everything a kick computes is defined before the loop: after s = 0
        # the first kick of a step reuses the last kick's values (same q).
        for i in range(n):
            self(f"g{i} = 0.0", f"gc{i} = 0.0")
        for i, j in E.H:
            self(f"H{i}_{j} = 0.0")
        for i, j in E.HC:
            self(f"HC{i}_{j} = 0.0")
        self("status = 0", "s = 0", "jo = 0",
             "while jo < outs.shape[0] and outs[jo] <= step0:", "    jo += 1",
             "for s in range(n_steps):")
        self.indent()
        self("step = step0 + s + 1")
        reuse_first = kinds[0] != DRIFT and kinds[-1] != DRIFT
        for st, kind in enumerate(kinds):
            if kind == DRIFT:
                self.drift(st)
                continue
            corrected = plan.corrected[st]
            what = self.needs(corrected)
            if st == 0 and reuse_first:
                self("if s == 0:")
                self.indent()
                self.derivatives(st, what)
                self.dedent()
            else:
                self.derivatives(st, what)
            self.kick(st, corrected)
        # The end-of-step checks of varint.kernels.checks.orbit_status.
        self("rq = " + " + ".join(f"{v} * {v}" for v in self.q),
             "rp = " + " + ".join(f"{v} * {v}" for v in self.p),
             "if rq > escape_r2:")
        self.fail(_ESCAPED)
        self("if not (rq + rp < np.inf):")
        self.fail(_NONFINITE)
        if k:
            # Renormalise: every step (every == 0), or on the schedule (every
            # < 0: adaptive; > 0: fixed), early if a vector grew huge.
            early = " or ".join(f"abs({v}) > EARLY" for v in self.vectors())
            self("if mode != NONE:")
            self.indent()
            self("due = every == 0 or step >= next_renorm",
                 "if not due and step % CHECK_EVERY == 0:", f"    due = {early}", "if due:")
            self.indent()
            self.renormalize()
            self.schedule()
            if plan.accumulator:
                self.accumulate(kinds)
            self.dedent()
            self.dedent()
            big = " or ".join(f"not (abs({v}) < TANGENT_LIMIT)" for v in self.vectors())
            self("elif step % CHECK_EVERY == 0:", f"    if {big}:")
            self.indent()
            self.fail(_OVERFLOW)
            self.dedent()
        self.snapshot()
        self.dedent()
        self.store()
        self("if status != 0:", "    return status, s", f"return {_OK}, n_steps")
        self.dedent()
        for name, parallel in (("batch_serial", False), ("batch_parallel", True)):
            self("", "",
                 f"@njit(cache=True, error_model='numpy', parallel={parallel}, nogil=True)",
                 f"def {name}(X, W, acc_m, acc_e, status, done, n_steps, step0, tau, h, hc, "
                 "escape_r2, counters, aux, rsched, outs, snap_x, snap_W, snap_m, snap_e, snap_aux,"
                 " mode, every):",
                 "    for m in prange(X.shape[0]):",
                 "        if status[m] != 0:",
                 "            done[m] = 0",
                 "            continue",
                 "        st, steps = orbit(X[m], W[m], acc_m[m], acc_e[m], n_steps, step0, tau, h,"
                 " hc, escape_r2, counters[m], aux[m], rsched[m], outs, snap_x[:, m],"
                 " snap_W[:, m], snap_m[:, m], snap_e[:, m], snap_aux[:, m], mode, every)",
                 "        status[m] = st",
                 "        done[m] = steps")
        self.lanes()
        return "\n".join(self.lines) + "\n"

    # -- structure of arrays: many orbits at once -------------------------------------------
    # ``lanes`` copies its block into two arrays it allocates itself, floats F
    # and integers I, LANE_WIDTH columns each, one row per quantity. Their rows
    # are a constant distance apart, so LLVM proves the loop over lanes free of
    # aliasing and vectorises it; over the caller's arrays (strides unknown to
    # it) it needed more run-time overlap checks than it allows and kept the
    # loop scalar: 28 against 4.4 ns per orbit and step (Hénon–Heiles, SBAB2C,
    # one vector, AVX-512).

    def lane_layout(self):
        """Row numbers of the per-lane quantities in F and I."""
        n, k, E, plan = self.n, self.k, self.E, self.plan
        self.fw = 2 * n                            # W[i, j] -> fw + i k + j
        self.fam = self.fw + 2 * n * k             # am_j
        self.fr = self.fam + k                     # r_j where renormalised, else 0
        self.reuse = []
        if plan.kinds[0] != DRIFT and plan.kinds[-1] != DRIFT:
            # After s = 0 the first kick reuses the last kick's values (same q).
            what = self.needs(plan.corrected[0])
            self.reuse = [f"g{i}" for i in range(n)]
            if "gc" in what:
                self.reuse += [f"gc{i}" for i in range(n)]
            if "H" in what:
                self.reuse += [f"H{i}_{j}" for i, j in E.H]
            if "HC" in what:
                self.reuse += [f"HC{i}_{j}" for i, j in E.HC]
        self.fd = self.fr + k
        self.faux = self.fd + len(self.reuse)
        self.ncols = len(_INLINE_COLUMNS.get(plan.inline, ()))
        self.nf = self.faux + k * self.ncols
        # I: status, failure step, ae_j, next renormalisation step.
        self.iae, self.inxt = 2, 2 + k
        self.ni = 3 + k

    def lane_fail(self, condition, status):
        """Mark the lane failed with ``status`` if ``condition`` holds and it
        has not failed before (selects, so the loop still vectorises)."""
        if status in (_GRAD, _HESS, _THIRD):
            rq = " + ".join(f"{v} * {v}" for v in self.q)
            value = f"({status} if {rq} < HUGE else {_NONFINITE})"
        else:
            value = str(status)
        self(f"bad = ({condition}) & (code == 0)",
             f"code = {value} if bad else code", "fstep = s if bad else fstep")

    def lane_rows(self):
        """(local, F or I row) of everything a lane carries through a step."""
        n, k = self.n, self.k
        rows = [(self.q[i], f"F[{i}, b]") for i in range(n)]
        rows += [(self.p[i], f"F[{n + i}, b]") for i in range(n)]
        rows += [(self._w(i, j), f"F[{self.fw + i * k + j}, b]")
                 for i in range(2 * n) for j in range(k)]
        rows += [(f"am{j}", f"F[{self.fam + j}, b]") for j in range(k)]
        rows += [(f"ae{j}", f"I[{self.iae + j}, b]") for j in range(k)]
        rows += [(name, f"F[{self.fd + c}, b]") for c, name in enumerate(self.reuse)]
        rows += [(f"u{j}_{c}", f"F[{self.faux + j * self.ncols + c}, b]")
                 for j in range(k) for c in _INLINE_LIVE.get(self.plan.inline, ())]
        return rows + [("code", "I[0, b]"), ("fstep", "I[1, b]")]

    def _w(self, i, j):
        """The local of component ``i`` (0 … 2N−1) of vector ``j``."""
        return self.a[i][j] if i < self.n else self.b[i - self.n][j]

    def lane_renormalize(self):
        """Renormalisation of the lane where due (every step, on its own
        sparse schedule ``nxt``, or early when a vector grew huge), by
        exactly the arithmetic of :meth:`renormalize`: done on copies of the
        vectors and kept only if due."""
        n, k = self.n, self.k
        early = " | ".join(f"(abs({self._w(i, j)}) > EARLY)"
                           for i in range(2 * n) for j in range(k))
        self(f"early = {early}",
             f"due = renorm & ((every == 0) | (step >= I[{self.inxt}, b]) | (chk & early))")
        kept = self.a, self.b
        self.a = [[f"c{v}" for v in row] for row in kept[0]]
        self.b = [[f"c{v}" for v in row] for row in kept[1]]
        for i in range(2 * n):
            for j in range(k):
                self(f"c{self._w_of(kept, i, j)} = {self._w_of(kept, i, j)}")
        for j in range(k):
            sq = self.orthogonalize(j)
            self(f"r{j} = math.sqrt({sq})")
            self.lane_fail(f"due & (not (r{j} > 0.0 and r{j} < np.inf))", _DEGENERATE)
            self(f"aa = am{j} * r{j}",
                 "ee = 500 if aa > ACC_BIG else (-500 if aa < ACC_SMALL else 0)",
                 "aa = aa * ACC_SMALL if aa > ACC_BIG else (aa * ACC_BIG if aa < ACC_SMALL else aa)",
                 f"am{j} = aa if due else am{j}", f"ae{j} += ee if due else 0",
                 f"F[{self.fr + j}, b] = r{j} if due else 0.0", f"inv = 1.0 / r{j}")
            for i in range(2 * n):
                self(f"{self._w(i, j)} *= inv")
        copies = self.a, self.b
        self.a, self.b = kept
        for i in range(2 * n):
            for j in range(k):
                self(f"{self._w(i, j)} = {self._w_of(copies, i, j)} if due else {self._w(i, j)}")

    def _w_of(self, ab, i, j):
        return ab[0][i][j] if i < self.n else ab[1][i - self.n][j]

    def lane_inline(self, kinds):
        """A built-in accumulator (``plan.inline``) in the lane loop, by
        exactly the arithmetic of its compiled update (so lanes and the
        one-orbit stepper, which calls it, agree bitwise)."""
        n, k = self.n, self.k
        self("ok = due & (code == 0)")
        if self.plan.inline == "fli":
            for j in range(k):
                self.fli_peak(j, f"u{j}_2", f"u{j}_3", ok="ok")
            return
        # varint.indicators.megno._update_megno, with the flow (M⁻¹p, −∇V).
        if kinds[-1] == DRIFT:
            self.derivatives("f", {"g"}, lane=True)
        flow = [self.p[i] if self.E.minv[i] == 1.0 else f"({self.E.minv[i]!r} * {self.p[i]})"
                for i in range(n)] + [f"(-g{i})" for i in range(n)]
        self("ff = " + " + ".join(f"{f} * {f}" for f in flow))
        for j in range(k):
            wf = " + ".join(f"{self._w(i, j)} * {flow[i]}" for i in range(2 * n))
            self(f"lr = math.log(r{j})", f"sv = u{j}_0 + lr",
                 f"u{j}_0 = sv if ok else u{j}_0",
                 f"u{j}_1 = u{j}_1 + t * lr if ok else u{j}_1",
                 f"u{j}_2 = u{j}_2 + 2.0 * u{j}_1 / t if ok else u{j}_2",
                 f"u{j}_3 = sv if ok and sv > u{j}_3 else u{j}_3",
                 f"wf = {wf}",
                 "perp = 1.0 - wf * wf / ff if ff > 0.0 else 1.0",
                 "o = sv + 0.5 * math.log(perp)",
                 f"u{j}_4 = o if ok and perp > 0.0 and o > u{j}_4 else u{j}_4")

    def lane_aux_out(self, j, target):
        """Copy vector ``j``'s inline accumulator columns of lane ``b`` to
        ``target`` (a format string of vector and column)."""
        col = self.faux + j * self.ncols
        if self.plan.inline == "fli":
            self.fli_readout(target.replace("{}", str(j), 1), f"F[{self.fam + j}, b]",
                             f"I[{self.iae + j}, b]", f"F[{col + 2}, b]", f"F[{col + 3}, b]")
            return
        for c in range(self.ncols):
            self(f"{target.format(j, c)} = F[{col + c}, b]")

    def lane_schedule(self):
        """The sparse schedule of every lane that was renormalised (a
        scalar loop: it takes logarithms, rarely)."""
        k = self.k
        logs = [f"math.log(F[{self.fr + j}, b])" for j in range(k)]
        self("if every != 0:")
        self.indent()
        self("for b in range(nb):")
        self.indent()
        self(f"if F[{self.fr}, b] == 0.0:", "    continue")
        self(f"lmax = max({', '.join(logs)})" if k > 1 else f"lmax = {logs[0]}")
        if k > 1:
            self(f"spread = lmax - min({', '.join(logs)}) if mode == QR else 0.0")
        else:
            self("spread = 0.0")
        self(f"itv[b] = next_interval(max(step - (I[{self.inxt}, b] - itv[b]), 1), lmax, spread)",
             "if every > 0 and itv[b] > every:", "    itv[b] = every",
             f"I[{self.inxt}, b] = step + itv[b]")
        self.dedent()
        self.dedent()

    def lane_accumulate(self, kinds):
        """An indicator's own accumulator, lane by lane (a scalar loop: it
        calls the indicator's compiled update)."""
        n, k = self.n, self.k
        self("for b in range(nb):")
        self.indent()
        self("if I[0, b] != 0:", "    continue")
        for j in range(k):
            self(f"rbuf[{j}] = F[{self.fr + j}, b]")
        for i in range(2 * n):
            self(f"xbuf[{i}] = F[{i}, b]")
            for j in range(k):
                self(f"Wbuf[{i}, {j}] = F[{self.fw + i * k + j}, b]")
        if self.plan.flow:
            self("code = 0", "fstep = 0")
            if kinds[-1] == DRIFT or not self.reuse:
                for i in range(n):
                    self(f"q{i} = F[{i}, b]")
                self.derivatives("f", {"g"}, lane=True)
                self("I[0, b] = code", "I[1, b] = fstep")
            else:
                for c, name in enumerate(self.reuse[:n]):
                    self(f"{name} = F[{self.fd + c}, b]")
            for i in range(n):
                m = self.E.minv[i]
                self(f"flowbuf[{i}] = F[{n + i}, b]" if m == 1.0
                     else f"flowbuf[{i}] = {m!r} * F[{n + i}, b]",
                     f"flowbuf[{n + i}] = -g{i}")
        self("accumulate(aux[b], rbuf, xbuf, Wbuf, flowbuf, step * tau)")
        self.dedent()

    def lanes(self):
        """``lanes``: a block of at most LANE_WIDTH orbits (the orbit index
        innermost), each step one loop over the lanes that does the whole
        step of each orbit with the arithmetic of ``orbit`` — bitwise its
        results, with the same renormalisation schedule. A lane that fails
        is marked (``st``, ``fs``) and goes on being computed; the caller
        recomputes it exactly with ``orbit``."""
        E, plan, n, k = self.E, self.plan, self.n, self.k
        kinds = plan.kinds
        self.lane_layout()
        inline = bool(plan.inline)
        rows = self.lane_rows()
        self("", "",
             "@njit(cache=True, error_model='numpy', nogil=True)",
             "def lanes(X, W, am, ae, st, fs, nxt, itv, n_steps, step0, tau, h, hc, escape_r2, mode,"
             " every, aux, outs, snap_x, snap_W, snap_m, snap_e, snap_aux):")
        self.indent()
        for stage in range(len(kinds)):
            self(f"h{stage} = h[{stage}]")
            if plan.corrected[stage]:
                self(f"hc{stage} = hc[{stage}]")
        self("nb = X.shape[1]",
             "if nb > LANE_WIDTH:",
             "    raise ValueError('a block of lanes is at most LANE_WIDTH orbits wide')",
             f"F = np.zeros(({self.nf}, LANE_WIDTH))",
             f"I = np.zeros(({self.ni}, LANE_WIDTH), dtype=np.int64)",
             "renorm = mode != NONE", "s = 0", "step = step0")
        if plan.accumulator and not inline:
            self(f"rbuf = np.empty({k})", f"xbuf = np.empty({2 * n})",
                 f"Wbuf = np.empty(({2 * n}, {k}))",
                 f"flowbuf = np.empty({2 * n if plan.flow else 0})")
        # In: the caller's block into F and I.
        self("for b in range(nb):")
        self.indent()
        for i in range(2 * n):
            self(f"F[{i}, b] = X[{i}, b]")
            for j in range(k):
                self(f"F[{self.fw + i * k + j}, b] = W[{i}, {j}, b]")
        for j in range(k):
            self(f"F[{self.fam + j}, b] = am[{j}, b]", f"I[{self.iae + j}, b] = ae[{j}, b]")
            for c in range(self.ncols):
                self(f"F[{self.faux + j * self.ncols + c}, b] = aux[b, {j}, {c}]")
        self("I[0, b] = st[b]", "I[1, b] = fs[b]", f"I[{self.inxt}, b] = nxt[b]")
        if self.reuse:
            # The first kick's values at the starting q.
            for i in range(n):
                self(f"q{i} = F[{i}, b]")
            self("code = I[0, b]", "fstep = I[1, b]")
            self.derivatives(0, self.needs(plan.corrected[0]), lane=True)
            for c, name in enumerate(self.reuse):
                self(f"F[{self.fd + c}, b] = {name}")
            self("I[0, b] = code", "I[1, b] = fstep")
        self.dedent()
        self("jo = 0", "while jo < outs.shape[0] and outs[jo] <= step0:", "    jo += 1",
             "for s in range(n_steps):")
        self.indent()
        self("step = step0 + s + 1", "chk = step % CHECK_EVERY == 0")
        if inline:
            self("t = step * tau")
        self("for b in range(nb):")
        self.indent()
        for local, row in rows:
            self(f"{local} = {row}")
        for stage, kind in enumerate(kinds):
            if kind == DRIFT:
                self.drift(stage)
                continue
            corrected = plan.corrected[stage]
            if not (stage == 0 and self.reuse):
                self.derivatives(stage, self.needs(corrected), lane=True)
            self.kick(stage, corrected, count=False)
        # The end-of-step checks of orbit_status.
        self("rq = " + " + ".join(f"{v} * {v}" for v in self.q),
             "rp = " + " + ".join(f"{v} * {v}" for v in self.p))
        self.lane_fail("rq > escape_r2", _ESCAPED)
        self.lane_fail("not (rq + rp < np.inf)", _NONFINITE)
        if k:
            self.lane_renormalize()
            if inline:
                self.lane_inline(kinds)
        for local, row in rows:
            self(f"{row} = {local}")
        self.dedent()
        if k:
            self("if renorm:")
            self.indent()
            self.lane_schedule()
            if plan.accumulator and not inline:
                self.lane_accumulate(kinds)
            self.dedent()
            big = " or ".join(f"not (abs(F[{self.fw + c}, b]) < TANGENT_LIMIT)"
                              for c in range(2 * n * k))
            self("elif chk:", "    for b in range(nb):",
                 f"        if ({big}) and I[0, b] == 0:",
                 f"            I[0, b] = {_OVERFLOW}", "            I[1, b] = s")
        # Output steps: copy every lane (raw vectors are checked there, as
        # in orbit).
        self("if jo < outs.shape[0] and step == outs[jo]:")
        self.indent()
        self("for b in range(nb):")
        self.indent()
        if k:
            big = " or ".join(f"not (abs(F[{self.fw + c}, b]) < TANGENT_LIMIT)"
                              for c in range(2 * n * k))
            self(f"if mode == NONE and ({big}) and I[0, b] == 0:",
                 f"    I[0, b] = {_OVERFLOW}", "    I[1, b] = s")
        for i in range(2 * n):
            self(f"snap_x[jo, {i}, b] = F[{i}, b]")
            for j in range(k):
                self(f"snap_W[jo, {i}, {j}, b] = F[{self.fw + i * k + j}, b]")
        for j in range(k):
            self(f"snap_m[jo, {j}, b] = F[{self.fam + j}, b]",
                 f"snap_e[jo, {j}, b] = I[{self.iae + j}, b]")
            self.lane_aux_out(j, "snap_aux[jo, b, {}, {}]")
        if plan.accumulator and not inline:
            self("for jj in range(aux.shape[1]):",
                 "    for cc in range(aux.shape[2]):",
                 "        snap_aux[jo, b, jj, cc] = aux[b, jj, cc]")
        self.dedent()
        self("jo += 1")
        self.dedent()
        self.dedent()
        # Out: F and I back into the caller's block.
        self("for b in range(nb):")
        self.indent()
        for i in range(2 * n):
            self(f"X[{i}, b] = F[{i}, b]")
            for j in range(k):
                self(f"W[{i}, {j}, b] = F[{self.fw + i * k + j}, b]")
        for j in range(k):
            self(f"am[{j}, b] = F[{self.fam + j}, b]", f"ae[{j}, b] = I[{self.iae + j}, b]")
            self.lane_aux_out(j, "aux[b, {}, {}]")
        self("st[b] = I[0, b]", "fs[b] = I[1, b]", f"nxt[b] = I[{self.inxt}, b]")
        self.dedent()
        self.dedent()
        for name, parallel in (("blocks_serial", False), ("blocks_parallel", True)):
            # numba cannot cache a kernel that calls set_parallel_chunksize
            # (a dynamic global): the parallel one compiles once per process.
            self("", "",
                 f"@njit(cache={not parallel}, error_model='numpy', parallel={parallel}, nogil=True)",
                 f"def {name}(X, W, am, ae, st, fs, nxt, itv, n_steps, step0, tau, h, hc, "
                 "escape_r2, mode, every, aux, outs, snap_x, snap_W, snap_m, snap_e, snap_aux):")
            self.indent()
            if parallel:
                # Blocks are handed out one at a time: a thread that is
                # descheduled holds up one block, not a share of them.
                self("old = set_parallel_chunksize(1)")
            self("for c in prange(X.shape[0]):")
            self("    lanes(X[c], W[c], am[c], ae[c], st[c], fs[c], nxt[c], itv[c], n_steps, "
                 "step0, tau, h, hc, escape_r2, mode, every, aux[c], outs, snap_x[c], snap_W[c],"
                 " snap_m[c], snap_e[c], snap_aux[c])")
            if parallel:
                self("set_parallel_chunksize(old)")
            self.dedent()


def generated_source(E, plan):
    """The Python source of the stepper for expressions ``E`` and ``plan``.
    Its first line names the generator's own code, as the file's name does
    (:func:`symbolic_stepper`): numba's cache does not follow a changed
    dependency, so a changed generator must write a new file."""
    return f"# varint generator {_generator_id()}\n" + _Emitter(E, plan).source()


@lru_cache(maxsize=1)
def _generator_id():
    """A hash of the modules whose code and constants a generated stepper
    compiles in (this one, the checks, the protocol's codes, the fused
    multiply–add)."""
    from .. import protocol
    from . import checks, fma

    digest = hashlib.sha256()
    for module in (sys.modules[__name__], checks, protocol, fma):
        digest.update(Path(module.__file__).read_bytes())
    return digest.hexdigest()[:16]


# -- loading --------------------------------------------------------------------------

_LOADED: dict = {}


def _load(digest, make_source, extra_globals):
    """Import the generated module ``varint_stepper_<digest>`` with
    ``extra_globals`` set (:func:`varint.codecache.load_module`: its file
    in the cache directory is written once, signed, from ``make_source()``,
    and verified before every later import; the digest names everything
    the source is made from, so it is not emitted again)."""
    if digest not in _LOADED:
        _LOADED[digest] = codecache.load_module(f"varint_stepper_{digest}", "kernels",
                                                make_source, extra_globals)
    return _LOADED[digest]


@lru_cache(maxsize=256)
def _function_id(function):
    """A name for a compiled function that changes when its code does
    (``module:qualname:hash of its source``), for the generated file's name;
    read once per function and process (reading the source costs ~1 ms)."""
    import inspect

    py = getattr(function, "py_func", function)
    try:
        code = inspect.getsource(py)
    except (OSError, TypeError):
        code = repr(py.__code__.co_code)
    digest = hashlib.sha256(code.encode()).hexdigest()[:16]
    return f"{py.__module__}:{py.__qualname__}:{digest}"


def symbolic_stepper(model, kinds, corrected, k, accumulator=None):
    """The generated stepper module for a model that :func:`symbolic_fits`.

    Parameters
    ----------
    model : Model
    kinds : sequence of int
        Stage kinds of the scheme (:func:`varint.schemes.stage_arrays`).
    corrected : sequence of bool
        Which kick stages carry a corrector.
    k : int
        Deviation vectors.
    accumulator : Accumulator, optional

    Returns
    -------
    module
        With ``orbit``, ``batch_serial`` and ``batch_parallel`` (see the
        module docstring); compiled on first call, or loaded from numba's
        cache. Their last two arguments are run-time settings: ``mode``, a
        :class:`~varint.protocol.Renorm`, and ``every``: renormalise every
        step (0), on the adaptive schedule of :func:`next_interval` (−1), or
        every ``every`` steps.
    """
    plan = Plan(kinds=tuple(int(v) for v in kinds), corrected=tuple(bool(c) for c in corrected),
                k=int(k), accumulator="" if accumulator is None else _function_id(accumulator.update),
                flow=bool(accumulator is not None and accumulator.needs_flow),
                inline=_inline_kind(accumulator))
    key = _model_key(model)
    extra = {"next_interval": next_interval}
    if accumulator is not None:
        extra["accumulate"] = accumulator.update

    def make_source():
        # The source is only ever emitted from the model's own form, never
        # from what a file says: the stored facts named it, the model
        # gives it (the same key: the facts are signed and named after
        # the code and SymPy's version that made them).
        if key not in _FORMS and _facts_now(model)[1] != key:
            raise RuntimeError(f"the cached symbolic facts of {model.name} do not match its "
                               f"form; delete {cachedir.location()} and run again")
        return _source(key, plan)

    return _load(_digest(key, plan), make_source, extra)


@lru_cache(maxsize=256)
def _digest(key, plan):
    """The generated module's name: the generator's code, the model's
    potential and masses (``key``) and the plan (scheme, k, accumulator's
    code) determine its source."""
    return hashlib.sha256(f"{_generator_id()}|{key}|{plan}".encode()).hexdigest()[:24]


def step_counts(kinds, corrected, k, flow=False):
    """Derivative evaluations of one step of a generated stepper, as
    ``(per_step, first)``: what every step costs (gradients, Hessians,
    corrector Hessians, tangent kicks) and what the first step of a call
    costs on top (the first kick of a BAB-type step reuses the last kick's
    values, except right after a call starts)."""
    kinds = list(kinds)
    reuse_first = kinds[0] != DRIFT and kinds[-1] != DRIFT
    per, first = np.zeros(4, dtype=np.int64), np.zeros(4, dtype=np.int64)
    for stage, kind in enumerate(kinds):
        if kind == DRIFT:
            continue
        c = np.array([1, 1 if k else 0, 1 if corrected[stage] and k else 0, 1 if k else 0])
        tan = np.array([0, 0, 0, c[3]])
        if stage == 0 and reuse_first:
            per += tan
            first += c - tan
        else:
            per += c
    if flow and kinds[-1] == DRIFT:
        per[0] += 1
    return per, first

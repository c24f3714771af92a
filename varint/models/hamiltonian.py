"""Models from any Hamiltonian H(q, p) (or H(q, p, t)) written in SymPy,
with the structure that keeps the tangent map exact recognised.

:func:`from_hamiltonian` takes one SymPy expression and finds which of four
forms it has, in this order:

1. **H = ½ Σ m⁻¹_i p_i² + V(q)** (or V(q, t)): the model is
   :func:`~varint.models.from_potential`'s, and every method, scheme and
   corrector of varint applies unchanged.
2. **H = T(p) + V(q)** with any kinetic energy T (relativistic, a
   non-quadratic dispersion, a non-diagonal mass): :class:`SeparableHamiltonian`.
   The drift is the exact flow of T, q ← q + h∇T(p), δq ← δq + h D²T(p) δp
   (:func:`varint.flows.split.kinetic_drift`), and the kick that of V, so
   every explicit two-part scheme without corrector and every k-part
   composition keeps the TM method exact.
3. **H = A + V(q)** with A quadratic and exactly solvable:
   ½a|p_⊥|² + ½b|q_⊥|² − Ω(q_u p_v − q_v p_u) in one plane (u, v) plus
   decoupled ½a_i p_i² + ½b_i q_i² — free motion seen from a rotating frame
   (the restricted three-body problem, a rotating bar), a uniform magnetic
   field in the symmetric gauge (the Larmor rotation), with an isotropic
   oscillator: :class:`IntegrableHamiltonian`. A's flow is a rotation
   composed with the oscillator's (:func:`varint.flows.split.planar_flow`),
   linear and so its own tangent map; the schemes are those of form 2.
   Quadratic terms of q alone in H join A when they make it of this form.
4. **H = V(q) + Σ_i P_i(q, p_i)**, each P_i holding the terms of one
   momentum p_i and free of q_i — a charged particle ½|p − A(q)|² whose A_i
   does not depend on q_i (a magnetic bottle in the symmetric gauge):
   :class:`TermwiseHamiltonian`. Every part's arguments are constant along
   its flow, so the flow is x ← x + hJ∇P(x) and the tangent map
   δx ← δx + hJ D²P(x) δx, exact and explicit; the k-part compositions
   apply.
5. **Anything else** (H(q, p, t) not of form 1, products of momenta, a
   coordinate and its momentum in one term): :class:`GeneralHamiltonian`,
   integrated by the implicit Gauss–Legendre methods
   (:mod:`varint.flows.gauss`) or Tao's explicit extended-phase-space
   method (:mod:`varint.flows.tao`), whose tangent maps are exact
   derivatives of their steps.

Every model of forms 2–5 carries compiled ∇H and D²H (the right-hand side
J∇H and its Jacobian J D²H for the reference methods, and the flows of the
general methods), and H itself for energies; ``structure=`` forces a form
(e.g. ``"general"`` to integrate a rotating frame with Gauss–Legendre).

Kernels are generated as in :mod:`varint.models.symbolic` (straight-line
code, common subexpressions eliminated, cached on disk); the exact
expression is kept (:meth:`HamiltonianModel.symbolic`) for heyoka's Taylor
reference, which builds Hamilton's equations from it.
"""

from __future__ import annotations

import functools
import numbers
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import sympy as sp
from sympy.printing.codeprinter import PrintMethodNotImplementedError

from ..flows import general as GEN
from ..flows import split as S
from ..kernels import row_program
from .base import Model
from .exact_zero import is_zero, without
from .lattice import Parts, no_band_kernel, no_gradient_kernel, no_third_kernel
from .potential_rows import rows_from
from .symbolic import (SymbolicModel, _assignments, _check_smooth, _coordinates,
                       KernelPrinter, _load_kernels, _NONFINITE, _time_symbol)

__all__ = ["SymbolicHamiltonian", "HamiltonianModel", "SeparableHamiltonian",
           "IntegrableHamiltonian", "TermwiseHamiltonian", "GeneralHamiltonian",
           "from_hamiltonian", "recognise", "STRUCTURES"]

#: The forms :func:`from_hamiltonian` recognises (``structure=``), in the
#: order it tries them; "auto" tries them all.
STRUCTURES = ("potential", "separable", "integrable", "terms", "general")


@dataclass(frozen=True)
class SymbolicHamiltonian:
    """A Hamiltonian written out in SymPy, with its recognised structure.

    Attributes
    ----------
    H : sympy.Expr
        The Hamiltonian, in the symbols ``q``, ``p`` (and ``time``).
    q, p : tuple of sympy.Symbol
        Coordinates and conjugate momenta, in state order x = (q, p).
    time : sympy.Symbol or None
        The time in H(q, p, t), or None.
    structure : str
        "separable", "integrable" or "general" (see the module docstring).
    A : sympy.Expr or None
        The exactly solvable part: T(p) for "separable", the quadratic A for
        "integrable"; None for "general".
    V : sympy.Expr or None
        H − A, a function of q alone, for the split forms.
    """

    H: sp.Expr
    q: tuple
    p: tuple
    time: sp.Symbol | None = None
    structure: str = "general"
    A: sp.Expr | None = None
    V: sp.Expr | None = None


# -- input ---------------------------------------------------------------------------------
def _check_hamiltonian(H, q, p, time):
    if isinstance(H, (int, float)) and not isinstance(H, bool):
        H = sp.Float(H) if isinstance(H, float) else sp.Integer(H)
    if not isinstance(H, sp.Expr):
        raise ValueError(f"H must be a SymPy expression in q and p, got {type(H).__name__} "
                         f"{H!r}")
    allowed = set(q) | set(p) | ({time} if time is not None else set())
    extra = H.free_symbols - allowed
    if extra:
        names = ", ".join(sorted(map(str, extra)))
        hint = "" if time is not None else " (a time-dependent H needs time=<its symbol>)"
        raise ValueError(f"H contains symbols that are neither coordinates nor momenta: "
                         f"{names}; substitute numbers for parameters (H.subs(...)){hint}")
    if H.has(*_NONFINITE):
        raise ValueError(f"H contains a non-finite constant (oo, zoo or nan): {H}")
    if H.has(sp.I):
        raise ValueError(f"H must be real; it contains the imaginary unit: {H}")
    if not H.free_symbols & set(p):
        raise ValueError(f"H does not depend on the momenta {[str(s) for s in p]}: nothing "
                         "moves (a potential alone is from_potential's V)")
    return H


def _momenta(p, q):
    p = _coordinates(p)
    if len(p) != len(q):
        raise ValueError(f"p must name one momentum per coordinate: {len(q)} coordinates "
                         f"{[str(s) for s in q]}, {len(p)} momenta {[str(s) for s in p]}")
    shared = set(p) & set(q)
    if shared:
        raise ValueError(f"{sorted(map(str, shared))[0]} is both a coordinate and a momentum")
    return p


# -- structure -----------------------------------------------------------------------------
@dataclass(frozen=True)
class Structure:
    """What :func:`recognise` found.

    Attributes
    ----------
    kind : str
        One of :data:`STRUCTURES`.
    A, V : sympy.Expr or None
        The solvable part and the potential (see :class:`SymbolicHamiltonian`).
    inverse_mass : tuple or None
        For "potential": the diagonal of M⁻¹, exact.
    planar : dict or None
        For "integrable": the plane (u, v), a, b, Ω and the other
        coordinates' (a_i, b_i) (:func:`varint.flows.split.planar_params`).
    terms : tuple of (str, sympy.Expr) or None
        For "terms": the parts, each a name and its expression.
    """

    kind: str
    A: sp.Expr | None = None
    V: sp.Expr | None = None
    inverse_mass: tuple | None = None
    planar: dict | None = None
    terms: tuple | None = None


def _separable(H, q, p):
    """(T, V) if H = T(p) + V(q), else None."""
    for qi in q:
        for pj in p:
            if not is_zero(sp.diff(H, qi, pj)):
                return None
    V = H.xreplace({s: 0 for s in p})
    T = H - V
    if T.free_symbols & set(q):
        T = without(T, q)
        if T is None:
            return None
    return T, V


def _diagonal_quadratic(T, p):
    """The diagonal of M⁻¹ if T = ½ Σ m⁻¹_i p_i² with constant m⁻¹_i > 0."""
    minv = []
    for i, pi in enumerate(p):
        c = sp.diff(T, pi, 2)
        if c.free_symbols or not c.is_number or not float(c) > 0:
            return None
        for pj in p[i + 1:]:
            if not is_zero(sp.diff(T, pi, pj)):
                return None
        minv.append(c)
    if not is_zero(T - sum(m * s**2 for m, s in zip(minv, p, strict=True)) / 2):
        return None
    return tuple(minv)


def _quadratic_terms(V, q):
    """The terms of V (at its top level) that are monomials of degree 2 in q
    with constant coefficients, and the rest."""
    quad, rest = [], []
    for term in sp.Add.make_args(sp.expand(V, deep=False)):
        if term.is_polynomial(*q) and sp.Poly(term, *q).is_homogeneous \
                and sp.Poly(term, *q).total_degree() == 2:
            quad.append(term)
        else:
            rest.append(term)
    return sp.Add(*quad), sp.Add(*rest)


def _planar(A, q, p):
    """The parameters of :func:`varint.flows.split.planar_flow` if the
    quadratic A has its form, else None."""
    if not A.is_polynomial(*q, *p):
        return None
    poly = sp.Poly(A, *q, *p)
    n = len(q)
    coeff = {}
    for monom, c in poly.terms():
        if sum(monom) == 0:
            continue             # a constant: no flow
        if sum(monom) != 2 or not c.is_number:
            return None
        idx = [i for i, e in enumerate(monom) for _ in range(e)]
        coeff[tuple(idx)] = c
    a = [2 * coeff.get((n + i, n + i), 0) for i in range(n)]
    b = [2 * coeff.get((i, i), 0) for i in range(n)]
    if any(not float(ai) > 0 for ai in a):
        return None
    mixed = {}
    for key, c in coeff.items():
        i, j = key
        if i == j:
            continue
        if i < n <= j:          # q_i p_{j−n}
            mixed[(i, j - n)] = c
        else:                   # q_i q_j or p_i p_j with i ≠ j: not of the form
            return None
    if not mixed:
        return None
    pairs = {tuple(sorted(k)) for k in mixed}
    if len(pairs) != 1:
        return None
    u, v = pairs.pop()
    if u == v:
        return None
    # −Ω (q_u p_v − q_v p_u).
    omega = -mixed.get((u, v), 0)
    if not is_zero(mixed.get((v, u), 0) - omega) or omega == 0:
        return None
    if not (is_zero(a[u] - a[v]) and is_zero(b[u] - b[v])):
        return None
    others = {i: (float(a[i]), float(b[i])) for i in range(n) if i not in (u, v)}
    return {"plane": (u, v), "a": float(a[u]), "b": float(b[u]), "omega": float(omega),
            "others": others}


def _integrable(H, q, p):
    """(A, V, planar parameters) if H = A + V(q) with A solvable, else None."""
    V0 = H.xreplace({s: 0 for s in p})
    P = H - V0
    if not P.is_polynomial(*q, *p):
        return None
    quad, rest = _quadratic_terms(V0, q)
    # The quadratic terms of q join A when that gives the solvable form (the
    # Larmor case), else A is the momentum-dependent part alone.
    for A, V in ((P + quad, rest), (P, V0)):
        planar = _planar(sp.expand(A), q, p)
        if planar is not None:
            return A, V, planar
    return None


def _terms(H, q, p):
    """H as a sum of parts whose vector fields are constant along their own
    flows, or None: the terms (after expansion) without momenta form the
    potential part; those with the single momentum p_i, the part of p_i,
    which must not depend on q_i. Along such a part's flow every argument
    of it is constant (q_i and p_j, j ≠ i, move, it depends on neither), so
    the flow is exactly x + h J∇P(x) and its tangent map 1 + h J D²P(x)."""
    parts = {}
    for term in sp.Add.make_args(sp.expand(H)):
        momenta = [i for i, pi in enumerate(p) if term.has(pi)]
        if len(momenta) > 1:
            return None
        key = momenta[0] if momenta else -1
        parts[key] = parts.get(key, 0) + term
    for i, part in parts.items():
        if i >= 0 and part.has(q[i]):
            return None
    if len([i for i in parts if i >= 0]) < 2 and -1 not in parts:
        return None
    named = [] if -1 not in parts else [("V", parts[-1])]
    named += [(str(p[i]), parts[i]) for i in sorted(i for i in parts if i >= 0)]
    return tuple(named) if len(named) >= 2 else None


def recognise(H, q, p, time=None):
    """The structure of H(q, p[, t]) (see the module docstring).

    Returns
    -------
    Structure
    """
    sep = _separable(H, q, p)
    if sep is not None:
        T, V = sep
        minv = _diagonal_quadratic(T, p)
        if minv is not None:
            return Structure("potential", A=T, V=V, inverse_mass=minv)
        if time is None or time not in H.free_symbols:
            return Structure("separable", A=T, V=V)
        return Structure("general")
    if time is None or time not in H.free_symbols:
        found = _integrable(H, q, p)
        if found is not None:
            A, V, planar = found
            return Structure("integrable", A=A, V=V, planar=planar)
        terms = _terms(H, q, p)
        if terms is not None:
            return Structure("terms", terms=terms)
    return Structure("general")


# -- kernels -------------------------------------------------------------------------------
def _function(printer, name, args, unpack, targets, exprs, returns=None):
    lines = ["", "", "@njit(cache=True, error_model='numpy')", f"def {name}({', '.join(args)}):",
             *unpack]
    if returns is not None:
        targets = [*targets, "_r"]
        exprs = [*exprs, returns]
    lines += _assignments(printer, targets, exprs)
    if returns is not None:
        lines.append("    return _r")
    return lines


def _hessian(expr, xs):
    g = [sp.diff(expr, s) for s in xs]
    D = [[sp.diff(g[i], xs[j]) if j >= i else None for j in range(len(xs))]
         for i in range(len(xs))]
    return g, D


def _grad_hess_lines(printer, name, arg, expr, xs, unpack, with_hessian):
    """``name(arg, par, g[, D])``: the gradient of ``expr`` in ``xs`` (and its
    dense Hessian, both triangles)."""
    g, D = _hessian(expr, xs)
    _check_smooth(g, "first derivatives", subject="H", need="twice differentiable")
    targets = [f"g[{i}]" for i in range(len(xs))]
    exprs = list(g)
    if with_hessian:
        flat = [D[i][j] for i in range(len(xs)) for j in range(i, len(xs))]
        _check_smooth(flat, "second derivatives", subject="H", need="twice differentiable")
        for i in range(len(xs)):
            for j in range(i, len(xs)):
                targets.append(f"D[{i}, {j}]")
                exprs.append(D[i][j])
        args = [arg, "par", "g", "D"]
    else:
        args = [arg, "par", "g"]
    lines = _function(printer, name, args, unpack, targets, exprs)
    if with_hessian:
        lines += [f"    D[{j}, {i}] = D[{i}, {j}]" for i in range(len(xs))
                  for j in range(i + 1, len(xs))]
    return lines


def _terms_apply_lines(count):
    """``apply(part, h, x, V, k, par, work)`` of a "terms" model: part P's
    flow x ← x + h J∇P(x) and tangent map δx ← δx + h J D²P(x) δx (exact:
    ∇P is constant along its flow), with the kernels ``term_<P>`` and
    ``term_grad_<P>``; ``work`` holds 2N + 4N² floats."""
    lines = ["", "", "@njit(cache=True, error_model='numpy')",
             "def apply(part, h, x, V, k, par, work):",
             "    d = x.shape[0]", "    n = d // 2", "    g = work[:d]",
             "    D = work[d:d + d * d].reshape((d, d))", "    y = work[d + d * d:2 * d + d * d]"]
    for i in range(count):
        lines += [f"    {'if' if i == 0 else 'elif'} part == {i}:",
                  "        if k == 0:", f"            term_grad_{i}(x, par, g)",
                  "        else:", f"            term_{i}(x, par, g, D)"]
    lines += ["    for c in range(k):", "        for i in range(d):", "            acc = 0.0",
              "            for j in range(d):", "                acc += D[i, j] * V[c, j]",
              "            y[i] = acc", "        for i in range(n):",
              "            V[c, i] += h * y[n + i]", "            V[c, n + i] -= h * y[i]",
              "    for i in range(n):", "        x[i] += h * g[n + i]",
              "        x[n + i] -= h * g[i]"]
    return lines


def _kernel_source(H, A, V, n, time, structure, terms=()):
    """Source of the module of kernels of a Hamiltonian in the standard
    symbols q_0 … q_{n−1}, p_0 … p_{n−1} (and t, read from ``par[-1]``);
    ``terms``: the parts of a "terms" model, in those symbols."""
    q = sp.symbols(f"q_0:{n}")
    p = sp.symbols(f"p_0:{n}")
    xs = (*q, *p)
    printer = KernelPrinter()
    unpack_x = [f"    q_{i} = x[{i}]" for i in range(n)] + [f"    p_{i} = x[{n + i}]"
                                                             for i in range(n)]
    if time:
        unpack_x.append("    t = par[-1]")
    lines = ['"""Generated by varint.models.hamiltonian.from_hamiltonian; do not edit."""',
             "import math", "from numba import njit"]
    try:
        lines += _grad_hess_lines(printer, "grad", "x", H, xs, unpack_x, False)
        lines += _grad_hess_lines(printer, "grad_hess", "x", H, xs, unpack_x, True)
        if time:
            dt = sp.diff(H, sp.Symbol("t"))
            _check_smooth([dt], "time derivative", subject="H", need="differentiable in t")
            lines += _function(printer, "dtime", ["x", "par"], unpack_x, [], [], returns=dt)
        if structure == "separable":
            unpack_p = [f"    p_{i} = p[{i}]" for i in range(n)]
            lines += _grad_hess_lines(printer, "grad_t", "p", A, p, unpack_p, False)
            lines += _grad_hess_lines(printer, "grad_hess_t", "p", A, p, unpack_p, True)
        if structure in ("separable", "integrable"):
            unpack_q = [f"    q_{i} = q[{i}]" for i in range(n)]
            lines += _grad_hess_lines(printer, "grad_v", "q", V, q, unpack_q, False)
            lines += _grad_hess_lines(printer, "grad_hess_v", "q", V, q, unpack_q, True)
        for i, term in enumerate(terms):
            lines += _grad_hess_lines(printer, f"term_grad_{i}", "x", term, xs, unpack_x, False)
            lines += _grad_hess_lines(printer, f"term_{i}", "x", term, xs, unpack_x, True)
        if terms:
            lines += _terms_apply_lines(len(terms))
    except PrintMethodNotImplementedError as exc:
        raise ValueError(f"H uses a function the compiled kernels cannot evaluate: {exc}") \
            from None
    return "\n".join(lines) + "\n"


# -- models --------------------------------------------------------------------------------
def _standard_symbols(q, p, time):
    """The substitution of q, p (and the time) by the kernels' symbols q_i,
    p_i (and t), the q_i, and the arguments (q_i, p_i[, t]) of H."""
    n = len(q)
    qs, ps = sp.symbols(f"q_0:{n}"), sp.symbols(f"p_0:{n}")
    std = {**dict(zip(q, qs, strict=True)), **dict(zip(p, ps, strict=True))}
    args = (*qs, *ps)
    if time is not None:
        std[time] = sp.Symbol("t")
        args += (sp.Symbol("t"),)
    return std, qs, args


def _numpy_function(args, expr):
    """``expr`` of ``args`` as NumPy code: SymPy's ``lambdify`` with
    NumPy's printer, its names looked up in NumPy's own namespace. Asked
    for ``modules="numpy"`` it builds that namespace by ``from numpy import
    *``, which loads NumPy's lazy submodules (``f2py``, ``testing``, …):
    ~0.08 CPU s of a fresh process's first model. The printed code is the
    same, and so are the functions its names find."""
    return sp.lambdify(args, expr, modules=[np])


class HamiltonianModel(Model):
    """A model H(q, p) that is not ½pᵀM⁻¹p + V(q), generated from SymPy;
    see :func:`from_hamiltonian`.

    Attributes
    ----------
    structure : str
        "separable", "integrable" or "general".
    grad_h, grad_hess_h : numba dispatchers
        ``grad_h(x, par, g)`` writes ∇H(x) (2N,); ``grad_hess_h(x, par, g, D)``
        also the dense Hessian D²H (2N, 2N). ``par[-1]`` is t for a
        time-dependent H.
    dtime_h : numba dispatcher or None
        ``dtime_h(x, par)`` = ∂_tH, for a time-dependent H.
    band_kernels : bool
        False: the band-Hessian kernels of :mod:`varint.models.base` do not
        exist for such H (methods that need them refuse the model).
    """

    band_kernels = False
    structure = "general"
    #: H, its structure and its kernels are fixed when the model is built:
    #: what is derived from its form may be kept per instance
    #: (:func:`varint.codegen.expressions.symbolic_fits`).
    frozen_form = True

    def __init__(self, H, q, p, time=None, name=None, escape_radius=None, _found=None):
        q = _coordinates(q)
        p = _momenta(p, q)
        time = _time_symbol(time, (*q, *p))
        H = _check_hamiltonian(H, q, p, time)
        found = _found if _found is not None else recognise(H, q, p, time)
        n = len(q)
        std, qs, args = _standard_symbols(q, p, time)
        H_std = H.xreplace(std)
        A_std = None if found.A is None else found.A.xreplace(std)
        V_std = None if found.V is None else found.V.xreplace(std)
        terms = () if found.terms is None else tuple(e.xreplace(std) for _, e in found.terms)
        source = _kernel_source(H_std, A_std, V_std, n, time is not None, self.structure, terms)
        kernels = _load_kernels(source)
        self.grad_h, self.grad_hess_h = kernels.grad, kernels.grad_hess
        self.dtime_h = getattr(kernels, "dtime", None)
        self._take_kernels(kernels)
        self._numpy_H = _numpy_function(args, H_std)
        self._numpy_V = None if V_std is None else _numpy_function(qs, V_std)
        self._symbolic = SymbolicHamiltonian(H, q, p, time, self.structure, found.A, found.V)
        self._found = found
        super().__init__(n, self._potential_values, no_gradient_kernel, no_band_kernel,
                         no_third_kernel, bandwidth=0, params=() if time is None else (0.0,),
                         name=name or f"H = {H}", escape_radius=escape_radius)
        if time is not None:
            self.time_dependent = True

    def _take_kernels(self, kernels):
        """Keep the structure's own kernels of the generated module."""

    # -- values ------------------------------------------------------------------------
    #: ``term(rows, out)`` adding to ``out`` (M,) a term of H of the
    #: positions (the first N columns of ``rows`` (M, ≥ N), C-contiguous)
    #: that the SymPy H leaves out, having no closed form (the rotating
    #: bar's potential), or None.
    _energy_term = None

    def _values(self, function, x, t, width, repeated=False):
        """``function`` (the lambdified H of (q, p[, t]), width 2N, or V of
        q, width N) plus zeros at the states ``x`` (..., width), then
        :attr:`_energy_term`. Bitwise the same either way: by the program
        of the same expression on the shared interpreter where its bits are
        NumPy's (:func:`~varint.models.potential_rows.rows_from`; the time,
        where H has one, as one more column) and the calls repeat
        (``repeated``: a short call, whose few states NumPy's ufuncs
        evaluate at ~0.7 µs an operation) or the interpreter is ready
        without compiling (:func:`varint.kernels.row_program.ready`), else
        NumPy's: a process's first runs compile nothing for their
        energies."""
        x = np.asarray(x, dtype=float)
        shape = x.shape[:-1]
        timed = self.time_dependent and width == self.dim
        rows = np.ascontiguousarray(x.reshape(-1, width))
        program = (rows_from(function, width + timed, True) if repeated or row_program.ready()
                   else None)
        if program is not None:
            if timed:
                times = np.broadcast_to(np.asarray(t, dtype=float), shape).reshape(-1, 1)
                rows = np.ascontiguousarray(np.concatenate([rows, times], axis=1))
            out = program(rows)
        else:
            args = [x[..., i] for i in range(width)] + ([t] if timed else [])
            out = (function(*args) + np.zeros(shape)).reshape(-1)
        if self._energy_term is not None:
            self._energy_term(rows, out)
        # One state's value as a NumPy scalar, as NumPy's H gives it.
        return out.reshape(shape)[()]

    def _potential_values(self, q, t=0.0, repeated=False):
        if self._numpy_V is not None:
            return self._values(self._numpy_V, q, t, self.n_dof, repeated)
        q = np.asarray(q, dtype=float)
        return self._values(self._numpy_H, np.concatenate([q, np.zeros_like(q)], axis=-1), t,
                            self.dim, repeated)

    def hamiltonian(self, x, t=0.0):
        """H(x) (H(x, t) if time-dependent) for states ``x`` of shape
        (..., 2N) (:meth:`_values`)."""
        return self._values(self._numpy_H, x, t, self.dim)

    def potential(self, q, t=0.0):
        """V(q) of the split forms; for a general H, H(q, 0) (the energy of
        a state at rest)."""
        q = np.asarray(q, dtype=float)
        return self._potential_values(q, t)

    def kinetic(self, p):
        """Not defined for H(q, p) that is not T(p) + V(q): the part of the
        energy that depends on the momenta also depends on q. Use
        :meth:`energy` (or :meth:`hamiltonian`)."""
        raise ValueError(f"{self.name} is not of the form T(p) + V(q): its kinetic energy "
                         "depends on q; use energy(x)")

    def energy(self, x, t=0.0, p_t=0.0):
        """H(x) for states ``x`` of shape (..., 2N); for a time-dependent H
        the extended energy K = H(x, t) + p_t."""
        e = self.hamiltonian(x, t)
        return e + p_t if self.time_dependent else e

    def energy_scale(self, x):
        """|H − V| + |V| per state (|H| for a general H), 1 where that is 0:
        the scale energy errors are relative to (see
        :meth:`varint.models.base.Model.energy_scale`)."""
        x = np.asarray(x, dtype=float)
        return self._scale(self.hamiltonian(x), x)

    def _scale(self, h, x, repeated=False):
        """:meth:`energy_scale` of the states ``x`` whose H is ``h``
        (``repeated``: :meth:`_values`)."""
        if self._numpy_V is None:
            scale = np.abs(h)
        else:
            v = self._potential_values(x[..., :self.n_dof], repeated=repeated)
            scale = np.abs(h - v) + np.abs(v)
        return np.where(scale > 0, scale, 1.0)

    def start_and_later_energies(self, x0, x):
        """(H, :meth:`energy_scale`) of the start states ``x0`` (M, 2N) and
        H of the states ``x`` (R, 2N), for a time-independent H: H once over
        the rows of both and V once (:meth:`_values` computes each row on
        its own, so the same bits as :meth:`hamiltonian` and
        :meth:`energy_scale` of each; a short call's accuracy verdict,
        :func:`varint.accuracy.reference_and_errors`, evaluated them in four
        calls). Its calls repeat: the energies' program is compiled for
        them where it is not ready (:meth:`_values`)."""
        m = len(x0)
        h = self._values(self._numpy_H, np.concatenate((x0, x)), 0.0, self.dim, repeated=True)
        return h[:m], self._scale(h[:m], x0, repeated=True), h[m:]

    def row_energies(self, states, m):
        """(H at every row of ``states`` (R, 2N), V at its first ``m`` rows,
        or None where the scale is |H| alone, a general H): the energies
        :meth:`start_and_later_energies` and :meth:`energy_scale` compute
        with them (their bits), for a time-independent H, evaluated as
        repeated calls' are (:meth:`_values`); a short call's verdict
        (:class:`varint.rerun.ShortCall`) computes the scale and the errors
        in one compiled call from these."""
        h = self._values(self._numpy_H, states, 0.0, self.dim, repeated=True)
        return h, (None if self._numpy_V is None else
                   self._potential_values(states[:m, :self.n_dof], repeated=True))

    def conserved(self, x, t=0.0, p_t=0.0):
        """The energy H (K = H + p_t for a time-dependent H); subclasses add
        their own first integrals (e.g. the Jacobi constant)."""
        return {"energy": self.energy(x, t, p_t)}

    def gradient_h(self, x, t=None):
        """∇H at the state ``x`` (2N,)."""
        x = np.ascontiguousarray(x, dtype=np.float64)
        g = np.empty(self.dim)
        self.grad_h(x, self.parameters_at(t), g)
        return g

    def hessian_h(self, x, t=None):
        """The dense Hessian D²H at ``x``, shape (2N, 2N)."""
        x = np.ascontiguousarray(x, dtype=np.float64)
        g = np.empty(self.dim)
        D = np.empty((self.dim, self.dim))
        self.grad_hess_h(x, self.parameters_at(t), g, D)
        return D

    def field(self, x, t=None):
        """The vector field ẋ = J∇H at ``x`` (Hamilton's equations)."""
        g = self.gradient_h(x, t)
        n = self.n_dof
        return np.concatenate([g[n:], -g[:n]])

    def momentum_from_energy(self, X, energy, index, t=0.0):
        """The momentum p_index that gives H = ``energy`` at the states ``X``
        (..., 2N) (their p_index ignored), on the branch with q̇_index =
        ∂H/∂p_index ≥ 0 (the crossing direction of a section q_index = c).

        H must be a polynomial of degree 1 or 2 in p_index (true of every
        rotating frame and magnetic field), solved in closed form.

        Returns
        -------
        p : ndarray, shape (...)
            NaN where no real momentum gives the energy (a forbidden region).

        Raises
        ------
        ValueError
            If H is not of degree 1 or 2 in p_index.
        """
        coeffs = self._momentum_coefficients(int(index))
        X = np.asarray(X, dtype=float)
        args = [X[..., i] for i in range(self.dim)]
        if self.time_dependent:
            args.append(t)
        c = [np.broadcast_to(f(*args), X.shape[:-1]).astype(float) for f in coeffs]
        if len(c) == 2:                       # β p + γ = E
            beta, gamma = c
            with np.errstate(all="ignore"):
                p = (energy - gamma) / beta
            # q̇ = β: the direction holds only where β > 0.
            return np.where(np.isfinite(p) & (beta > 0), p, np.nan)
        alpha, beta, gamma = c                # α p² + β p + γ = E; ∂H/∂p = 2αp + β ≥ 0
        with np.errstate(all="ignore"):
            disc = beta * beta - 4.0 * alpha * (gamma - energy)
            p = (-beta + np.sign(alpha) * np.sqrt(disc)) / (2.0 * alpha)
        return np.where(disc >= 0, p, np.nan)

    def _momentum_coefficients(self, index):
        key = ("_momentum", index)
        if key not in self.__dict__.setdefault("_memo", {}):
            s = self._symbolic
            if not 0 <= index < self.n_dof:
                raise ValueError(f"index must be a momentum index in 0..{self.n_dof - 1}, "
                                 f"got {index}")
            pi = s.p[index]
            expr = sp.expand(s.H)
            if not expr.is_polynomial(pi) or sp.degree(expr, pi) not in (1, 2):
                raise ValueError(f"H is not a polynomial of degree 1 or 2 in {pi}: solve its "
                                 "momentum from the energy by other means")
            poly = sp.Poly(expr, pi)
            coeffs = [poly.coeff_monomial(pi ** d) for d in range(poly.degree(), -1, -1)]
            std, _, args = _standard_symbols(s.q, s.p, s.time)
            self._memo[key] = [_numpy_function(args, c.xreplace(std))
                               for c in coeffs]
        return self._memo[key]

    def _memoised(self, key, make):
        """``make()``, made once per model: what depends only on H (H never
        changes). Dropped on pickling (:meth:`__getstate__`), made again."""
        memo = self.__dict__.setdefault("_memo", {})
        if key not in memo:
            memo[key] = make()
        return memo[key]

    def symbolic(self) -> SymbolicHamiltonian:
        """The Hamiltonian, coordinates, momenta and structure as given."""
        return self._symbolic

    def describe(self):
        d = super().describe()
        s = self._symbolic
        d.pop("inverse_mass", None)
        # H never changes, and its srepr costs ~5 ms for the three-body
        # problem, asked ~10 times by one chaos map: made once; so are the
        # symbols' names (SymPy's printer: 0.1 ms a call, every run asks).
        names = self._memoised("names", lambda: ([str(v) for v in s.q], [str(v) for v in s.p]))
        d.update(hamiltonian=self._memoised("srepr", lambda: sp.srepr(s.H)), q=list(names[0]),
                 p=list(names[1]), structure=self.structure, escape_radius=self.escape_radius)
        if s.time is not None:
            d["time"] = str(s.time)
        return d

    def __getstate__(self):
        # The lambdified functions do not pickle; they are rebuilt from H.
        state = dict(self.__dict__)
        for key in ("_numpy_H", "_numpy_V", "_memo"):
            state.pop(key, None)
        return state

    def __setstate__(self, state):
        self.__dict__.update(state)
        s = self._symbolic
        std, qs, args = _standard_symbols(s.q, s.p, s.time)
        self._numpy_H = _numpy_function(args, s.H.xreplace(std))
        self._numpy_V = (None if s.V is None
                         else _numpy_function(qs, s.V.xreplace(std)))




class _SplitHamiltonian(HamiltonianModel):
    """H = A + V(q) with both parts exactly solvable: the kernels of V and
    the part flows the part stepper runs (:class:`~varint.models.lattice.Parts`)."""

    #: The scheme of ``method="tm"`` when none is given (per structure).
    default_scheme = "s11odr6"

    def _take_kernels(self, kernels):
        self.grad_v, self.grad_hess_v = kernels.grad_v, kernels.grad_hess_v

    @property
    def parts(self):
        """The two parts (the solvable A, then V) and their fused flows
        (made once: a run asks ~7 times)."""
        return self._memoised("parts", self._parts)

    def _parts(self):
        n = self.n_dof
        return Parts(names=self.part_names, apply=self._apply(), field=S.hamiltonian_field(
            self.grad_h), splits={2: self.part_names}, par=self._part_params(),
            n_work=n + n * n, default_scheme=self.default_scheme)


class SeparableHamiltonian(_SplitHamiltonian):
    """H = T(p) + V(q) with a kinetic energy T other than ½pᵀM⁻¹p; see
    :func:`from_hamiltonian`. Parts "T" (drift, the flow of T) and "V"."""

    structure = "separable"
    part_names = ("T", "V")
    #: A composition of the second-order split (Kahan & Li): its order 6
    #: holds for any T, whereas the Runge–Kutta–Nyström schemes (SRKN14a)
    #: assume T quadratic in p and drop to order 4 for T = √(1 + p²)
    #: (measured, tests/flows/test_split.py).
    default_scheme = "s11odr6"

    def _take_kernels(self, kernels):
        super()._take_kernels(kernels)
        self.grad_t, self.grad_hess_t = kernels.grad_t, kernels.grad_hess_t

    def _apply(self):
        return S.separable_apply(self.grad_t, self.grad_hess_t, self.grad_v, self.grad_hess_v)

    def _part_params(self):
        return self.parameters_at(None)


class IntegrableHamiltonian(_SplitHamiltonian):
    """H = A + V(q), A the solvable quadratic of a rotating frame or a
    uniform magnetic field (module docstring); see :func:`from_hamiltonian`.
    Parts "A" (its exact linear flow) and "V".

    Attributes
    ----------
    planar : dict
        A's coefficients: the plane (u, v), a, b, Ω and the other
        coordinates' (a_i, b_i) (:func:`varint.flows.split.planar_params`).
    """

    structure = "integrable"
    part_names = ("A", "V")
    #: A is quadratic in p and V depends on q alone, so {V,{V,{V,A}}} = 0 and
    #: the Runge–Kutta–Nyström scheme SRKN14a (Blanes & Moan 2002) keeps its
    #: order 6 (measured on the CR3BP, tests/flows/test_split.py).
    default_scheme = "SRKN14a"

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.planar = self._found.planar

    def _apply(self):
        return S.rotating_apply(self.grad_v, self.grad_hess_v)

    def _part_params(self):
        pl = self.planar
        return S.planar_params(self.n_dof, pl["plane"], pl["a"], pl["b"], pl["omega"],
                               pl["others"])


class TermwiseHamiltonian(HamiltonianModel):
    """H = P_1 + … + P_k, each part either a potential V(q) or the terms of
    a single momentum p_i that do not depend on q_i (e.g. ½(p_i − A_i(q))²
    of a charged particle whose vector potential's A_i does not depend on
    q_i: a magnetic bottle in the symmetric gauge). Along each part's flow
    all of its arguments are constant, so the flow is x ← x + h J∇P(x) and
    its tangent map δx ← δx + h J D²P(x) δx, both exact and explicit: the
    k-part compositions of :data:`varint.schemes.SCHEMES` and the TM
    method apply (He, Sun, Liu & Qin, Phys. Lett. A 381, 568 (2017), split
    charged-particle Hamiltonians so).

    Attributes
    ----------
    part_names : tuple of str
        "V" for the potential, then the momentum of each part.
    """

    structure = "terms"

    def _take_kernels(self, kernels):
        self._apply_terms = kernels.apply

    @property
    def part_names(self):
        return tuple(name for name, _ in self._found.terms)

    @property
    def default_scheme(self):
        """An order-6 composition over the model's parts: s11ABC6 for three
        parts (Sofroniou & Spaletta's s11odr6 γ), the same γ over k parts
        otherwise."""
        k = len(self.part_names)
        if k == 3:
            return "s11ABC6"
        from ..schemes import CompositionScheme, get_scheme

        base = get_scheme("S11ABC6")
        return CompositionScheme(f"s11odr6 over {k} parts", k, base.gammas, base.order,
                                 base.reference)

    @property
    def parts(self):
        """The parts and their fused explicit flows (made once)."""
        return self._memoised("parts", self._parts)

    def _parts(self):
        d = self.dim
        return Parts(names=self.part_names, apply=self._apply_terms,
                     field=S.hamiltonian_field(self.grad_h),
                     splits={len(self.part_names): self.part_names},
                     par=self.parameters_at(None), n_work=2 * d + d * d,
                     default_scheme=self.default_scheme)


class GeneralHamiltonian(HamiltonianModel):
    """Any H(q, p) (or H(q, p, t)) without a solvable split; see
    :func:`from_hamiltonian`. ``method="tm"`` integrates it by implicit
    Gauss–Legendre steps (schemes GL4, GL6, GL8; :mod:`varint.flows.general`)
    or Tao's explicit method (TAO4, TAO6; :mod:`varint.flows.tao`), the
    reference methods by Hamilton's equations."""

    structure = "general"
    #: The scheme of ``method="tm"`` when none is given.
    default_scheme = "GL8"
    #: Gauss–Legendre through the part stepper, Tao's method through its own body.
    parts_propagator = "varint.methods.general:GeneralPropagator"

    @property
    def parts(self):
        """The whole-step integrators as the part stepper's flows
        (:mod:`varint.flows.general`); for a time-dependent H they run in
        the extended phase space, the time in the last parameter and its
        conjugate momentum carried by the stepper (``Parts.timed``). Made
        once per model (a run asks ~7 times, 10 µs each)."""
        return self._memoised("parts", self._parts)

    def _parts(self):
        par = np.ascontiguousarray(self.parameters_at(None), dtype=np.float64)
        timed = bool(self.time_dependent)
        kernels = (self.grad_h, self.grad_hess_h, self.n_dof, par.shape[0],
                   self.dtime_h if timed else None)
        # A run compiles only its scheme's Gauss–Legendre step (apply_only).
        return Parts(names=GEN.INTEGRATORS, apply=GEN.general_apply(*kernels),
                     apply_only=functools.partial(GEN.general_apply, *kernels),
                     field=S.hamiltonian_field(self.grad_h),
                     splits={len(GEN.INTEGRATORS): GEN.INTEGRATORS},
                     par=par, n_work=GEN.general_work(self.n_dof, par.shape[0], timed),
                     default_scheme=self.default_scheme,
                     schemes={**GEN.GENERAL_SCHEMES, **GEN.TAO_SCHEMES}, timed=timed)


_CLASSES = {"separable": SeparableHamiltonian, "integrable": IntegrableHamiltonian,
            "terms": TermwiseHamiltonian, "general": GeneralHamiltonian}


def from_hamiltonian(H: sp.Expr, q: Sequence[sp.Symbol], p: Sequence[sp.Symbol],
                     time: sp.Symbol | None = None, name: str | None = None,
                     escape_radius: float | None = None, structure: str = "auto"):
    """A model from a Hamiltonian H(q, p) (or H(q, p, t)) written in SymPy.

    The structure that keeps the tangent map exact is recognised (module
    docstring): ½pᵀM⁻¹p + V(q) gives :func:`~varint.models.from_potential`'s
    model; T(p) + V(q) a :class:`SeparableHamiltonian`; a rotating-frame or
    uniform-field quadratic plus V(q) an :class:`IntegrableHamiltonian`; a
    potential plus single-momentum parts free of their own coordinate a
    :class:`TermwiseHamiltonian`; anything else a
    :class:`GeneralHamiltonian`.

    Parameters
    ----------
    H : sympy.Expr
        The Hamiltonian; its free symbols must be among ``q``, ``p`` (and
        ``time``). Real and twice differentiable (no ``Abs``, ``sign``,
        ``Piecewise``, …); parameters substituted by numbers.
    q, p : sequence of sympy.Symbol
        Coordinates and their conjugate momenta, in the order of the state
        x = (q, p).
    time : sympy.Symbol, optional
        The time in a time-dependent H(q, p, t) (integrated in the extended
        phase space, with the momentum conjugate to time; the conserved
        quantity is K = H + p_t).
    name : str, optional
        Name in results; ``"H = <expression>"`` by default.
    escape_radius : float, optional
        Runs stop an orbit once |q| exceeds it.
    structure : {"auto", "potential", "separable", "integrable", "terms", "general"}
        "auto" recognises it; another value insists on that form (raising
        if H does not have it), e.g. "general" to integrate a rotating frame
        with Gauss–Legendre or Tao's method for comparison.

    Returns
    -------
    SymbolicModel or HamiltonianModel

    Raises
    ------
    ValueError
        If H has free symbols other than q, p and the time, non-finite
        constants, non-smooth functions or functions numba cannot compile;
        if q and p are not sequences of distinct symbols of equal length; if
        H does not depend on p; if ``structure`` is unknown or does not fit H.

    Examples
    --------
    The restricted three-body problem in the synodic frame is recognised as
    a rotating frame plus a potential:

    >>> import sympy as sp
    >>> x, y, px, py = sp.symbols("x y p_x p_y")
    >>> mu = sp.Rational(1, 100)
    >>> r1 = sp.sqrt((x + mu)**2 + y**2)
    >>> r2 = sp.sqrt((x - 1 + mu)**2 + y**2)
    >>> H = (px**2 + py**2) / 2 + y * px - x * py - (1 - mu) / r1 - mu / r2
    >>> from_hamiltonian(H, [x, y], [px, py]).structure
    'integrable'

    A relativistic particle, T = √(1 + p²), in a quartic well:

    >>> q1, p1 = sp.symbols("q p")
    >>> from_hamiltonian(sp.sqrt(1 + p1**2) + q1**4 / 4, [q1], [p1]).structure
    'separable'
    """
    if structure != "auto" and structure not in STRUCTURES:
        raise ValueError(f"structure must be 'auto' or one of {', '.join(STRUCTURES)}, got "
                         f"{structure!r}")
    qs = _coordinates(q)
    ps = _momenta(p, qs)
    t = _time_symbol(time, (*qs, *ps))
    H = _check_hamiltonian(H, qs, ps, t)
    if escape_radius is not None and not (isinstance(escape_radius, numbers.Real)
                                          and np.isfinite(escape_radius) and escape_radius > 0):
        raise ValueError(f"escape_radius must be positive and finite, got {escape_radius!r}")
    found = recognise(H, qs, ps, t)
    kind = found.kind if structure == "auto" else structure
    if kind == "potential":
        if found.kind != "potential":
            raise ValueError(f"H is not of the form ½pᵀM⁻¹p + V(q) with a constant diagonal "
                             f"mass (it is {found.kind}); structure='potential' does not fit")
        return SymbolicModel(found.V, qs, inverse_mass=found.inverse_mass, name=name,
                             escape_radius=escape_radius, time=t)
    if kind != found.kind and kind != "general":
        if kind == "separable" and found.kind == "potential":
            found = Structure("separable", A=found.A, V=found.V)
        elif kind == "integrable":
            pieces = None if t is not None and t in H.free_symbols else _integrable(H, qs, ps)
            if pieces is None:
                raise ValueError(f"H is not a solvable quadratic (rotating frame, uniform "
                                 f"field) plus V(q) (it is {found.kind}); "
                                 "structure='integrable' does not fit")
            found = Structure("integrable", A=pieces[0], V=pieces[1], planar=pieces[2])
        elif kind == "terms":
            terms = None if t is not None and t in H.free_symbols else _terms(H, qs, ps)
            if terms is None:
                raise ValueError(f"H is not a sum of a potential and single-momentum parts "
                                 f"free of their own coordinate (it is {found.kind}); "
                                 "structure='terms' does not fit")
            found = Structure("terms", terms=terms)
        else:
            raise ValueError(f"H is not of the form T(p) + V(q) (it is {found.kind}); "
                             f"structure={structure!r} does not fit")
    if kind == "general":
        found = Structure("general")
    return _CLASSES[kind](H, qs, ps, time=t, name=name, escape_radius=escape_radius,
                          _found=found)

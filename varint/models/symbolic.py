"""Models from a potential (or a map) written in SymPy: one definition for
every method.

:func:`from_potential` takes V(q) — or V(q, t), with ``time=t`` — as a SymPy
expression and derives what the integrators need (paper eqs. 6–7 and, for
the correctors, eq. 26):

* ∇V, D²V in symmetric band storage (:mod:`varint.kernels.banded`), and the third
  derivatives contracted with a vector, Σ_k v_k D²(∂_kV), as numba kernels
  for the TM stepper (the corrector C = ∇Vᵀ M⁻¹ ∇V, its gradient and its
  Hessian are assembled from these by :mod:`varint.kernels.tm`);
* V itself as a vectorised NumPy function (energies at output times);
* the expression, for the Taylor reference (heyoka builds its own
  variational equations from it) — :meth:`SymbolicModel.symbolic`.

A time-dependent V(q, t) is integrated in the extended phase space (see
:mod:`varint.kernels.tm`): the kernels read t from their last parameter,
``par[-1]``, and a fourth kernel ``dtime(q, par, gt)`` returns ∂_tV and
writes ∂_t∇V, for the momentum conjugate to time and the conserved extended
energy K = H + p_t.

:func:`from_map` takes a map x' = F(x) as SymPy expressions and compiles F
and its tangent map DF, derived symbolically, into a
:class:`~varint.models.maps.MapModel`.

The Hessian's bandwidth is read off its symbolic sparsity, so a lattice with
nearest-neighbour coupling gets bandwidth 1. Kernels are straight-line code
with common subexpressions eliminated; their source goes to
``<cache dir>/models/`` (see :func:`varint.cache.cache_dir`), never the
source tree, and numba caches their compilation beside it. Generated code
grows with N² (the Hessian) and N³ for dense third derivatives: fine up to a
few dozen degrees of freedom; long lattices want hand-written O(N) kernels
like :class:`~varint.models.FPUBeta`.
"""

from __future__ import annotations

import hashlib
import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import sympy as sp
from sympy.printing.codeprinter import PrintMethodNotImplementedError
from sympy.printing.pycode import PythonCodePrinter

from .. import codecache
from .base import Model
from .maps import MapModel
from .potential_rows import rows_from

__all__ = ["SymbolicPotential", "SymbolicModel", "from_potential", "SymbolicMap", "from_map",
           "NonSymplecticWarning",
           "KernelPrinter"]

#: Functions whose presence in V or its first three derivatives means V is
#: not smooth enough (the corrector needs third derivatives everywhere).
_NONSMOOTH = (sp.Abs, sp.sign, sp.Heaviside, sp.DiracDelta, sp.Piecewise, sp.Min, sp.Max,
              sp.floor, sp.ceiling, sp.frac, sp.re, sp.im, sp.arg, sp.Derivative, sp.Subs)
_NONFINITE = (sp.nan, sp.zoo, sp.oo, -sp.oo)


@dataclass(frozen=True)
class SymbolicPotential:
    """A model written out in SymPy: H = ½ Σ m⁻¹_i p_i² + V(q).

    Attributes
    ----------
    V : sympy.Expr
        The potential, in the symbols ``q`` only.
    q : tuple of sympy.Symbol
        The coordinates, in state order.
    inverse_mass : tuple of sympy.Expr
        Diagonal of M⁻¹, exact where the model knows it exactly (√2, not
        1.41421356…), so extended-precision references see the exact model.
    time : sympy.Symbol or None
        The time in V(q, t), or None for an autonomous V.
    """

    V: sp.Expr
    q: tuple
    inverse_mass: tuple
    time: sp.Symbol | None = None


def _coordinates(q):
    if isinstance(q, sp.Symbol):
        q = (q,)
    try:
        q = tuple(q)
    except TypeError:
        raise ValueError(f"q must be a sequence of SymPy symbols, got {q!r}") from None
    if not q:
        raise ValueError("q must name at least one coordinate")
    bad = [s for s in q if not isinstance(s, sp.Symbol)]
    if bad:
        raise ValueError(f"q must hold SymPy symbols; {bad[0]!r} is a {type(bad[0]).__name__}")
    if len(set(q)) != len(q):
        raise ValueError(f"q holds a symbol twice: {[str(s) for s in q]}")
    return q


def _time_symbol(time, q):
    if time is None:
        return None
    if not isinstance(time, sp.Symbol):
        raise ValueError(f"time must be a SymPy symbol (the t in V(q, t)), got "
                         f"{type(time).__name__} {time!r}")
    if time in q:
        raise ValueError(f"the time symbol {time} is also a coordinate")
    return time


def _check_potential(V, q, time=None):
    if isinstance(V, (int, float)) and not isinstance(V, bool):
        V = sp.Float(V) if isinstance(V, float) else sp.Integer(V)
    if not isinstance(V, sp.Expr):
        raise ValueError(f"V must be a SymPy expression in q, got {type(V).__name__} {V!r}")
    extra = V.free_symbols - set(q) - ({time} if time is not None else set())
    if extra:
        names = ", ".join(sorted(map(str, extra)))
        hint = "" if time is not None else " (a time-dependent V needs time=<its symbol>)"
        raise ValueError(
            f"V contains symbols that are not coordinates: {names}; substitute numbers for "
            f"parameters (V.subs(...)) or add them to q{hint}")
    if V.has(*_NONFINITE):
        raise ValueError(f"V contains a non-finite constant (oo, zoo or nan): {V}")
    if V.has(sp.I):
        raise ValueError(f"V must be real; it contains the imaginary unit: {V}")
    return V


def _check_smooth(exprs, what, subject="V", need="three times differentiable"):
    for e in exprs:
        if e.has(*_NONFINITE):
            raise ValueError(f"{what} of {subject} contain a non-finite constant: {e}")
        bad = e.atoms(*_NONSMOOTH)
        if bad:
            raise ValueError(
                f"{subject} must be {need}, but its {what} contain "
                f"{sorted(map(str, bad))[0]}"
                " (from |.|, sign, max/min, floor, a piecewise definition or similar); "
                f"write {subject} as a smooth expression")


def _inverse_mass(inverse_mass, n):
    if inverse_mass is None:
        return (sp.Integer(1),) * n
    values = inverse_mass if np.ndim(inverse_mass) else [inverse_mass] * n
    values = list(values)
    if len(values) != n:
        raise ValueError(
            f"inverse_mass must have {n} entries (one per coordinate), got {len(values)}")
    out = []
    for i, m in enumerate(values):
        e = _exact_number(m, f"inverse_mass[{i}]")
        value = float(e)
        if not (np.isfinite(value) and value > 0):
            raise ValueError(f"inverse_mass[{i}] must be positive and finite, got {m!r}")
        out.append(e)
    return tuple(out)


def _exact_number(value, name):
    """``value`` (a Python, NumPy or SymPy number, such as ``sympy.sqrt(2)``)
    as an exact SymPy number. Text is refused, never parsed: SymPy would
    evaluate it as Python code (``sympify`` calls ``eval``)."""
    if isinstance(value, (str, bytes, bool, np.bool_)):
        raise ValueError(f"{name} must be a number, got {type(value).__name__} {value!r}")
    if isinstance(value, float):
        return sp.Float(value)
    try:
        e = sp.sympify(value, strict=True)   # strict: numbers and SymPy objects only
    except (sp.SympifyError, TypeError):
        raise ValueError(f"{name} must be a number, got {value!r}") from None
    if not (isinstance(e, sp.Expr) and e.is_number and not e.free_symbols):
        raise ValueError(f"{name} must be a number, got {value!r}")
    return e


#: The largest integer numba types as a literal (int64).
_INT64_MAX = 2 ** 63 - 1


class KernelPrinter(PythonCodePrinter):
    """Python source for numba: ``math`` functions, float literals.

    An integer or a fraction whose parts are beyond int64 (numba cannot
    compile such a literal: a parameter such as ``FPUT(alpha=1e300)`` is
    the exact integer 10³⁰⁰ to SymPy) is written as the nearest double; one
    beyond the range of a double is refused with a ``ValueError`` naming it.
    """

    def __init__(self):
        super().__init__({"fully_qualified_modules": True, "strict": True})

    def _print_Integer(self, expr):
        if abs(expr.p) <= _INT64_MAX:
            return super()._print_Integer(expr)
        return _double(expr)

    def _print_Rational(self, expr):
        if abs(expr.p) <= _INT64_MAX and expr.q <= _INT64_MAX:
            return super()._print_Rational(expr)
        return _double(expr)


def _double(number):
    """``number`` (an exact SymPy number) as a float literal."""
    value = float(number)
    if not math.isfinite(value):
        digits = len(str(abs(sp.Integer(number.p)))) - len(str(number.q)) + 1
        raise ValueError(f"a coefficient of the model's derivatives is about 10^{digits}, "
                         "beyond the range of a double (1.8e308): its parameters are too large "
                         "to compute with")
    return repr(value)


def _assignments(printer, targets, exprs):
    """Source lines computing ``targets[i] = exprs[i]`` with CSE."""
    temps, reduced = sp.cse(list(exprs), symbols=sp.numbered_symbols("_t"))
    lines = [f"    {s} = {printer.doprint(e)}" for s, e in temps]
    lines += [f"    {t} = {printer.doprint(e)}" for t, e in zip(targets, reduced, strict=True)]
    return lines


def _kernel_source(V, n, time=False):
    """Source of the module defining ``grad``, ``hess``, ``third`` for V in
    the symbols q_0 … q_{n−1} (and ``dtime`` when V depends on the symbol
    ``t``, read from ``par[-1]``), and the Hessian's bandwidth."""
    q = sp.symbols(f"q_0:{n}")
    v = sp.symbols(f"v_0:{n}")
    g = [sp.diff(V, s) for s in q]
    _check_smooth(g, "first derivatives")
    H = {(i, j): sp.diff(g[i], q[j]) for i in range(n) for j in range(i, n)}
    _check_smooth(H.values(), "second derivatives")
    bw = max((j - i for (i, j), e in H.items() if e != 0), default=0)
    band = [(b, i) for b in range(bw + 1) for i in range(n)]
    hess = [H[i, i + b] if i + b < n else sp.Integer(0) for b, i in band]
    third = []
    for b, i in band:
        terms = [sp.diff(H[i, i + b], q[m]) for m in range(n)] if i + b < n else []
        _check_smooth(terms, "third derivatives")
        third.append(sp.Add(*[v[m] * t for m, t in enumerate(terms)]))
    printer = KernelPrinter()
    unpack_q = [f"    q_{i} = q[{i}]" for i in range(n)]
    if time:
        unpack_q.append("    t = par[-1]")
    unpack_v = [f"    v_{i} = v[{i}]" for i in range(n)]
    try:
        body_g = _assignments(printer, [f"g[{i}]" for i in range(n)], g)
        body_h = _assignments(printer, [f"B[{b}, {i}]" for b, i in band], hess)
        body_t = _assignments(printer, [f"B[{b}, {i}]" for b, i in band], third)
        if time:
            t = sp.Symbol("t")
            dt = sp.diff(V, t)
            dtg = [sp.diff(dt, s) for s in q]
            _check_smooth([dt, *dtg], "time derivatives")
            body_d = _assignments(printer, [f"gt[{i}]" for i in range(n)] + ["dv"],
                                  [*dtg, dt])
    except PrintMethodNotImplementedError as exc:
        raise ValueError(f"V uses a function the compiled kernels cannot evaluate: {exc}") from None
    lines = [
        '"""Generated by varint.models.symbolic.from_potential; do not edit."""',
        "import math", "from numba import njit", "",
        "", "@njit(cache=True, error_model='numpy')", "def grad(q, par, g):", *unpack_q, *body_g,
        "", "", "@njit(cache=True, error_model='numpy')", "def hess(q, par, B):", *unpack_q, *body_h,
        "", "", "@njit(cache=True, error_model='numpy')", "def third(q, par, v, B):", *unpack_q, *unpack_v, *body_t,
        "",
    ]
    if time:
        lines += ["", "@njit(cache=True, error_model='numpy')", "def dtime(q, par, gt):",
                  *unpack_q, *body_d, "    return dv", ""]
    return "\n".join(lines), bw


_LOADED: dict = {}


def _load_kernels(source):
    """Import the generated module (written once, signed, to
    ``<cache dir>/models`` and verified before every later import:
    :func:`varint.codecache.load_module`). One module object per source in
    a process, so equal potentials share kernels and the TM stepper
    compiled for them."""
    digest = hashlib.sha256(source.encode()).hexdigest()[:20]
    if digest not in _LOADED:
        _LOADED[digest] = codecache.load_module(f"varint_potential_{digest}", "models",
                                                lambda: source)
    return _LOADED[digest]


class SymbolicModel(Model):
    """A model generated from a SymPy potential; see :func:`from_potential`."""

    def __init__(self, V, q, inverse_mass=None, name=None, escape_radius=None, time=None):
        q = _coordinates(q)
        time = _time_symbol(time, q)
        V = _check_potential(V, q, time)
        minv = _inverse_mass(inverse_mass, len(q))
        n = len(q)
        qs = sp.symbols(f"q_0:{n}")
        t = sp.Symbol("t")
        V_std = V.xreplace({**dict(zip(q, qs, strict=True)), **({time: t} if time is not None else {})})
        source, bw = _kernel_source(V_std, n, time=time is not None)
        kernels = _load_kernels(source)
        #: SymPy's NumPy V, where V is autonomous (its source is the compiled
        #: V's, :attr:`potential_rows`).
        self._numpy_V = None
        if time is None:
            self._numpy_V = numpy_V = sp.lambdify(qs, V_std, modules="numpy")

            def autonomous(x):
                # A constant term comes back as a scalar; broadcast to x's shape.
                return numpy_V(*(x[..., i] for i in range(n))) + np.zeros(x.shape[:-1])
            potential = autonomous
        else:
            numpy_Vt = sp.lambdify((*qs, t), V_std, modules="numpy")

            def timed(x, t=0.0):
                return numpy_Vt(*(x[..., i] for i in range(n)), t) + np.zeros(x.shape[:-1])
            potential = timed

        self._symbolic = SymbolicPotential(V, q, minv, time)
        # The kernels of a time-dependent V read t from par[-1].
        super().__init__(n, potential, kernels.grad, kernels.hess, kernels.third, bandwidth=bw,
                         params=() if time is None else (0.0,),
                         inverse_mass=[float(m) for m in minv], name=name or f"V = {V}",
                         escape_radius=escape_radius)
        if time is not None:
            self.time_dependent = True
            self.time_kernel = kernels.dtime

    @property
    def potential_rows(self) -> Any:
        """V compiled over rows, emitted from the expression of SymPy's
        NumPy V (:meth:`Model.potential_rows
        <varint.models.base.Model.potential_rows>`,
        :func:`~varint.models.potential_rows.rows_from`: on every CPU for a
        V of sums, products, quotients, squares and square roots; with other
        powers wholly where NumPy's power is libm's, else but for those
        powers, which NumPy computes); None for a V(q, t)."""
        if self._numpy_V is None:
            return None
        # (The NumPy V adds zeros to the expression's value: a constant V
        # broadcast.)
        return rows_from(self._numpy_V, self.n_dof, plus_zero=True)

    def symbolic(self) -> SymbolicPotential:
        """The potential, coordinates and inverse mass as given."""
        return self._symbolic

    def describe(self):
        d = super().describe()
        s = self._symbolic
        d.update(potential=sp.srepr(s.V), q=[str(x) for x in s.q],
                 inverse_mass_exact=[sp.srepr(m) for m in s.inverse_mass],
                 escape_radius=self.escape_radius)
        if s.time is not None:
            d["time"] = str(s.time)
        return d


def from_potential(V: sp.Expr, q: Sequence[sp.Symbol], inverse_mass: Sequence[Any] | None = None,
                   name: str | None = None, escape_radius: float | None = None,
                   time: sp.Symbol | None = None) -> SymbolicModel:
    """A model H = ½ pᵀM⁻¹p + V(q) (or V(q, t)) from a SymPy potential.

    Everything every method needs is derived from ``V``: compiled ∇V, band
    D²V and third-derivative kernels for the TM stepper (hence the corrector
    C = ∇Vᵀ M⁻¹ ∇V of paper eq. 26 and its derivatives), the right-hand
    sides of the CVODE and DOP853 baselines (built from those kernels), and
    the Taylor reference's variational equations (built by heyoka from ``V``).

    Parameters
    ----------
    V : sympy.Expr
        The potential; its only free symbols must be those in ``q``. It must
        be real and three times differentiable (no ``Abs``, ``sign``,
        ``Piecewise``, ``Max``, …). Parameters must be substituted by numbers.
    q : sequence of sympy.Symbol
        The coordinates q_1 … q_N, in the order of the state vector
        x = (q, p).
    inverse_mass : sequence of numbers, optional
        Diagonal of M⁻¹ (SymPy numbers such as ``sympy.sqrt(2)`` are kept
        exact for the extended-precision reference); ones by default.
    name : str, optional
        Name in results; ``"V = <expression>"`` by default.
    escape_radius : float, optional
        Runs stop when |q| exceeds it (see :class:`~varint.models.Model`).
    time : sympy.Symbol, optional
        The time t in a time-dependent V(q, t) (a periodically driven
        pendulum or lattice, a rotating potential). The model is integrated
        in the extended phase space with t and its momentum p_t as one more
        degree of freedom (see :mod:`varint.kernels.tm`): every scheme and
        corrector stays symplectic, the TM method applies unchanged, runs
        start at t = 0, indicators use the physical deviation vectors
        (δt = 0), and the energy error is that of the conserved extended
        energy K = H(q, p, t) + p_t with p_t(0) = 0.

    Returns
    -------
    SymbolicModel

    Raises
    ------
    ValueError
        If ``V`` has free symbols other than ``q``, non-finite constants,
        non-smooth functions or functions numba cannot compile; if ``q`` is
        not a sequence of distinct symbols; if an inverse mass is not a
        positive finite number or their number is not N.

    Examples
    --------
    >>> import sympy as sp
    >>> x, y = sp.symbols("x y")
    >>> m = from_potential((x**2 + y**2) / 2 + x**2 * y - y**3 / 3, [x, y], name="HH")
    >>> m.gradient([0.1, 0.2]).round(3).tolist()
    [0.14, 0.17]

    A parametrically driven pendulum, V = −cos q (1 + ε cos Ωt):

    >>> q, t = sp.symbols("q t")
    >>> m = from_potential(-sp.cos(q) * (1 + sp.Rational(1, 2) * sp.cos(2 * t)), [q], time=t)
    >>> m.time_dependent
    True
    """
    return SymbolicModel(V, q, inverse_mass=inverse_mass, name=name, escape_radius=escape_radius,
                         time=time)


# -- maps ----------------------------------------------------------------------------------
def _map_source(F, n):
    """Source of the module defining ``iterate`` and ``jacobian`` for the map
    ``F`` (expressions in x_0 … x_{n−1})."""
    x = sp.symbols(f"x_0:{n}")
    _check_smooth(F, "expressions", subject="the map", need="differentiable")
    J = [[sp.diff(f, xi) for xi in x] for f in F]
    _check_smooth([e for row in J for e in row], "first derivatives", subject="the map",
                  need="differentiable")
    printer = KernelPrinter()
    unpack = [f"    x_{i} = x[{i}]" for i in range(n)]
    try:
        body_f = _assignments(printer, [f"out[{i}]" for i in range(n)], F)
        body_j = _assignments(printer, [f"J[{i}, {j}]" for i in range(n) for j in range(n)],
                              [e for row in J for e in row])
    except PrintMethodNotImplementedError as exc:
        raise ValueError(f"the map uses a function the compiled kernels cannot evaluate: "
                         f"{exc}") from None
    lines = [
        '"""Generated by varint.models.symbolic.from_map; do not edit."""',
        "import math", "from numba import njit", "",
        "", "@njit(cache=True, error_model='numpy')", "def iterate(x, par, out):", *unpack,
        *body_f,
        "", "", "@njit(cache=True, error_model='numpy')", "def jacobian(x, par, J):", *unpack,
        *body_j, "",
    ]
    return "\n".join(lines)


def _map_periods(periods, coords):
    if periods is None:
        return None
    if isinstance(periods, dict):
        unknown = [str(c) for c in periods if c not in coords]
        if unknown:
            raise ValueError(f"periods names {unknown[0]}, which is not one of the coordinates "
                             f"{[str(c) for c in coords]}")
        values = [periods.get(c, 0) for c in coords]
    else:
        values = list(periods) if np.ndim(periods) else [periods] * len(coords)
        if len(values) != len(coords):
            raise ValueError(f"periods must have {len(coords)} entries (one per coordinate, 0 "
                             f"for none), got {len(values)}")
    out = []
    for c, v in zip(coords, values, strict=True):
        try:
            value = float(_exact_number(v, f"the period of {c}"))
        except (TypeError, ValueError):
            raise ValueError(f"the period of {c} must be a number, got "
                             f"{type(v).__name__} {v!r}") from None
        if not (np.isfinite(value) and value >= 0):
            raise ValueError(f"the period of {c} must be finite and >= 0 (0: none), got {v!r}")
        out.append(value)
    return out


class SymbolicMap(MapModel):
    """A map generated from SymPy expressions; see :func:`from_map`."""

    def __init__(self, exprs, coords, periods=None, name=None, escape_radius=None):
        coords = _coordinates(coords)
        n = len(coords)
        if n % 2:
            raise ValueError(f"a symplectic map acts on an even number of variables (q and p); "
                             f"got {n} coordinates {[str(c) for c in coords]}")
        if isinstance(exprs, (sp.Expr, str)) or not np.iterable(exprs):
            raise ValueError("exprs must be a sequence of SymPy expressions, one per coordinate")
        exprs = [_check_map_expr(e, coords, i) for i, e in enumerate(exprs)]
        if len(exprs) != n:
            raise ValueError(f"exprs must give the image of each of the {n} coordinates, got "
                             f"{len(exprs)} expressions")
        xs = sp.symbols(f"x_0:{n}")
        F = [e.xreplace(dict(zip(coords, xs, strict=True))) for e in exprs]
        kernels = _load_kernels(_map_source(F, n))
        self._symbolic = (tuple(exprs), coords)
        periods = _map_periods(periods, coords)
        _warn_unless_symplectic(F, xs, periods)
        super().__init__(n, kernels.iterate, kernels.jacobian,
                         periods=periods,
                         name=name or "map " + ", ".join(f"{c}' = {e}" for c, e in
                                                         zip(coords, exprs, strict=True)),
                         escape_radius=escape_radius, variables=[str(c) for c in coords])

    def symbolic(self):
        """(expressions, coordinates) as given."""
        return self._symbolic

    def describe(self):
        d = super().describe()
        exprs, coords = self._symbolic
        d.update(map=[sp.srepr(e) for e in exprs], coords=[str(c) for c in coords])
        return d


#: Points at which :func:`_warn_unless_symplectic` checks a map.
SYMPLECTIC_SAMPLES = 16


def _warn_unless_symplectic(F, xs, periods):
    """Warn (:class:`NonSymplecticWarning`) if the map ``F`` (expressions in
    ``xs`` = (q, p)) is not symplectic: DFᵀ J DF = J, J = [[0, I], [−I, 0]],
    fails beyond round-off at one of :data:`SYMPLECTIC_SAMPLES` seeded points
    (uniform in [−1, 1] per coordinate, in [0, period) for a periodic one;
    points where DF is not finite are skipped). A map that is not
    symplectic is still iterated, but the laws the indicators rest on
    (exponents in pairs X_i + X_{2N−i+1} = 0, the GALI power laws) do not
    hold for it: a map with det DF = 2 gives X1 + X2 = ln 2."""
    n = len(xs)
    half = n // 2
    J = np.block([[np.zeros((half, half)), np.eye(half)],
                  [-np.eye(half), np.zeros((half, half))]])
    try:
        jac = sp.lambdify(xs, sp.Matrix(F).jacobian(xs), modules="numpy")
    except Exception:      # a form NumPy cannot evaluate: nothing to check
        return
    rng = np.random.default_rng(2010)
    lo = np.full(n, -1.0)
    hi = np.array([p if p else 1.0 for p in (periods or [0.0] * n)])
    lo[hi != 1.0] = 0.0
    worst, where = 0.0, None
    for point in rng.uniform(lo, hi, (SYMPLECTIC_SAMPLES, n)):
        with np.errstate(all="ignore"):
            try:
                D = np.array(jac(*point), dtype=float)
            except (ArithmeticError, TypeError, ValueError):
                continue
        if D.shape != (n, n) or not np.isfinite(D).all():
            continue
        defect = np.abs(D.T @ J @ D - J).max()
        tol = 1e3 * n * np.finfo(float).eps * (1.0 + np.abs(D).max() ** 2)
        if defect > tol and defect > worst:
            worst, where = defect, point
    if where is not None:
        warnings.warn(
            f"the map is not symplectic: max |DFᵀ J DF − J| = {worst:.3g} at x = "
            f"{np.round(where, 6).tolist()} (coordinates taken as q then p); it is iterated, "
            "but its Lyapunov exponents do not come in pairs X_i + X_(2N−i+1) = 0 and the GALI "
            "and SALI laws of symplectic maps do not hold for it", NonSymplecticWarning,
            stacklevel=4)


class NonSymplecticWarning(UserWarning):
    """A map given to :func:`from_map` is not symplectic (DFᵀ J DF ≠ J)."""


def _check_map_expr(e, coords, i):
    if isinstance(e, (int, float)) and not isinstance(e, bool):
        e = sp.Float(e) if isinstance(e, float) else sp.Integer(e)
    if not isinstance(e, sp.Expr):
        raise ValueError(f"exprs[{i}] must be a SymPy expression, got {type(e).__name__} {e!r}")
    extra = e.free_symbols - set(coords)
    if extra:
        raise ValueError(f"exprs[{i}] contains symbols that are not coordinates: "
                         f"{', '.join(sorted(map(str, extra)))}; substitute numbers for "
                         "parameters (expr.subs(...))")
    if e.has(sp.I):
        raise ValueError(f"exprs[{i}] must be real; it contains the imaginary unit: {e}")
    return e


def from_map(exprs, coords, periods=None, name=None, escape_radius=None):
    """A map model x' = F(x) from SymPy expressions.

    F and its tangent map DF (derived symbolically) are compiled into the
    kernels of :class:`~varint.models.maps.MapModel`, so every indicator,
    chaos maps and the two-particle method run on it (``method="tm"``
    iterates DF exactly).

    Parameters
    ----------
    exprs : sequence of sympy.Expr
        The images x'_i of the coordinates, in terms of the old coordinates
        only. A map composed of steps (kick then drift) is written by
        substitution: ``p1 = p + K*sin(x); exprs = [x + p1, p1]``.
    coords : sequence of sympy.Symbol
        The coordinates, in state order (an even number: a symplectic map).
        Symplecticity (DFᵀ J DF = J) is checked at a sample of points
        (:func:`_warn_unless_symplectic`): a map that fails is iterated all
        the same, with a :class:`NonSymplecticWarning`, since the laws of the
        indicators (paired exponents, GALI power laws) assume it.
    periods : dict or sequence, optional
        Periods of coordinates taken modulo them after every iteration
        (e.g. ``{x: 2*sympy.pi}``); 0 or absent: unbounded.
    name : str, optional
    escape_radius : float, optional
        Runs stop an orbit once |x| exceeds it.

    Returns
    -------
    SymbolicMap

    Examples
    --------
    The standard map:

    >>> import sympy as sp
    >>> x, p = sp.symbols("x p")
    >>> p1 = p + 1.2 * sp.sin(x)
    >>> m = from_map([x + p1, p1], [x, p], periods={x: 2 * sp.pi})
    >>> m.jacobian([0.0, 0.0]).tolist()
    [[2.2, 1.0], [1.2, 1.0]]
    """
    return SymbolicMap(exprs, coords, periods=periods, name=name, escape_radius=escape_radius)

"""Models from a potential written in SymPy: one definition for every method.

:func:`from_potential` takes V(q) as a SymPy expression and derives what the
integrators need (paper eqs. 6–7 and, for the correctors, eq. 26):

* ∇V, D²V in symmetric band storage (:mod:`varint.kernels.banded`), and the third
  derivatives contracted with a vector, Σ_k v_k D²(∂_kV), as numba kernels
  for the TM stepper (the corrector C = ∇Vᵀ M⁻¹ ∇V, its gradient and its
  Hessian are assembled from these by :mod:`varint.kernels.tm`);
* V itself as a vectorised NumPy function (energies at output times);
* the expression, for the Taylor reference (heyoka builds its own
  variational equations from it) — :meth:`SymbolicModel.symbolic`.

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
import importlib.util
import sys
import tempfile
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import sympy as sp
from sympy.printing.codeprinter import PrintMethodNotImplementedError
from sympy.printing.pycode import PythonCodePrinter

from ..files import atomic_write
from .base import Model

__all__ = ["SymbolicPotential", "SymbolicModel", "from_potential"]

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
    """

    V: sp.Expr
    q: tuple
    inverse_mass: tuple


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


def _check_potential(V, q):
    if isinstance(V, (int, float)) and not isinstance(V, bool):
        V = sp.Float(V) if isinstance(V, float) else sp.Integer(V)
    if not isinstance(V, sp.Expr):
        raise ValueError(f"V must be a SymPy expression in q, got {type(V).__name__} {V!r}")
    extra = V.free_symbols - set(q)
    if extra:
        names = ", ".join(sorted(map(str, extra)))
        raise ValueError(
            f"V contains symbols that are not coordinates: {names}; substitute numbers for "
            "parameters (V.subs(...)) or add them to q")
    if V.has(*_NONFINITE):
        raise ValueError(f"V contains a non-finite constant (oo, zoo or nan): {V}")
    if V.has(sp.I):
        raise ValueError(f"V must be real; it contains the imaginary unit: {V}")
    return V


def _check_smooth(exprs, what):
    for e in exprs:
        if e.has(*_NONFINITE):
            raise ValueError(f"{what} of V contain a non-finite constant: {e}")
        bad = e.atoms(*_NONSMOOTH)
        if bad:
            raise ValueError(
                f"V must be three times differentiable, but its {what} contain "
                f"{sorted(map(str, bad))[0]}"
                " (from |.|, sign, max/min, floor, a piecewise definition or similar); "
                "write V as a smooth expression")


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
        try:
            e = sp.sympify(m, strict=True) if not isinstance(m, float) else sp.Float(m)
        except (sp.SympifyError, TypeError):
            raise ValueError(f"inverse_mass[{i}] must be a number, got {m!r}") from None
        if not (isinstance(e, sp.Expr) and e.is_number):
            raise ValueError(f"inverse_mass[{i}] must be a number, got {m!r}")
        value = float(e)
        if not (np.isfinite(value) and value > 0):
            raise ValueError(f"inverse_mass[{i}] must be positive and finite, got {m!r}")
        out.append(e)
    return tuple(out)


class _KernelPrinter(PythonCodePrinter):
    """Python source for numba: ``math`` functions, float literals."""

    def __init__(self):
        super().__init__({"fully_qualified_modules": True, "strict": True})


def _assignments(printer, targets, exprs):
    """Source lines computing ``targets[i] = exprs[i]`` with CSE."""
    temps, reduced = sp.cse(list(exprs), symbols=sp.numbered_symbols("_t"))
    lines = [f"    {s} = {printer.doprint(e)}" for s, e in temps]
    lines += [f"    {t} = {printer.doprint(e)}" for t, e in zip(targets, reduced)]
    return lines


def _kernel_source(V, n):
    """Source of the module defining ``grad``, ``hess``, ``third`` for V in
    the symbols q_0 … q_{n−1}, and the Hessian's bandwidth."""
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
    printer = _KernelPrinter()
    unpack_q = [f"    q_{i} = q[{i}]" for i in range(n)]
    unpack_v = [f"    v_{i} = v[{i}]" for i in range(n)]
    try:
        body_g = _assignments(printer, [f"g[{i}]" for i in range(n)], g)
        body_h = _assignments(printer, [f"B[{b}, {i}]" for b, i in band], hess)
        body_t = _assignments(printer, [f"B[{b}, {i}]" for b, i in band], third)
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
    return "\n".join(lines), bw


_LOADED = {}


def _write_source(folder, digest, source):
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"potential_{digest}.py"
    if not path.exists() or path.read_text() != source:
        # Rewriting an identical file would only invalidate numba's cache.
        atomic_write(path, source)
    return path


def _load_kernels(source):
    """Import the generated module (written once, atomically, to the cache
    directory). One module object per source in a process, so equal
    potentials share kernels and the TM stepper compiled for them."""
    digest = hashlib.sha256(source.encode()).hexdigest()[:20]
    if digest in _LOADED:
        return _LOADED[digest]
    from ..cache import cache_dir

    try:
        path = _write_source(cache_dir() / "models", digest, source)
    except OSError as exc:
        # An unwritable cache costs numba's on-disk caching, not the model.
        warnings.warn(f"cannot write generated kernels to {cache_dir()} ({exc}); using a "
                      "temporary directory", RuntimeWarning, stacklevel=4)
        path = _write_source(Path(tempfile.mkdtemp(prefix="varint-")), digest, source)
    spec = importlib.util.spec_from_file_location(f"varint_potential_{digest}", path)
    module = importlib.util.module_from_spec(spec)
    # numba's on-disk cache finds the kernels' globals by module name.
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    _LOADED[digest] = module
    return module


class SymbolicModel(Model):
    """A model generated from a SymPy potential; see :func:`from_potential`."""

    def __init__(self, V, q, inverse_mass=None, name=None, escape_radius=None):
        q = _coordinates(q)
        V = _check_potential(V, q)
        minv = _inverse_mass(inverse_mass, len(q))
        n = len(q)
        qs = sp.symbols(f"q_0:{n}")
        V_std = V.xreplace(dict(zip(q, qs)))
        source, bw = _kernel_source(V_std, n)
        kernels = _load_kernels(source)
        numpy_V = sp.lambdify(qs, V_std, modules="numpy")

        def potential(x):
            # A constant term comes back as a scalar; broadcast to x's shape.
            return numpy_V(*(x[..., i] for i in range(n))) + np.zeros(x.shape[:-1])

        self._symbolic = SymbolicPotential(V, q, minv)
        super().__init__(n, potential, kernels.grad, kernels.hess, kernels.third, bandwidth=bw,
                         inverse_mass=[float(m) for m in minv], name=name or f"V = {V}",
                         escape_radius=escape_radius)

    def symbolic(self) -> SymbolicPotential:
        """The potential, coordinates and inverse mass as given."""
        return self._symbolic

    def describe(self):
        d = super().describe()
        s = self._symbolic
        d.update(potential=sp.srepr(s.V), q=[str(x) for x in s.q],
                 inverse_mass_exact=[sp.srepr(m) for m in s.inverse_mass],
                 escape_radius=self.escape_radius)
        return d


def from_potential(V: sp.Expr, q: Sequence[sp.Symbol], inverse_mass: Sequence[Any] | None = None,
                   name: str | None = None, escape_radius: float | None = None) -> SymbolicModel:
    """A model H = ½ pᵀM⁻¹p + V(q) from a SymPy potential.

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
    """
    return SymbolicModel(V, q, inverse_mass=inverse_mass, name=name, escape_radius=escape_radius)

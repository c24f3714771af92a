"""A model's V compiled over rows of states, emitted from the very
expression its NumPy V evaluates (issue 28: a prepared run's short call
measures V of its few start and output states, where NumPy's ufuncs cost
~0.7 µs an operation on such tiny arrays; :class:`varint.rerun.ShortCall`).

The NumPy V is a function ``def f(q_0, …, q_{N−1}): return <expression>``
evaluated on the columns of the states (SymPy's ``lambdify`` writes such a
function for :func:`~varint.models.from_potential`; Hénon–Heiles' is
written so). :func:`rows_from` reads that function's source and compiles
the same expression, on one row's numbers at a time, into a numba loop over
the rows. The same operations in the same order, each one IEEE operation
rounded once in both (numba compiles without fast-math: LLVM neither fuses
a product and a sum into an FMA nor reorders them), give the same bits,
except where NumPy does not compute what numba would for the same text;
there the compiled copy is written otherwise, or not made:

* ``b ** 2``, ``b ** -1``, ``b ** 0.5`` (an array to the integer or the
  float 2, −1, or to 0.5): ``ndarray.__pow__``'s fast paths, NumPy's
  ``square`` (one product), ``reciprocal`` (one division) and ``sqrt``; the
  compiled copy writes ``(b) * (b)``, ``1.0 / (b)`` and ``sqrt(b)``;
* ``b ** e`` for another constant ``e``: NumPy's float ``power``. That is
  libm's ``pow`` only on a CPU without AVX-512 (:data:`NUMPY_POWER_IS_LIBM`);
  with AVX-512 NumPy calls Intel SVML's ``pow``, whose last bit need not be
  libm's. So where NumPy's power is libm's the compiled copy writes
  ``(b) ** e`` with ``e`` written as a float (numba then calls libm's
  ``pow``; ``b ** 3`` with an integer would be numba's binary powering,
  products); elsewhere NumPy computes these powers itself
  (:class:`NumPyPowers`: the rest compiled, in two parts around one call
  of NumPy's ``power``). SymPy writes every integer power this way
  (``y**3``, not ``y*y*y``), so a cube or a fourth power is such a power;
  NumPy's fast paths for 0 and 1 are not reproduced (no compiled V);
* a function: only ``sqrt`` (correctly rounded in both). NumPy's float64
  ``exp``, ``log``, ``sin``, … are its own SIMD code or SVML's on some
  CPUs, not libm's that numba calls: no compiled V;
* anything else (a name that is not an argument, an attribute, a
  comparison, a constant base, an integer beyond 2⁵³, …): no compiled V.

So a V of sums, products and quotients of its coordinates, their squares,
reciprocals and square roots (``x**2*y**2 + (1/2)*x**2``) is compiled on
every CPU; one with a cube (Hénon–Heiles' ``y**3``) wholly only where
NumPy's power is libm's, and else but for its powers (a power within the
base of another is not split so: no compiled V).
The compiled module goes to ``<cache dir>/models/`` like the kernels of
:func:`~varint.models.from_potential` (:func:`varint.codecache.load_module`,
signed, named by its source), and numba caches its compilation beside it.
"""

from __future__ import annotations

import ast
import functools
import hashlib
import inspect
import operator
import textwrap
from collections.abc import Callable
from typing import Any

import numpy as np

from .. import codecache, floating_errors
from ..kernels.resolved import Resolved

try:
    from numpy._core._multiarray_umath import __cpu_features__ as _NUMPY_CPU
except ImportError:  # another NumPy's layout: assume its SIMD loops
    _NUMPY_CPU = {}

__all__ = ["NUMPY_POWER_IS_LIBM", "NumPyPowers", "rows_from", "rows_source"]

#: Whether NumPy's float64 ``power`` is libm's ``pow`` on this CPU, as a
#: compiled ``b ** 3.0`` is: on a CPU with AVX-512 NumPy's loop calls Intel
#: SVML's ``pow`` (``numpy/_core/src/umath/loops_umath_fp.dispatch.c.src``,
#: even for a scalar exponent), whose last bit need not be libm's.
NUMPY_POWER_IS_LIBM = _NUMPY_CPU.get("AVX512F") is False

#: Exponents ``ndarray.__pow__`` computes by another ufunc than ``power``
#: (its fast paths) that the compiled copy does not write (SymPy never
#: prints them).
_FAST_EXPONENTS = (0.0, 1.0)

#: The prefix of the names of the powers NumPy computes (:class:`_Rows`).
_POWER = "_pw"

#: Names the compiled copy's source gives meanings of its own; a NumPy V
#: with an argument so named gets no compiled V.
_RESERVED = frozenset({"np", "njit", "_sqrt", "states", "powers", "out", "i", "EXPONENTS",
                       "bases", "potential_rows"})

#: NumPy's ``power``, the ufunc ``ndarray.__pow__`` calls for the powers
#: :class:`NumPyPowers` leaves to NumPy (a name of its own, so that a test
#: can stand in for a CPU where it is not libm's).
_power = np.power

#: Largest integer constant taken: every one up to it converts exactly to
#: a double, in NumPy (a Python int beside a float64 array) and in numba.
_EXACT_INT = 2 ** 53


class _Unsafe(Exception):
    """The expression holds something whose compiled value could differ
    from NumPy's (module docstring)."""


def _constant(node: ast.expr) -> float | None:
    """The value of ``node`` where it is a number or arithmetic on numbers
    only (an exponent such as ``(3/2)`` or ``-2.0``), else None."""
    if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)) \
            and not isinstance(node.value, bool):
        return float(node.value)
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
        value = _constant(node.operand)
        return None if value is None else (-value if isinstance(node.op, ast.USub) else value)
    if isinstance(node, ast.BinOp) and isinstance(node.op, (ast.Add, ast.Sub, ast.Mult,
                                                             ast.Div)):
        left, right = _constant(node.left), _constant(node.right)
        if left is None or right is None:
            return None
        # (As Python computes it when it evaluates the NumPy V's text: its
        # true division of two integers is the correctly rounded quotient,
        # as of the two doubles, exact for both up to 2^53.)
        return _ARITHMETIC[type(node.op)](left, right)
    return None


#: The arithmetic of :func:`_constant`.
_ARITHMETIC = {ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul,
               ast.Div: operator.truediv}


class _Rows(ast.NodeTransformer):
    """The NumPy V's expression as the compiled copy writes it, or
    :class:`_Unsafe` (module docstring's rules). ``numpy_powers``: each
    power that NumPy computes by its ``power`` is written as the name
    ``_pw<i>`` instead, its (base, exponent) kept in :attr:`powers`."""

    def __init__(self, names: tuple[str, ...], numpy_powers: bool = False) -> None:
        if _RESERVED.intersection(names) or any(a.startswith(_POWER) for a in names):
            # (The compiled copy's own names: an argument so named would
            # be read as one of them.)
            raise _Unsafe("an argument named as the compiled copy's names")
        self.names = set(names)
        self.numpy_powers = numpy_powers
        #: (the base as the compiled copy writes it, the exponent) of each
        #: ``_pw<i>``, in order.
        self.powers: list[tuple[ast.expr, float]] = []

    def generic_visit(self, node: ast.AST) -> ast.AST:
        raise _Unsafe(type(node).__name__)

    def visit_Expression(self, node: ast.Expression) -> ast.AST:
        node.body = self.visit(node.body)
        return node

    def visit_Constant(self, node: ast.Constant) -> ast.AST:
        if type(node.value) is float or (type(node.value) is int
                                          and abs(node.value) <= _EXACT_INT):
            return node
        raise _Unsafe(repr(node.value))

    def visit_Name(self, node: ast.Name) -> ast.AST:
        if node.id in self.names and isinstance(node.ctx, ast.Load):
            return node
        raise _Unsafe(node.id)

    def visit_UnaryOp(self, node: ast.UnaryOp) -> ast.AST:
        if not isinstance(node.op, (ast.USub, ast.UAdd)):
            raise _Unsafe(type(node.op).__name__)
        node.operand = self.visit(node.operand)
        return node

    def visit_Call(self, node: ast.Call) -> ast.AST:
        if not (isinstance(node.func, ast.Name) and node.func.id == "sqrt"
                and len(node.args) == 1 and not node.keywords):
            raise _Unsafe(ast.unparse(node.func))
        return ast.Call(func=ast.Name("_sqrt", ast.Load()), args=[self.visit(node.args[0])],
                        keywords=[])

    def visit_BinOp(self, node: ast.BinOp) -> ast.AST:
        if isinstance(node.op, (ast.Add, ast.Sub, ast.Mult, ast.Div)):
            node.left, node.right = self.visit(node.left), self.visit(node.right)
            return node
        if not isinstance(node.op, ast.Pow):
            raise _Unsafe(type(node.op).__name__)
        exponent = _constant(node.right)
        if exponent is None or not any(isinstance(n, ast.Name) for n in ast.walk(node.left)):
            raise _Unsafe("a power of a variable exponent or a constant base")
        held = len(self.powers)
        base = self.visit(node.left)
        if exponent == 2.0:
            # NumPy's square: one product.
            return ast.BinOp(base, ast.Mult(), base)
        if exponent == -1.0:
            # NumPy's reciprocal: one division.
            return ast.BinOp(ast.Constant(1.0), ast.Div(), base)
        if exponent == 0.5:
            # NumPy's sqrt.
            return ast.Call(func=ast.Name("_sqrt", ast.Load()), args=[base], keywords=[])
        if exponent in _FAST_EXPONENTS:
            raise _Unsafe(f"a power {exponent!r}")
        if not self.numpy_powers:
            # libm's pow, as NumPy's power here.
            return ast.BinOp(base, ast.Pow(), ast.Constant(exponent))
        if len(self.powers) > held:
            # (Its base would need NumPy's power before the compiled bases.)
            raise _Unsafe("a power within the base of a power computed by NumPy")
        self.powers.append((base, exponent))
        return ast.Name(f"{_POWER}{len(self.powers) - 1}", ast.Load())


def _expression(function: Callable[..., Any], n: int) -> tuple[str, tuple[str, ...]]:
    """(the returned expression's source, the argument names) of
    ``function``, a ``def f(a_0, …, a_{n−1}): return <expression>``."""
    tree = ast.parse(textwrap.dedent(inspect.getsource(function)))
    node = tree.body[0]
    if not (isinstance(node, ast.FunctionDef) and len(node.body) == 1
            and isinstance(node.body[0], ast.Return) and node.body[0].value is not None):
        raise _Unsafe("not one returned expression")
    args = node.args
    names = tuple(a.arg for a in args.args)
    if (len(names) != n or args.posonlyargs or args.vararg or args.kwonlyargs or args.kwarg
            or args.defaults or node.decorator_list):
        raise _Unsafe("not a function of the N coordinates alone")
    return ast.unparse(node.body[0].value), names


def rows_source(expression: str, names: tuple[str, ...], plus_zero: bool = False,
                numpy_powers: bool | None = None) -> str | None:
    """The source of a module whose ``potential_rows(states)`` is V at each
    row of ``states`` (R, ≥ N) from the NumPy V's ``expression`` in the
    coordinates ``names`` (columns 0 … N−1), or None where its bits could
    differ from NumPy's (module docstring). ``plus_zero``: the NumPy V adds
    zeros to the expression's value (a constant V broadcast), which turns
    −0 into +0; the compiled copy adds 0.0 likewise.

    ``numpy_powers`` (default: where NumPy's power is not libm's,
    :data:`NUMPY_POWER_IS_LIBM`): the powers NumPy computes by its
    ``power`` are left to it. Where the expression has such powers, the
    module's ``bases(states)`` is then their bases (P, R),
    ``EXPONENTS`` their exponents, and ``potential_rows(states, powers)``
    V from the states and the powers (P, R) (:class:`NumPyPowers`)."""
    if numpy_powers is None:
        numpy_powers = not NUMPY_POWER_IS_LIBM
    try:
        rows = _Rows(names, numpy_powers)
        tree = rows.visit(ast.parse(expression, mode="eval"))
    except (_Unsafe, SyntaxError):
        return None
    body = ast.unparse(tree)
    if plus_zero:
        body = f"({body}) + 0.0"
    unpack = [f"        {name} = states[i, {j}]" for j, name in enumerate(names)]
    head = ['"""Generated by varint.models.potential_rows; do not edit."""',
            "import numpy as np", "from numba import njit", "", "_sqrt = np.sqrt", "", ""]
    if not rows.powers:
        return "\n".join([
            *head, "@njit(cache=True, error_model='numpy')", "def potential_rows(states):",
            "    out = np.empty(states.shape[0])", "    for i in range(states.shape[0]):",
            *unpack, f"        out[i] = {body}", "    return out", ""])
    p = len(rows.powers)
    exponents = ", ".join(repr(e) for _, e in rows.powers)
    return "\n".join([
        *head, f"EXPONENTS = ({exponents},)", "", "",
        "@njit(cache=True, error_model='numpy')", "def bases(states):",
        f"    out = np.empty(({p}, states.shape[0]))", "    for i in range(states.shape[0]):",
        *unpack, *(f"        out[{j}, i] = {ast.unparse(b)}" for j, (b, _) in enumerate(rows.powers)),
        "    return out", "", "",
        "@njit(cache=True, error_model='numpy')", "def potential_rows(states, powers):",
        "    out = np.empty(states.shape[0])", "    for i in range(states.shape[0]):",
        *unpack, *(f"        {_POWER}{j} = powers[{j}, i]" for j in range(p)),
        f"        out[i] = {body}", "    return out", ""])


class NumPyPowers:
    """V over rows compiled but for its powers, which NumPy's ``power``
    computes, as the NumPy V's own ``b ** e`` does (on a CPU where that is
    not libm's ``pow``, :data:`NUMPY_POWER_IS_LIBM`): the bases compiled,
    their powers in one call of ``power`` (floating-point errors ignored,
    as the compiled parts ignore them), V compiled from the states and the
    powers.

    The bits are the NumPy V's: the bases and the rest are the same IEEE
    operations in the same order (module docstring), and each power is
    NumPy's ``power`` of the same two doubles. That ufunc's float64 loop
    gives each element a function of its two operands alone, whatever the
    layout of the arrays: libm's ``pow`` one element at a time, or SVML's
    vector ``pow``, whose lanes are independent, for every stride
    (``numpy/_core/src/umath/loops_umath_fp.dispatch.c.src``); its one
    exception, an exponent 2 or 0.5 broadcast (a square, a square root), is
    written otherwise before (:class:`_Rows`), so no exponent here is one.

    Parameters
    ----------
    bases, combine : numba dispatchers (or :class:`~varint.kernels.resolved.Resolved`)
        The generated module's ``bases`` and ``potential_rows``.
    exponents : tuple of float
        Its ``EXPONENTS``, one per row of the bases.
    """

    __slots__ = ("bases", "combine", "exponents", "_exponent")

    def __init__(self, bases: Any, combine: Any, exponents: tuple[float, ...]) -> None:
        self.bases, self.combine = bases, combine
        self.exponents = exponents
        # The exponent of every row of the bases: one NumPy scalar where
        # they are all one (NumPy's quickest call, ~1.4 µs against ~3.8 µs
        # for a column broadcast, on a few rows), else a column (P, 1).
        self._exponent = (np.float64(exponents[0]) if len(set(exponents)) == 1
                          else np.array(exponents, dtype=np.float64)[:, None])

    def __call__(self, states: np.ndarray) -> np.ndarray:
        """V (R,) at each row of ``states`` (R, ≥ N), C-contiguous float64."""
        bases = self.bases(states)
        quiet = floating_errors.ignoring()
        try:
            powers = _power(bases, self._exponent)
        finally:
            floating_errors.restore(quiet)
        return self.combine(states, powers)

    def resolved(self) -> NumPyPowers:
        """This V with its compiled parts called through the compiled
        versions their first call selects (:class:`~varint.kernels.resolved.Resolved`):
        for a caller whose states are made the same way at every call."""
        return NumPyPowers(Resolved(self.bases), Resolved(self.combine), self.exponents)


@functools.lru_cache(maxsize=256)
def rows_from(function: Callable[..., Any], n: int, plus_zero: bool = False,
              numpy_powers: bool | None = None) -> Any:
    """V compiled over rows from the NumPy V's ``function`` of the ``n``
    coordinates (``def f(q_0, …): return <expression>``), a numba
    dispatcher taking states (R, ≥ n) C-contiguous float64 and returning
    V (R,), bitwise ``function`` of their columns (``+ 0.0`` where
    ``plus_zero``), or a :class:`NumPyPowers` (called the same way) where
    NumPy computes its powers (``numpy_powers``, :func:`rows_source`);
    None where it could round otherwise (module
    docstring) or ``function`` is not of that form. Made once per
    ``function``: the models ask for it on every prepared run and keep
    nothing of it, since a remembered call's key reads every attribute of
    its model (:mod:`varint.remembered`), and one set at a first call would
    make the next call with the same arguments miss."""
    try:
        expression, names = _expression(function, n)
    except (_Unsafe, OSError, TypeError, SyntaxError):
        return None     # (no source to read, or not one expression)
    source = rows_source(expression, names, plus_zero, numpy_powers)
    if source is None:
        return None
    digest = hashlib.sha256(source.encode()).hexdigest()[:20]
    module = codecache.load_module(f"varint_vrows_{digest}", "models", lambda: source)
    exponents = getattr(module, "EXPONENTS", None)
    if exponents is None:
        return module.potential_rows
    return NumPyPowers(module.bases, module.potential_rows, exponents)

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
  libm's. So the compiled copy, ``(b) ** e`` with ``e`` written as a float
  (numba then calls libm's ``pow``; ``b ** 3`` with an integer would be
  numba's binary powering, products), is made only where NumPy's power is
  libm's. SymPy writes every integer power this way (``y**3``, not
  ``y*y*y``), so a cube or a fourth power is such a power; NumPy's fast
  paths for 0 and 1 are not reproduced (no compiled V);
* a function: only ``sqrt`` (correctly rounded in both). NumPy's float64
  ``exp``, ``log``, ``sin``, … are its own SIMD code or SVML's on some
  CPUs, not libm's that numba calls: no compiled V;
* anything else (a name that is not an argument, an attribute, a
  comparison, a constant base, an integer beyond 2⁵³, …): no compiled V.

So a V of sums, products and quotients of its coordinates, their squares,
reciprocals and square roots (``x**2*y**2 + (1/2)*x**2``) is compiled on
every CPU; one
with a cube (Hénon–Heiles' ``y**3``) only where NumPy's power is libm's.
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

from .. import codecache

try:
    from numpy._core._multiarray_umath import __cpu_features__ as _NUMPY_CPU
except ImportError:  # another NumPy's layout: assume its SIMD loops
    _NUMPY_CPU = {}

__all__ = ["NUMPY_POWER_IS_LIBM", "rows_from", "rows_source"]

#: Whether NumPy's float64 ``power`` is libm's ``pow`` on this CPU, as a
#: compiled ``b ** 3.0`` is: on a CPU with AVX-512 NumPy's loop calls Intel
#: SVML's ``pow`` (``numpy/_core/src/umath/loops_umath_fp.dispatch.c.src``,
#: even for a scalar exponent), whose last bit need not be libm's.
NUMPY_POWER_IS_LIBM = _NUMPY_CPU.get("AVX512F") is False

#: Exponents ``ndarray.__pow__`` computes by another ufunc than ``power``
#: (its fast paths) that the compiled copy does not write (SymPy never
#: prints them).
_FAST_EXPONENTS = (0.0, 1.0)

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
    :class:`_Unsafe` (module docstring's rules)."""

    def __init__(self, names: tuple[str, ...]) -> None:
        self.names = set(names)

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
        if exponent in _FAST_EXPONENTS or not NUMPY_POWER_IS_LIBM:
            raise _Unsafe(f"a power {exponent!r}")
        # libm's pow, as NumPy's power here.
        return ast.BinOp(base, ast.Pow(), ast.Constant(exponent))


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


def rows_source(expression: str, names: tuple[str, ...], plus_zero: bool = False) -> str | None:
    """The source of a module whose ``potential_rows(states)`` is V at each
    row of ``states`` (R, ≥ N) from the NumPy V's ``expression`` in the
    coordinates ``names`` (columns 0 … N−1), or None where its bits could
    differ from NumPy's (module docstring). ``plus_zero``: the NumPy V adds
    zeros to the expression's value (a constant V broadcast), which turns
    −0 into +0; the compiled copy adds 0.0 likewise."""
    try:
        tree = _Rows(names).visit(ast.parse(expression, mode="eval"))
    except (_Unsafe, SyntaxError):
        return None
    body = ast.unparse(tree)
    if plus_zero:
        body = f"({body}) + 0.0"
    unpack = [f"        {name} = states[i, {j}]" for j, name in enumerate(names)]
    return "\n".join([
        '"""Generated by varint.models.potential_rows; do not edit."""',
        "import numpy as np", "from numba import njit", "", "_sqrt = np.sqrt", "", "",
        "@njit(cache=True, error_model='numpy')", "def potential_rows(states):",
        "    out = np.empty(states.shape[0])", "    for i in range(states.shape[0]):",
        *unpack, f"        out[i] = {body}", "    return out", ""])


@functools.lru_cache(maxsize=256)
def rows_from(function: Callable[..., Any], n: int, plus_zero: bool = False) -> Any:
    """V compiled over rows from the NumPy V's ``function`` of the ``n``
    coordinates (``def f(q_0, …): return <expression>``), a numba
    dispatcher taking states (R, ≥ n) C-contiguous float64 and returning
    V (R,), bitwise ``function`` of their columns (``+ 0.0`` where
    ``plus_zero``); None where it could round otherwise (module
    docstring) or ``function`` is not of that form. Made once per
    ``function``: the models ask for it on every prepared run and keep
    nothing of it, since a remembered call's key reads every attribute of
    its model (:mod:`varint.remembered`), and one set at a first call would
    make the next call with the same arguments miss."""
    try:
        expression, names = _expression(function, n)
    except (_Unsafe, OSError, TypeError, SyntaxError):
        return None     # (no source to read, or not one expression)
    source = rows_source(expression, names, plus_zero)
    if source is None:
        return None
    digest = hashlib.sha256(source.encode()).hexdigest()[:20]
    return codecache.load_module(f"varint_vrows_{digest}", "models",
                                 lambda: source).potential_rows

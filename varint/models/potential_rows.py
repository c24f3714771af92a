"""A model's V (or H) over rows of states, computed from the very
expression its NumPy V evaluates (issue 28: a prepared run's short call
measures V of its few start and output states, and a general H's accuracy
verdict H of its few states, where NumPy's ufuncs cost ~0.7 µs an
operation on such tiny arrays; :class:`varint.rerun.ShortCall`,
:meth:`varint.models.hamiltonian.HamiltonianModel.hamiltonian`).

The NumPy V is a function ``def f(q_0, …, q_{N−1}): return <expression>``
evaluated on the columns of the states (SymPy's ``lambdify`` writes such a
function for :func:`~varint.models.from_potential`; Hénon–Heiles' is
written so). :func:`rows_from` reads that function's source and turns the
same expression into a program of one compiled interpreter shared by every
model (:func:`varint.kernels.row_program.run_program`: nothing is compiled
per expression), which applies to each row the same operations in the same
order, each one IEEE operation rounded once in both (numba compiles without
fast-math: LLVM neither fuses a product and a sum into an FMA nor reorders
them). That gives the same bits, except where NumPy does not compute what
the interpreter would for the same text; there the program is written
otherwise, or not made:

* ``b ** 2``, ``b ** -1``, ``b ** 0.5`` (an array to the integer or the
  float 2, −1, or to 0.5): ``ndarray.__pow__``'s fast paths, NumPy's
  ``square`` (one product), ``reciprocal`` (one division) and ``sqrt``; the
  program writes ``(b) * (b)``, ``1.0 / (b)`` and ``sqrt(b)``;
* ``b ** e`` for another constant ``e``: NumPy's float ``power``. That is
  libm's ``pow`` only on a CPU without AVX-512 (:data:`NUMPY_POWER_IS_LIBM`);
  with AVX-512 NumPy calls Intel SVML's ``pow``, whose last bit need not be
  libm's. So where NumPy's power is libm's the program writes
  ``(b) ** e`` with ``e`` a double (the interpreter then calls libm's
  ``pow``); elsewhere NumPy computes these powers itself
  (:class:`NumPyPowers`: the rest interpreted, in two programs around one
  call of NumPy's ``power``). SymPy writes every integer power this way
  (``y**3``, not ``y*y*y``), so a cube or a fourth power is such a power;
  NumPy's fast paths for 0 and 1 are not reproduced (no program);
* a function: only ``sqrt`` (correctly rounded in both). NumPy's float64
  ``exp``, ``log``, ``sin``, … are its own SIMD code or SVML's on some
  CPUs, not libm's: no program;
* arithmetic on constants alone (``1/3``, ``sqrt(2)/2``) is Python's (and
  NumPy's ``sqrt``), as the NumPy V computes it, before the program runs;
* anything else (a name that is not an argument, an attribute, a
  comparison, a constant base, an integer beyond 2⁵³, …): no program.

So a V of sums, products and quotients of its coordinates, their squares,
reciprocals and square roots (``x**2*y**2 + (1/2)*x**2``) has a whole
program on every CPU; one with a cube (Hénon–Heiles' ``y**3``) wholly only
where NumPy's power is libm's, and else but for its powers (a power within
the base of another is not split so: no program).
"""

from __future__ import annotations

import ast
import functools
import inspect
import operator
import textwrap
from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np

from .. import floating_errors
from ..kernels import row_program
from ..kernels.resolved import Resolved
from ..kernels.row_program import run_program

try:
    from numpy._core._multiarray_umath import __cpu_features__ as _NUMPY_CPU
except ImportError:  # another NumPy's layout: assume its SIMD loops
    _NUMPY_CPU = {}

__all__ = ["NUMPY_POWER_IS_LIBM", "NumPyPowers", "Program", "Rows", "rows_from", "rows_program"]

#: Whether NumPy's float64 ``power`` is libm's ``pow`` on this CPU, as a
#: compiled ``b ** 3.0`` is: on a CPU with AVX-512 NumPy's loop calls Intel
#: SVML's ``pow`` (``numpy/_core/src/umath/loops_umath_fp.dispatch.c.src``,
#: even for a scalar exponent), whose last bit need not be libm's.
NUMPY_POWER_IS_LIBM = _NUMPY_CPU.get("AVX512F") is False

#: Exponents ``ndarray.__pow__`` computes by another ufunc than ``power``
#: (its fast paths) that the program does not write (SymPy never
#: prints them).
_FAST_EXPONENTS = (0.0, 1.0)

#: The prefix of the names of the powers NumPy computes (:class:`_Rows`).
_POWER = "_pw"

#: NumPy's ``power``, the ufunc ``ndarray.__pow__`` calls for the powers
#: :class:`NumPyPowers` leaves to NumPy (a name of its own, so that a test
#: can stand in for a CPU where it is not libm's).
_power = np.power

#: Largest integer constant taken: every one up to it converts exactly to
#: a double, in NumPy (a Python int beside a float64 array) and in the program.
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
    """The NumPy V's expression as the program computes it, or
    :class:`_Unsafe` (module docstring's rules). ``numpy_powers``: each
    power that NumPy computes by its ``power`` is written as the name
    ``_pw<i>`` instead, its (base, exponent) kept in :attr:`powers`."""

    def __init__(self, names: tuple[str, ...], numpy_powers: bool = False) -> None:
        if any(a.startswith(_POWER) for a in names):
            # (An argument so named would be read as a power.)
            raise _Unsafe("an argument named as the powers")
        self.names = set(names)
        self.numpy_powers = numpy_powers
        #: (the base as the program computes it, the exponent) of each
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


class Program(NamedTuple):
    """A program of :func:`~varint.kernels.row_program.run_program`."""

    #: Its instructions (K, 4) int64.
    code: np.ndarray
    #: The constants they read.
    constants: np.ndarray
    #: The number of registers they use.
    registers: int


#: The powers of a program that reads none.
_NO_POWERS = np.empty((0, 0))

#: Python's arithmetic, as the NumPy V evaluates its constants' (:func:`_python_value`).
_PYTHON = {ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul,
           ast.Div: operator.truediv}

#: The instructions of the arithmetic of two registers.
_BINARY = {ast.Add: row_program.ADD, ast.Sub: row_program.SUBTRACT,
           ast.Mult: row_program.MULTIPLY, ast.Div: row_program.DIVIDE}


def _python_value(node: ast.expr) -> Any:
    """The value of ``node`` where it holds no coordinate (``1 / 3``,
    ``-2``, ``_sqrt(2)``), as the NumPy V computes it: Python's arithmetic
    on Python's numbers (``1 / 3`` a correctly rounded double, ``2 * 3`` an
    exact integer), NumPy's ``sqrt``; else None."""
    if isinstance(node, ast.Constant):
        return node.value
    if isinstance(node, ast.UnaryOp):
        value = _python_value(node.operand)
        return None if value is None else (-value if isinstance(node.op, ast.USub) else +value)
    if isinstance(node, ast.BinOp) and type(node.op) in _PYTHON:
        left, right = _python_value(node.left), _python_value(node.right)
        if left is None or right is None:
            return None
        return _PYTHON[type(node.op)](left, right)
    if isinstance(node, ast.Call):
        value = _python_value(node.args[0])
        return None if value is None else np.sqrt(value)
    return None     # a coordinate, a power NumPy computes, a power of a coordinate


class _Assembler:
    """The program of expressions :class:`_Rows` wrote, one register per
    value (a coordinate's loaded once), in the order Python evaluates
    them: each operand before its operation, the left before the right."""

    def __init__(self, names: tuple[str, ...]) -> None:
        self.columns = {name: j for j, name in enumerate(names)}
        self.code: list[tuple[int, int, int, int]] = []
        self.constants: list[float] = []
        self.registers = 0
        self.loaded: dict[str, int] = {}

    def _emit(self, op: int, a: int = 0, b: int = 0) -> int:
        self.code.append((op, self.registers, a, b))
        self.registers += 1
        return self.registers - 1

    def _constant(self, value: float) -> int:
        self.constants.append(value)
        return len(self.constants) - 1

    def value(self, node: ast.expr) -> int:
        """The register of ``node``'s value."""
        try:
            folded = _python_value(node)
        except (ZeroDivisionError, OverflowError) as exc:
            raise _Unsafe(str(exc)) from None     # (the NumPy V raises it too)
        if folded is not None:
            if isinstance(folded, int) and abs(folded) > _EXACT_INT:
                raise _Unsafe(repr(folded))
            # (A Python int or float beside a float64 array: its double.)
            return self._emit(row_program.CONSTANT, self._constant(float(folded)))
        if isinstance(node, ast.Name):
            if node.id.startswith(_POWER):
                return self._emit(row_program.POWER_ROW, int(node.id[len(_POWER):]))
            if node.id not in self.loaded:
                self.loaded[node.id] = self._emit(row_program.LOAD, self.columns[node.id])
            return self.loaded[node.id]
        if isinstance(node, ast.UnaryOp):
            operand = self.value(node.operand)
            # (+x: the same double.)
            return (self._emit(row_program.NEGATE, operand) if isinstance(node.op, ast.USub)
                    else operand)
        if isinstance(node, ast.Call):
            return self._emit(row_program.SQRT, self.value(node.args[0]))
        assert isinstance(node, ast.BinOp)
        left = self.value(node.left)
        if isinstance(node.op, ast.Pow):
            exponent = _constant(node.right)
            assert exponent is not None
            return self._emit(row_program.POW, left, self._constant(exponent))
        return self._emit(_BINARY[type(node.op)], left, self.value(node.right))

    def store(self, node: ast.expr) -> None:
        """Write ``node``'s value as the next output."""
        outputs = sum(1 for c in self.code if c[0] == row_program.STORE)
        self.code.append((row_program.STORE, outputs, self.value(node), 0))

    def program(self) -> Program:
        return Program(np.array(self.code, dtype=np.int64).reshape(-1, 4),
                       np.array(self.constants, dtype=np.float64), max(self.registers, 1))


def _assembled(names: tuple[str, ...], nodes: list[ast.expr]) -> Program:
    """The program whose outputs are ``nodes``' values."""
    assembler = _Assembler(names)
    for node in nodes:
        assembler.store(node)
    return assembler.program()


class Rows:
    """V over rows by the shared interpreter
    (:func:`~varint.kernels.row_program.run_program`) from the program of
    its expression.

    Parameters
    ----------
    expression : str
        The expression as :class:`_Rows` wrote it (what the program computes).
    program : Program
    kernel : numba dispatcher or :class:`~varint.kernels.resolved.Resolved`
        :func:`~varint.kernels.row_program.run_program`, by default.
    """

    __slots__ = ("expression", "program", "kernel")

    def __init__(self, expression: str, program: Program, kernel: Any = run_program) -> None:
        self.expression, self.program, self.kernel = expression, program, kernel

    def __call__(self, states: np.ndarray) -> np.ndarray:
        """V (R,) at each row of ``states`` (R, ≥ N), C-contiguous float64."""
        out = np.empty(states.shape[0])
        self.kernel(states, _NO_POWERS, *self.program, out.reshape(1, -1))
        return out

    def resolved(self) -> Rows:
        """This V with the interpreter called through the compiled version
        its first call selects (:class:`~varint.kernels.resolved.Resolved`):
        for a caller whose states are made the same way at every call."""
        return Rows(self.expression, self.program, Resolved(run_program))


class NumPyPowers:
    """V over rows by the shared interpreter but for its powers, which
    NumPy's ``power`` computes, as the NumPy V's own ``b ** e`` does (on a
    CPU where that is not libm's ``pow``, :data:`NUMPY_POWER_IS_LIBM`): the
    bases by one program, their powers in one call of ``power``
    (floating-point errors ignored, as the interpreter ignores them), V by
    another program from the states and the powers.

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
    expression : str
        V as :class:`_Rows` wrote it, the powers named ``_pw<i>``.
    bases, combine : Program
        The programs of the bases (one output each) and of V.
    exponents : tuple of float
        The powers' exponents, one per base.
    kernel : numba dispatcher or :class:`~varint.kernels.resolved.Resolved`
        :func:`~varint.kernels.row_program.run_program`, by default.
    """

    __slots__ = ("expression", "bases", "combine", "exponents", "kernel", "_exponent")

    def __init__(self, expression: str, bases: Program, combine: Program,
                 exponents: tuple[float, ...], kernel: Any = run_program) -> None:
        self.expression, self.bases, self.combine = expression, bases, combine
        self.exponents, self.kernel = exponents, kernel
        # The exponent of every row of the bases: one NumPy scalar where
        # they are all one (NumPy's quickest call, ~1.4 µs against ~3.8 µs
        # for a column broadcast, on a few rows), else a column (P, 1).
        self._exponent = (np.float64(exponents[0]) if len(set(exponents)) == 1
                          else np.array(exponents, dtype=np.float64)[:, None])

    def __call__(self, states: np.ndarray) -> np.ndarray:
        """V (R,) at each row of ``states`` (R, ≥ N), C-contiguous float64."""
        rows = states.shape[0]
        bases = np.empty((len(self.exponents), rows))
        self.kernel(states, _NO_POWERS, *self.bases, bases)
        quiet = floating_errors.ignoring()
        try:
            powers = _power(bases, self._exponent)
        finally:
            floating_errors.restore(quiet)
        out = np.empty(rows)
        self.kernel(states, powers, *self.combine, out.reshape(1, -1))
        return out

    def resolved(self) -> NumPyPowers:
        """This V with the interpreter called through the compiled version
        its first call selects (:class:`~varint.kernels.resolved.Resolved`;
        both calls pass arrays of the same types): for a caller whose states
        are made the same way at every call."""
        return NumPyPowers(self.expression, self.bases, self.combine, self.exponents,
                           Resolved(run_program))


def rows_program(expression: str, names: tuple[str, ...], plus_zero: bool = False,
                 numpy_powers: bool | None = None) -> Rows | NumPyPowers | None:
    """V at each row of states (R, ≥ N) from the NumPy V's ``expression``
    in the coordinates ``names`` (columns 0 … N−1), run by the shared
    interpreter, or None where its bits could differ from NumPy's (module
    docstring). ``plus_zero``: the NumPy V adds zeros to the expression's
    value (a constant V broadcast), which turns −0 into +0; the program
    adds 0.0 likewise.

    ``numpy_powers`` (default: where NumPy's power is not libm's,
    :data:`NUMPY_POWER_IS_LIBM`): the powers NumPy computes by its
    ``power`` are left to it (:class:`NumPyPowers`, where the expression
    has such powers)."""
    if numpy_powers is None:
        numpy_powers = not NUMPY_POWER_IS_LIBM
    try:
        rows = _Rows(names, numpy_powers)
        body = rows.visit(ast.parse(expression, mode="eval")).body
        if plus_zero:
            body = ast.BinOp(body, ast.Add(), ast.Constant(0.0))
        text = ast.unparse(body)
        program = _assembled(names, [body])
        if not rows.powers:
            return Rows(text, program)
        bases = _assembled(names, [b for b, _ in rows.powers])
    except (_Unsafe, SyntaxError):
        return None
    return NumPyPowers(text, bases, program, tuple(e for _, e in rows.powers))


@functools.lru_cache(maxsize=256)
def rows_from(function: Callable[..., Any], n: int, plus_zero: bool = False,
              numpy_powers: bool | None = None) -> Rows | NumPyPowers | None:
    """V over rows from the NumPy V's ``function`` of the ``n``
    coordinates (``def f(q_0, …): return <expression>``), a callable taking
    states (R, ≥ n) C-contiguous float64 and returning V (R,), bitwise
    ``function`` of their columns (``+ 0.0`` where ``plus_zero``): a
    :class:`Rows`, or a :class:`NumPyPowers` where NumPy computes its
    powers (``numpy_powers``, :func:`rows_program`); None where it could
    round otherwise (module docstring) or ``function`` is not of that
    form. Made once per ``function`` (reading its source is the cost): the
    models ask for it on every call and keep nothing of it, since a
    remembered call's key reads every attribute of its model
    (:mod:`varint.remembered`), and one set at a first call would make the
    next call with the same arguments miss. Nothing is compiled per
    ``function``: every program runs on the one interpreter."""
    try:
        expression, names = _expression(function, n)
    except (_Unsafe, OSError, TypeError, SyntaxError):
        return None     # (no source to read, or not one expression)
    return rows_program(expression, names, plus_zero, numpy_powers)

"""Formulas typed by users (``varint run --potential EXPR``), read safely.

``sympy.sympify`` runs its input through ``eval``: a "potential" such as
``__import__('os').system(...)`` would run a shell command. This module
reads a formula with Python's :mod:`ast` parser (which only parses) and
builds the SymPy expression itself from a whitelist of node types: numbers,
the named coordinates, ``+ - * / **`` (``^`` is read as ``**``),
parentheses, unary signs, the constants ``pi`` and ``E`` and the functions
of :data:`FUNCTIONS`. Anything else is refused with a one-line
``ValueError`` quoting the offending part of the formula. Nothing is ever
evaluated by Python.

The size of the work is bounded before SymPy sees it: the length of the
text (:data:`MAX_LENGTH`), the nesting depth (:data:`MAX_DEPTH`), and every
power of numbers, which must stay within the range of a double (so
``9**9**9**9`` is refused instead of computed exactly); a numeric exponent
of anything else is limited to :data:`MAX_EXPONENT`.
"""

from __future__ import annotations

import ast
import keyword
import math
import unicodedata

import sympy as sp

__all__ = ["parse_formula", "coordinate_symbols", "FUNCTIONS", "CONSTANTS", "MAX_LENGTH",
           "MAX_DEPTH", "MAX_EXPONENT"]

#: Function name → (SymPy function, number of arguments). Each compiles into
#: the numba kernels of :func:`varint.models.from_potential`.
FUNCTIONS = {
    **{name: (getattr(sp, name), 1) for name in (
        "sin", "cos", "tan", "cot", "sec", "csc", "asin", "acos", "atan", "acot",
        "sinh", "cosh", "tanh", "coth", "asinh", "acosh", "atanh", "exp", "log", "sqrt")},
    "atan2": (sp.atan2, 2),
}
#: Named constants.
CONSTANTS = {"pi": sp.pi, "E": sp.E}
#: Longest formula read, in characters.
MAX_LENGTH = 10_000
#: Deepest nesting of parentheses, function calls, powers and unary signs
#: (a chain such as a + b - c + … or a * b / c counts as one level).
MAX_DEPTH = 100
#: Largest |exponent| of a power whose exponent is a number.
MAX_EXPONENT = 1000
#: Largest decimal exponent of a power of two numbers (a double's range).
_MAX_DECADES = 308

_SUM = (ast.Add, ast.Sub)
_PRODUCT = (ast.Mult, ast.Div)

# What a refused node is called in messages.
_DESCRIPTIONS = {
    ast.Attribute: "attribute access", ast.Subscript: "indexing", ast.Lambda: "a lambda",
    ast.ListComp: "a comprehension", ast.SetComp: "a comprehension",
    ast.DictComp: "a comprehension", ast.GeneratorExp: "a generator expression",
    ast.Compare: "a comparison", ast.BoolOp: "'and'/'or'", ast.IfExp: "'if ... else'",
    ast.NamedExpr: "an assignment", ast.Starred: "'*' unpacking", ast.Tuple: "a tuple",
    ast.List: "a list", ast.Set: "a set", ast.Dict: "a dict", ast.JoinedStr: "an f-string",
    ast.Await: "'await'", ast.Yield: "'yield'", ast.YieldFrom: "'yield'",
    ast.Slice: "a slice",
}
_OPERATORS = {
    ast.FloorDiv: "'//'", ast.Mod: "'%'", ast.MatMult: "'@'", ast.LShift: "'<<'",
    ast.RShift: "'>>'", ast.BitOr: "'|'", ast.BitAnd: "'&'", ast.BitXor: "'^'",
    ast.Invert: "'~'", ast.Not: "'not'",
}


#: Names people write for an allowed one.
_ALIASES = {"ln": "log", "arcsin": "asin", "arccos": "acos", "arctan": "atan",
            "arctan2": "atan2", "e": "E"}


def _allowed(coordinates):
    return (f"allowed: numbers, {', '.join(coordinates)}, + - * / ** ^ ( ), pi, E, "
            f"{', '.join(FUNCTIONS)}")


def coordinate_symbols(names, name="coordinates"):
    """The SymPy symbols of the coordinate names of a formula.

    Parameters
    ----------
    names : sequence of str
        Distinct identifiers, none of them a Python keyword or a name of
        :data:`FUNCTIONS` or :data:`CONSTANTS`.
    name : str
        What the names are called in messages (e.g. ``"--coords"``).

    Returns
    -------
    tuple of sympy.Symbol

    Raises
    ------
    ValueError
        Naming the first bad or repeated name.
    """
    if isinstance(names, str):
        raise ValueError(f"{name} must be a sequence of names, got the string {names!r}")
    out, seen = [], set()
    for i, text in enumerate(names):
        if not isinstance(text, str) or not text.isidentifier():
            raise ValueError(f"{name}: coordinate {i + 1} must be a name (letters, digits and "
                             f"_, not starting with a digit), got {text!r}")
        # The parser reads identifiers in Unicode normal form NFKC (ﬁ is fi).
        key = unicodedata.normalize("NFKC", text)
        if keyword.iskeyword(key) or key in FUNCTIONS or key in CONSTANTS:
            raise ValueError(f"{name}: {text!r} is reserved (a Python keyword, function or "
                             "constant); choose another coordinate name")
        if key in seen:
            raise ValueError(f"{name} names {text!r} twice")
        seen.add(key)
        out.append(sp.Symbol(key))
    if not out:
        raise ValueError(f"{name} must name at least one coordinate")
    return tuple(out)


def parse_formula(text, coordinates, name="formula"):
    """Read a formula in the given coordinates as a SymPy expression, safely.

    Parameters
    ----------
    text : str
        E.g. ``"(x**2 + y**2)/2 + x^2*y - y^3/3"``.
    coordinates : sequence of str or sympy.Symbol
        The names the formula may use as variables.
    name : str
        What the formula is called in messages (e.g. ``"--potential"``).

    Returns
    -------
    sympy.Expr
        Integers and their quotients stay exact (``1/3`` is a Rational);
        decimal numbers become SymPy Floats.

    Raises
    ------
    ValueError
        One line naming the offending token (a disallowed construct, an
        unknown name, a wrong number of arguments, a number that is not
        finite, a power too large) or the limit exceeded.

    Examples
    --------
    >>> parse_formula("x^2/2 + cos(y)", ["x", "y"])
    x**2/2 + cos(y)
    >>> parse_formula("__import__('os')", ["x"])  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ValueError: formula: '__import__' is not an allowed function; allowed: ...
    """
    if not isinstance(text, str):
        raise ValueError(f"{name} must be a string, got {type(text).__name__} {text!r}")
    if not isinstance(coordinates, str):  # a string is refused there, not split into letters
        coordinates = [c.name if isinstance(c, sp.Symbol) else c for c in coordinates]
    symbols = coordinate_symbols(coordinates, f"the coordinates of {name}")
    if not text.strip():
        raise ValueError(f"{name} is empty; expected a formula such as 'x**2/2 + y**2/2'")
    if len(text) > MAX_LENGTH:
        raise ValueError(f"{name} is {len(text)} characters long; at most {MAX_LENGTH} are read")
    # One line without indentation (the parser reads an indented or
    # multi-line expression as a statement block), ^ as the power.
    source = " ".join(text.split()).replace("^", "**")
    try:
        tree = ast.parse(source, mode="eval")
    except SyntaxError as exc:
        where = f" at column {exc.offset}" if exc.offset else ""
        raise ValueError(f"{name}: cannot read {_quote(source)}: {exc.msg}{where}") from None
    except (RecursionError, MemoryError, ValueError):
        # The C parser gives up on chains of about a thousand operators.
        raise ValueError(f"{name} is too deeply nested or has too many operators in one "
                         "chain for the parser; shorten it") from None
    reader = _Reader(source, {s.name: s for s in symbols}, name)
    reader.check_depth(tree.body)
    expr = reader.expr(tree.body)
    if expr.has(sp.zoo, sp.nan, sp.oo, -sp.oo):
        raise ValueError(f"{name}: {_quote(source)} is not finite (a division by zero such as "
                         "0**-1, or similar)")
    return expr


def _quote(text, limit=60):
    text = " ".join(text.split())
    return repr(text if len(text) <= limit else text[:limit - 3] + "...")


class _Reader:
    """Turns a checked :mod:`ast` tree into a SymPy expression."""

    def __init__(self, source, symbols, name):
        self.source = source
        self.symbols = symbols
        self.name = name

    def fail(self, node, what, allowed=True):
        """Raise the one-line error quoting ``node``'s text; ``allowed``
        appends what a formula may contain."""
        segment = ast.get_source_segment(self.source, node) or type(node).__name__
        tail = f"; {_allowed(list(self.symbols))}" if allowed else ""
        raise ValueError(f"{self.name}: {_quote(segment, 40)} {what}{tail}")

    def check_depth(self, root):
        """Refuse trees nested deeper than :data:`MAX_DEPTH` before reading
        them (recursively), counting a chain of + and - (or * and /) as one
        level, as SymPy holds it flat."""
        stack = [(root, 1)]
        while stack:
            node, depth = stack.pop()
            if depth > MAX_DEPTH:
                self.fail(node, f"is nested more than {MAX_DEPTH} levels deep", allowed=False)
            for child in ast.iter_child_nodes(node):
                same_chain = (isinstance(node, ast.BinOp) and isinstance(child, ast.BinOp)
                              and child is node.left
                              and any(isinstance(node.op, c) and isinstance(child.op, c)
                                      for c in (_SUM, _PRODUCT)))
                stack.append((child, depth if same_chain else depth + 1))

    def expr(self, node):
        if isinstance(node, ast.BinOp):
            if isinstance(node.op, _SUM):
                return sp.Add(*[t if positive else -t
                                for _, t, positive in self._chain(node, _SUM)])
            if isinstance(node.op, _PRODUCT):
                factors = []
                for operand, f, up in self._chain(node, _PRODUCT):
                    if not up and f.is_zero:
                        self.fail(operand, "is a divisor that is zero", allowed=False)
                    factors.append(f if up else sp.Pow(f, -1))
                return sp.Mul(*factors)
            if isinstance(node.op, ast.Pow):
                return self._power(node)
            self.fail(node, f"uses {_OPERATORS.get(type(node.op), 'an operator')}, which is "
                      "not allowed")
        if isinstance(node, ast.UnaryOp):
            if isinstance(node.op, ast.USub):
                return -self.expr(node.operand)
            if isinstance(node.op, ast.UAdd):
                return self.expr(node.operand)
            self.fail(node, f"uses {_OPERATORS.get(type(node.op), 'an operator')}, which is "
                      "not allowed")
        if isinstance(node, ast.Constant):
            return self._number(node)
        if isinstance(node, ast.Name):
            return self._name(node)
        if isinstance(node, ast.Call):
            return self._call(node)
        self.fail(node, f"is {_DESCRIPTIONS.get(type(node), 'a construct')}, which is not "
                  "allowed")

    def _chain(self, node, ops):
        """``(node, expression, sign)`` of each operand of a left-leaning
        chain of ``ops`` (sign True for + or *), read without recursion along
        the chain."""
        operands = []
        while isinstance(node, ast.BinOp) and isinstance(node.op, ops):
            operands.append((node.right, isinstance(node.op, (ast.Add, ast.Mult))))
            node = node.left
        operands.append((node, True))
        return [(n, self.expr(n), sign) for n, sign in reversed(operands)]

    def _number(self, node):
        value = node.value
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            kind = "an imaginary number" if isinstance(value, complex) else (
                f"{type(value).__name__} {value!r}" if not isinstance(value, str) else "text")
            self.fail(node, f"is {kind}, not a real number")
        if isinstance(value, float):
            if not math.isfinite(value):
                self.fail(node, "is not a finite number (beyond the range of a double)",
                          allowed=False)
            return sp.Float(value)
        if value.bit_length() > 1024:
            self.fail(node, "is a number beyond the range of a double", allowed=False)
        return sp.Integer(value)

    def _name(self, node):
        if node.id in self.symbols:
            return self.symbols[node.id]
        if node.id in CONSTANTS:
            return CONSTANTS[node.id]
        if node.id in FUNCTIONS:
            self.fail(node, f"is a function: write {node.id}(...)")
        self.fail(node, f"is not a coordinate, constant or function{self._hint(node.id)}")

    def _hint(self, name):
        """`` (did you mean 'E'?)`` for a near miss of an allowed name."""
        known = [*self.symbols, *CONSTANTS, *FUNCTIONS]
        guess = _ALIASES.get(name) or next((k for k in known if k.lower() == name.lower()), None)
        return f" (did you mean {guess!r}?)" if guess else ""

    def _call(self, node):
        func = node.func
        if not isinstance(func, ast.Name):
            self.expr(func)  # refuses attribute access, subscripts, ... with their own message
            self.fail(node, "calls something that is not a function name")
        if func.id not in FUNCTIONS:
            if func.id in self.symbols or func.id in CONSTANTS:
                self.fail(func, "is not a function")
            self.fail(func, f"is not an allowed function{self._hint(func.id)}")
        if node.keywords:
            self.fail(node, "passes keyword arguments, which are not allowed")
        function, arity = FUNCTIONS[func.id]
        for arg in node.args:
            if isinstance(arg, ast.Starred):
                self.fail(arg, "is '*' unpacking, which is not allowed")
        if len(node.args) != arity:
            self.fail(node, f"gives {func.id} {len(node.args)} argument"
                      f"{'' if len(node.args) == 1 else 's'}; it takes {arity}", allowed=False)
        return function(*[self.expr(a) for a in node.args])

    def _power(self, node):
        base, exponent = self.expr(node.left), self.expr(node.right)
        if exponent.is_number and exponent.is_finite:
            e = complex(exponent.evalf(20))
            if abs(e) > MAX_EXPONENT:
                self.fail(node, f"has an exponent of magnitude above {MAX_EXPONENT}",
                          allowed=False)
            if base.is_number and base.is_finite:
                b = complex(base.evalf(20))
                # |b**e| = 10**(e log10|b|) for real e; refuse what a double cannot hold.
                if b != 0 and abs(e.real * math.log10(abs(b))) > _MAX_DECADES:
                    self.fail(node, "is a number beyond the range of a double", allowed=False)
        return sp.Pow(base, exponent)

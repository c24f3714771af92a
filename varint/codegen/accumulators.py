"""An accumulator's :class:`~varint.protocol.UpdateRule` turned into code:
written out per vector in a generated stepper's loop (one orbit, or SIMD
lanes where only the lanes whose interval ended well take the update), and
compiled into the ``update`` every other stepper calls — one rule, the
same operations in the same order, the same bits.

A rule's statements are parsed, checked, and their names rewritten
(:class:`_Rename`): a live column becomes the variable that holds it, ``r``,
``am``, ``ae`` the vector's, ``dot(a, b)`` the sum written out (from 0.0,
component by component, as the compiled update's loop adds), and every
other name assigned a temporary of the vector's own.
"""

from __future__ import annotations

import ast
import math

import numpy as np
from numba import njit

from ..kernels.logarithm import vlog
from .source import Source

__all__ = ["emit_rule", "emit_readout", "compile_update", "rule_text"]

#: What ``dot`` takes: the state, the renormalised vector, the flow.
_OPERANDS = ("x", "w", "f")
#: The names a rule reads besides its columns and temporaries.
_INPUTS = ("r", "t", "am", "ae")
_GLOBALS = ("math", "np", "ACC_BIG", "ACC_SMALL", "LN2", "abs", "float", "int", "max", "min",
            "vlog")


def rule_text(rule):
    """The rule as one string (what a generated stepper's name hashes)."""
    return repr((tuple(rule.live), tuple(rule.step), tuple(rule.readout)))


def _statements(lines, what):
    """Each line parsed as one assignment ``name = expression``."""
    out = []
    for line in lines:
        try:
            tree = ast.parse(line, mode="exec")
        except SyntaxError as exc:
            raise ValueError(f"accumulator rule: {what} statement {line!r} is not Python "
                             f"({exc.msg})") from None
        body = tree.body
        if len(body) != 1 or not isinstance(body[0], ast.Assign) or len(body[0].targets) != 1 \
                or not isinstance(body[0].targets[0], ast.Name):
            raise ValueError(f"accumulator rule: {what} statement {line!r} must assign one "
                             "name (name = expression)")
        out.append(body[0])
    return out


class _Rename(ast.NodeTransformer):
    """Names of a rule replaced by expressions (``names``), ``dot(a, b)``
    by ``dot(a, b)`` of the emitting side; an unknown name is refused."""

    def __init__(self, names, dot, known, log="vlog"):
        self.names, self.dot, self.known, self.log = names, dot, known, log

    def visit_Name(self, node):
        if node.id in self.names:
            return ast.copy_location(ast.parse(self.names[node.id], mode="eval").body, node)
        if node.id == "vlog":
            return ast.copy_location(ast.Name(id=self.log, ctx=node.ctx), node)
        if node.id not in self.known:
            raise ValueError(f"accumulator rule: unknown name {node.id!r} (a rule reads its "
                             f"columns, its temporaries, {', '.join(_INPUTS)}, dot(), and "
                             f"{', '.join(_GLOBALS)})")
        return node

    def visit_Attribute(self, node):
        # A rule's math.log is varint's logarithm, the same on every target
        # (varint.kernels.logarithm).
        if isinstance(node.value, ast.Name) and node.value.id == "math" and node.attr == "log":
            return ast.copy_location(ast.Name(id=self.log, ctx=ast.Load()), node)
        self.generic_visit(node)
        return node

    def visit_Call(self, node):
        f = node.func
        if isinstance(f, ast.Name) and f.id == "dot":
            ops = [a.id if isinstance(a, ast.Name) else None for a in node.args]
            if len(ops) != 2 or node.keywords or not set(ops) <= set(_OPERANDS):
                raise ValueError(f"accumulator rule: dot() takes two of {', '.join(_OPERANDS)}, "
                                 f"got {ast.unparse(node)!r}")
            return ast.copy_location(ast.parse(self.dot(*ops), mode="eval").body, node)
        self.generic_visit(node)
        return node


def _rewrite(stmt, names, dot, known, log="vlog"):
    """``target, expression`` source of one statement, names rewritten
    (the logarithm as ``log``: :func:`emit_rule`)."""
    value = _Rename(names, dot, known, log).visit(ast.fix_missing_locations(stmt.value))
    return ast.unparse(value)


def emit_rule(src, rule, columns, names, dot, prefix, guard=None, log="vlog"):
    """Write ``rule.step`` for one vector into ``src``.

    Parameters
    ----------
    src : Source
    rule : UpdateRule
    columns : tuple of str
        The accumulator's columns.
    names : dict
        Source of ``r``, ``t``, ``am``, ``ae`` and of each live column (a
        variable the emitted code keeps).
    dot : callable
        ``dot(a, b)`` → source of that sum.
    prefix : str
        Prefix of the temporaries (one per vector).
    guard : str, optional
        A condition: the live columns take the new values only where it
        holds (SIMD lanes: the lanes whose interval ended well).
    log : str, default "vlog"
        The name the rule's logarithm (``math.log``, ``vlog``) is written
        as: :func:`~varint.kernels.logarithm.vlog` (numba inlines its IR at
        the call: the SIMD lanes vectorise it) or ``vlog_called`` (the same
        algorithm called, the same bits: one orbit, where the rule runs
        only at a renormalisation and numba's inlining of the logarithm's
        IR at each use is compile time off the hot path, as for the
        sparse schedule's logarithm; ``studies/stepper_compile_parts.py``).
    """
    live = tuple(rule.live)
    stmts = _statements(rule.step, "step")
    targets = [s.targets[0].id for s in stmts]
    names = dict(names)
    if guard is not None:
        # The new values in variables of their own, kept where the guard holds.
        for col in live:
            src(f"{prefix}new_{col} = {names[col]}")
        current = {col: f"{prefix}new_{col}" for col in live}
    else:
        current = {col: names[col] for col in live}
    env = {**{k: names[k] for k in _INPUTS if k in names}, **current}
    known = set(_GLOBALS)
    for stmt, target in zip(stmts, targets, strict=True):
        if target in _INPUTS or target in _GLOBALS or target in _OPERANDS:
            raise ValueError(f"accumulator rule: a statement assigns {target!r}, which it may "
                             "only read")
        if target in columns and target not in live:
            raise ValueError(f"accumulator rule: a step statement assigns column {target!r}, "
                             "which is not live (readout gives it)")
        value = _rewrite(stmt, env, dot, known, log)
        if target not in current:
            env[target] = f"{prefix}{target}"
        src(f"{env[target]} = {value}")
    if guard is not None:
        for col in live:
            src(f"{names[col]} = {prefix}new_{col} if {guard} else {names[col]}")


def emit_readout(src, rule, columns, names, prefix, log="vlog"):
    """Write ``rule.readout`` for one vector, the logarithm written as
    ``log`` (:func:`emit_rule`); returns the source of every column's value
    (the live ones as ``names`` gives them)."""
    env = {**{k: names[k] for k in ("am", "ae") if k in names},
           **{col: names[col] for col in rule.live}}
    out = {col: names[col] for col in rule.live}
    for stmt in _statements(rule.readout, "readout"):
        target = stmt.targets[0].id
        value = _rewrite(stmt, env, None, set(_GLOBALS), log)
        env[target] = f"{prefix}{target}"
        src(f"{env[target]} = {value}")
        if target in columns:
            out[target] = env[target]
    missing = [c for c in columns if c not in out]
    if missing:
        raise ValueError(f"accumulator rule: columns {missing} are neither live nor given by "
                         "the readout")
    return out


def compile_update(rule, columns):
    """The compiled ``update(aux, r, x, W, flow, t)`` of a rule that reads
    neither ``am`` nor ``ae`` (see :class:`~varint.protocol.Accumulator`):
    for each vector j, its live columns ``aux[j, c]``, the rule's
    statements, the columns back. The same operations as the rule written
    out by a generated stepper, in the same order: the same bits."""

    live = tuple(rule.live)
    index = {c: columns.index(c) for c in live}
    names = {"r": "r[j]", "t": "t", **{c: f"c_{c}" for c in live}}
    loops = {"x": "x[i]", "w": "W[i, j]", "f": "flow[i]"}
    sums = []

    def dot(a, b):
        name = f"d_{a}{b}"
        if name not in {s for s, _, _ in sums}:
            # Over the flow's components when it is a factor: a map has none.
            bound = "flow.shape[0]" if "f" in (a, b) else "W.shape[0]"
            sums.append((name, bound, f"{loops[a]} * {loops[b]}"))
        return name

    body = Source()
    with body.block(), body.block():
        emit_rule(body, rule, columns, names, dot, prefix="v_")
    src = Source()
    src("def update(aux, r, x, W, flow, t):")
    with src.block(), src.block("for j in range(aux.shape[0]):"):
        for col in live:
            src(f"c_{col} = aux[j, {index[col]}]")
        for name, bound, term in sums:
            # A sum from 0.0 over the components, in order.
            src(f"{name} = 0.0")
            with src.block(f"for i in range({bound}):"):
                src(f"{name} += {term}")
    src.lines += body.lines
    with src.block(), src.block():
        for col in live:
            src(f"aux[j, {index[col]}] = c_{col}")
    scope = {"math": math, "np": np, "ACC_BIG": 2.0 ** 500, "ACC_SMALL": 2.0 ** -500,
             "LN2": math.log(2.0), "vlog": vlog}
    exec(compile(src.text(), f"<accumulator rule {live}>", "exec"), scope)
    return njit(error_model="numpy")(scope["update"])

"""The cost of a generated step, read from its source: what the defaults of
an FLI map price the logarithmic-Hamiltonian (LH) stepper and the
constant-step stepper by (:func:`varint.maps.chaos_map`, ``time_transform=
"auto"``).

Both steppers are emitted as Python source for one model and scheme (the
LH's by :mod:`varint.codegen.lh`, one orbit at a time; the constant step's
by :mod:`varint.codegen.interval`, as SIMD lanes). :func:`operations`
walks one step of that source and counts the floating-point operations it
executes, by kind (:data:`KINDS`): additions, multiplications, fused
multiply–adds, divisions, square roots, logarithms, exponentials, sines and
cosines, powers, comparisons and array accesses. The weighted sum
(:func:`weighted`) with the table of the stepper's context
(:data:`LH_WEIGHTS` for the LH one orbit at a time in scalar code,
:data:`LH_LANES_WEIGHTS` for the LH over SIMD lanes, as a map's long runs
take it, :meth:`varint.time_transform.LogHamiltonian.runs_in_lanes`;
:data:`VECTOR_LANE_WEIGHTS` or :data:`SCALAR_LANE_WEIGHTS` for a lane of
the constant step, as its loop over the lanes vectorises or not,
:func:`vectorises`: nanoseconds per operation of four classes,
:data:`CLASSES`, fitted to the two maps' measured runs), divided by the force evaluations of the step, is the cost
of one force evaluation (:func:`lh_cost`, :func:`lanes_cost`). The choice
therefore depends on what is compiled, not on the timing of the run that
makes it: the same model, scheme and versions price the same, bit for
bit, on every machine.

How a step is read (:func:`operations`): names whose values are known at
emission (``log``, ``k``, the loop bounds) select their branch; a branch
that cannot be decided statically and leaves the step (a failure: return,
break, continue, raise) is not counted, any other is (the emitted code is
written so that the common path computes everything); loops over ``range``
of a known bound count their body that many times; both arms of a
conditional expression count (the lanes compute both and select). A call
of an emitted kernel or library function not in :data:`CALLS` counts
nothing of its own.

Why fitted tables: the steppers as the maps run them are bound by their
dependency chains (the LH's dτ = h/U needs V before each drift; a lane's
step is too long for two lanes to overlap) and by whether LLVM vectorises
the loop over the lanes, not by their operation counts. One table per
operation (:data:`WEIGHTS`, ``studies/step_cost.py``: a chain of each
operation, lengths 1 and 9, the difference per operation) priced the LH
against the lanes 2–3 times too cheap (Hénon–Heiles 3.1 against 7.3
measured, the three-body problem 2.2 against 6.4), so that the defaults
ran the LH where constant steps were faster. One fitted table for all
lanes failed its held-out check (``studies/switch_check.py``): the
three-body lanes vectorise and cost 18 ns per force evaluation, the cored
potential's, with ``(R² + r²)**(-2)`` in their Hessian, did not and cost
32 (14 since the steppers print that power as a division,
:mod:`varint.codegen.printer`, and their loop vectorises). The fitted tables give arithmetic
little cost of its own (it overlaps the chains and the checks). Not seen:
branch mispredictions, the cache (a step's state fits in L1), another
machine's ratio of scalar to vector speed: the tables are fitted on one
machine (an AMD EPYC with AVX-512, whose lanes run 2–3 times faster
against the LH than an Intel Xeon's, on which they were fitted before:
the choice changed on the three-body map, whose prices were within 1.3
times of each other).
"""

from __future__ import annotations

import ast
from collections import Counter
from collections.abc import Mapping
from functools import lru_cache

__all__ = ["KINDS", "CALLS", "WEIGHTS", "CLASSES", "SCALAR_KINDS", "LH_WEIGHTS", "LH_LANES_WEIGHTS",
           "VECTOR_LANE_WEIGHTS", "SCALAR_LANE_WEIGHTS", "vectorises", "operations", "weighted",
           "lh_cost", "lanes_cost", "log_gradient_cost", "constant_gradient_cost"]

#: The kinds of operation counted.
KINDS = ("add", "mul", "fma", "div", "invert", "sqrt", "log", "exp", "sin", "cos", "pow", "compare",
         "memory")

#: Calls by name (the last part of a dotted name) and the kind they count as.
CALLS = {"sqrt": "sqrt", "fma": "fma", "log": "log", "vlog": "log", "vlog_called": "log",
         "lane_log": "log",
         "exp": "exp", "sin": "sin", "cos": "cos", "sinh": "exp", "cosh": "exp", "pow": "pow",
         "max": "compare", "min": "compare", "abs": "compare"}

#: Cost of one operation of each kind, in scalar additions: measured once
#: by ``studies/step_cost.py`` in one orbit's straight-line code (four
#: independent chains; ``studies/results/step_cost.json``, part "weights",
#: context "scalar"; Intel Xeon at 2.5 GHz, load 6 on 2 cores; one
#: addition 0.33 ns), two significant figures; comparisons and loads
#: measured below 0.005 (hidden behind the arithmetic): 0. The same table
#: prices a lane of the constant step's SIMD loop: the study's ideal vector
#: loop (context "lanes": arithmetic 0.14, calls 2–5 times one orbit's)
#: priced the emitted lanes' step 3–6 times too cheap on Hénon–Heiles and
#: the cored potentials, and 1.3 times too dear on the three-body problem
#: (part "track": predicted LH/constant ratio 20, 11, 0.54 against 7.6,
#: 3.1–3.4, 0.80 measured), where this table gives 3.1, 2.4, 0.73. (The
#: three-body figures are of a constant step that still called ``pow`` 84
#: times; with its half-integer powers as products and square roots
#: (:mod:`varint.codegen.printer`) this table predicts 2.15.)
WEIGHTS: Mapping[str, float] = {
    "add": 1.0, "mul": 1.0, "fma": 0.99, "div": 4.0, "invert": 4.0, "sqrt": 5.9, "log": 18.0, "exp": 18.0,
    "sin": 18.0, "cos": 23.0, "pow": 61.0, "compare": 0.0, "memory": 0.0}

#: The classes of operation the two steppers' costs are fitted by
#: (``studies/switch_check.py``, part "fit"), each the kinds it sums:
#: arithmetic, division and square root, library calls, checks and
#: array accesses.
CLASSES = {"arithmetic": ("add", "mul", "fma"), "division": ("div", "invert", "sqrt"),
           "call": ("log", "exp", "sin", "cos", "pow"), "check": ("compare", "memory")}
#: The kinds that keep LLVM from vectorising the loop over the lanes: a
#: call of a library function (a square root is an instruction) and the
#: inverse of a negative integer power (numba's ``x**(-2)`` tests for a
#: zero divisor; ``1/(x*x)`` vectorises, and the steppers print it so,
#: :mod:`varint.codegen.printer`: none of theirs holds an inverse).
SCALAR_KINDS = ("log", "exp", "sin", "cos", "pow", "invert")


def _by_kind(per_class):
    return {kind: per_class[cls] for cls, kinds in CLASSES.items() for kind in kinds}


#: Nanoseconds per operation of each class (:data:`CLASSES`) as the maps
#: run each stepper, fitted by non-negative least squares to the measured
#: nanoseconds per force evaluation of the two maps of training models
#: (``studies/switch_check.py`` part "fit", full grids, every row measured
#: in one run, ``studies/results/switch_check.json``; AMD EPYC (znver4,
#: AVX-512), load 8–9 on 2 cores, CPU time; map25), two significant
#: figures. The tables fitted before on an Intel Xeon at 2.5 GHz (load 1–2)
#: priced a vectorised lane's force evaluation 2–3 times dearer than this
#: machine runs it (the three-body problem's 13.6 ns against 4.9 measured
#: on the full map of ``studies/hamiltonians.py``) and the LH over lanes
#: at 2.2 times it against 4.0 measured, so that the defaults ran the LH
#: on that map where the constant step agreeing at τ = 0.125 costs 0.73
#: times as much (``studies/results/map25/``). ``LH_WEIGHTS``: the LH
#: stepper, one orbit in scalar code, whose chain (dτ = h/U needs V before
#: each drift) makes it pay for divisions and calls more than for
#: arithmetic. The constant step's
#: lanes: ``VECTOR_LANE_WEIGHTS`` where the loop over the lanes
#: vectorises (:func:`vectorises`), ``SCALAR_LANE_WEIGHTS`` where it does
#: not (a library call in the step: every lane then runs the whole step
#: in scalar code; fitted on two models only, Toda's exponentials and the
#: pendulums' sines and cosines, it prices their checks alone: leave one
#: out 0.37 and 2.7).
LH_WEIGHTS: Mapping[str, float] = _by_kind(
    {"arithmetic": 0.29, "division": 0.62, "call": 3.0, "check": 0.13})
#: Nanoseconds per operation of each class of the LH stepper as a map's
#: long runs take it, over SIMD lanes (:mod:`varint.codegen.lh_lanes`,
#: where :meth:`~varint.time_transform.LogHamiltonian.runs_in_lanes`):
#: the same operations as :data:`LH_WEIGHTS` prices (every lane runs the
#: one-orbit step's statements in the same order), fitted alike to the
#: training maps over lanes (``studies/switch_check.py`` part "fit",
#: column ``log_lanes``; its leave one out 0.43–2.2, the three-body
#: problem 0.61), two significant figures. (Before: :data:`LH_WEIGHTS`
#: times the lanes' share of one orbit's time on the cored race map,
#: ``studies/results/lhlanes17/lh_lanes.json``.) Its library calls cost
#: about as much as one orbit's (the lanes' ``lane_log`` is the branch-free
#: ``vlog``); its arithmetic and divisions overlap across the lanes.
LH_LANES_WEIGHTS: Mapping[str, float] = _by_kind(
    {"arithmetic": 0.055, "division": 0.43, "call": 3.3, "check": 0.0})
VECTOR_LANE_WEIGHTS: Mapping[str, float] = _by_kind(
    {"arithmetic": 0.011, "division": 0.18, "call": 0.0, "check": 0.35})
SCALAR_LANE_WEIGHTS: Mapping[str, float] = _by_kind(
    {"arithmetic": 0.0, "division": 0.0, "call": 0.0, "check": 2.7})


def vectorises(counts):
    """Whether the loop over the lanes whose step executes ``counts``
    (:func:`operations`) vectorises: none of :data:`SCALAR_KINDS`."""
    return not any(counts.get(kind, 0) for kind in SCALAR_KINDS)


_BINARY = {ast.Add: "add", ast.Sub: "add", ast.Mult: "mul", ast.Div: "div",
           ast.FloorDiv: "div", ast.Mod: "div"}
_LEAVES = (ast.Return, ast.Break, ast.Continue, ast.Raise)


def operations(source, function, known, loop=None):
    """The operations one call of ``function`` in ``source`` executes, by
    kind (module docstring).

    Parameters
    ----------
    source : str
        A module's source.
    function : str
        The name of a function defined at its top level.
    known : dict
        Values of names at emission (``{"log": True, "k": 1}``): they decide
        ``if`` tests and ``range`` bounds.
    loop : int, optional
        Count the body of the ``loop``-th loop (0: the first) found in
        ``function`` by a depth-first walk, run once, instead of the whole
        function: one step of a loop over steps.

    Returns
    -------
    collections.Counter
        Operations by kind (:data:`KINDS`).

    >>> src = "def f(x, k):\\n    for c in range(k):\\n        x[c] = math.sqrt(x[c] * 2.0 + 1.0)"
    >>> sorted(operations(src, "f", {"k": 3}).items())
    [('add', 3), ('memory', 6), ('mul', 3), ('sqrt', 3)]
    """
    tree = ast.parse(source)
    body = next((node.body for node in tree.body
                 if isinstance(node, ast.FunctionDef) and node.name == function), None)
    if body is None:
        raise ValueError(f"the source defines no function {function!r}")
    if loop is not None:
        loops = [node for node in _walk(body) if isinstance(node, (ast.For, ast.While))]
        if loop >= len(loops):
            raise ValueError(f"{function!r} has {len(loops)} loops, not a loop {loop}")
        body = loops[loop].body
    counts: Counter = Counter()
    _statements(body, dict(known), counts, 1)
    return counts


def weighted(counts, table=None):
    """The cost of ``counts`` (:func:`operations`) by ``table``: in scalar
    additions by :data:`WEIGHTS` (the default), in nanoseconds by
    :data:`LH_WEIGHTS`, :data:`VECTOR_LANE_WEIGHTS` or
    :data:`SCALAR_LANE_WEIGHTS`."""
    table = WEIGHTS if table is None else table
    return float(sum(table[kind] * n for kind, n in sorted(counts.items())))


def lh_cost(source, n, kinds, lanes=False):
    """The cost of one force evaluation of the LH stepper whose module
    source is ``source`` (:func:`varint.codegen.lh.lh_source`; ``n``
    degrees of freedom, the scheme's stage ``kinds``, 0 drift, 1 kick), with
    one deviation vector, as an FLI map runs it: one LH step (``step``
    with ``log``) and the copies of ``advance`` around it, priced by
    :data:`LH_WEIGHTS` (one orbit at a time) or, with ``lanes``,
    :data:`LH_LANES_WEIGHTS` (nanoseconds), over its kicks. Returns
    ``(cost, counts)``."""
    known = {"log": True, "k": 1, "d": 2 * n, "n": n}
    counts = operations(source, "step", known) + operations(source, "advance", known,
                                                            loop=_last_loop(source))
    kicks = int(sum(1 for kind in kinds if kind == 1))
    return weighted(counts, LH_LANES_WEIGHTS if lanes else LH_WEIGHTS) / kicks, counts


def lanes_cost(source, gradients):
    """The cost of one force evaluation of a generated TM stepper whose
    module source is ``source`` (:func:`varint.codegen.stepper.generated_source`)
    run as SIMD lanes, per lane: one lane's step and its end (checks,
    renormalisation, the accumulator's rule), the first loop over the lanes
    inside the loop over steps of ``lanes``, priced by
    :data:`VECTOR_LANE_WEIGHTS` or :data:`SCALAR_LANE_WEIGHTS`
    (:func:`vectorises`; nanoseconds), over the ``gradients`` one step evaluates (:func:`varint.codegen.tm.step_counts`). Returns ``(cost,
    counts)``."""
    counts = operations(source, "lanes", {"nb": 1, "renorm": True}, loop=_lane_step(source))
    table = VECTOR_LANE_WEIGHTS if vectorises(counts) else SCALAR_LANE_WEIGHTS
    return weighted(counts, table) / gradients, counts


def log_gradient_cost(lh, lanes=False):
    """:func:`lh_cost` of the LH stepper ``lh`` (a
    :class:`~varint.time_transform.LogHamiltonian`), one orbit at a time
    or with ``lanes`` over SIMD lanes, as the map's run will take it
    (:meth:`~varint.time_transform.LogHamiltonian.runs_in_lanes`):
    ``(cost, counts)``, read once per process and source (parsing a
    three-body module takes a good part of a quick map's time)."""
    return _log_cost(lh.source(), lh.model.dim // 2, tuple(int(v) for v in lh.kinds),
                     bool(lanes))


@lru_cache(maxsize=32)
def _log_cost(source, n, kinds, lanes):
    return lh_cost(source, n, kinds, lanes)


def constant_gradient_cost(model, scheme, k, accumulator):
    """:func:`lanes_cost` of the generated TM stepper of ``model``, the
    splitting ``scheme`` (a name or scheme), ``k`` vectors and the
    indicator's ``accumulator``, as a map runs it: ``(cost, counts)``.
    Emits its source (SymPy; cached per process by the model's form),
    compiles nothing."""
    from .codegen.expressions import ensure_form, model_key
    from .schemes import DRIFT, get_scheme, stage_arrays

    kinds, _, hc = stage_arrays(get_scheme(scheme), 1.0)
    corrected = (hc != 0.0) & (kinds != DRIFT)
    key = model_key(model)
    ensure_form(model, key)
    return _constant_cost(key, tuple(int(v) for v in kinds),
                          tuple(bool(c) for c in corrected), int(k), accumulator)


@lru_cache(maxsize=32)
def _constant_cost(key, kinds, corrected, k, accumulator):
    """:func:`constant_gradient_cost` of the model form ``key``, once per
    process (emitting the source costs SymPy's common subexpressions)."""
    from .codegen.expressions import expressions
    from .codegen.stepper import Plan, generated_source
    from .codegen.tm import step_counts

    plan = Plan(kinds=kinds, corrected=corrected, k=k, accumulator="")
    source = generated_source(expressions(key), plan, accumulator)
    per_step, _ = step_counts(kinds, corrected, k)
    return lanes_cost(source, int(per_step[0]))


def _last_loop(source):
    """The index of ``advance``'s loop over LH steps (its ``while``)."""
    tree = ast.parse(source)
    advance = next(node for node in tree.body
                   if isinstance(node, ast.FunctionDef) and node.name == "advance")
    loops = [node for node in _walk(advance.body) if isinstance(node, (ast.For, ast.While))]
    return next(i for i, node in enumerate(loops) if isinstance(node, ast.While))


def _lane_step(source):
    """The index of the loop over the lanes inside ``lanes``' loop over
    steps (``for s in range(n_steps)``)."""
    tree = ast.parse(source)
    lanes = next(node for node in tree.body
                 if isinstance(node, ast.FunctionDef) and node.name == "lanes")
    loops = [node for node in _walk(lanes.body) if isinstance(node, (ast.For, ast.While))]
    steps = next(i for i, node in enumerate(loops) if isinstance(node, ast.For)
                 and isinstance(node.target, ast.Name) and node.target.id == "s")
    return steps + 1


def _walk(body):
    """The statements of ``body``, depth first, in source order."""
    for node in body:
        yield node
        for field in ("body", "orelse"):
            yield from _walk(getattr(node, field, []))


def _static(node, known):
    """The value of expression ``node`` if ``known`` decides it, else None."""
    if isinstance(node, ast.Constant):
        return node.value
    if isinstance(node, ast.Name):
        return known.get(node.id)
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.Not):
        v = _static(node.operand, known)
        return None if v is None else not v
    if isinstance(node, ast.BoolOp):
        values = [_static(v, known) for v in node.values]
        if isinstance(node.op, ast.And):
            if any(v is not None and not v for v in values):
                return False
            return True if all(v is not None for v in values) else None
        if any(v is not None and v for v in values):
            return True
        return False if all(v is not None for v in values) else None
    if isinstance(node, ast.Compare) and len(node.ops) == 1:
        a, b = _static(node.left, known), _static(node.comparators[0], known)
        if a is None or b is None:
            return None
        op = type(node.ops[0])
        table = {ast.Gt: a > b, ast.GtE: a >= b, ast.Lt: a < b, ast.LtE: a <= b,
                 ast.Eq: a == b, ast.NotEq: a != b}
        return table.get(op)
    return None


def _statements(body, known, counts, times):
    for node in body:
        _statement(node, known, counts, times)


def _statement(node, known, counts, times):
    if isinstance(node, ast.If):
        decided = _static(node.test, known)
        if decided is None:
            _expression(node.test, counts, times)
            # A failure leaves: its branch is not the step's.
            if not (node.body and isinstance(node.body[-1], _LEAVES)):
                _statements(node.body, known, counts, times)
            if not (node.orelse and isinstance(node.orelse[-1], _LEAVES)):
                _statements(node.orelse, known, counts, times)
            return
        _statements(node.body if decided else node.orelse, known, counts, times)
        return
    if isinstance(node, ast.For):
        n = _trips(node.iter, known)
        _statements(node.body, known, counts, times * n)
        return
    if isinstance(node, ast.While):
        raise ValueError("a while loop inside a step: count its body with loop=")
    if isinstance(node, ast.AugAssign):
        kind = _BINARY.get(type(node.op))
        if kind:
            counts[kind] += times
        _expression(node.target, counts, times)
        _expression(node.value, counts, times)
        return
    if isinstance(node, (ast.Assign, ast.AnnAssign, ast.Expr, ast.Return)):
        for child in ast.iter_child_nodes(node):
            _expression(child, counts, times)


def _trips(iterator, known):
    """How many times a ``for`` over ``iterator`` runs: ``range`` of
    bounds ``known`` decides."""
    if isinstance(iterator, ast.Call) and isinstance(iterator.func, ast.Name) \
            and iterator.func.id in ("range", "prange"):
        args = [_static(a, known) for a in iterator.args]
        if all(isinstance(a, int) for a in args):
            return len(range(*args))
    raise ValueError(f"a loop whose trip count is not known: {ast.unparse(iterator)}")


def _call_name(func):
    if isinstance(func, ast.Attribute):
        return func.attr
    return func.id if isinstance(func, ast.Name) else ""


def _constant(node):
    """The value of a numeric expression of literals (``3/2``, ``-2``), or
    None."""
    if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)) \
            and not isinstance(node.value, bool):
        return node.value
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
        v = _constant(node.operand)
        return None if v is None else (-v if isinstance(node.op, ast.USub) else v)
    if isinstance(node, ast.BinOp) and type(node.op) in (ast.Add, ast.Sub, ast.Mult, ast.Div):
        a, b = _constant(node.left), _constant(node.right)
        if a is None or b is None or (isinstance(node.op, ast.Div) and b == 0):
            return None
        return {ast.Add: a + b, ast.Sub: a - b, ast.Mult: a * b,
                ast.Div: a / b if b else None}[type(node.op)]
    return None


def _expression(node, counts, times):
    """Count the operations of expression ``node`` (and its children)."""
    if node is None or _constant(node) is not None:
        return   # folded by the compiler
    if isinstance(node, ast.BinOp):
        if isinstance(node.op, ast.Pow):
            e = _constant(node.right)
            # An integer power is multiplications (LLVM's powi: x**(-2) is
            # 1/(x·x)), another one a call of pow (a user's x**y; the
            # steppers print half-integer powers as products and a square
            # root, varint.codegen.printer).
            if e is not None and float(e).is_integer():
                counts["mul"] += times * max(int(abs(e)) - 1, 0)
                if e < 0:
                    # A division, but numba inverts with its own error
                    # model (a zero test): the loop around it does not
                    # vectorise (SCALAR_KINDS).
                    counts["invert"] += times
            else:
                counts["pow"] += times
        else:
            kind = _BINARY.get(type(node.op))
            if kind:
                counts[kind] += times
    elif isinstance(node, ast.Compare):
        counts["compare"] += times * len(node.ops)
    elif isinstance(node, ast.Subscript):
        counts["memory"] += times
        _expression(node.value, counts, times)
        return   # an index is integer arithmetic, not counted
    elif isinstance(node, ast.Call):
        kind = CALLS.get(_call_name(node.func))
        if kind:
            counts[kind] += times
        for arg in node.args:
            _expression(arg, counts, times)
        return
    for child in ast.iter_child_nodes(node):
        _expression(child, counts, times)

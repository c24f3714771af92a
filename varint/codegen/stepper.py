"""Tangent-map steppers generated per model and scheme, cached on disk.

For a model that knows its potential symbolically (every built-in model and
every :func:`~varint.models.from_potential` model) and has few degrees of
freedom (:func:`~varint.codegen.expressions.symbolic_fits`), the stepper is
written out as Python source and compiled by numba: the scheme's stages
unrolled with straight-line derivatives (:mod:`varint.codegen.tm`), the
state in registers, the end of every step and the copies at output steps
inside the loop (:mod:`varint.codegen.interval`), as one orbit and as SIMD
lanes; or, compact (``compact=True``), one orbit whose stages are a loop
over the stage arrays, bitwise the same, compiled in a fraction of the
time and shared by every scheme of its shape
(:meth:`~varint.codegen.tm.TMBody.compact_stages`).

The source goes to ``<cache dir>/kernels/`` under a name that hashes the
generator's code, the model's potential and the plan, signed, and is
verified before every later import and executed from the verified bytes
(:func:`varint.codecache.load_module`); numba caches its compilation beside
it (signed too), so a new process (or a new varint version, or
another model) finds or builds exactly the kernel it needs; the first run
in a new process loads it instead of compiling it, without emitting the
source again.
"""

from __future__ import annotations

import hashlib
import importlib.util
import inspect
import os
import uuid
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from types import ModuleType

from .. import codecache
from ..kernels.closures import Unnamed, describe_cells
from .accumulators import rule_text
from .expressions import ensure_form, expressions, model_key
from .interval import Interval
from .tm import TMBody, compact_shape, level

__all__ = ["Plan", "generated_source", "generator_sources", "symbolic_stepper", "written_out_ready"]


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
        What identifies the indicator's accumulator: its rule
        (:func:`~varint.codegen.accumulators.rule_text`), written out in the
        loop, or ``"module:name:hash"`` of its compiled update, called; ""
        for none.
    compensated : bool, "orbit" or "step"
        Drifts and kicks (``"orbit"``: the orbit's, not the vectors';
        ``"step"``: the orbit's displacement over each step) add by
        compensated summation (:class:`~varint.codegen.tm.TMBody`); such a
        module has no lanes.
    compact : bool
        The stages as a loop over the stage arrays
        (:meth:`~varint.codegen.tm.TMBody.compact_stages`): ``kinds`` and
        ``corrected`` are then the scheme's
        :func:`~varint.codegen.tm.compact_shape`, shared by every scheme of
        that shape; such a module has no lanes.
    """

    kinds: tuple
    corrected: tuple
    k: int
    accumulator: str
    compensated: bool | str = False
    compact: bool = False


def generated_source(E, plan, accumulator=None):
    """The Python source of the stepper for expressions ``E``, ``plan`` and
    ``accumulator``. Its first line names the generator's own code, as the
    file's name does (:func:`symbolic_stepper`): numba's cache does not
    follow a changed dependency, so a changed generator must write a new
    file."""
    body = TMBody(E, plan.kinds, plan.corrected, plan.k, plan.compensated, plan.compact)
    source = Interval(body, plan.k, accumulator).module(plan.accumulator)
    return f"# varint generator {_generator_id()}\n" + source


def generator_sources():
    """The files whose code and constants a generated stepper's source is
    made of: this layer, the kernels it calls (the fused multiply–add, the
    logarithm, the sparse schedule, the checks' constants), the threads
    its parallel batches run on, the protocol's codes, the scheme table's
    stage codes and the expression printer
    (``varint.models.symbolic``'s ``KernelPrinter``, which the layer's
    printer extends)."""
    from .. import protocol, schemes, threads
    from ..kernels import checks, fma, interval, logarithm

    layer = sorted(Path(__file__).parent.glob("*.py"))
    # The printer's file, found without running it: importing it imports
    # SymPy (~0.4 s of a first run whose kernels are all cached).
    spec = importlib.util.find_spec("varint.models.symbolic")
    assert spec is not None and spec.origin is not None
    return layer + [Path(m.__file__) for m in (checks, fma, interval, logarithm, protocol,
                                               schemes, threads)] + [Path(spec.origin)]


def _sympy_release():
    """SymPy's ``release.py``, which holds its ``__version__``: found without
    importing SymPy or :mod:`importlib.metadata` (4–9 ms of a first run
    whose kernels are all cached, scanning every installed distribution)."""
    spec = importlib.util.find_spec("sympy")
    assert spec is not None and spec.submodule_search_locations
    return Path(spec.submodule_search_locations[0]) / "release.py"


@lru_cache(maxsize=1)
def _generator_id():
    """A hash of :func:`generator_sources` and SymPy's version (its
    differentiation, CSE and printing write the expressions): numba's cache
    does not follow a changed dependency, so any change names new modules
    instead of loading a stale one."""
    digest = hashlib.sha256(_sympy_release().read_bytes())
    for path in generator_sources():
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


@lru_cache(maxsize=256)
def _function_id(function):
    """A name for a compiled function that changes when what is compiled
    in from it does, for the generated file's name: ``module:qualname:``
    the hash of its source, of its file's size and modification time (the
    globals it reads there) and of the values it closes over; worked out
    once per function and process (reading the source costs ~1 ms).

    A function whose closed-over values no key can name (an array, a
    function of the user's: :func:`varint.kernels.closures.describe_cells`)
    gets a name of this process only, and its module is compiled in memory
    (:func:`_on_disk`): named by its source alone, two closures of one
    function (``make_update(w)`` for two weights w) shared one generated
    stepper, in this process and through the cache, and the second ran the
    first one's update."""
    py = getattr(function, "py_func", function)
    try:
        code = inspect.getsource(py)
    except (OSError, TypeError):
        code = repr(py.__code__.co_code)
    try:
        cells = repr(describe_cells(py))
    except Unnamed:
        _IN_PROCESS.setdefault(function, uuid.uuid4().hex)
        cells = f"in process {_IN_PROCESS[function]}"
    try:
        stat = os.stat(py.__code__.co_filename)
        stamp = f"{stat.st_size} {stat.st_mtime_ns}"
    except OSError:
        stamp = ""
    digest = hashlib.sha256(f"{code}|{stamp}|{cells}".encode()).hexdigest()[:16]
    return f"{py.__module__}:{py.__qualname__}:{digest}"


#: Update functions named for this process only (:func:`_function_id`),
#: each with its token (held here: a token is never given to another).
_IN_PROCESS: dict = {}


def _on_disk(accumulator):
    """Whether the stepper of ``accumulator`` may be cached on disk: not if
    its update is named for this process only."""
    if accumulator is None or accumulator.rule is not None:
        return True
    _function_id(accumulator.update)        # gives it its token if it needs one
    return accumulator.update not in _IN_PROCESS


def _accumulator_id(accumulator):
    if accumulator is None:
        return ""
    if accumulator.rule is not None:
        return f"rule {accumulator.name} {tuple(accumulator.columns)} " \
               f"{rule_text(accumulator.rule)} flow={accumulator.needs_flow}"
    return f"{_function_id(accumulator.update)} flow={accumulator.needs_flow}"


_LOADED: dict[str, ModuleType] = {}


@lru_cache(maxsize=64)
def _source(key, plan, accumulator):
    """The stepper's source for the model of ``key``
    (:func:`~varint.codegen.expressions.model_key`), ``plan`` and
    ``accumulator``, written once per process: each chunk of a chaos map
    makes its own propagator, and emitting the source (SymPy's common
    subexpressions, printing) costs ~60 ms."""
    return generated_source(expressions(key), plan, accumulator)


def symbolic_stepper(model, kinds, corrected, k, accumulator=None, compensated=False,
                     compact=False):
    """The generated stepper module for a model that
    :func:`~varint.codegen.expressions.symbolic_fits`.

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
    compensated : bool, "orbit" or "step", default False
        Compensated summation in every drift and kick, in the orbit's
        drifts and kicks (``"orbit"``), or of the orbit's displacement over
        each step (``"step"``; :class:`~varint.codegen.tm.TMBody`).
    compact : bool, default False
        The stages as a loop (:meth:`~varint.codegen.tm.TMBody.
        compact_stages`; bitwise the stages written out): the module of
        every scheme of the same :func:`~varint.codegen.tm.compact_shape`.

    Returns
    -------
    module
        With ``orbit``, ``batch_serial``, ``batch_parallel``, ``lanes``,
        ``blocks_serial`` and ``blocks_parallel`` (see
        :mod:`varint.codegen.interval`; compensated or compact: the first
        three); compiled on first call, or loaded from numba's cache.
    """
    if compact:
        shape = compact_shape(kinds, corrected)
        if shape is None:
            raise ValueError(f"stages {tuple(int(v) for v in kinds)} with correctors "
                             f"{tuple(bool(c) for c in corrected)} have no compact stepper: "
                             "drifts and kicks must alternate, correctors on the end kicks")
        kinds, corrected = shape
    plan = _plan(kinds, corrected, k, accumulator, compensated, compact)
    key = model_key(model)
    digest = _digest(key, plan)
    if digest not in _LOADED:
        # An update without a rule is called: the module finds it by name.
        extra = {} if accumulator is None or accumulator.rule is not None else {
            "accumulate": accumulator.update}
        # A model's extra force (varint.codegen.expressions.ExtraForce) is
        # called by name too; the key names its code and constants.
        force = getattr(model, "extra_force", None)
        if force is not None:
            extra["extra_force"] = force.function

        def make_source():
            # The source is only ever emitted from the model's own form,
            # never from what a file says: the stored facts named it, the
            # model gives it (the same key: the facts are signed and named
            # after the code and SymPy's version that made them).
            ensure_form(model, key)
            return _source(key, plan, accumulator)

        _LOADED[digest] = codecache.load_module(f"varint_stepper_{digest}", "kernels",
                                                make_source, extra,
                                                on_disk=_on_disk(accumulator))
    return _LOADED[digest]


def written_out_ready(model, kinds, corrected, k, accumulator=None, compensated=False):
    """Whether the stepper with its stages written out (``compact=False``)
    for these arguments is loaded in this process or its file is in the
    kernel cache, where the process that wrote it compiled it: then its
    compile is paid, and a short run need not take the compact stepper
    (:attr:`~varint.methods.tm.TangentMapPropagator.COMPACT_WORK`). Only a
    choice between two forms with the same bits rests on it; the file is
    verified when it is loaded, as every cached file is."""
    plan = _plan(kinds, corrected, k, accumulator, compensated, False)
    digest = _digest(model_key(model), plan)
    return digest in _LOADED or (_on_disk(accumulator) and codecache.module_on_disk(
        f"varint_stepper_{digest}", "kernels"))


def _plan(kinds, corrected, k, accumulator, compensated, compact):
    return Plan(kinds=tuple(int(v) for v in kinds), corrected=tuple(bool(c) for c in corrected),
                k=int(k), accumulator=_accumulator_id(accumulator),
                compensated=level(compensated), compact=bool(compact))


@lru_cache(maxsize=256)
def _digest(key, plan):
    """The generated module's name: the generator's code, the model's
    potential and masses (``key``) and the plan (scheme, k, accumulator)
    determine its source."""
    return hashlib.sha256(f"{_generator_id()}|{key}|{plan}".encode()).hexdigest()[:24]

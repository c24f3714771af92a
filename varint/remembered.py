"""One-shot calls remembered per process: a call of :func:`varint.run`
(and of the public functions over it) that repeats an earlier call's
arguments but its initial states and vectors runs that call's set-up again
(:class:`varint.rerun.Rerun`: its checked arguments, propagator and short
path) instead of building it anew (issue 28: the fixed cost of a call; at
one step about a tenth of a one-shot call's time is arithmetic).

A call is remembered by a key of everything it was given but ``x0`` and
``deviations`` (of which only the shapes): every argument by type and
value, an object that is not a plain value (the model, a scheme, an
indicator) by identity, and the model's state (:func:`model_token`: every
attribute's value, its arrays' bytes included, as the model pickles it). So a later call hits only
with equal arguments and a model in the same state; anything else, a model
changed in place included, misses and is run from scratch. The remembered
calls hold every object their key names by identity, so no identity is
reused while the key lives. At most :data:`CAPACITY` calls are kept, the
least recently used dropped, each a run of small outputs
(:data:`RECORD_BYTES`); at its first repeat the call's
:class:`~varint.rerun.Rerun` is made, and a call without a short path
(:class:`varint.rerun.ShortCall`) is marked as such and run from scratch.
"""

from __future__ import annotations

import collections
import operator
import threading
from typing import TYPE_CHECKING, Any

import numpy as np

from . import _validate as check

if TYPE_CHECKING:
    from .rerun import FirstRun, Rerun

__all__ = ["CAPACITY", "call_key", "model_token", "recall", "remember", "forget"]

#: How many calls a process keeps (each holds its first run, one thread's
#: buffers of at most 1 MiB per thread that called it, and its model).
CAPACITY = 8

#: Most bytes of outputs of a run that is remembered (about what its
#: records hold; :meth:`varint.rerun.ShortCall.over` bounds them again).
RECORD_BYTES = 1 << 22

#: Largest array (elements) of a model's attributes a key copies: a model
#: holding a larger one is not remembered (its copy would cost more than
#: the set-up it saves).
_ARRAY_MAX = 4096

#: key -> [the first run, its run's seconds, its Rerun once made, held].
_calls: collections.OrderedDict[_Key, list] = collections.OrderedDict()
_lock = threading.Lock()

#: Deepest nesting of containers and attributes a key walks (the bar's
#: planar parameters, a dict of dicts of tuples among its attributes, sit
#: 4 levels down); deeper, or a cycle: the call is not remembered.
_DEPTH = 8

#: The plain values a key holds by type and value (a bool is not an int
#: there: ``seed=True`` is refused where ``seed=1`` is not).
_PLAIN = frozenset((int, float, str, bool, type(None), np.float64, np.int64, np.bool_))


#: Per type, whether a key holds its values by identity whatever their
#: state (callables: functions, compiled kernels, bound methods; varint's
#: frozen records; :func:`_frozen`), as its first value seen showed: both
#: are properties of the type (``callable`` reads the type's call slot).
#: A model's attributes are mostly such values, each otherwise asked again.
_BY_IDENTITY: dict[type, bool] = {}


class _Key:
    """A call's key with its hash computed once (a model's key is a deep
    tuple: its hash walks every level, and a call hashes it to check it,
    to look it up and to keep it)."""

    __slots__ = ("items", "hash")

    def __init__(self, items: tuple) -> None:
        self.items = items
        self.hash = hash(items)

    def __hash__(self) -> int:
        return self.hash

    def __eq__(self, other: object) -> bool:
        return (isinstance(other, _Key) and self.hash == other.hash
                and self.items == other.items)


class _Unkeyed(Exception):
    """An argument a key cannot hold: the call is not remembered."""


def _frozen(value: Any, held: list, depth: int = 0, checks: list | None = None) -> Any:
    """``value`` as part of a key: plain values by type and value, tuples,
    lists and dicts by their items, arrays by dtype, shape and bytes,
    functions, varint's frozen dataclasses and other objects by identity (kept in
    ``held``), objects with attributes (not callables) by their state too:
    their attributes, or what their ``__getstate__`` gives where they
    define one (the state they pickle: a model's caches of what it derives
    from the rest, e.g. the memo of a
    :class:`~varint.models.hamiltonian.HamiltonianModel`, left out, so that
    filling them changes no key).

    ``checks``, where given, gets what tells that a later walk would give
    an equal value (:func:`_unchanged`): each list's and dict's items by
    identity, each array's bytes, each object's state."""
    kind = type(value)
    if kind in _PLAIN:
        return kind, value
    if _BY_IDENTITY.get(kind):
        held.append(value)
        return kind, id(value)
    if kind is tuple or kind is list:
        if depth > _DEPTH:
            raise _Unkeyed
        if checks is not None and kind is list:
            checks.append((_same_items, (value, tuple(value))))
        if all([type(v) in _PLAIN for v in value]):
            # (Plain items, e.g. a model's constants: their types and
            # values in two C loops.)
            return kind, tuple(map(type, value)), tuple(value)
        return kind, tuple([_frozen(v, held, depth + 1, checks) for v in value])
    if kind is dict:
        if depth > _DEPTH:
            raise _Unkeyed
        if checks is not None:
            checks.append((_same_dict, (value, tuple(value), tuple(value.values()))))
        return kind, _frozen_items(value, held, depth, checks)
    if kind is np.ndarray:
        if value.size > _ARRAY_MAX or value.dtype.hasobject:
            raise _Unkeyed
        held.append(value)
        frozen = kind, id(value), value.dtype.str, value.shape, value.tobytes()
        if checks is not None:
            checks.append((_same_array, (value, frozen)))
        return frozen
    held.append(value)
    attributes = getattr(value, "__dict__", None)
    by_identity = _BY_IDENTITY.get(kind)
    if by_identity is None:
        by_identity = _BY_IDENTITY[kind] = callable(value) or _frozen_record(kind)
    if attributes is None or by_identity:
        # Code (functions, compiled kernels), values without attributes
        # (frozen scheme and indicator records of slots, SymPy expressions)
        # and varint's frozen dataclasses (a model's symbolic form, structure and
        # extra force: records that are never rebound, of values that never
        # change): by identity, at any depth.
        return kind, id(value)
    if depth > _DEPTH:
        raise _Unkeyed
    if kind.__getstate__ is object.__getstate__:
        if checks is not None:
            checks.append((_same_state, (value, attributes, None)))
        return kind, id(value), _frozen(attributes, held, depth + 1, checks)
    attributes = value.__getstate__()
    if type(attributes) is not dict:
        if checks is not None:
            checks.append((_same_state, (value, attributes, (None, None))))   # (never holds)
        return kind, id(value), _frozen(attributes, held, depth + 1, checks)
    if depth + 1 > _DEPTH:
        raise _Unkeyed
    if checks is not None:
        # A new dict at each call: its keys and objects compared by this
        # check, not by a check of the dict.
        checks.append((_same_state, (value, attributes,
                                     (tuple(attributes), tuple(attributes.values())))))
    return kind, id(value), (dict, _frozen_items(attributes, held, depth + 1, checks))


def _frozen_items(value: dict, held: list, depth: int, checks: list | None) -> tuple:
    """The items of the dict ``value`` (at ``depth``) as part of a key
    (:func:`_frozen`)."""
    # (Plain values inline: a model's attributes are mostly these.)
    return tuple([(k, (type(v), v) if type(v) in _PLAIN else
                   _frozen(v, held, depth + 1, checks)) for k, v in value.items()])


def _same_items(items: list, then: tuple) -> bool:
    """Whether the list ``items`` holds the objects ``then`` (a check of
    :func:`_frozen`)."""
    return len(items) == len(then) and all(map(operator.is_, items, then))


def _same_dict(d: dict, keys: tuple, values: tuple) -> bool:
    """Whether the dict ``d`` has the ``keys``, in order, and the objects
    ``values`` (a check of :func:`_frozen`)."""
    return tuple(d) == keys and all(map(operator.is_, d.values(), values))


def _same_array(a: np.ndarray, frozen: tuple) -> bool:
    """Whether the array ``a`` is as :func:`_frozen` gave it (``frozen``):
    its dtype, shape and bytes (its identity its holder's check's)."""
    return a.shape == frozen[3] and a.dtype.str == frozen[2] and a.tobytes() == frozen[4]


def _same_state(value: Any, state: Any, items: tuple | None) -> bool:
    """Whether the object ``value``'s state (as :func:`_frozen` reads it)
    is still ``state``: its ``__dict__`` (whose items a check of their own
    compares), or, for ``items`` (the keys and the objects of the dict its
    ``__getstate__`` gave, a new dict at each call), a dict of the same
    keys and objects."""
    if items is None:
        return getattr(value, "__dict__", None) is state
    now = value.__getstate__()
    return type(now) is dict and _same_dict(now, *items)


def _unchanged(checks: list) -> bool:
    """Whether every check of a walk of :func:`_frozen` still holds: a new
    walk would visit the same objects, arrays of the same bytes among
    them, so give an equal value."""
    return all(same(*args) for same, args in checks)


def _frozen_record(kind: type) -> bool:
    """Whether ``kind`` is one of varint's frozen dataclasses (records
    built once and never changed in place). A user's frozen dataclass may
    hold an array that is changed in place: it is keyed by its state."""
    params = getattr(kind, "__dataclass_params__", None)
    return (params is not None and params.frozen
            and kind.__module__.split(".")[0] == "varint")


class _Token(_Key):
    """A model's state in a key (:func:`model_token`), its hash computed
    once: the same object while the model is unchanged, so that a key
    hashes and compares it at no cost."""

    __slots__ = ()

    def __eq__(self, other: object) -> bool:
        return self is other or super().__eq__(other)

    __hash__ = _Key.__hash__


#: Per model (by identity), the last walk of its state: (the model, its
#: token, the walk's checks, the objects the token names by identity).
#: The last :data:`CAPACITY` models walked are kept.
_TOKENS: dict[int, tuple[Any, _Token, list, list]] = {}


def model_token(model: Any, held: list) -> Any:
    """The state of ``model`` as part of a key: its identity and every
    attribute's value, or its ``__getstate__``'s where it defines one
    (:func:`_frozen`).

    The last walk's token where that walk's checks all hold
    (:func:`_unchanged`: every list and dict holds the same objects, every
    array the same bytes, so a new walk would give an equal value): a
    model's state is mostly values held by identity and plain values,
    which a walk keys one by one (~10 µs for the rotating bar's, issue
    28: the fixed cost of a call) and the checks compare in C loops."""
    last = _TOKENS.get(id(model))
    if last is not None and last[0] is model and _unchanged(last[2]):
        held.append(last[3])
        return last[1]
    checks: list = []
    own: list = []
    token = _Token(_frozen(model, own, 0, checks))
    held.append(own)
    with _lock:
        _TOKENS.pop(id(model), None)
        _TOKENS[id(model)] = (model, token, checks, own)
        while len(_TOKENS) > CAPACITY:
            del _TOKENS[next(iter(_TOKENS))]
    return token


def call_key(model: Any, x0: Any, indicator: Any, t_end: Any, tau: Any,
             options: dict) -> tuple[_Key, list] | None:
    """(key, held objects) of a call of :func:`varint.run`, or None for a
    call not remembered: τ chosen by a pilot (the pilot runs per orbit), a
    checkpoint, a drawn seed, or an argument a key cannot hold."""
    if tau is None or "checkpoint" in options or options.get("seed", 0) is None:
        return None
    deviations = options.get("deviations")
    held: list = []
    try:
        key = (model_token(model, held), _frozen(indicator, held), _frozen(t_end, held),
               _frozen(tau, held),
               tuple([(name, _frozen(value, held)) for name, value in sorted(options.items())
                      if name != "deviations"]),
               # The shapes only: the number of orbits picks the short path,
               # the vectors' presence and number how they are made.
               getattr(x0, "shape", None),
               None if deviations is None else np.shape(deviations))
        return _Key(key), held
    except (_Unkeyed, TypeError):     # (TypeError: an unhashable dict key)
        return None


def recall(key: _Key) -> Rerun | None:
    """The remembered call of ``key`` (its :class:`~varint.rerun.Rerun`,
    made at its first repeat), or None; a call without a short path is
    forgotten there."""
    with _lock:
        entry = _calls.get(key)
        if entry is None:
            return None
        _calls.move_to_end(key)
        first, seconds, again, _ = entry
        if again is None:
            # Imported at a process's first repeated call, not by its first
            # run (the short path's compiled energy errors load ~0.1 s of
            # kernels from the cache; issue 28's start-up).
            from .rerun import Rerun

            again = Rerun(first, seconds, check.KernelCheck(first.model))
            # Without a short path: kept as such (no run held), so that
            # its calls are neither made again nor remembered again.
            entry[:3] = [None, seconds, again if again.short is not None else False]
    return entry[2] or None


def remember(key: _Key, held: list, first: FirstRun, run_seconds: float) -> None:
    """Keep the executed run ``first`` (``run_seconds`` the time of its run)
    for the calls of ``key`` (holding ``held``, the objects it names by
    identity), if it is small: its records held no more than
    :data:`RECORD_BYTES`."""
    m, dim = first.x0.shape
    if 8 * len(first.steps) * m * (dim + 1) * (first.W0.shape[2] + 1) > RECORD_BYTES:
        return
    with _lock:
        if key in _calls:
            return      # (a call without a short path, kept as such)
        _calls[key] = [first, run_seconds, None, held]
        _calls.move_to_end(key)
        while len(_calls) > CAPACITY:
            _calls.popitem(last=False)


def forget() -> None:
    """Drop every remembered call (tests that patch what a run calls)."""
    with _lock:
        _calls.clear()
        _TOKENS.clear()

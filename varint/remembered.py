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
attribute's value, its arrays' bytes included). So a later call hits only
with equal arguments and a model in the same state; anything else, a model
changed in place included, misses and is run from scratch. The remembered
calls hold every object their key names by identity, so no identity is
reused while the key lives. At most :data:`CAPACITY` calls are kept, the
least recently used dropped; only calls whose runs have a short path
(:class:`varint.rerun.ShortCall`, which bounds what they keep) are kept.
"""

from __future__ import annotations

import collections
import threading
from typing import Any

import numpy as np

from .rerun import Rerun

__all__ = ["CAPACITY", "call_key", "model_token", "recall", "remember", "forget"]

#: How many calls a process keeps (each holds its first run, one thread's
#: buffers of at most 1 MiB per thread that called it, and its model).
CAPACITY = 8

#: Largest array (elements) of a model's attributes a key copies: a model
#: holding a larger one is not remembered (its copy would cost more than
#: the set-up it saves).
_ARRAY_MAX = 4096

_calls: collections.OrderedDict[tuple, tuple[Rerun, list]] = collections.OrderedDict()
_lock = threading.Lock()

#: The plain values a key holds by type and value (a bool is not an int
#: there: ``seed=True`` is refused where ``seed=1`` is not).
_PLAIN = frozenset((int, float, str, bool, type(None), np.float64, np.int64, np.bool_))


class _Unkeyed(Exception):
    """An argument a key cannot hold: the call is not remembered."""


def _frozen(value: Any, held: list, depth: int = 0) -> Any:
    """``value`` as part of a key: plain values by type and value, tuples,
    lists and dicts by their items, arrays by dtype, shape and bytes,
    functions and other objects by identity (kept in ``held``), objects
    with attributes (not callables) by their attributes too."""
    kind = type(value)
    if kind in _PLAIN:
        return kind, value
    if depth > 4:
        raise _Unkeyed
    if kind is tuple or kind is list:
        return kind, tuple([_frozen(v, held, depth + 1) for v in value])
    if kind is dict:
        # (Plain values inline: a model's attributes are mostly these.)
        return kind, tuple([(k, (type(v), v) if type(v) in _PLAIN else
                             _frozen(v, held, depth + 1)) for k, v in value.items()])
    if kind is np.ndarray:
        if value.size > _ARRAY_MAX or value.dtype.hasobject:
            raise _Unkeyed
        held.append(value)
        return kind, id(value), value.dtype.str, value.shape, value.tobytes()
    held.append(value)
    attributes = getattr(value, "__dict__", None)
    if attributes is None or callable(value):
        # Code (functions, compiled kernels) and values without attributes
        # (frozen scheme and indicator records of slots, SymPy expressions).
        return kind, id(value)
    return kind, id(value), _frozen(attributes, held, depth + 1)


def model_token(model: Any, held: list) -> Any:
    """The state of ``model`` as part of a key: its identity and every
    attribute's value (:func:`_frozen`)."""
    return _frozen(model, held)


def call_key(model: Any, x0: Any, indicator: Any, t_end: Any, tau: Any,
             options: dict) -> tuple[tuple, list] | None:
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
               tuple((name, _frozen(value, held)) for name, value in sorted(options.items())
                     if name != "deviations"),
               # The shapes only: the number of orbits picks the short path,
               # the vectors' presence and number how they are made.
               getattr(x0, "shape", None),
               None if deviations is None else np.shape(deviations))
        hash(key)
    except (_Unkeyed, TypeError):     # (TypeError: an unhashable dict key)
        return None
    return key, held


def recall(key: tuple) -> Rerun | None:
    """The remembered call of ``key``, or None."""
    with _lock:
        entry = _calls.get(key)
        if entry is None:
            return None
        _calls.move_to_end(key)
    return entry[0]


def remember(key: tuple, held: list, rerun: Rerun) -> None:
    """Keep ``rerun`` for the calls of ``key`` (holding ``held``, the
    objects it names by identity), if it has a short path."""
    if rerun.short is None:
        return
    with _lock:
        _calls[key] = (rerun, held)
        _calls.move_to_end(key)
        while len(_calls) > CAPACITY:
            _calls.popitem(last=False)


def forget() -> None:
    """Drop every remembered call (tests that patch what a run calls)."""
    with _lock:
        _calls.clear()

"""The stepping skeleton's kernels cached on disk, across processes.

The skeleton's kernels (:mod:`varint.kernels.interval`) are closures: a
method's step body, the model's kernels and the indicator's update are
compiled into them as constants (passed in records instead, numba types a
call ~10× slower). numba caches a closure on disk under a hash of its cells
pickled, but a pickled dispatcher carries an identity drawn anew in every
process (its ``uuid``): that key never matched in another process, so
every process compiled the part steppers of the lattices again (6–8 s).

:func:`cache_on_disk` gives such a kernel numba's disk cache under a key
that names what the kernel is compiled from, the same in every process:

* every function it closes over, recursively (the step body's hooks, the
  model's kernels they close over, numba's options of each), by its
  module, qualified name, bytecode, constants and names;
* a function of a generated module read from its verified cache file (a
  generated stepper, a :func:`~varint.models.symbolic.from_potential`
  model's kernels) by the module's name — a hash of everything its source
  is made from — and its code;
* the plain values it closes over (flags, sizes, strings) by value, and
  so the arrays it closes over whose memory is an immutable ``bytes``
  object (``np.frombuffer``: a compiled right-hand side's parameters and
  masses, which numba compiles in as constants) — by dtype, shape, strides
  and content; any other array could change after it is named;
* all of varint's source (:func:`varint.identity.source_digest`): the
  helpers a function calls through its globals are compiled in too, and
  numba's cache does not follow them.

A kernel that closes over anything else — a function of the user's own
(whose helpers the key could not follow) or of code without a file — is
left compiled in memory, as before; so is one whose machine code holds an
address of this process (numba's ``has_dynamic_globals``). numba puts one
there for a dispatcher that a function takes from a cell or global and
passes on as an argument to a function LLVM does not inline (called, it
leaves none): a general H's Gauss–Legendre step therefore closes over the
model's kernels rather than taking them as arguments
(:func:`varint.flows.gauss.gauss_stepper`). numba's files of these kernels are
pickles that numba loads, so they are kept as a generated module's are
(:class:`varint.codecache.SignedCache`): in ``<cache dir>/closures/``,
signed with the cache directory's secret and unpickled only after their
signature verifies; a file that fails is discarded with a warning and the
kernel compiled again. Without a usable cache directory or secret the
kernel is compiled in memory; a cache that cannot be written costs a
warning, one that cannot be read a recompilation.
"""

from __future__ import annotations

import contextlib
import dataclasses
import enum
import hashlib
import types
from pathlib import Path

import numpy as np
from numba.core.dispatcher import Dispatcher
from numba.core.extending import _Intrinsic

from .. import baselines, cachedir, codecache
from ..identity import source_digest

__all__ = ["cache_on_disk", "closure_key", "describe_cells", "Unnamed"]

#: The folders whose functions a key may name: varint's own sources
#: (``varint`` and ``varint.baselines``), all of which the key hashes.
_SOURCES = (Path(__file__).resolve().parent.parent, Path(baselines.__file__).resolve().parent)


#: varint's sources, read when the skeleton is imported, as near as can be
#: to when the code that runs was: a file edited later, while this process
#: runs, must not give the kernels it compiles the key of the new code.
_SOURCE_DIGEST = source_digest()

#: The cache directory's folder of these kernels' numba files.
_FOLDER = "closures"


class Unnamed(Exception):
    """A value that no key can name (a user's function, an object)."""


def describe_cells(function):
    """A plain, process-independent description of the values ``function``
    closes over (by value; functions of varint's sources by their code);
    :class:`Unnamed` if one has none."""
    return tuple(_describe(c.cell_contents) for c in function.__closure__ or ())


def cache_on_disk(dispatcher):
    """Give the closure kernel ``dispatcher`` numba's disk cache under
    :func:`closure_key`, signed in ``<cache dir>/closures/``, unless a key
    cannot name what it closes over or there is no usable cache directory
    and secret (then it stays compiled in memory). Returns ``dispatcher``."""
    try:
        key = closure_key(dispatcher)
    except Unnamed:
        return dispatcher
    folder = cachedir.subdir(_FOLDER)
    secret = None if folder is None else cachedir.secret()
    if secret is None or not codecache.numba_hooks_present():
        return dispatcher               # (cachedir has said why, once)
    with contextlib.suppress(RuntimeError):   # numba found no locator for the file
        dispatcher._cache = _ClosureCache(dispatcher.py_func, key, secret, folder)
    return dispatcher


def closure_key(dispatcher):
    """The name (64 hex digits) of what the closure kernel ``dispatcher``
    is compiled from (see the module docstring): its function and numba's
    options (``parallel``, …).

    Raises
    ------
    Unnamed
        If it closes over something no key can name.
    """
    text = repr(_describe(dispatcher))
    return hashlib.sha256(f"{_SOURCE_DIGEST}|{text}".encode()).hexdigest()


def _describe(value, depth=0):
    """A plain, process-independent description of ``value`` (nested
    tuples of strings and numbers); :class:`Unnamed` if there is none."""
    if depth > 64:
        raise Unnamed("nested too deeply")
    if value is None or isinstance(value, (bool, int, float, complex, str, bytes)):
        return (type(value).__name__, repr(value))
    if isinstance(value, enum.Enum):
        return ("enum", _class_name(type(value)), value.name)
    if isinstance(value, (np.generic, np.dtype)):
        return ("numpy", repr(value))
    if isinstance(value, np.ndarray) and isinstance(_memory(value), bytes):
        data = hashlib.sha256(np.ascontiguousarray(value).tobytes()).hexdigest()
        return ("ndarray", value.dtype.str, value.shape, value.strides, data)
    if isinstance(value, Dispatcher):
        options = sorted((k, _describe(v, depth + 1)) for k, v in value.targetoptions.items())
        return ("dispatcher", _describe(value.py_func, depth + 1), tuple(options))
    if isinstance(value, _Intrinsic):
        return ("intrinsic", _describe(value._defn, depth + 1))
    if isinstance(value, types.FunctionType):
        return _describe_function(value, depth)
    if isinstance(value, types.CodeType):
        return _describe_code(value, depth)
    if isinstance(value, type):
        return ("class", _class_name(value))
    if dataclasses.is_dataclass(value):
        return ("dataclass", _class_name(type(value)),
                tuple((f.name, _describe(getattr(value, f.name), depth + 1))
                      for f in dataclasses.fields(value)))
    if isinstance(value, (tuple, list, frozenset)):
        items = sorted(value, key=repr) if isinstance(value, frozenset) else value
        return (_class_name(type(value)), tuple(_describe(v, depth + 1) for v in items))
    raise Unnamed(f"a {type(value).__name__}")


def _memory(array):
    """The object that owns the memory of ``array`` (of its views too)."""
    while isinstance(array, np.ndarray) and array.base is not None:
        array = array.base
    return array


def _class_name(cls):
    return f"{cls.__module__}.{cls.__qualname__}"


def _describe_function(function, depth):
    """A function of varint's sources (its globals are in the source digest),
    of a generated module read from its file (named by its module), or of
    generated code without a file (an accumulator's compiled rule:
    then every global it names, described too): its code and, recursively,
    its cells."""
    code = function.__code__
    if codecache.named_by_file(function):
        # A generated module read from its verified file: its name is a hash
        # of everything its source is made from, so it names the helpers
        # the function calls through the module's globals too.
        return ("generated", function.__module__, function.__qualname__,
                _describe_code(code, depth + 1),
                tuple(_describe(c.cell_contents, depth + 1) for c in function.__closure__ or ()),
                _describe(function.__defaults__ or (), depth + 1))
    if code.co_filename.startswith("<"):
        scope = function.__globals__
        names = tuple((name, _global(scope[name], depth + 1)) for name in code.co_names
                      if name in scope)
    else:
        try:
            path = Path(code.co_filename).resolve()
            inside = any(path.is_relative_to(folder) for folder in _SOURCES)
        except (OSError, ValueError):
            inside = False
        if not inside:
            raise Unnamed(f"the function {function.__qualname__} outside varint's sources")
        names = ()
    cells = tuple(_describe(c.cell_contents, depth + 1) for c in function.__closure__ or ())
    defaults = _describe(function.__defaults__ or (), depth + 1)
    return ("function", function.__module__, function.__qualname__,
            _describe_code(code, depth + 1), cells, defaults, names)


def _global(value, depth):
    """A global of generated code: a module (math, numpy: what numba
    compiles of them is numba's) by its name, anything else described."""
    if isinstance(value, types.ModuleType):
        return ("module", value.__name__)
    return _describe(value, depth)


def _describe_code(code, depth):
    digest = hashlib.sha256(code.co_code).hexdigest()
    consts = tuple(_describe(c, depth + 1) for c in code.co_consts)
    return ("code", digest, consts, code.co_names, code.co_freevars)


class _ClosureCache(codecache.SignedCache):
    """numba's cache of one closure kernel, its entries found by
    :func:`closure_key` instead of its pickled cells, its files signed with
    ``secret`` in ``folder``; a failure to write is a warning, one to read
    (or to verify) a recompilation."""

    def __init__(self, py_func, key, secret, folder):
        super().__init__(py_func, secret, folder)
        self._closure_key = key

    def _index_key(self, sig, codegen):
        code = hashlib.sha256(self._py_func.__code__.co_code).hexdigest()
        return (sig, codegen.magic_tuple(), (code, self._closure_key))

    def save_overload(self, sig, data):
        if getattr(data.library, "has_dynamic_globals", False):
            # A kernel holding pointers of this process (e.g. a compiled
            # right-hand side's) cannot be cached: it stays compiled in
            # memory, as before, without numba's warning in every run.
            return
        super().save_overload(sig, data)

"""Generated code and data in the cache directory, verified before use.

varint writes Python source it generated (steppers, model kernels) and
small JSON facts to the private cache directory (:mod:`varint.cachedir`),
and numba writes its compiled copies beside the source. All of it is read
back by later processes, so all of it is signed here and checked before
anything runs:

* a file is written as one header line ``# varint-signed <HMAC>`` and its
  content (a comment to Python, so a generated module's line numbers stay
  those of its file); the HMAC covers the file's folder, name and content
  (:func:`varint.cachedir.sign`);
* a generated module is executed from the very bytes that were verified
  (never re-read from disk, never from a ``.pyc``), and only after the check;
  its compiled code is kept beside it as a signed file of its own
  (:func:`_compiled`: compiling a stepper's source costs more than the rest
  of loading it), used only once its signature verifies and only for the
  verified source, file name and Python it was compiled from;
* numba's cache files of a generated module (``*.nbi``, ``*.nbc``: pickles
  that numba loads) are written signed by :class:`SignedCache` and
  unpickled only after their MAC verifies;
* a file that fails its check (tampered, truncated, written by another user
  or with another secret) is discarded with one :class:`CacheDirWarning`
  and rebuilt; an unpickling error of a verified file (another numba) is a
  discard and a recompilation, never an error of the run;
* a compiled kernel is used only for what it was compiled for: numba's
  index (what → data file) and data files are written one after the other,
  so two processes caching two versions of one function at once (two
  closures, two signatures: the test suite's workers on a cold cache) can
  leave an index entry naming the other's code — which then ran, giving
  other bits or writing past a buffer. A generated kernel's data file
  carries its index key, and a package kernel's compiled signature is
  compared with the one asked for (:class:`_TolerantCache`); a file that
  does not match is a cache miss (compiled again and written over);
* compiled code has symbol names no other process gives other code
  (:func:`unique_symbol_names`): numba names a function by its qualified
  name and a counter of the process, so the same closure with other
  constants, compiled by two processes, had one name, and a process that
  loaded both from the cache ran the first one's helper in the second;
* a cache that cannot be written (full disk, read-only, no private
  directory) costs the cache, not the run: the module is compiled in memory
  (numba's on-disk caching off) after one warning.

What the signature protects against, and what not, is in
:mod:`varint.cachedir`.
"""

from __future__ import annotations

import ast
import contextlib
import hashlib
import importlib.util
import io
import json
import marshal
import os
import pickle
import secrets
import sys
import threading
import types
from pathlib import Path

from numba.core import bytecode, caching, sigutils
from numba.core.dispatcher import Dispatcher

from . import cachedir, collector
from .cachedir import CacheDirWarning, warn_once
from .files import atomic_write

__all__ = ["load_module", "module_on_disk", "in_disk_cache", "read_json", "write_json", "read_signed", "write_signed",
           "tolerate_full_disks", "SignedCache", "numba_hooks_present", "HEADER",
           "CacheDirWarning", "unique_symbol_names", "named_by_file"]

#: One generated module is loaded at a time: threads of one process (a Dask
#: worker's) ask for the same kernels at once, and CPython 3.11's AST
#: conversion is not thread-safe (two such threads raised SystemError).
_LOAD_LOCK = threading.RLock()

#: The file of each generated module this process executed from a verified
#: cache file, by module name: a module whose name names everything its
#: source is made from (:func:`load_module`), so a kernel compiled from its
#: functions may be keyed by that name (:func:`named_by_file`).
_FROM_FILE: dict[str, str] = {}

#: First bytes of every signed file; the hex HMAC and a newline follow.
HEADER = b"# varint-signed "
_MAC_LEN = 64


def _label(path):
    """What a file's MAC covers besides its content: its folder and name."""
    path = Path(path)
    return f"{path.parent.name}/{path.name}"


def write_signed(path, content, key=None):
    """Write ``content`` (str or bytes) to ``path`` atomically, signed with
    ``key`` (by default the cache directory's secret).

    Raises
    ------
    OSError
        If it cannot be written or no secret can be kept.
    """
    data = content.encode() if isinstance(content, str) else content
    mac = cachedir.sign(_label(path), data, key)
    atomic_write(path, HEADER + mac.encode() + b"\n" + data)


def read_signed(path, what="cache file", key=None):
    """The content (bytes) of the signed file ``path`` if it verifies with
    ``key`` (by default the cache directory's secret); None if there is
    none, or if it fails (then it is deleted with one warning naming it:
    it is rebuilt by the caller)."""
    try:
        blob = Path(path).read_bytes()
    except FileNotFoundError:
        return None
    except OSError as exc:
        _discard(path, what, f"it cannot be read ({exc.strerror or exc})", delete=False)
        return None
    head, sep, data = blob.partition(b"\n")
    mac = head[len(HEADER):]
    if not (sep and head.startswith(HEADER) and len(mac) == _MAC_LEN):
        why = "it is empty" if not blob else "it has no valid signature line"
        _discard(path, what, why)
        return None
    if not cachedir.verify(_label(path), data, mac, key):
        _discard(path, what, "its signature does not match its content (edited, damaged, "
                 "truncated, or written by another user or with another secret)")
        return None
    return data


def _discard(path, what, why, delete=True):
    warn_once(("discard", str(path), why),
              f"varint {what} {path} is not used: {why}; it is "
              + ("deleted and rebuilt" if delete else "rebuilt in memory"), stacklevel=5)
    if delete:
        with contextlib.suppress(OSError):
            os.unlink(path)


def _unwritable(where, exc):
    warn_once(("unwritable", str(where)),
              f"cannot write varint's cache in {where} ({exc.strerror or exc}); generated "
              "kernels are compiled in memory, so later processes compile them again",
              stacklevel=5)


# -- JSON facts ------------------------------------------------------------------

def read_json(folder, name, what="cache file"):
    """The JSON value signed in ``<cache>/<folder>/<name>``, or None (absent,
    failed its check, or not JSON: then deleted with a warning)."""
    directory = cachedir.subdir(folder)
    if directory is None:
        return None
    path = directory / name
    data = read_signed(path, what)
    if data is None:
        return None
    try:
        return json.loads(data)
    except ValueError as exc:
        _discard(path, what, f"it is not JSON ({exc})")
        return None


def write_json(folder, name, value):
    """Sign and write ``value`` as JSON to ``<cache>/<folder>/<name>``;
    returns False (after one warning) if the cache cannot be written."""
    directory = cachedir.subdir(folder)
    if directory is None:
        return False
    try:
        write_signed(directory / name, json.dumps(value))
    except OSError as exc:
        _unwritable(directory, exc)
        return False
    return True


# -- generated modules -----------------------------------------------------------------

def load_module(name, folder, make_source, extra_globals=None, on_disk=True):
    """Import the generated module ``name`` from ``<cache>/<folder>/<name>.py``.

    Parameters
    ----------
    name : str
        Module name; it must name everything the source is made from (a
        hash), since a verified file of that name is used as it is.
    folder : str
        Subdirectory of the cache directory.
    make_source : callable
        Returns the source (str) when the file is absent or discarded.
    extra_globals : dict, optional
        Set in the module before its code runs.
    on_disk : bool, default True
        False: compiled in memory, nothing read from or written to the
        cache (a module whose name is valid in this process only).

    Returns
    -------
    module
        Registered in ``sys.modules`` under ``name`` (numba's cache finds a
        kernel's globals by module name).
    """
    with _LOAD_LOCK:
        tolerate_full_disks()
        if not on_disk:
            return _execute(name, make_source().encode(), None, extra_globals)
        return _load(name, folder, make_source, extra_globals)


def module_on_disk(name, folder):
    """Whether the generated module ``name`` has a file in
    ``<cache>/<folder>`` (not whether it is valid: :func:`load_module`
    verifies it before anything of it runs)."""
    directory = cachedir.subdir(folder)
    return directory is not None and (directory / f"{name}.py").is_file()


def in_disk_cache(dispatcher):
    """Whether numba's disk cache holds compiled code of ``dispatcher`` (a
    kernel compiled with ``cache=True``) for its present source: its index
    read (a small pickle, checked against the source file's stamp),
    nothing compiled or loaded. False where it has no disk cache or the
    index cannot be read (numba then compiles it at its first call)."""
    cache_file = getattr(getattr(dispatcher, "_cache", None), "_cache_file", None)
    if cache_file is None:
        return False
    try:
        return bool(cache_file._load_index())
    except Exception:   # (another numba's layout, an unreadable file: as absent)
        return False


def _load(name, folder, make_source, extra_globals):
    directory = cachedir.subdir(folder)
    # The secret of the directory the files are in, kept by the module's
    # kernels for numba's files, whatever the cache directory later is.
    key = None if directory is None else cachedir.secret()
    path = None if key is None else directory / f"{name}.py"
    data = None if path is None else read_signed(path, "generated kernel file", key)
    if data is None:
        # numba's files of a discarded module are kept: they are verified on
        # their own, and numba uses them only for the source they were
        # compiled from (its stamp), which is what is written again.
        data = make_source().encode()
        if path is not None:
            try:
                write_signed(path, data, key)
            except OSError as exc:
                _unwritable(path.parent, exc)
                path = None
        elif directory is not None:
            _unwritable(directory, OSError("no secret can be kept to sign it"))
        # (directory None: cachedir has said why, once.)
    return _execute(name, data, path, extra_globals, key)


def _execute(name, data, path, extra_globals, key=None):
    """Run the source ``data`` (bytes) as the module ``name``: from the
    bytes given, never re-read from disk nor from a ``.pyc``. ``path``: the
    verified file they came from, whose kernels numba caches signed (the
    code is compiled one line down, as it stands in the file below its
    signature line; ``key`` signs numba's files); None: compiled in memory,
    numba's disk caching off."""
    module = types.ModuleType(name)
    module.__dict__.update(extra_globals or {})
    if path is None:
        tree = _without_disk_cache(ast.parse(data, filename=f"<varint {name}>"))
        code = compile(tree, f"<varint {name}>", "exec", dont_inherit=True)
    else:
        module.__file__ = str(path)
        code = _compiled(data, path, key)
    sys.modules[name] = module
    try:
        exec(code, module.__dict__)  # verified above, or generated in this process
    except BaseException:
        sys.modules.pop(name, None)
        raise
    if path is not None:
        _sign_numba_caches(module, key)
        _FROM_FILE[name] = str(path)
    return module


def _compiled(data, path, key):
    """The code object of the verified source ``data`` of the file ``path``,
    read back from its signed code file if one was written for exactly
    that, else compiled now and written for the next process.

    The code file (``<module>.<cache tag>.code`` beside the source) holds
    :func:`_code_tag` and the marshalled code. It is unmarshalled only
    after its MAC verifies (key ``key``, as every file here), and used only
    if its tag is the one of ``data``: a code file of another source (the
    module was rebuilt), another location of the cache directory (the
    code names its file, where numba keeps its kernels' caches) or another
    Python is compiled again and written over. What marshal reads is
    therefore bytes this user's varint wrote for these verified bytes; a
    code file that fails its check is discarded with a warning, as any.
    """
    tag = _code_tag(data, path)
    code_path = path.with_name(f"{path.stem}.{sys.implementation.cache_tag}.code")
    blob = read_signed(code_path, "compiled kernel file", key)
    if blob is not None and blob.startswith(tag + b"\n"):
        try:
            return marshal.loads(blob[len(tag) + 1:])
        except (EOFError, ValueError, TypeError) as exc:  # verified: another Python's
            _discard(code_path, "compiled kernel file", f"it cannot be read ({exc})")
    # One blank line for the signature line above the code in the file.
    code = compile(b"\n" + data, str(path), "exec", dont_inherit=True)
    try:
        write_signed(code_path, tag + b"\n" + marshal.dumps(code), key)
    except OSError as exc:
        _unwritable(code_path.parent, exc)
    return code


def _code_tag(data, path):
    """What a code object compiled by :func:`_compiled` depends on (hex
    SHA-256, bytes): the source ``data``, the file name compiled into it,
    the bytecode's version (:data:`importlib.util.MAGIC_NUMBER`) and the
    optimisation level (``-O`` drops ``assert``)."""
    h = hashlib.sha256()
    for part in (importlib.util.MAGIC_NUMBER, str(sys.flags.optimize).encode(),
                 str(path).encode(), data):
        h.update(len(part).to_bytes(8, "little"))
        h.update(part)
    return h.hexdigest().encode()


def named_by_file(function):
    """Whether ``function`` is code of a generated module this process
    executed from its verified file: its module's name then names its
    source (a hash of what the source is made from, :func:`load_module`).
    Modules compiled in memory (named for this process only) are not."""
    path = _FROM_FILE.get(getattr(function, "__module__", None))
    return path is not None and function.__code__.co_filename == path


def _without_disk_cache(tree):
    """``tree`` with every ``cache=True`` keyword of a decorator call set to
    False: numba cannot cache code that has no file."""
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            for deco in node.decorator_list:
                if isinstance(deco, ast.Call):
                    for kw in deco.keywords:
                        if kw.arg == "cache":
                            kw.value = ast.Constant(False)
    return ast.fix_missing_locations(tree)


# -- numba's cache of varint's own kernels ---------------------------------------------

_SWEPT: set = set()


def tolerate_full_disks():
    """Make a failure to write numba's cache of varint's own (package)
    kernels a warning, not an error of the run: numba raises the raw
    ``OSError`` of a full or read-only disk from inside a compilation.
    Applies to every varint module imported so far (cheap: each kernel's
    cache is wrapped once, :class:`_TolerantCache`)."""
    for name, module in list(sys.modules.items()):
        if not (name == "varint" or name.startswith(("varint.", "varint_"))) or name in _SWEPT:
            continue
        _SWEPT.add(name)
        for value in list(vars(module).values()):
            if isinstance(value, Dispatcher) and \
                    isinstance(getattr(value, "_cache", None), caching.FunctionCache) and \
                    not isinstance(value._cache, SignedCache):
                value._cache = _TolerantCache(value._cache)


class _TolerantCache:
    """numba's cache of one kernel, whose failures to write cost a warning,
    and whose loaded code is used only if it was compiled for the
    signature asked for.

    numba's index and data files are written one after the other, so two
    processes caching two signatures of one kernel at once can leave the
    index naming the other signature's code for this one (seen: a kernel
    for contiguous arrays run on a strided one). The signature is in the
    data; a mismatch is a cache miss: the kernel is compiled and written
    over the foreign file (its index entry names it)."""

    def __init__(self, cache):
        self._inner = cache

    def __getattr__(self, name):
        return getattr(self._inner, name)

    def load_overload(self, sig, target_context):
        with collector.held():       # loading, not compiling (a miss returns None)
            cres = self._inner.load_overload(sig, target_context)
        if cres is None:
            return None
        args, _ = sigutils.normalize_signature(sig)
        return cres if tuple(cres.signature.args) == tuple(args) else None

    def save_overload(self, sig, data):
        try:
            self._inner.save_overload(sig, data)
        except OSError as exc:
            _unwritable(self._inner.cache_path, exc)


# -- symbol names unique across processes ------------------------------------------------

class _RandomIds:
    """An endless iterator of random 63-bit ids, drawn from the system's
    entropy at each step (so forked children do not repeat their parent's,
    as a copied counter or seed would)."""

    def __iter__(self):
        return self

    def __next__(self):
        return secrets.randbits(63)


def unique_symbol_names():
    """Make the symbol names of code numba compiles from now on, in this
    process, unique across processes.

    numba names a compiled function by its qualified name, its argument
    types and an id drawn from a counter of the process
    (``FunctionIdentity._unique_ids``), counting from 1 in every process.
    Two closures of one function (KG's and FPUT's stencil kick, their
    helpers) compiled by two processes in the same order get one name for
    two bodies. A process that loads both from the disk cache links the
    second against the first one's helpers (LLVM merges same-named weak
    definitions): the second kernel runs with the first one's constants
    and sizes — other bits, or writes past a buffer (numba issue 10486).
    Random 63-bit ids make a shared name as unlikely as a hash collision.
    Applied once, when this module is imported (before varint compiles a
    kernel: the closure kernels' module imports it); a numba without that
    counter is left as it is (its names are its own affair)."""
    if isinstance(getattr(bytecode.FunctionIdentity, "_unique_ids", None), _RandomIds):
        return
    if hasattr(bytecode.FunctionIdentity, "_unique_ids"):
        bytecode.FunctionIdentity._unique_ids = _RandomIds()


unique_symbol_names()


# -- numba's cache of generated modules -------------------------------------------------

#: The parts of numba's cache that :class:`_SignedCacheFile` replaces: with
#: another numba that lacks one, generated kernels are not cached on disk
#: (numba itself would then read signed files as plain pickles).
_NUMBA_HOOKS = ("_load_index", "_save_index", "_load_data", "_save_data", "_open_for_write",
                "_dump", "_data_path")


def numba_hooks_present():
    """Whether this numba's cache is the one :class:`_SignedCacheFile` knows
    (else numba would read signed files as plain pickles)."""
    return (all(hasattr(caching.IndexDataCacheFile, name) for name in _NUMBA_HOOKS)
            and hasattr(caching.FunctionCache, "load_overload"))


def _sign_numba_caches(module, key):
    """Give every cached kernel defined in ``module`` a :class:`SignedCache`
    (signing with ``key``) before it is first called (numba loads its cache
    at the first call); if this numba's cache is not the one
    :class:`_SignedCacheFile` knows, switch its disk cache off."""
    usable = numba_hooks_present()
    for value in vars(module).values():
        if not isinstance(value, Dispatcher):
            continue
        if getattr(value.py_func, "__module__", None) != module.__name__:
            continue            # a kernel of varint's package, passed in
        if isinstance(getattr(value, "_cache", None), caching.FunctionCache):
            try:
                if not usable:
                    raise NotImplementedError("another numba cache layout")
                value._cache = SignedCache(value.py_func, key)
            except Exception:   # no usable location: compile in memory
                value._cache = caching.NullCache()


class SignedCache(caching.FunctionCache):
    """numba's per-function cache, with files signed by varint's secret and
    every failure to read or write one turned into a recompilation or a
    warning.

    Parameters
    ----------
    py_func : function
        The kernel's Python function.
    key : bytes
        The secret that signs and verifies its files.
    folder : Path, optional
        Where its files are kept; by default where numba would keep them
        (beside a generated module, in the cache directory).
    """

    def __init__(self, py_func, key, folder=None):
        super().__init__(py_func)
        if folder is not None:
            self._cache_path = str(folder)
        self._cache_file = _SignedCacheFile(
            cache_path=self._cache_path, filename_base=self._impl.filename_base,
            source_stamp=self._impl.locator.get_source_stamp())
        self._cache_file.key = key

    def load_overload(self, sig, target_context):
        try:
            with collector.held():   # loading, not compiling (a miss returns None)
                return super().load_overload(sig, target_context)
        except Exception as exc:   # verified, but not loadable by this numba
            self._cache_file.discard(self._cache_file._index_path,
                                     f"numba could not load it ({type(exc).__name__}: {exc})")
            return None

    def save_overload(self, sig, data):
        try:
            super().save_overload(sig, data)
        except OSError as exc:
            _unwritable(self._cache_path, exc)


class _SignedCacheFile(caching.IndexDataCacheFile):
    """numba's index and data files, each written as ``HEADER``, the HMAC
    of its name and content, and numba's own bytes; read back only when the
    HMAC verifies. A data file holds its index key with the compiled code,
    and is used only for that key.

    numba writes an entry as: read the index, pick the first free data file
    number, write the index, write the data. Two processes saving two keys
    of one function at once (two closures of one kernel: KG's and FPUT's
    part steppers, compiled by two test workers on a cold cache) can both
    pick number 1, and the index left by one then names the data left by
    the other: that kernel, with other constants and sizes, ran for it. The
    key in the data turns this into a cache miss; the kernel compiled again
    is written over that file (the index names it for its key)."""

    #: The secret that signs them (set by :class:`SignedCache`).
    key = None

    def save(self, key, data):
        super().save(key, (key, data))

    def load(self, key):
        entry = super().load(key)
        # Another key's code (two processes saved at once), or a file of a
        # varint that did not store the key: a miss, never that code.
        if isinstance(entry, tuple) and len(entry) == 2 and entry[0] == key:
            return entry[1]
        return None

    def _read(self, path):
        """The verified content of ``path``; FileNotFoundError if absent or
        discarded."""
        data = read_signed(path, "numba cache file", self.key)
        if data is None:
            raise FileNotFoundError(path)
        return data

    def discard(self, path, why):
        _discard(path, "numba cache file", why)

    def _load_index(self):
        try:
            data = self._read(self._index_path)
        except FileNotFoundError:
            return {}
        try:
            stream = io.BytesIO(data)
            version = pickle.load(stream)
            if version != self._version:
                return {}
            stamp, overloads = pickle.loads(stream.read())
        except Exception as exc:  # verified: written by us, by another numba
            self.discard(self._index_path, f"it cannot be read ({type(exc).__name__})")
            return {}
        return overloads if stamp == self._source_stamp else {}

    def _save_index(self, overloads):
        stream = io.BytesIO()
        pickle.dump(self._version, stream, protocol=-1)
        stream.write(self._dump((self._source_stamp, overloads)))
        self._write(self._index_path, stream.getvalue())

    def _load_data(self, name):
        path = self._data_path(name)
        data = self._read(path)
        try:
            return pickle.loads(data)
        except Exception as exc:
            self.discard(path, f"it cannot be read ({type(exc).__name__})")
            raise FileNotFoundError(path) from None

    def _save_data(self, name, data):
        self._write(self._data_path(name), self._dump(data))

    def _write(self, path, data):
        mac = cachedir.sign(_label(path), data, self.key)
        with self._open_for_write(path) as f:
            f.write(HEADER + mac.encode() + b"\n" + data)


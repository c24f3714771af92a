"""Files written safely, and JSON written canonically: the two helpers every
writer in varint uses (checkpoints, chaos-map chunks, the reference cache,
generated kernels, the studies' results); and the import of generated
source (:func:`import_generated`).

:func:`atomic_file` writes to a temporary file in the target's directory,
flushes it to disk (``fsync``), moves it over the target with
:func:`os.replace` and syncs the directory, so at every instant the path
holds either the old complete file or the new one — never half of one,
even if the process is killed or the machine loses power.

:func:`canonical` is the one JSON form of parameters (sorted keys; NumPy
arrays and scalars as lists and numbers): two descriptions of the same run
compare equal, and hash equal, whichever way they were built.
"""

from __future__ import annotations

import contextlib
import importlib.util
import json
import os
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np

__all__ = ["atomic_file", "atomic_write", "canonical", "canonical_json", "jsonable",
           "import_generated"]


def jsonable(obj):
    """``obj`` with NumPy arrays and scalars, tuples and non-string keys
    turned into what JSON holds (non-finite floats stay floats)."""
    if isinstance(obj, dict):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    return obj


def canonical_json(obj, indent=None):
    """``obj`` as JSON text with sorted keys (see :func:`jsonable`).

    Raises
    ------
    TypeError
        If ``obj`` holds something JSON cannot (the message says what).
    """
    try:
        return json.dumps(jsonable(obj), sort_keys=True, indent=indent)
    except TypeError as exc:
        raise TypeError(f"not JSON data ({exc}); descriptions must be numbers, strings, lists "
                        "and dicts") from exc


def canonical(obj):
    """``obj`` as it reads back from :func:`canonical_json` (tuples become
    lists, NumPy scalars Python numbers), so a fresh description compares
    equal to a stored one."""
    plain = _plain(obj)
    return json.loads(canonical_json(obj)) if plain is _NOT_PLAIN else plain


_NOT_PLAIN = object()
_SCALARS = (str, int, float, bool, type(None))


def _plain(obj):
    """What :func:`canonical` returns, built directly (keys sorted, a new
    container) when ``obj`` holds only dicts with string keys, lists and
    Python scalars — a run's options, whose JSON round trip cost more than
    the rest of its provenance; else ``_NOT_PLAIN``."""
    if type(obj) in _SCALARS:
        return obj
    if type(obj) is dict:
        if not all(type(key) is str for key in obj):
            return _NOT_PLAIN
        out = {}
        for key in sorted(obj):          # as json.dumps(sort_keys=True)
            value = _plain(obj[key])
            if value is _NOT_PLAIN:
                return _NOT_PLAIN
            out[key] = value
        return out
    if type(obj) is list:
        out = [_plain(v) for v in obj]
        return _NOT_PLAIN if any(v is _NOT_PLAIN for v in out) else out
    return _NOT_PLAIN


@contextlib.contextmanager
def atomic_file(path, mode="wb"):
    """Open a temporary file that replaces ``path`` when the block ends
    without an exception (see the module docstring); on an exception the
    temporary file is removed and ``path`` is left as it was.

    Raises
    ------
    OSError
        If the directory cannot be written.
    """
    path = os.fspath(path)
    directory = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(prefix=f".{os.path.basename(path)}.", suffix=".tmp",
                               dir=directory)
    try:
        with os.fdopen(fd, mode) as f:
            yield f
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
    _fsync_directory(directory)


def atomic_write(path, data):
    """Write ``data`` (bytes or str) to ``path`` atomically."""
    with atomic_file(path, "wb" if isinstance(data, bytes) else "w") as f:
        f.write(data)


def _fsync_directory(directory):
    # Makes the rename itself durable (POSIX); not possible on every platform.
    with contextlib.suppress(OSError, AttributeError):
        fd = os.open(directory, os.O_RDONLY | os.O_DIRECTORY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def import_generated(folder, name, source, extra_globals=None, module=None, stacklevel=3):
    """Import the generated module ``name`` (or ``module``) from
    ``folder/name.py``.

    The file is written (atomically) when it is missing — and, when
    ``source`` is the text itself rather than a function that makes it,
    when it holds anything else — so a new process imports the file an
    earlier one wrote, and numba finds the kernels it cached beside it
    (by module name: the module is entered in ``sys.modules``).
    ``extra_globals`` are set in the module before it runs. A folder that
    cannot be written costs the on-disk caches, not the run: a warning, and
    a temporary folder (the warning points ``stacklevel`` frames up).
    """
    text = source if isinstance(source, str) else None
    try:
        Path(folder).mkdir(parents=True, exist_ok=True)
        path = Path(folder) / f"{name}.py"
        # Rewriting an identical file would only invalidate numba's cache.
        if not path.exists() or (text is not None and path.read_text() != text):
            atomic_write(path, text if text is not None else source())
    except OSError as exc:
        warnings.warn(f"cannot write generated kernels to {folder} ({exc}); compiling them in a "
                      "temporary directory", RuntimeWarning, stacklevel=stacklevel)
        path = Path(tempfile.mkdtemp(prefix="varint-")) / f"{name}.py"
        path.write_text(text if text is not None else source())
    spec = importlib.util.spec_from_file_location(module or name, path)
    loaded = importlib.util.module_from_spec(spec)
    loaded.__dict__.update(extra_globals or {})
    sys.modules[spec.name] = loaded
    spec.loader.exec_module(loaded)
    return loaded

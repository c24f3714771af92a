"""An on-disk cache of results, so a reference solution is computed once.

A result is stored under the hash of everything that determines it: the
kind of run, the model's description, the initial state, the times, the
method with its options, every other argument, and the versions of the
packages and of varint's own source. Change any of them and the key changes.

Entries are written atomically (:func:`varint.files.atomic_file`), so a
reader never sees half a file. Each entry carries the SHA-256 of its payload;
an entry that is truncated or corrupt fails that check, is reported with a
warning naming the file, deleted and recomputed — never used.

The cache lives in ``$VARINT_CACHE_DIR`` if set, else in the platform's
per-user cache directory (:func:`cache_dir`). Deleting the directory is
always safe.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import io
import warnings
from pathlib import Path

import numpy as np

from .files import atomic_write, canonical_json
from .paths import cache_dir
from .results import load_result, package_versions

__all__ = ["cache_dir", "cache_key", "cached", "reference", "CacheWarning"]

_MAGIC = b"varint-cache-1\n"
_KINDS = ("integrate", "lyapunov_spectrum", "gali", "sali")


class CacheWarning(UserWarning):
    """A cache entry was unreadable and is being recomputed."""


@functools.cache
def _source_digest():
    # Results depend on varint's code as well as on its version number, which
    # does not change with every edit: hash the sources themselves.
    from . import baselines

    h = hashlib.sha256()
    for name, folder in (("varint", Path(__file__).resolve().parent),
                         ("varint.baselines", Path(baselines.__file__).resolve().parent)):
        for path in sorted(folder.rglob("*.py")):
            if name == "varint" and "baselines" in path.relative_to(folder).parts:
                continue  # an installed copy, hashed as varint.baselines
            h.update(f"{name}/{path.relative_to(folder)}".encode())
            h.update(path.read_bytes())
    return h.hexdigest()


def _canonical(obj):
    """JSON-able form of the key parts; arrays become nested lists of exact
    floats (``json`` writes the shortest repr that round-trips)."""
    if isinstance(obj, dict):
        return {str(k): _canonical(v) for k, v in sorted(obj.items(), key=lambda kv: str(kv[0]))}
    if isinstance(obj, (list, tuple)):
        return [_canonical(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return {"array": _canonical(obj.tolist()), "dtype": str(obj.dtype)}
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, float) and not np.isfinite(obj):
        return repr(obj)
    if obj is None or isinstance(obj, (bool, int, float, str)):
        return obj
    describe = getattr(obj, "describe", None)
    if callable(describe):  # models, schemes
        return _canonical(describe())
    raise TypeError(f"cannot use {type(obj).__name__} {obj!r} in a cache key")


def cache_key(parts) -> str:
    """SHA-256 (hex) of ``parts`` plus the package versions and varint's source.

    Parameters
    ----------
    parts : dict
        Everything that determines the result (models and schemes may appear
        as objects: their ``describe()`` is used).
    """
    versions = package_versions("heyoka", "scikit-sundae")
    payload = {"parts": _canonical(parts), "versions": versions, "source": _source_digest()}
    return hashlib.sha256(canonical_json(payload).encode()).hexdigest()


def _entry(key):
    return cache_dir() / "results" / f"{key}.bin"


def _read(path):
    """The result stored at ``path``; None if absent or unreadable; raises
    ValueError if the entry is damaged."""
    try:
        blob = path.read_bytes()
    except OSError:  # absent, or the cache cannot be read at all
        return None
    header, sep, rest = blob.partition(b"\n")
    if not blob.startswith(_MAGIC) or not sep:
        raise ValueError("not a varint cache entry")
    digest, sep, payload = rest.partition(b"\n")
    if not sep or hashlib.sha256(payload).hexdigest().encode() != digest:
        raise ValueError("checksum mismatch (truncated or corrupt)")
    return load_result(io.BytesIO(payload))


def _write(path, result):
    buf = io.BytesIO()
    result.save(buf)
    payload = buf.getvalue()
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write(path, _MAGIC + hashlib.sha256(payload).hexdigest().encode() + b"\n" + payload)


def cached(parts, compute):
    """The result for ``parts`` from the cache, or ``compute()`` stored there.

    Parameters
    ----------
    parts : dict
        Everything that determines the result (see :func:`cache_key`).
    compute : callable
        Returns the result (any varint result object) when it is not cached.

    Warns
    -----
    CacheWarning
        When an entry is damaged (it is deleted and recomputed), or cannot
        be written (the result is returned all the same).
    """
    path = _entry(cache_key(parts))
    try:
        result = _read(path)
    except Exception as exc:  # a damaged entry must never be used
        warnings.warn(f"varint cache entry {path} is unreadable ({exc}); recomputing it",
                      CacheWarning, stacklevel=2)
        with contextlib.suppress(OSError):
            path.unlink()
        result = None
    if result is None:
        result = compute()
        try:
            _write(path, result)
        except OSError as exc:  # a read-only or full disk costs speed, not the result
            warnings.warn(f"could not write varint cache entry {path} ({exc})", CacheWarning,
                          stacklevel=2)
    return result


def reference(model, x0, t_end, tau=0.05, kind="integrate", method="taylor",
              precision="extended", **kwargs):
    """A cached run, by default the extended-precision Taylor reference.

    Parameters
    ----------
    model : Model
    x0 : array_like
    t_end, tau : float
    kind : {"integrate", "lyapunov_spectrum", "gali", "sali"}
        Which public run function to call.
    method : str, default "taylor"
    precision : {"extended", "double"}
        Passed to the Taylor method (ignored for other methods).
    **kwargs
        Passed to the run function (``deviations``, ``n_exponents``,
        ``seed``, ``t_out``, method options, …).

    Returns
    -------
    The run function's result, from the cache when it was computed before
    with exactly these inputs and package versions.

    Examples
    --------
    >>> import numpy as np, varint
    >>> from varint.cache import reference
    >>> model, x0 = varint.paper_orbit("R1")
    >>> ref = reference(model, x0, 10.0, deviations=np.eye(4))   # doctest: +SKIP
    """
    import varint

    if kind not in _KINDS:
        raise ValueError(f"unknown kind {kind!r}; expected one of: {', '.join(_KINDS)}")
    if method == "taylor":
        kwargs["precision"] = precision
    kwargs.setdefault("progress", False)
    parts = {"kind": kind, "model": model, "x0": np.asarray(x0, dtype=float),
             "t_end": float(t_end), "tau": float(tau), "method": method,
             "kwargs": {k: v for k, v in kwargs.items() if k != "progress"}}
    run = getattr(varint, kind)
    return cached(parts, lambda: run(model, x0, t_end, tau=tau, method=method, **kwargs))

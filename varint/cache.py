"""An on-disk cache of results, so a reference solution is computed once.

A result is stored under the hash of everything that determines it: the
kind of run, the model's description, the initial state, the times, the
method with its options, every other argument, and the versions of the
packages and of varint's own source. Change any of them and the key changes.

Entries are written atomically (:func:`varint.files.atomic_file`), so a
reader never sees half a file, and each carries the key it was stored
under and an HMAC of that key and its content by the user's secret
(:mod:`varint.cachedir`). An entry is used only if its MAC verifies, its key
is the one asked for and it loads as a valid result
(:func:`varint.results.load_result`); any other entry (truncated, corrupt,
edited, moved from another key's name, written by another user) is
reported with a warning naming the file, deleted and recomputed — never
used.

The cache lives in the private cache directory (:func:`cache_dir`, checked
by :func:`varint.cachedir.private_dir`). Deleting the directory is always
safe.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import re
import warnings

import numpy as np

from . import cachedir
from .cachedir import CacheDirWarning
from .files import atomic_write, canonical_json
from .identity import source_digest
from .results import load_result, package_versions

__all__ = ["cache_dir", "cache_key", "cached", "reference", "CacheWarning"]

_MAGIC = b"varint-cache-2\n"
_KINDS = ("integrate", "lyapunov_spectrum", "gali", "sali")
_KEY = re.compile(rb"[0-9a-f]{64}\Z")

#: The configured cache directory (:func:`varint.cachedir.location`).
cache_dir = cachedir.location


class CacheWarning(CacheDirWarning):
    """A cache entry was unreadable and is being recomputed, or could not
    be written."""




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
    payload = {"parts": _canonical(parts), "versions": versions, "source": source_digest()}
    return hashlib.sha256(canonical_json(payload).encode()).hexdigest()


def _entry(key):
    folder = cachedir.subdir("results")
    return None if folder is None else folder / f"{key}.bin"


def _label(path):
    return f"results/{path.name}"


def _read(path, key=None):
    """The result stored at ``path`` for ``key`` (by default the one its
    name says); None if absent or unreadable; raises ValueError (saying
    why) if the entry is damaged, foreign or another key's."""
    key = path.stem if key is None else key
    try:
        blob = path.read_bytes()
    except OSError:  # absent, or the cache cannot be read at all
        return None
    if not blob.startswith(_MAGIC):
        raise ValueError("not a varint cache entry" if blob else "it is empty")
    mac, sep, rest = blob[len(_MAGIC):].partition(b"\n")
    if not sep or not cachedir.verify(_label(path), rest, mac):
        raise ValueError("its signature does not match (truncated, corrupt, edited, or "
                         "written by another user)")
    stored, sep, payload = rest.partition(b"\n")
    if not sep or not _KEY.match(stored):
        raise ValueError("it holds no key")
    if stored.decode() != key:
        raise ValueError(f"it holds the result of another call (key {stored.decode()[:12]}…, "
                         f"not {key[:12]}…)")
    return load_result(io.BytesIO(payload))


def _write(path, key, result):
    buf = io.BytesIO()
    result.save(buf)
    rest = key.encode() + b"\n" + buf.getvalue()
    mac = cachedir.sign(_label(path), rest)
    atomic_write(path, _MAGIC + mac.encode() + b"\n" + rest)


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
    key = cache_key(parts)
    path = _entry(key)
    result = None
    if path is not None:
        try:
            result = _read(path, key)
        except Exception as exc:  # a damaged entry must never be used
            warnings.warn(f"varint cache entry {path} is unreadable ({exc}); recomputing it",
                          CacheWarning, stacklevel=2)
            with contextlib.suppress(OSError):
                path.unlink()
    if result is None:
        result = compute()
        if path is not None:
            try:
                _write(path, key, result)
            except OSError as exc:  # a read-only or full disk costs speed, not the result
                warnings.warn(f"could not write varint cache entry {path} ({exc})",
                              CacheWarning, stacklevel=2)
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

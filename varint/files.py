"""Files written safely, and JSON written canonically: the two helpers every
writer in varint uses (checkpoints, chaos-map chunks, the reference cache,
generated kernels, the studies' results, the command line's outputs).

:func:`atomic_file` writes to a temporary file in the target's directory,
flushes it to disk (``fsync``), moves it over the target with
:func:`os.replace` and syncs the directory, so at every instant the path
holds either the old complete file or the new one — never half of one,
even if the process is killed or the machine loses power. The temporary
file's name says who writes it (host and process id, then a random part:
:func:`temporary_owner`), so a writer never takes another's file for the
debris of a dead one. Moving a file over the path replaces a symbolic link
planted there instead of writing through it; :func:`output_file` opens a
user's output file that way (devices and pipes, such as ``/dev/stdout``,
are written directly).

:func:`canonical` is the one JSON form of parameters (sorted keys; NumPy
arrays and scalars as lists and numbers): two descriptions of the same run
compare equal, and hash equal, whichever way they were built.
"""

from __future__ import annotations

import contextlib
import errno
import hashlib
import json
import os
import re
import socket
import stat
import tempfile
from dataclasses import dataclass

import numpy as np

__all__ = ["atomic_file", "atomic_write", "canonical", "canonical_json", "jsonable",
           "output_file", "is_device_path", "temporary_owner", "DEVICE_DIRS", "digest"]


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


def _host():
    # Letters, digits, '-' only: the name is parsed back by temporary_owner.
    return re.sub(r"[^A-Za-z0-9-]", "-", socket.gethostname())[:64] or "host"


@dataclass(frozen=True)
class Owner:
    """Who writes a temporary file: a host and a process id there."""

    host: str
    pid: int

    def alive(self):
        """Whether the writer may still run (True unless it is a process of
        this host that no longer exists)."""
        if self.host != _host():
            return True
        try:
            os.kill(self.pid, 0)
        except ProcessLookupError:
            return False
        except OSError:       # exists, owned by someone else
            return True
        return True


def temporary_owner(name, path):
    """The :class:`Owner` encoded in the name of a temporary file of
    ``path`` made by :func:`atomic_file`, or None if it is not one."""
    base = re.escape(os.path.basename(os.fspath(path)))
    match = re.fullmatch(rf"\.{base}\.([A-Za-z0-9-]+)\.(\d+)\.[^.]+\.tmp",
                         os.path.basename(os.fspath(name)))
    return None if match is None else Owner(match.group(1), int(match.group(2)))


@contextlib.contextmanager
def atomic_file(path, mode="wb", permissions=None, newline=None):
    """Open a temporary file that replaces ``path`` when the block ends
    without an exception (see the module docstring); on an exception the
    temporary file is removed and ``path`` is left as it was.

    Parameters
    ----------
    path : str or os.PathLike
    mode : str
        ``"wb"`` or ``"w"``.
    permissions : int, optional
        Mode bits of the new file; by default 0600 (private: checkpoints,
        the cache). :func:`output_file` gives a user's outputs the usual
        ones (0666 less the umask).
    newline : str, optional
        As for :func:`open`, in text mode.

    Raises
    ------
    OSError
        If the directory cannot be written, or if the temporary file
        vanished before it could be moved into place (another process
        deleted it): the message says so.
    """
    path = os.fspath(path)
    directory = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(prefix=f".{os.path.basename(path)}.{_host()}.{os.getpid()}.",
                               suffix=".tmp", dir=directory)
    try:
        if permissions is not None:
            os.fchmod(fd, permissions)
        with os.fdopen(fd, mode, newline=newline) as f:
            yield f
            f.flush()
            os.fsync(f.fileno())
        try:
            os.replace(tmp, path)
        except FileNotFoundError as exc:
            if os.path.isdir(directory):
                raise OSError(exc.errno, f"its temporary file {tmp} was deleted by another "
                              "process before it could be moved into place") from None
            raise
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


def _umask():
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


#: Directories of device files: a path there (``/dev/stdout``, a link to
#: ``/proc/self/fd/1``) is written directly, never replaced.
DEVICE_DIRS = ("/dev", "/proc")


def is_device_path(path):
    """Whether ``path`` lies in :data:`DEVICE_DIRS` or is itself a character
    device or a pipe (not following a link)."""
    absolute = os.path.abspath(os.fspath(path))
    if any(absolute == d or absolute.startswith(d + os.sep) for d in DEVICE_DIRS):
        return True
    try:
        st = os.lstat(absolute)
    except OSError:
        return False
    return stat.S_ISCHR(st.st_mode) or stat.S_ISFIFO(st.st_mode)


@contextlib.contextmanager
def output_file(path, mode="w", newline=None):
    """Open a user's output file (``--csv``, ``--png``) for writing, without
    following a symbolic link planted at ``path``: the path is replaced
    atomically by a new file with the usual permissions (0666 less the
    umask), so whatever a link there pointed to is never written. A device
    or a pipe (``/dev/null``, ``/dev/stdout``: :func:`is_device_path`) is
    written directly.

    Raises
    ------
    OSError
        If it cannot be written.
    """
    if is_device_path(path):
        with open(path, mode, newline=newline) as f:
            yield f
        return
    if os.path.isdir(path) and not os.path.islink(path):
        raise OSError(errno.EISDIR, f"{os.fspath(path)} is a directory")
    with atomic_file(path, mode, permissions=0o666 & ~_umask(), newline=newline) as f:
        yield f


def digest(array):
    """A short, exact fingerprint of a float array (its bytes and shape)."""
    a = np.ascontiguousarray(array)
    h = hashlib.sha256(str((a.dtype.str, a.shape)).encode() + a.tobytes()).hexdigest()
    return f"sha256:{h[:32]}"

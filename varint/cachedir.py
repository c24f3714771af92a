"""The per-user cache directory: where it is, that it is private, and the
secret with which varint signs what it keeps there.

varint keeps generated code (the steppers of :mod:`varint.codegen.stepper`
and the kernels of :func:`varint.models.from_potential`), numba's compiled
copies of it, the symbolic facts of built-in models and cached reference
results in one directory (:func:`location`). Code found there is imported
and compiled code is unpickled by numba, so whoever can write that
directory can run code as the user: it must be the user's alone.

Threat model
------------
Guarded against:

* **another local user** who prepares the directory (a shared scratch path
  in ``$VARINT_CACHE_DIR``, with file names that are the same hashes on
  every machine) or plants files or symbolic links in it: a directory (or
  subdirectory) not owned by the user, or writable by group or others, is
  refused with one warning, and a private fallback is used
  (:func:`private_dir`); new directories are created 0700;
* **a damaged, truncated, hand-edited or foreign file** (copied from another
  user's or machine's cache): every file varint reads back from the cache
  carries an HMAC-SHA256 of its content and its name (:func:`sign`), keyed
  by a per-user secret of 32 random bytes kept 0600 in the directory
  (:func:`secret`). A file whose MAC does not verify is never executed,
  unpickled or trusted; it is discarded and rebuilt with a warning.

Not guarded against: a process running as the same user (it can read the
secret and sign what it likes: it could as well edit varint itself), the
superuser, and numba's own cache of varint's package kernels, which lives
beside the installed package as its bytecode does. Swapping the directory
between the checks and the use needs write access to a parent directory:
the fallback sits in the system's sticky temporary directory, where only
its owner can rename it.

Nothing here imports the rest of varint.
"""

from __future__ import annotations

import atexit
import contextlib
import errno
import hashlib
import hmac
import os
import shutil
import stat
import tempfile
import threading
import warnings
from pathlib import Path

__all__ = ["location", "private_dir", "subdir", "secret", "sign", "verify",
           "CacheDirWarning", "SECRET_FILE", "warn_once"]

#: The per-user secret's file name in the cache directory.
SECRET_FILE = "secret.key"
_SECRET_BYTES = 32
_POSIX = os.name == "posix"


class CacheDirWarning(UserWarning):
    """The cache directory, or a file in it, was not used: not private,
    unwritable, or a file failed its check (it is rebuilt)."""


_LOCK = threading.Lock()
_WARNED: set = set()


def warn_once(key, message, category=CacheDirWarning, stacklevel=3):
    """Warn with ``message`` the first time ``key`` is seen in this process
    (a broken cache costs one warning, not one per kernel)."""
    with _LOCK:
        if key in _WARNED:
            return
        _WARNED.add(key)
    warnings.warn(message, category, stacklevel=stacklevel)


def location() -> Path:
    """The configured cache directory (not created or checked here).

    ``$VARINT_CACHE_DIR`` if set; otherwise the platform's convention, from
    :func:`platformdirs.user_cache_dir`: ``$XDG_CACHE_HOME/varint`` or
    ``~/.cache/varint`` on Linux, ``~/Library/Caches/varint`` on macOS,
    ``%LOCALAPPDATA%\\varint\\Cache`` on Windows.
    """
    path = os.environ.get("VARINT_CACHE_DIR")
    if path:
        return Path(path).expanduser()
    # Imported here: a process with $VARINT_CACHE_DIR set needs none of it.
    import platformdirs

    # appauthor=False: no vendor folder above "varint" on Windows.
    return Path(platformdirs.user_cache_dir("varint", appauthor=False))


def _problem(st, what):
    """Why a directory with ``os.stat`` result ``st`` is not private, or None."""
    if not stat.S_ISDIR(st.st_mode):
        return f"{what} is not a directory"
    if not _POSIX:
        return None      # ownership and modes are ACLs there
    if st.st_uid != os.getuid():
        return f"{what} belongs to user id {st.st_uid}, not to you (user id {os.getuid()})"
    if st.st_mode & 0o022:
        return (f"{what} is writable by {'others' if st.st_mode & 0o002 else 'its group'} "
                f"(mode {stat.S_IMODE(st.st_mode):04o})")
    return None


def _ensure(path, follow):
    """Create ``path`` 0700 if missing; return why it is unusable, or None.
    ``follow``: a symbolic link to a private directory is accepted (the
    configured directory may be a link the user made); a subdirectory must
    be a real one."""
    try:
        os.mkdir(path, 0o700)
    except FileExistsError:
        pass
    except FileNotFoundError:
        try:
            os.makedirs(path, 0o700, exist_ok=True)
        except OSError as exc:
            return f"it cannot be created ({exc.strerror or exc})"
    except OSError as exc:
        return f"it cannot be created ({exc.strerror or exc})"
    try:
        st = os.stat(path) if follow else os.lstat(path)
    except OSError as exc:
        return f"it cannot be read ({exc.strerror or exc})"
    if not follow and stat.S_ISLNK(st.st_mode):
        return "it is a symbolic link"
    return _problem(st, "it")


_FALLBACK: dict = {}


def _fallback():
    """A private directory for this user when the configured one is refused:
    ``<tmp>/varint-<uid>``, reused by every process (no debris piles up);
    if that name is taken by something not private, a fresh directory
    removed when the process exits. None if the temporary directory cannot
    be written either."""
    with _LOCK:
        if "dir" in _FALLBACK:
            return _FALLBACK["dir"]
    uid = os.getuid() if _POSIX else os.getpid()
    shared = Path(tempfile.gettempdir()) / f"varint-{uid}"
    found = None
    if _ensure(shared, follow=False) is None:
        found = shared
    else:
        try:
            found = Path(tempfile.mkdtemp(prefix=f"varint-{uid}-"))
        except OSError:
            found = None
        else:
            atexit.register(shutil.rmtree, found, True)
    with _LOCK:
        return _FALLBACK.setdefault("dir", found)


def private_dir() -> Path | None:
    """The cache directory, created 0700 if missing and checked private
    (a directory owned by this user and not writable by group or others).
    If it is not, one :class:`CacheDirWarning` says why and a private
    fallback is returned (see :func:`_fallback`); None when no directory
    can be used at all (everything is then computed in memory)."""
    configured = location()
    why = _ensure(configured, follow=True)
    if why is None:
        return configured
    fallback = _fallback()
    instead = "nothing is cached on disk" if fallback is None else f"using {fallback} instead"
    if why.startswith("it cannot"):
        advice = f"{instead} (set VARINT_CACHE_DIR to a directory you can write)"
    else:
        advice = (f"another user could plant code there, so {instead} (make it yours and "
                  "private: chmod 700, or set VARINT_CACHE_DIR)")
    warn_once(("refused", str(configured), why),
              f"varint cache directory {configured} is not used: {why}; {advice}",
              stacklevel=4)
    return fallback


def subdir(name) -> Path | None:
    """``<private_dir()>/name``, created 0700 and checked private (a real
    directory, not a link); None if it cannot be used (warned once)."""
    base = private_dir()
    if base is None:
        return None
    path = base / name
    why = _ensure(path, follow=False)
    if why is None:
        return path
    warn_once(("refused", str(path), why),
              f"varint cache directory {path} is not used: {why}; nothing is cached there "
              "(delete it to let varint make it again)", stacklevel=4)
    return None


_SECRETS: dict = {}


def secret(base=None) -> bytes | None:
    """The per-user secret of the cache directory ``base`` (by default
    :func:`private_dir`): 32 random bytes in ``SECRET_FILE``, created 0600
    on first use. A secret file that is not a private regular file of this
    user (readable by others, a link, the wrong size) is replaced by a new
    one, with a warning: whatever it signed is rebuilt. None if no secret
    can be kept (nothing on disk is then trusted)."""
    base = private_dir() if base is None else Path(base)
    if base is None:
        return None
    path = base / SECRET_FILE
    with contextlib.suppress(OSError):
        st = os.lstat(path)
        known = _SECRETS.get(str(path))
        if known is not None and known[0] == (st.st_ino, st.st_mtime_ns, st.st_size):
            return known[1]
    value = _read_secret(path)
    if value is None:
        value = _new_secret(path)
    if value is None:
        return None
    with contextlib.suppress(OSError):
        st = os.lstat(path)
        _SECRETS[str(path)] = ((st.st_ino, st.st_mtime_ns, st.st_size), value)
    return value


def _read_secret(path):
    flags = os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0)
    try:
        fd = os.open(path, flags)
    except FileNotFoundError:
        return None
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            _replace_warning(path, "it is a symbolic link")
            return None
        return None
    try:
        st = os.fstat(fd)
        why = None
        if not stat.S_ISREG(st.st_mode):
            why = "it is not a regular file"
        elif _POSIX and st.st_uid != os.getuid():
            why = f"it belongs to user id {st.st_uid}"
        elif _POSIX and st.st_mode & 0o077:
            why = f"others may read or change it (mode {stat.S_IMODE(st.st_mode):04o})"
        elif st.st_size != _SECRET_BYTES:
            why = f"it holds {st.st_size} bytes, not {_SECRET_BYTES}"
        if why is not None:
            _replace_warning(path, why)
            return None
        data = os.read(fd, _SECRET_BYTES + 1)
    finally:
        os.close(fd)
    return data if len(data) == _SECRET_BYTES else None


def _replace_warning(path, why):
    warn_once(("secret", str(path), why),
              f"varint's cache secret {path} is not private ({why}); a new one is made and "
              "everything it signed is rebuilt", stacklevel=5)


def _new_secret(path):
    """A new secret in ``path``, written whole to a private temporary file
    first. A missing secret is created by a hard link, which fails if
    another process made one meanwhile (its secret is then read: both sign
    alike); a bad one found by :func:`_read_secret` is replaced."""
    value = os.urandom(_SECRET_BYTES)
    try:
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{SECRET_FILE}.", suffix=".tmp")
    except OSError:
        return None
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(value)
            f.flush()
            os.fsync(f.fileno())
        try:
            os.link(tmp, path)
        except FileExistsError:
            theirs = _read_secret(path)
            if theirs is not None:
                return theirs
            os.replace(tmp, path)
        except OSError:          # a file system without hard links
            os.replace(tmp, path)
    except OSError:
        return None
    finally:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
    return value


def sign(label, data, key=None) -> str:
    """HMAC-SHA256 (hex) of ``data`` (bytes) under ``label`` (a file's role
    and name, so a file moved to another name fails its check), keyed by
    :func:`secret`.

    Raises
    ------
    OSError
        If no secret can be kept.
    """
    key = secret() if key is None else key
    if key is None:
        raise OSError("no private cache directory to keep a secret in")
    return hmac.new(key, label.encode() + b"\0" + data, hashlib.sha256).hexdigest()


def verify(label, data, mac, key=None) -> bool:
    """Whether ``mac`` (hex text or bytes) is :func:`sign` of ``data``
    (compared in constant time)."""
    key = secret() if key is None else key
    if key is None:
        return False
    if isinstance(mac, bytes):
        try:
            mac = mac.decode("ascii")
        except UnicodeDecodeError:
            return False
    return hmac.compare_digest(sign(label, data, key), mac)

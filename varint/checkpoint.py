"""Checkpoints: a run saved to one file, from which the same call resumes
with a bitwise identical result.

A propagator keeps everything that determines how a run continues in its
:class:`~varint.state.RunState` (rules 3 and 8 of :mod:`varint.methods`), so
a checkpoint is that state, the outputs recorded so far and the parameters of
the run. The random initial deviation vectors are a function of the seed
alone (:func:`varint.state.initial_deviations`), so the seed is the whole
random-number state; with ``seed=None`` the seed drawn by the first call is
stored and reused on resume.

File format
-----------
``MAGIC`` (one line naming the format and its version), then an ``.npz``
archive (NumPy arrays, no pickles) holding the state, the stacked records and
a JSON ``__meta__`` entry (parameters, step, counts, wall time), then a
fixed-length trailer ``size=<bytes of the archive> sha256=<digest of
everything before the trailer>``. A file is written to a temporary file in the same
directory, flushed to disk and moved over the old one with
:func:`os.replace`, so at every instant the path holds either the previous
complete checkpoint or the new one. A truncated or corrupted file fails the
size or checksum test and is reported, never used: :class:`CheckpointError`
names the file and tells the user to delete it to start over (a damaged
checkpoint is not silently discarded, since it may stand for hours of work
that the user can still recover from a backup).
"""

from __future__ import annotations

import contextlib
import glob
import hashlib
import io
import json
import os
import re
import time
import warnings
import zipfile
from dataclasses import dataclass

import numpy as np

from .files import atomic_file, canonical as _canonical
from .records import Records
from .state import RunState

__all__ = ["CheckpointError", "Checkpoint", "Snapshot", "read", "write"]

MAGIC = b"varint checkpoint, format 1\n"
_TRAILER = re.compile(rb"size=(\d{20}) sha256=([0-9a-f]{64})\n\Z")
_TRAILER_LEN = len(b"size=") + 20 + len(b" sha256=") + 64 + 1
#: RunState fields stored as arrays; ``step``, ``counts`` and ``extra`` are
#: stored beside them (the test suite checks this covers every field).
STATE_ARRAYS = ("x", "W", "acc_m", "acc_e", "status", "fail_step")


class CheckpointError(ValueError):
    """A checkpoint cannot be used: unreadable, truncated, corrupt, written
    by a run with different parameters, or its path cannot be written."""


@dataclass
class Snapshot:
    """The content of a checkpoint.

    Attributes
    ----------
    parameters : dict
        JSON description of everything that determines the result (see
        :meth:`varint.run.Run.parameters`).
    state : RunState
    records : varint.records.Records or list of dict
        One dict of per-orbit arrays per output time reached (read back as
        :class:`~varint.records.Records`).
    wall_time : float
        Seconds spent on the run so far, summed over sessions.
    """

    parameters: dict
    state: RunState
    records: Records | list
    wall_time: float = 0.0


def canonical(parameters):
    """``parameters`` as they read back from JSON (tuples become lists,
    NumPy scalars Python numbers), so a fresh dict compares equal to a
    stored one."""
    try:
        return _canonical(parameters)
    except TypeError as exc:
        raise TypeError(f"cannot checkpoint this run: its parameters are {exc}; a model's "
                        "describe() must return numbers, strings, lists and dicts") from exc


def _differing(a, b, prefix=""):
    """Dotted names of the entries in which nested dicts ``a`` and ``b``
    differ, with both values. Two differently named objects (schemes,
    models) differ in their name only, not in each coefficient."""
    if isinstance(a, dict) and isinstance(b, dict):
        if "name" in a and "name" in b and a["name"] != b["name"]:
            return [(prefix + "name", a["name"], b["name"])]
        out = []
        for key in sorted(set(a) | set(b)):
            out += _differing(a.get(key, "<absent>"), b.get(key, "<absent>"),
                              f"{prefix}{key}.")
        return out
    return [] if a == b else [(prefix.rstrip("."), a, b)]


def differences(stored, current):
    """The parameters in which two runs differ, as readable strings: dotted
    names (``method_options.scheme.name``) with both values when they are
    short; arrays, stored as digests, are only named."""
    out = []
    for name, va, vb in _differing(canonical(stored), canonical(current)):
        ra, rb = repr(va), repr(vb)
        digests = "sha256:" in ra + rb
        out.append(f"{name} (other values)" if digests or len(ra) + len(rb) > 120
                   else f"{name} (checkpoint: {ra}, this call: {rb})")
    # The kind of run first: if it differs, the rest follows from it.
    return sorted(out, key=lambda line: not line.startswith("kind"))


def digest(array):
    """A short, exact fingerprint of a float array (its bytes and shape)."""
    a = np.ascontiguousarray(array)
    h = hashlib.sha256(str((a.dtype.str, a.shape)).encode() + a.tobytes()).hexdigest()
    return f"sha256:{h[:32]}"


# -- the file format ----------------------------------------------------------

class _HashingWriter:
    """A write-only stream that hashes and counts what passes through it;
    ``zipfile`` writes to it as to an unseekable file."""

    def __init__(self, f, h):
        self.f, self.h, self.n = f, h, 0

    def write(self, data):
        self.f.write(data)
        self.h.update(data)
        self.n += len(data)
        return len(data)

    def tell(self):
        return self.n

    def flush(self):
        self.f.flush()


def _arrays_and_meta(snapshot):
    s = snapshot.state
    arrays = {f"state__{name}": getattr(s, name) for name in STATE_ARRAYS}
    for key, value in s.extra.items():
        arrays[f"extra__{key}"] = np.asarray(value)
    records = snapshot.records
    stacked = (records if isinstance(records, Records) else Records(records)).stacked()
    keys = list(stacked)
    for key in keys:
        arrays[f"records__{key}"] = stacked[key]
    meta = {"parameters": canonical(snapshot.parameters), "step": int(s.step),
            "counts": {k: int(v) for k, v in s.counts.items()}, "extra": list(s.extra),
            "records": keys, "n_records": len(snapshot.records),
            "wall_time": float(snapshot.wall_time)}
    bad = [k for k, a in arrays.items() if a.dtype.hasobject]
    if bad:
        raise TypeError(f"cannot checkpoint {bad[0]}: it is not a numeric array "
                        "(RunState.extra must hold NumPy arrays, rule 8 of varint.methods)")
    return arrays, meta


def write(path, snapshot):
    """Write ``snapshot`` to ``path`` atomically (see the module docstring).

    Raises
    ------
    OSError
        If the file cannot be written; ``path`` is then left as it was.
    """
    arrays, meta = _arrays_and_meta(snapshot)
    with atomic_file(path) as f:
        h = hashlib.sha256(MAGIC)
        f.write(MAGIC)
        payload = _HashingWriter(f, h)
        _write_npz(payload, dict(arrays, __meta__=np.array(json.dumps(meta))))
        f.write(b"size=%020d sha256=%s\n" % (payload.n, h.hexdigest().encode()))


def _write_npz(stream, arrays):
    # What numpy.savez writes (so numpy.load reads it), but to a stream that
    # cannot seek, without pickles.
    with zipfile.ZipFile(stream, mode="w", compression=zipfile.ZIP_STORED) as zf:
        for name, a in arrays.items():
            with zf.open(f"{name}.npy", "w", force_zip64=True) as member:
                np.lib.format.write_array(member, np.asanyarray(a), allow_pickle=False)


def read(path):
    """Read and verify the checkpoint at ``path``.

    Returns
    -------
    Snapshot

    Raises
    ------
    CheckpointError
        If the file is not a varint checkpoint, or is truncated or corrupt.
    FileNotFoundError
        If there is no file.
    """
    path = os.fspath(path)
    with open(path, "rb") as f:
        data = f.read()
    advice = "delete it to start the run over"
    if not data.startswith(MAGIC):
        what = "is empty" if not data else f"does not start with {MAGIC[:-1].decode()!r}"
        if data and MAGIC.startswith(data):
            what = f"is truncated ({len(data)} bytes)"
        raise CheckpointError(f"checkpoint {path} is not a varint checkpoint: it {what}; "
                              f"{advice}, or pass another checkpoint= path")
    body, trailer = data[:-_TRAILER_LEN], data[-_TRAILER_LEN:]
    match = _TRAILER.match(trailer)
    if match is None:
        raise CheckpointError(f"checkpoint {path} is truncated or corrupt (its end marker is "
                              f"missing; {len(data)} bytes); {advice}")
    size, expected = int(match.group(1)), match.group(2).decode()
    if len(body) - len(MAGIC) != size:
        raise CheckpointError(f"checkpoint {path} is truncated or corrupt ({len(body) - len(MAGIC)}"
                              f" bytes of data where its trailer says {size}); {advice}")
    if hashlib.sha256(body).hexdigest() != expected:
        raise CheckpointError(f"checkpoint {path} is corrupt (SHA-256 checksum mismatch); "
                              f"{advice}")
    try:
        return _decode(body[len(MAGIC):])
    except (ValueError, KeyError, TypeError, zipfile.BadZipFile) as exc:
        # The checksum passed, so the writer itself produced this: a format
        # from another varint version.
        raise CheckpointError(f"checkpoint {path} cannot be decoded by this varint version "
                              f"({exc}); {advice}") from exc


def _decode(payload):
    with np.load(io.BytesIO(payload), allow_pickle=False) as z:
        meta = json.loads(str(z["__meta__"][()]))
        arrays = {k: np.require(z[k], requirements=["C", "W"]) for k in z.files
                  if k != "__meta__"}
    state = RunState(**{name: arrays[f"state__{name}"] for name in STATE_ARRAYS},
                     step=int(meta["step"]), counts=dict(meta["counts"]),
                     extra={k: arrays[f"extra__{k}"] for k in meta["extra"]})
    stacked = {k: arrays[f"records__{k}"] for k in meta["records"]}
    records = Records.from_stacked(stacked, int(meta["n_records"]))
    return Snapshot(parameters=meta["parameters"], state=state, records=records,
                    wall_time=float(meta["wall_time"]))


# -- a run's checkpoint --------------------------------------------------------

class Checkpoint:
    """The checkpoint file of one run: read at the start, written every
    ``interval`` seconds of wall time and whenever the run stops.

    Parameters
    ----------
    path : str or os.PathLike
        The checkpoint file. Its directory must exist.
    interval : float, default 60
        Seconds of wall time between writes (0: after every chunk of work,
        about 0.2 s).

    Notes
    -----
    One run per file at a time: two processes given the same path would
    overwrite each other's checkpoints.
    """

    def __init__(self, path, interval=60.0):
        try:
            # Absolute, so a later change of working directory cannot move it.
            self.path = os.path.abspath(os.fspath(path))
        except TypeError:
            raise CheckpointError(f"checkpoint must be a file path, got {path!r}") from None
        if isinstance(interval, bool) or not (isinstance(interval, (int, float, np.number))
                                              and np.isfinite(interval) and interval >= 0):
            raise ValueError(f"checkpoint_interval must be a finite number of seconds >= 0, "
                             f"got {interval!r}")
        self.interval = float(interval)
        if os.path.isdir(self.path):
            raise CheckpointError(f"checkpoint must be a file path, {self.path} is a directory")
        directory = os.path.dirname(self.path)
        if not os.path.isdir(directory):
            what = "is not a directory" if os.path.exists(directory) else "does not exist"
            raise CheckpointError(f"cannot write checkpoint {self.path}: its directory "
                                  f"{directory} {what}")
        self.parameters = None
        self._wall_before = 0.0
        self._clock = self._last_write = time.perf_counter()
        self._saved = None  # _mark() of what the file holds

    def read(self):
        """The stored :class:`Snapshot`, or None if there is no file yet."""
        try:
            return read(self.path)
        except FileNotFoundError:
            return None

    def require(self, snapshot, parameters):
        """Raise :class:`CheckpointError` unless ``snapshot`` was written by a
        run with these parameters; the message lists each one that differs."""
        diff = differences(snapshot.parameters, parameters)
        if diff:
            raise CheckpointError(
                f"checkpoint {self.path} was written by a run with other parameters: "
                + "; ".join(diff) + ". Pass the same arguments to resume it, or another "
                "checkpoint= path (or delete the file) to start a new run")

    def begin(self, parameters, wall_before=0.0):
        """Start a session: later writes carry ``parameters`` and the wall
        time spent so far plus this session's."""
        self.parameters = parameters
        self._wall_before = float(wall_before)
        self._clock = self._last_write = time.perf_counter()
        self._remove_stale_temporaries()

    def _remove_stale_temporaries(self):
        # Left by a process killed while writing (the checkpoint itself is
        # intact, see write()); harmless but they would pile up.
        pattern = os.path.join(os.path.dirname(self.path),
                               f".{glob.escape(os.path.basename(self.path))}.*.tmp")
        for stale in glob.glob(pattern):
            with contextlib.suppress(OSError):
                os.unlink(stale)

    def due(self):
        """Whether ``interval`` seconds have passed since the last write."""
        return time.perf_counter() - self._last_write >= self.interval

    def wall_time(self):
        """Seconds spent on the run, over all sessions."""
        return self._wall_before + time.perf_counter() - self._clock

    def save(self, state, records, strict=False):
        """Write the run's state and records.

        A failure to write raises :class:`CheckpointError` if ``strict``
        (used before any work is done, so an unusable path costs nothing);
        otherwise it is reported as a ``RuntimeWarning`` and the run goes on,
        since its result in memory is still correct and the previous
        checkpoint on disk is intact.

        Returns True if the checkpoint was written (or was already up to date).
        """
        mark = _mark(state, records)
        if mark == self._saved:
            return True
        snapshot = Snapshot(self.parameters, state, records, self.wall_time())
        try:
            write(self.path, snapshot)
        except OSError as exc:
            reason = exc.strerror or str(exc)
            if strict:
                raise CheckpointError(f"cannot write checkpoint {self.path}: {reason}") from exc
            kept = ("" if self._saved is None
                    else f"; the previous checkpoint (step {self._saved[0]}) is kept")
            warnings.warn(f"could not write checkpoint {self.path} at step {state.step}: "
                          f"{reason}{kept}; the run goes on", RuntimeWarning, stacklevel=5)
            self._last_write = time.perf_counter()
            return False
        self._saved = mark
        self._last_write = time.perf_counter()
        return True

    def mark_saved(self, state, records):
        """Note that ``state`` and ``records`` are what the file holds (after
        a resume), so an unchanged run is not rewritten."""
        self._saved = _mark(state, records)


def _mark(state, records):
    # What distinguishes one save from the next of the same run.
    return state.step, len(records), int((state.status != 0).sum())

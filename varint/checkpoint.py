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

The checksum only catches accidents: anyone can edit a checkpoint and
compute a new one. So nothing read back is used before it is validated
against the call that resumes it (:meth:`Checkpoint.validate`): its
parameters (the canonical key of the call: model, orbits, method and its
options, times, seed, versions), the archive's members (stored, numeric,
no pickles), the state's shapes, dtypes and values
(:meth:`varint.state.RunState.problems`), the step against the records, and
each record's keys, shapes, dtypes and finiteness. A checkpoint that fails
is refused with a :class:`CheckpointError` naming the file and the field;
nothing from it reaches a compiled stepper.

The CPU time of every session (:func:`time.process_time`) is measured and
summed in the checkpoint, so a resumed run reports the CPU it took, never
an extrapolation.
"""

from __future__ import annotations

import contextlib
import glob
import hashlib
import io
import json
import math
import os
import re
import time
import warnings
import zipfile
from dataclasses import dataclass

import numpy as np

# digest: a run's provenance names arrays by it (:mod:`varint.files`); kept
# importable from here, where it was defined first.
from .files import atomic_file, canonical as _canonical, digest, temporary_owner
from .records import Records
from .state import RunState

__all__ = ["CheckpointError", "Checkpoint", "Snapshot", "read", "write", "digest"]

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
    cpu_time : float or None
        CPU seconds (process time) spent on the run so far, measured in
        every session and summed; None if a session's was not measured (a
        checkpoint written before varint recorded it).
    """

    parameters: dict
    state: RunState
    records: Records | list
    wall_time: float = 0.0
    cpu_time: float | None = 0.0


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
            "wall_time": float(snapshot.wall_time),
            "cpu_time": None if snapshot.cpu_time is None else float(snapshot.cpu_time)}
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
    except (ValueError, KeyError, TypeError, OSError, EOFError, zipfile.BadZipFile) as exc:
        # The checksum passed: the file was edited, or another varint
        # version wrote it.
        raise CheckpointError(f"checkpoint {path} cannot be decoded by this varint version "
                              f"({exc}); it was edited or written by another version; "
                              f"{advice}") from exc


class _Malformed(ValueError):
    """A checksummed checkpoint whose structure is not what :func:`write`
    writes (an edited file, or another varint version's format)."""


def _decode(payload):
    archive = zipfile.ZipFile(io.BytesIO(payload))
    for info in archive.infolist():
        # write() stores members uncompressed: a compressed one is foreign
        # (and could expand to any size).
        if info.compress_type != zipfile.ZIP_STORED:
            raise _Malformed(f"member {info.filename} is compressed")
    with np.load(io.BytesIO(payload), allow_pickle=False) as z:
        if "__meta__" not in z.files:
            raise _Malformed("it has no __meta__ entry")
        meta = json.loads(str(z["__meta__"][()]))
        arrays = {k: np.require(z[k], requirements=["C", "W"]) for k in z.files
                  if k != "__meta__"}
    if not isinstance(meta, dict):
        raise _Malformed("__meta__ is not a JSON object")
    for key, a in arrays.items():
        if a.dtype.kind not in "biuf":
            raise _Malformed(f"{key} is not a numeric array (dtype {a.dtype})")
    _need(meta, "parameters", dict)
    _need(meta, "counts", dict)
    for key in ("step", "n_records"):
        _need(meta, key, int)
    for key in ("extra", "records"):
        if not isinstance(meta.get(key), list) or not all(isinstance(k, str) for k in meta[key]):
            raise _Malformed(f"{key} is not a list of names")
    wall, cpu = meta.get("wall_time"), meta.get("cpu_time")
    for key, value in (("wall_time", wall), ("cpu_time", cpu)):
        if value is not None and (isinstance(value, bool) or not isinstance(value, (int, float))
                                  or not 0 <= value < math.inf):
            raise _Malformed(f"{key} is {value!r}, not a number of seconds")
    if wall is None:
        raise _Malformed("wall_time is missing")
    named = ({f"state__{n}" for n in STATE_ARRAYS} | {f"extra__{k}" for k in meta["extra"]}
             | {f"records__{k}" for k in meta["records"]})
    if set(arrays) != named:
        odd = sorted(set(arrays) ^ named)[0]
        raise _Malformed(f"array {odd} is {'missing' if odd in named else 'not listed'}")
    n = meta["n_records"]
    stacked = {k: arrays[f"records__{k}"] for k in meta["records"]}
    for key, a in stacked.items():
        if a.ndim == 0 or a.shape[0] != n:
            raise _Malformed(f"records of {key} hold {a.shape[0] if a.ndim else 0} outputs, "
                             f"not {n}")
    if n < 0 or (n and not stacked):
        raise _Malformed(f"n_records = {n} with records {sorted(stacked)}")
    state = RunState(**{name: arrays[f"state__{name}"] for name in STATE_ARRAYS},
                     step=meta["step"], counts=dict(meta["counts"]),
                     extra={k: arrays[f"extra__{k}"] for k in meta["extra"]})
    records = Records.from_stacked(stacked, n)
    return Snapshot(parameters=meta["parameters"], state=state, records=records,
                    wall_time=float(wall), cpu_time=None if cpu is None else float(cpu))


def _need(meta, key, kind):
    value = meta.get(key)
    if isinstance(value, bool) or not isinstance(value, kind):
        raise _Malformed(f"{key} is {value!r:.60}, not {'an integer' if kind is int else 'a dict'}")


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
        self._cpu_before = 0.0
        self._clock = self._last_write = time.perf_counter()
        self._cpu_clock = time.process_time()
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

    def validate(self, snapshot, like, steps, record, renorm):
        """Raise :class:`CheckpointError` naming the file and the field
        unless ``snapshot`` (already :meth:`require`-d to have this call's
        parameters) can continue the run: its state fits ``like`` (the state
        the call starts from, see :meth:`varint.state.RunState.problems`),
        its step lies between the last recorded output step and the next of
        ``steps``, and its records have the keys, shapes and dtypes of
        ``record`` (one record of the call, (M, ...) per key) and finite
        values wherever the orbit was running."""
        state, records = snapshot.state, snapshot.records
        n = len(records)
        problems = state.problems(like, renorm, int(steps[-1]))
        if not problems:
            if n > len(steps):
                problems = [("records", f"{n} outputs, but the run has {len(steps)}")]
            elif (n and state.step < steps[n - 1]) or (n < len(steps) and state.step > steps[n]):
                problems = [("step", f"{state.step} does not follow the {n} outputs recorded "
                             f"(the next output step is {steps[min(n, len(steps) - 1)]})")]
        if not problems and n:
            problems = _record_problems(records.stacked(), record, state, steps[:n])
        if problems:
            field, why = problems[0]
            raise CheckpointError(
                f"checkpoint {self.path} cannot resume this run: {field}: {why}; it was edited "
                "or damaged after its checksum was made; delete it to start the run over")

    def begin(self, parameters, wall_before=0.0, cpu_before=0.0):
        """Start a session: later writes carry ``parameters`` and the wall
        and CPU time spent so far plus this session's (``cpu_before`` None:
        not measured before, so the total stays unknown)."""
        self.parameters = parameters
        self._wall_before = float(wall_before)
        self._cpu_before = None if cpu_before is None else float(cpu_before)
        self._clock = self._last_write = time.perf_counter()
        self._cpu_clock = time.process_time()
        for stale in stale_temporaries(self.path):
            # Left by a process killed while writing (the checkpoint itself
            # is intact, see write()); harmless but they would pile up. A
            # live writer's are not touched.
            with contextlib.suppress(OSError):
                os.unlink(stale)

    def due(self):
        """Whether ``interval`` seconds have passed since the last write."""
        return time.perf_counter() - self._last_write >= self.interval

    def wall_time(self):
        """Seconds spent on the run, over all sessions."""
        return self._wall_before + time.perf_counter() - self._clock

    def cpu_time(self):
        """CPU seconds (process time) spent on the run, over all sessions,
        each measured; None if an earlier session's was not."""
        if self._cpu_before is None:
            return None
        return self._cpu_before + time.process_time() - self._cpu_clock

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
        snapshot = Snapshot(self.parameters, state, records, self.wall_time(), self.cpu_time())
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


def _record_problems(stacked, record, state, steps):
    """(field, reason) pairs for stored records ``stacked`` (n, M, ...)
    that do not match one fresh ``record`` (M, ...) of the call, or hold a
    non-finite number for an orbit running at that output (in a field that
    is finite in ``record``: some are undefined at first, such as a local
    exponent before its first window closes)."""
    if set(stacked) != set(record):
        odd = sorted(set(stacked) ^ set(record))[0]
        return [(f"records.{odd}", "missing" if odd in record else "not a record of this run")]
    running = (state.status[None, :] == 0) | (state.fail_step[None, :] > steps[:, None])
    for key, ref in record.items():
        a, ref = stacked[key], np.asarray(ref)
        if a.shape[1:] != ref.shape or a.dtype.kind != ref.dtype.kind:
            return [(f"records.{key}", f"{a.dtype}{list(a.shape[1:])} per output, expected "
                     f"{ref.dtype}{list(ref.shape)}")]
        if a.dtype.kind == "f" and np.isfinite(ref).all():
            finite = np.isfinite(a.reshape(a.shape[:2] + (-1,))).all(axis=2)
            bad = running & ~finite
            if bad.any():
                r, m = np.argwhere(bad)[0]
                return [(f"records.{key}", f"not finite at output {r} (step {steps[r]}) of "
                         f"orbit {m}, which was running")]
    return []


def stale_temporaries(path):
    """Temporary files of ``path`` (:func:`varint.files.atomic_file`) whose
    writer is gone: written on this host by a process that no longer runs.
    Those of live processes, of other hosts (a shared file system) and of
    unknown writers are left alone."""
    pattern = os.path.join(os.path.dirname(os.fspath(path)),
                           f".{glob.escape(os.path.basename(os.fspath(path)))}.*.tmp")
    for candidate in glob.glob(pattern):
        owner = temporary_owner(candidate, path)
        if owner is not None and not owner.alive():
            yield candidate


def _mark(state, records):
    # What distinguishes one save from the next of the same run.
    return state.step, len(records), int((state.status != 0).sum())

"""Resumable stores: the finished pieces of a workflow kept in a directory,
each tied to the call that made it and checked before it is used.

A chaos map keeps its finished chunks (:func:`varint.chaos_map`), an
ensemble its finished realisations (:func:`varint.ensemble`), so that the
same call again computes only what is missing. Both need the same thing:
a piece read back must be a piece of *this* call, whole and sane, or not be
used at all. A :class:`Store` gives that:

* every piece is one ``.npz`` file (NumPy arrays, no pickles, written
  atomically) holding, beside its arrays, a ``__store__`` entry: the
  canonical key of the call (the SHA-256 of its parameters: model, initial
  conditions, method and options, times, seed, versions), the parameters
  themselves (to name what differs), the piece's name and its own metadata;
* :meth:`Store.load` uses a piece only if its structure is exactly that,
  its name is the one asked for (a file copied from another chunk's name is
  not) and its key is this call's; the workflow then validates its arrays
  (shapes, dtypes, finiteness, counters) before any use;
* a damaged piece is reported with a warning naming the file and deleted
  (it is recomputed); one of another call is reported and recomputed, or
  refused with a :class:`~varint.CheckpointError` naming the parameters
  that differ (:meth:`Store.load`'s ``foreign``);
* a full or unwritable directory costs the store, not the work: one
  warning, and the workflow goes on without keeping what it cannot write.

Pieces are not signed (they may be moved between machines with their
directory): a piece is data, checked for being what this call would have
written, never code, so an edited piece can at worst be refused.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import warnings
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .checkpoint import CheckpointError, canonical, differences
from .files import atomic_write, canonical_json, jsonable

__all__ = ["Store", "Piece", "call_key", "Invalid"]

_FORMAT = 1
_ENTRY = "__store__"


class Invalid(ValueError):
    """A stored piece that is not what this call would have written: its
    message names the field and why."""


def call_key(parameters):
    """The canonical key of a call: SHA-256 (hex) of its parameters as
    canonical JSON."""
    return hashlib.sha256(canonical_json(canonical(parameters)).encode()).hexdigest()


@dataclass
class Piece:
    """A piece read back: its arrays and its own metadata."""

    arrays: dict
    meta: dict


class Store:
    """The checkpoint directory of one workflow call.

    Parameters
    ----------
    path : str or os.PathLike
        The directory (created if missing).
    what : str
        What it keeps, for messages ("chaos map", "ensemble").
    parameters : dict, optional
        Everything that determines the call's pieces (JSON-able); pieces
        that each have their own (an ensemble's realisations, one seed each)
        give theirs to :meth:`load` and :meth:`save`.

    Raises
    ------
    CheckpointError
        If ``path`` is a file or cannot be made a directory.
    """

    def __init__(self, path, what, parameters=None):
        self.path = Path(path)
        self.what = what
        self.parameters = None if parameters is None else canonical(parameters)
        self._unwritable = None
        if self.path.exists() and not self.path.is_dir():
            raise CheckpointError(f"cannot use {self.path} as a {what} checkpoint directory: it "
                                  "is a file (checkpoint must be a directory)")
        try:
            self.path.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise CheckpointError(f"cannot use {self.path} as a {what} checkpoint directory: "
                                  f"{exc.strerror or exc}") from exc

    def file(self, name):
        return self.path / f"{name}.npz"

    @property
    def unwritable(self):
        """Whether a write failed (the directory is full or read-only)."""
        return self._unwritable is not None

    def manifest(self, name):
        """Refuse the directory if its manifest ``name`` (e.g. ``map.json``:
        the parameters of the call that made it) names other parameters;
        write it if there is none.

        Raises
        ------
        CheckpointError
            Naming each parameter that differs, or an unreadable manifest.
        """
        path = self.path / name
        if path.exists():
            try:
                stored = json.loads(path.read_text())
            except (OSError, ValueError) as exc:
                raise CheckpointError(f"{path} is not readable ({exc}); delete the directory "
                                      f"to start the {self.what} over") from exc
            if not isinstance(stored, dict):
                raise CheckpointError(f"{path} does not hold a {self.what}'s parameters; delete "
                                      f"the directory to start the {self.what} over")
            diff = differences(stored, self.parameters)
            if diff:
                raise CheckpointError(
                    f"{self.path} holds a {self.what} with other parameters: " + "; ".join(diff)
                    + ". Use another directory, or delete this one to start over")
            return
        try:
            atomic_write(path, json.dumps(self.parameters, indent=1))
        except OSError as exc:
            self._cannot_write(path, exc)

    def load(self, name, parameters=None, foreign="recompute"):
        """The piece ``name`` of this call, or None (absent, damaged or
        another call's: then recomputed).

        Parameters
        ----------
        name : str
        parameters : dict, optional
            The piece's own parameters (by default the store's).
        foreign : {"recompute", "refuse"}
            What a piece of another call means: a stray file (warned about
            and recomputed), or a directory of another call (a
            :class:`CheckpointError` naming the parameters that differ).
        """
        path = self.file(name)
        if not path.exists():
            return None
        parameters = self.parameters if parameters is None else canonical(parameters)
        key = call_key(parameters)
        try:
            stored, piece = _read(path)
            if stored.get("piece") != name:
                raise Invalid(f"it holds piece {stored.get('piece')!r}, not {name!r} (a file "
                              "moved or copied from another name)")
        except Exception as exc:  # a damaged piece must never be used
            self.discard(path, exc)
            return None
        if stored["key"] == key == call_key(stored["parameters"]):
            return piece
        diff = differences(stored["parameters"], parameters) or ["its key"]
        if foreign == "refuse":
            raise CheckpointError(
                f"{path} holds a piece of a {self.what} with other parameters: "
                + "; ".join(diff) + ". Use another directory, or delete it to start over")
        warnings.warn(f"{self.what} checkpoint file {path} belongs to another {self.what} ("
                      + "; ".join(diff) + "); recomputing it", RuntimeWarning, stacklevel=3)
        return None

    def discard(self, path, exc):
        """Report an unusable piece (``exc`` says why) and delete it."""
        warnings.warn(f"{self.what} checkpoint file {path} is unreadable ({exc}); recomputing "
                      "it", RuntimeWarning, stacklevel=4)
        with contextlib.suppress(OSError):
            Path(path).unlink()

    def save(self, name, arrays, meta, parameters=None):
        """Write the piece ``name`` (numeric ``arrays`` and JSON ``meta``;
        ``parameters``: its own, by default the store's) atomically; a
        failure (full disk, read-only) is one warning and returns False:
        the workflow goes on without keeping it."""
        if self._unwritable is not None:
            return False
        path = self.file(name)
        parameters = self.parameters if parameters is None else canonical(parameters)
        entry = {"format": _FORMAT, "key": call_key(parameters), "parameters": parameters,
                 "piece": name, "meta": jsonable(meta)}
        buf = io.BytesIO()
        np.savez(buf, **{_ENTRY: np.array(json.dumps(entry))}, **arrays)
        try:
            atomic_write(path, buf.getvalue())
        except OSError as exc:
            self._cannot_write(path, exc)
            return False
        return True

    def _cannot_write(self, path, exc):
        self._unwritable = exc
        warnings.warn(f"could not write {self.what} checkpoint file {path} "
                      f"({exc.strerror or exc}); the {self.what} goes on, but what it "
                      "computes from now on is not kept for a resume", RuntimeWarning,
                      stacklevel=4)


def _read(path):
    """(the ``__store__`` entry, the Piece) of the file at ``path``;
    raises (saying why) if it is not exactly what :meth:`Store.save` writes."""
    blob = Path(path).read_bytes()
    with zipfile.ZipFile(io.BytesIO(blob)) as archive:
        for info in archive.infolist():
            if info.compress_type != zipfile.ZIP_STORED:
                raise Invalid(f"member {info.filename} is compressed (not written by varint)")
    with np.load(io.BytesIO(blob), allow_pickle=False) as data:
        if _ENTRY not in data.files:
            raise Invalid("it has no __store__ entry (written by another varint version?)")
        stored = json.loads(str(data[_ENTRY][()]))
        arrays = {k: data[k] for k in data.files if k != _ENTRY}
    if not (isinstance(stored, dict) and stored.get("format") == _FORMAT
            and isinstance(stored.get("key"), str) and isinstance(stored.get("piece"), str)
            and isinstance(stored.get("parameters"), dict)
            and isinstance(stored.get("meta"), dict)):
        raise Invalid("its __store__ entry is not one this varint writes")
    for key, a in arrays.items():
        if a.dtype.kind not in "biuf":
            raise Invalid(f"array {key} is not numeric (dtype {a.dtype})")
    return stored, Piece(arrays=arrays, meta=stored["meta"])

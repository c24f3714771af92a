"""What every public run shares: checking the inputs, building the initial
deviation vectors and the propagator, resuming from a checkpoint, driving to
the output times, and packaging the records into a result with its
provenance."""

from __future__ import annotations

import copy
import warnings

import numpy as np
from numba.core.errors import NumbaError

from . import _validate as check
from .checkpoint import Checkpoint, digest
from .driver import IntegrationError, drive, failure_message
from .methods import make_propagator
from .results import Provenance, package_versions
from .state import RunState, initial_deviations, output_steps

__all__ = ["Run"]

#: Initial states of at most this many numbers are stored in a checkpoint's
#: parameters as values (so a mismatch shows them), larger ones as a digest.
_SHOWN_X0 = 32


class Run:
    """One call of a public run function, from inputs to result.

    Parameters
    ----------
    kind : str
        Name of the public function (for provenance and messages).
    model, x0, t_end, tau, method, t_out, seed, progress, errors
        As in the public functions.
    k : int
        Number of random deviation vectors to draw when none are given
        (0 for none).
    renorm : {"qr", "normalize", "none"}
    deviations : array_like or None
        Given initial vectors; drawn from ``seed`` when None.
    require : {"orthonormal", "unit", None}
        What given vectors must satisfy: orthonormal columns, or linearly
        independent columns (which are then normalised to unit length).
    method_options : dict
        Passed to the propagator (e.g. ``scheme``).
    options : dict
        Other call arguments to record in the provenance.
    escape_radius : float, optional
        Overrides the model's ``escape_radius`` for this run.
    checkpoint, checkpoint_interval
        Checkpoint file and seconds between writes (see
        :mod:`varint.checkpoint`); the run resumes from the file if it exists.
    """

    def __init__(self, kind, model, x0, t_end, tau, *, method, k, renorm, deviations=None,
                 seed=0, t_out=None, progress=None, errors="raise", require=None,
                 method_options=None, options=None, escape_radius=None, checkpoint=None,
                 checkpoint_interval=60.0):
        self.kind = kind
        self.options = dict(options or {})
        if escape_radius is not None:
            # A copy, so the caller's model keeps its own radius.
            model = copy.copy(model)
            model.escape_radius = check.positive_float(escape_radius, "escape_radius")
            self.options["escape_radius"] = model.escape_radius
        self.model = model
        self.x0, self.single = check.states(model, x0)
        self.t_end, self.tau = check.horizon(t_end, tau)
        self.errors = check.choice(errors, ("raise", "flag"), "errors")
        self.progress = check.flag(progress, "progress")
        self.checkpoint = None if checkpoint is None else Checkpoint(checkpoint,
                                                                     checkpoint_interval)
        saved = None if self.checkpoint is None else self.checkpoint.read()
        m, dim = self.x0.shape
        self.given_deviations = deviations is not None
        if deviations is not None:
            W0 = check.deviations(deviations, dim, m)
            if renorm != "none":
                check.n_vectors(W0.shape[2], dim, "the number of deviation vectors "
                                "(columns of deviations)")
            if require == "orthonormal":
                check.orthonormal(W0)
            elif require == "unit":
                check.full_rank(W0)
                W0 = W0 / np.linalg.norm(W0, axis=1, keepdims=True)
            self.seed = None
        else:
            self.seed = self._seed(seed, saved)
            W0 = initial_deviations(dim, k, m, self.seed)
        self.W0 = W0
        self.steps = output_steps(self.t_end, self.tau, check.output_times(t_out))
        self.propagator = make_propagator(method, model, self.tau, renorm,
                                          **(method_options or {}))
        self.method = method.lower()
        self.energy0 = model.energy(self.x0)
        if saved is None:
            self.state, self.records, self.wall_before = RunState.start(self.x0, W0), [], 0.0
        else:
            self.checkpoint.require(saved, self.parameters())
            self.state, self.records, self.wall_before = (saved.state, saved.records,
                                                          saved.wall_time)
        self.resumed = saved is not None

    @staticmethod
    def _seed(seed, saved):
        if seed is None:
            # A random seed, unless a checkpoint already drew one: resuming
            # must continue with the same vectors.
            stored = None if saved is None else saved.parameters.get("seed")
            return stored if isinstance(stored, int) else int(np.random.SeedSequence().entropy)
        if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
            raise ValueError(f"seed must be a non-negative integer or None, got {seed!r}")
        return int(seed)

    def parameters(self):
        """Everything that determines the result, as JSON: what a checkpoint
        must match to be resumed (package versions included, since a
        different NumPy or numba may change the last bits)."""
        x0 = self.x0.tolist() if self.x0.size <= _SHOWN_X0 else digest(self.x0)
        return {"kind": self.kind, "model": self.model.describe(), "x0": x0,
                "t_end": self.t_end, "tau": self.tau, "t_out": digest(self.steps),
                "method": self.method, "method_options": self.propagator.describe(),
                "seed": self.seed,
                "deviations": digest(self.W0) if self.given_deviations else None,
                "options": self.options, "versions": self._versions()}

    def _versions(self):
        versions = dict(package_versions())
        versions.update(self.propagator.versions())
        return versions

    def energy_error(self, x):
        """Relative energy error of states ``x`` (M, 2N) against the start."""
        h0 = self.energy0
        scale = np.where(h0 != 0, np.abs(h0), 1.0)
        # A failed orbit's frozen state may overflow here; its records are
        # replaced by NaN anyway, so NumPy's warnings would be noise.
        with np.errstate(over="ignore", invalid="ignore"):
            return np.abs(self.model.energy(x) - h0) / scale

    def execute(self, record, build, decide=None):
        """Drive the run and return ``build(t, fields)`` as the result.

        ``record(state)`` returns a dict of per-orbit arrays at an output
        time (the energy error is added here); ``build(t, fields, common)``
        makes the result from the stacked, orbit-first arrays; ``decide``
        stops orbits early (see :func:`varint.driver.drive`).
        """
        def full_record(state):
            rec = record(state)
            rec["energy_error"] = self.energy_error(state.x)
            return rec

        if self.checkpoint is not None:
            self.checkpoint.begin(self.parameters(), self.wall_before)
            if self.resumed:
                self.checkpoint.mark_saved(self.state, self.records)
            else:
                # Before any work: an unusable path fails now, not hours later.
                self.checkpoint.save(self.state, self.records, strict=True)
        try:
            records, stop, wall = drive(self.propagator, self.state, self.steps, full_record,
                                        records=self.records, progress=self.progress,
                                        desc=self.kind, errors=self.errors,
                                        checkpoint=self.checkpoint, decide=decide)
        except NumbaError as exc:
            # A model kernel that does not fit the protocol fails to compile
            # into the stepper; say so instead of showing numba's internals.
            first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
            raise TypeError(
                f"the kernels of model {self.model.name!r} could not be compiled into the "
                f"{self.method!r} integrator ({first}); they must be numba functions "
                "grad(q, par, g), hess(q, par, B), third(q, par, v, B) writing float64 arrays "
                "in place, see varint.models.base") from exc
        n_done = len(next(iter(records.values()))) if records else 0
        t = self.steps[:n_done] * self.tau
        fields = {}
        for key, arr in records.items():
            arr = np.moveaxis(arr, 0, 1)  # (M, n_out, ...)
            fields[key] = arr[0] if self.single else arr
        common = dict(t=t, energy_error=fields.pop("energy_error", np.empty((0,))),
                      state=self._squeeze(self.state.x),
                      provenance=self._provenance(self.wall_before + wall),
                      status=self._squeeze(self.state.status), interrupted=stop == "interrupted")
        result = build(t, fields, common)
        failed = self.state.status > 0  # negative: stopped early on purpose
        if failed.any():
            msg, info = failure_message(self.state, self.tau, self.single,
                                        getattr(self.propagator, "failure_reasons", None))
            msg += self._escape_hint(info["orbit"])
            if self.errors == "raise":
                if failed.sum() > 1:
                    msg += f" ({failed.sum()} orbits failed; pass errors='flag' to keep the others)"
                raise IntegrationError(msg, partial=result, **info)
            warnings.warn(f"{int(failed.sum())} of {failed.size} orbits failed and were frozen "
                          f"(their status is non-zero, their later outputs NaN); first: {msg}",
                          RuntimeWarning, stacklevel=3)
        return result

    def _escape_hint(self, orbit):
        # Hénon–Heiles above 1/6 (any model with an escape energy): say why.
        e_esc = getattr(self.model, "escape_energy", None)
        e0 = float(self.energy0[orbit])
        if e_esc is None or not e0 > e_esc:
            return ""
        return (f"; its energy {e0:.6g} is above the escape energy {e_esc:.6g} of "
                f"{self.model.name}, so it can leave the potential well (escape_radius= stops "
                "such orbits as soon as |q| exceeds it)")

    def _squeeze(self, arr):
        return arr[0] if self.single else arr

    def _provenance(self, wall):
        prop = self.propagator
        return Provenance(
            kind=self.kind, model=self.model.describe(),
            x0=(self.x0[0] if self.single else self.x0).tolist(), method=self.method,
            method_options=prop.describe(), tau=self.tau, t_end=self.t_end, seed=self.seed,
            options=self.options, versions=self._versions(), counts=dict(self.state.counts),
            wall_time=wall)

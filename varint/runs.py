"""What every public run shares: checking the inputs, building the initial
deviation vectors and the propagator, driving to the output times, and
packaging the records into a result with its provenance."""

from __future__ import annotations

import numpy as np

from . import _validate as check
from .driver import IntegrationError, drive, failure_message
from .methods import make_propagator
from .results import Provenance, package_versions
from .state import RunState, initial_deviations, output_steps

__all__ = ["Run"]


class Run:
    """One call of a public run function, from inputs to result.

    Parameters
    ----------
    kind : str
        Name of the public function (for provenance and messages).
    model, x0, t_end, tau, method, t_out, seed, progress, errors
        As in the public functions.
    k : int
        Number of deviation vectors to carry (0 for none).
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
    """

    def __init__(self, kind, model, x0, t_end, tau, *, method, k, renorm, deviations=None,
                 seed=0, t_out=None, progress=None, errors="raise", require=None,
                 method_options=None, options=None):
        self.kind, self.model = kind, model
        self.x0, self.single = check.states(model, x0)
        self.t_end, self.tau = check.horizon(t_end, tau)
        self.errors = check.choice(errors, ("raise", "flag"), "errors")
        self.progress = progress
        m, dim = self.x0.shape
        if deviations is not None:
            W0 = check.deviations(deviations, dim, m)
            if require == "orthonormal":
                check.orthonormal(W0)
            elif require == "unit":
                check.full_rank(W0)
                W0 = W0 / np.linalg.norm(W0, axis=1, keepdims=True)
            self.seed = None
        else:
            if seed is None:
                seed = int(np.random.SeedSequence().entropy)
            elif isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
                raise ValueError(f"seed must be a non-negative integer or None, got {seed!r}")
            self.seed = int(seed)
            W0 = initial_deviations(dim, k, m, self.seed)
        self.W0 = W0
        self.steps = output_steps(self.t_end, self.tau, t_out)
        self.propagator = make_propagator(method, model, self.tau, renorm,
                                          **(method_options or {}))
        self.method = method.lower()
        self.options = dict(options or {})
        self.state = RunState.start(self.x0, W0)
        self.energy0 = model.energy(self.x0)

    def energy_error(self, x):
        """Relative energy error of states ``x`` (M, 2N) against the start."""
        h0 = self.energy0
        scale = np.where(h0 != 0, np.abs(h0), 1.0)
        return np.abs(self.model.energy(x) - h0) / scale

    def execute(self, record, build):
        """Drive the run and return ``build(t, fields)`` as the result.

        ``record(state)`` returns a dict of per-orbit arrays at an output
        time (the energy error is added here); ``build(t, fields, common)``
        makes the result from the stacked, orbit-first arrays.
        """
        def full_record(state):
            rec = record(state)
            rec["energy_error"] = self.energy_error(state.x)
            return rec

        records, stop, wall = drive(self.propagator, self.state, self.steps, full_record,
                                    progress=self.progress, desc=self.kind, errors=self.errors)
        n_done = len(next(iter(records.values()))) if records else 0
        t = self.steps[:n_done] * self.tau
        fields = {}
        for key, arr in records.items():
            arr = np.moveaxis(arr, 0, 1)  # (M, n_out, ...)
            fields[key] = arr[0] if self.single else arr
        common = dict(t=t, energy_error=fields.pop("energy_error", np.empty((0,))),
                      state=self._squeeze(self.state.x), provenance=self._provenance(wall),
                      status=self._squeeze(self.state.status), interrupted=stop == "interrupted")
        result = build(t, fields, common)
        if stop == "failed" or (self.errors == "raise" and (self.state.status != 0).any()):
            msg, info = failure_message(self.state, self.tau, self.single)
            raise IntegrationError(msg, partial=result, **info)
        return result

    def _squeeze(self, arr):
        return arr[0] if self.single else arr

    def _provenance(self, wall):
        prop = self.propagator
        versions = dict(package_versions())
        versions.update(prop.versions())
        return Provenance(
            kind=self.kind, model=self.model.describe(),
            x0=(self.x0[0] if self.single else self.x0).tolist(), method=self.method,
            method_options=prop.describe(), tau=self.tau, t_end=self.t_end, seed=self.seed,
            options=self.options, versions=versions, counts=dict(self.state.counts),
            wall_time=wall)

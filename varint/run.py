"""One generic run: (model, indicator, method, times) → result.

:func:`run` computes any registered indicator (:data:`varint.INDICATORS`)
with any method (:data:`varint.METHODS`) for one orbit or a batch; the
public functions :func:`~varint.lyapunov_spectrum`, :func:`~varint.gali`,
:func:`~varint.sali`, :func:`~varint.megno` and :func:`~varint.integrate`
are thin wrappers over it, and :func:`~varint.chaos_map` runs it chunk by
chunk. What it shares with every indicator and method: the inputs checked
before any work into a :class:`~varint.runspec.RunSpec`
(:func:`~varint.runspec.specify`), which a :class:`Run` executes: drawing
seeded initial deviation vectors, choosing τ when it is not given, building the
propagator, resuming from a checkpoint, driving to the output times
(:mod:`varint.driver`), and packaging the records into a result with its
provenance and its accuracy.
"""

from __future__ import annotations

import copy
import os
import time
import warnings
from typing import Any

import numpy as np
from numba.core.errors import NumbaError
from numpy.typing import ArrayLike

from . import _validate as check
from . import accuracy, compiling, identity, remembered
from .driver import IntegrationError, drive, failure_message
from .files import canonical, digest
from .indicators import Indicator
from .methods import make_propagator
from .models.base import Model
from .protocol import TIME_MOMENTUM, Renorm, is_failure
from .records import Records
from .runspec import DEFAULT_TAU, RunSpec, default_tau, specify
from .results import Provenance, _Result, package_versions
from .state import Rows, RunState, initial_deviations, renormalized_copy

__all__ = ["run", "prepare", "Run", "DEFAULT_TAU", "default_tau", "energy_scale"]

#: Initial states of at most this many numbers are stored in a checkpoint's
#: parameters as values (so a mismatch shows them), larger ones as a digest.
_SHOWN_X0 = 32


def run(model: Model, x0: ArrayLike, indicator: str | Indicator, t_end: float,
        tau: float | None = None, **options: Any) -> _Result:
    """Compute an indicator along one or many orbits.

    Parameters
    ----------
    model : Model
        The system (:mod:`varint.models`, or :func:`~varint.models.from_potential`).
    x0 : array_like, shape (2N,) or (M, 2N)
        Initial state(s) (q, p); several orbits run in one call.
    indicator : str or Indicator
        A name of :data:`varint.INDICATORS` ("lyapunov", "gali", "sali",
        "megno", "fli", "ofli", "local_exponents", "integrate", …, or the
        shorthands "x1" and "gali_3"), or an
        :class:`~varint.indicators.Indicator`.
    t_end : float
        Final time (rounded to a multiple of τ).
    tau : float, optional
        Renormalisation interval, which is also the step of the splitting
        methods ("tm" and the TDH methods). By default the largest step of
        the scheme whose relative energy error over a short pilot run stays
        within ``energy_tol / 100`` (:mod:`varint.stepsize`; recorded in
        ``result.provenance.tau_choice``); 0.05 for the methods whose τ is
        not a step (CVODE, DOP853, Taylor). A given τ is used as it is. For
        a map model (:mod:`varint.models.maps`): a whole number of
        iterations, default 1, and t counts iterations.

    Other Parameters
    ----------------
    method : str, default "tm"
        Integration method (see :data:`varint.METHODS`).
    scheme : str or SplittingScheme, optional
        Splitting scheme of "tm" and the TDH methods; the paper's SBAB2C by
        default.
    t_out : None, int or array_like
        Output times (see :func:`varint.state.output_steps`); by default
        log-spaced, 10 per decade (or the indicator's own default, e.g.
        only t_end for "integrate").
    seed : int or None, default 0
        Seed of the random orthonormal initial deviation vectors (orbit m of
        a batch draws from ``numpy.random.default_rng([seed, m])``); None
        draws one (recorded in the provenance, and reused when resuming).
    deviations : array_like, shape ([M,] 2N, k), optional
        Initial deviation vectors instead of random ones; they must satisfy
        what the indicator requires (orthonormal for Lyapunov exponents,
        independent for GALI and SALI, which normalise them).
    progress : bool, optional
        Progress bar on stderr; by default only when stderr is a terminal.
    errors : {"raise", "flag"}
        A failing orbit (non-finite, escaped, degenerate vectors, a
        potential singular on the orbit) raises :class:`IntegrationError`,
        whose message gives the time and step and which carries the partial
        result; with "flag" it is frozen, its ``status`` is non-zero and its
        later values are NaN (a warning says how many failed).
    escape_radius : float, optional
        Stop an orbit as escaped once |q| exceeds this (overrides the
        model's ``escape_radius`` for this call).
    checkpoint : str or os.PathLike, optional
        Save the run to this file every ``checkpoint_interval`` seconds and
        when it stops (finished, failed or interrupted by Ctrl-C). If the
        file exists, the run resumes from it, and the result is bitwise
        identical to an uninterrupted run. A checkpoint written with other
        arguments is refused with a :class:`CheckpointError` naming them.
    checkpoint_interval : float, default 60
        Seconds of wall time between checkpoint writes.
    energy_tol : float, optional
        The relative error of the energy (and of any other quantity the
        model conserves) above which the result's indicators are not
        trusted: ``result.accuracy`` says so and an
        :class:`~varint.accuracy.AccuracyWarning` gives the figure and what
        to do; 1e-3 by default (:data:`varint.accuracy.DEFAULT_ENERGY_TOL`,
        measured), ``inf`` never warns. Also sets the automatic step.
    **options
        The indicator's options (e.g. ``k`` for GALI, ``n_exponents`` for
        the spectrum, ``window`` for local exponents; see
        ``varint.INDICATORS[name].options``) and the method's (e.g.
        ``rtol`` for CVODE). An option neither takes raises ``TypeError``
        listing the valid ones.

    Returns
    -------
    result
        The indicator's result class (e.g. :class:`~varint.LyapunovResult`):
        ``t`` (n_out,), its series ([M,] n_out, ...), ``energy_error``,
        ``status``, the final ``state`` and ``deviations``, the
        ``accuracy`` verdict (:class:`~varint.accuracy.Accuracy`) and
        ``provenance``. After Ctrl-C: the outputs recorded so far, with
        ``interrupted=True`` (and a warning); a second Ctrl-C stops at once.

    Raises
    ------
    ValueError
        For bad input, before any work is done (the message names the value
        and what was expected).
    IntegrationError
        When an orbit fails and ``errors="raise"``.

    Warns
    -----
    AccuracyWarning
        When the energy error exceeds ``energy_tol``.

    Notes
    -----
    A call that repeats one of the last few calls' arguments (τ given, no
    checkpoint, a fixed seed) but its initial states and vectors runs that
    call's checked set-up again (:mod:`varint.remembered`), as a prepared
    run's call does (:func:`varint.prepare`): same result, bit for bit,
    for a fraction of the fixed cost.

    Examples
    --------
    >>> import varint
    >>> model, x0 = varint.paper_orbit("C1")
    >>> r = varint.run(model, x0, "local_exponents", 200.0, window=50.0)
    >>> r.local.shape
    (4, 1)
    """
    found = remembered.call_key(model, x0, indicator, t_end, tau, options)
    if found is not None:
        again = remembered.recall(found[0])
        if again is not None:
            # An earlier call's arguments but the states and vectors: its
            # set-up run again (varint.remembered), the result bitwise.
            return again(x0, options.get("deviations"))
    first = prepare(model, x0, indicator, t_end, tau, **options)
    result = first.execute()
    if found is not None and not result.interrupted:
        remembered.remember(*found, first, result.provenance.timing.get("run", np.inf))
    return result


def prepare(model: Model, x0: ArrayLike, indicator: str | Indicator, t_end: float,
            tau: float | None = None, *, method: str = "tm",
            t_out: int | ArrayLike | None = None, seed: int | None = 0,
            deviations: ArrayLike | None = None, progress: bool | None = None,
            errors: str = "raise", escape_radius: float | None = None,
            checkpoint: str | os.PathLike[str] | None = None,
            checkpoint_interval: float = 60.0, energy_tol: float | None = None,
            **options: Any) -> Run:
    """The :class:`Run` of :func:`run` (same arguments), every input checked
    and the state started or resumed, not yet executed."""
    spec = specify(model, x0, indicator, t_end, tau, method=method, t_out=t_out, seed=seed,
                   escape_radius=escape_radius, energy_tol=energy_tol, **options)
    return Run(spec, deviations=deviations, progress=progress, errors=errors,
               checkpoint=checkpoint, checkpoint_interval=checkpoint_interval)


def _copied(obj):
    """A copy of the JSON-like ``obj``, its dicts and lists copied at every
    level: no result's provenance shares what another's holds."""
    if isinstance(obj, dict):
        return {key: _copied(value) for key, value in obj.items()}
    if isinstance(obj, list):
        return [_copied(value) for value in obj]
    return obj


def energy_scale(model, x):
    """The energy scale against which energy errors are relative, per orbit
    (:meth:`varint.models.base.Model.energy_scale`: |T| + |V| at t = 0)."""
    return model.energy_scale(x)


class Run:
    """One run of a :class:`~varint.runspec.RunSpec` (built by
    :func:`prepare`, or by a chaos map for each chunk): its deviation
    vectors drawn or checked, τ chosen if the specification leaves it open,
    its propagator built, its state started or resumed from a checkpoint.

    Attributes
    ----------
    spec : RunSpec
        What it runs, τ and the output steps fixed.
    model, indicator, options
        The model, the :class:`~varint.indicators.Indicator` and its
        checked options.
    x0 : ndarray, shape (M, 2N)
    single : bool
        Whether the caller passed one state (results drop the orbit axis).
    t_end, tau : float
    tau_choice : dict
        How τ was chosen (:class:`varint.stepsize.StepChoice`): given, or by
        a pilot.
    energy_tol : float
    steps : ndarray of int
        Output steps (multiples of τ).
    propagator
        The method (:class:`varint.protocol.Propagator`).
    seed : int or None
        None when the deviation vectors were given.
    state : RunState
    records : varint.records.Records
        The outputs recorded so far (after a resume, those of earlier
        sessions).
    """

    def __init__(self, spec: RunSpec, deviations=None, progress=None, errors="raise",
                 checkpoint=None, checkpoint_interval=60.0):
        # The machine as the run starts (its load, above all), and the code:
        # worked out once per process, at its first run, not hours later.
        self.machine, self.code = identity.machine(), identity.code_identity()
        self.errors = check.choice(errors, ("raise", "flag"), "errors")
        self.progress = check.flag(progress, "progress")
        self.model, self.x0, self.single = spec.model, spec.x0, spec.single
        self.indicator = ind = spec.indicator
        self.options = dict(spec.options)
        self.run_options = spec.run_options
        self.method, self.energy_tol = spec.method, spec.energy_tol
        # A chunk's specification leaves its orbits' reference to its run.
        self.reference = (spec.reference if spec.reference is not None
                          else accuracy.Reference(spec.model, spec.x0))
        ckpt = None
        if checkpoint is not None:
            # Imported here: a run without a checkpoint file (most) loads no
            # file format (issue 28, a first run's start-up).
            from .checkpoint import Checkpoint

            ckpt = Checkpoint(checkpoint, checkpoint_interval)
        self.checkpoint = ckpt
        saved = None if ckpt is None else ckpt.read()
        self.W0, self.seed = self._initial_vectors(deviations, spec.seed, saved)
        if ind.count_option is not None:
            self.options[ind.count_option] = self.W0.shape[2]
        self.accumulator = ind.accumulator_for(self.options)
        scheme = spec.scheme
        self.clock = compiling.Clock(
            f"{ind.name} of {spec.model.name} by {self.method}"
            + (f" ({getattr(scheme, 'name', scheme)})" if scheme is not None else ""),
            self.progress)
        if spec.tau is None:
            with self.clock.part("pilot"):
                spec = spec.with_pilot_step(W0=self.W0, accumulator=self.accumulator)
        elif spec.steps is None:
            spec = spec.with_step(spec.tau)
        self.spec = spec
        self.t_end, self.tau, self.steps = spec.t_end, spec.tau, np.asarray(spec.steps)
        self.tau_choice = spec.tau_choice
        self._check_size()
        with self.clock.part("setup"):
            self.propagator = make_propagator(self.method, self.model, self.tau, ind.renorm,
                                              self.accumulator, **spec.method_options)
        if hasattr(self.propagator, "set_horizon"):
            # A baseline integrating blocks of intervals ends none past the run.
            self.propagator.set_horizon(int(self.steps[-1]))
        start = self._start_state()
        if ckpt is None or saved is None:
            self.state, self.records = start, Records()
            self.wall_before, self.cpu_before = 0.0, 0.0
        else:
            ckpt.require(saved, self.parameters())
            # Nothing from the file reaches a stepper before it is checked.
            ckpt.validate(saved, start, self.steps, self._template_record(start),
                                     ind.renorm)
            self.state, self.records = saved.state, saved.records
            self.wall_before, self.cpu_before = saved.wall_time, saved.cpu_time
        self.resumed = saved is not None
        self.cpu_session = 0.0
        self.energy0 = self.reference.values["energy"]
        self.energy_scale = self.reference.scales["energy"]
        # The provenance's parts that no orbit changes (:meth:`provenance`),
        # worked out once for the runs :meth:`with_orbits` makes of this one.
        self._fixed = None

    def with_orbits(self, spec, deviations=None):
        """A new run of this run's setup over other orbits, nothing that
        depends only on the specification done again (what a prepared run,
        :mod:`varint.prepared`, does at each call).

        ``spec`` is this run's specification with other states
        (:meth:`RunSpec.with_states`; τ, output steps and everything else
        the same); ``deviations`` as for :func:`prepare`, as many vectors as
        this run's, or None: this run's vectors (for as many orbits; else
        seeded ones of the specification's seed). The propagator (and its
        compiled kernels) is this run's: it holds no state of a run, so the
        new run's result is bitwise that of a run built from scratch. Not
        for a run with a checkpoint (a file belongs to one run).
        """
        if self.checkpoint is not None:
            raise ValueError("a run with a checkpoint cannot be run again over other orbits")
        if self._fixed is None:
            self._fixed = self._fixed_provenance()     # shared by every new run
        new = copy.copy(self)
        new.spec, new.x0, new.single, new.reference = spec, spec.x0, spec.single, spec.reference
        new.options = dict(self.options)
        m = spec.x0.shape[0]
        if deviations is None and m == self.x0.shape[0] and (
                self.seed is None or spec.seed is not None):
            # This run's vectors, given and checked or seeded, for as many
            # orbits (the state starts from a copy of them); a run whose
            # seed is drawn (seed=None) draws a new one.
            new.W0 = self.W0
        else:
            new.W0, new.seed = new._initial_vectors(deviations, spec.seed, None)
            if new.W0.shape[2] != self.W0.shape[2]:
                raise ValueError(f"deviations must hold {self.W0.shape[2]} vectors (columns), "
                                 f"as this run's do, got {new.W0.shape[2]}")
            if m != self.x0.shape[0]:
                new._check_size()
        new.machine = identity.machine()
        new.clock = compiling.Clock(self.clock.what, self.progress)
        new.state, new.records = new._start_state(), Records()
        new.wall_before, new.cpu_before, new.cpu_session = 0.0, 0.0, 0.0
        new.energy0 = spec.reference.values["energy"]
        new.energy_scale = spec.reference.scales["energy"]
        return new

    def _start_state(self):
        """The state the run starts from: the orbits, the initial vectors and
        the indicator's accumulator."""
        state = RunState.start(self.x0, self.W0)
        acc = self.accumulator
        if acc is not None:
            state.extra[acc.key] = np.tile(np.array(acc.initial, dtype=np.float64),
                                           (state.n_orbits, state.k, 1))
        return state

    def _template_record(self, start):
        """One record of this run (its keys, shapes and dtypes), read off the
        start state one step on, to check stored records against."""
        rows = Rows.of(start)
        rows.step = rows.step + 1
        with np.errstate(all="ignore"):
            rec = self.indicator.read(rows, self.model, rows.step * self.tau, self.options)
            rec.update(self.reference.errors(rows.x, rows.step * self.tau,
                                             rows.extra.get(TIME_MOMENTUM, 0.0)))
        return rec

    def _check_size(self):
        """Refuse a run whose vectors and records would not fit in memory,
        before allocating them."""
        m, dim = self.x0.shape
        k = self.W0.shape[2]
        # Vectors: the state's, the initial ones and the QR workspace; per
        # output and orbit at most the state, k exponents, 2N GALIs and the
        # errors, held twice (the records and their stacked arrays).
        need = check.array_bytes((4, m, dim, k), (2, len(self.steps), m, 2 * dim + k + 4))
        check.check_memory(need, f"a run of {m} orbit(s) of {self.model.name} with {k} "
                                 f"deviation vectors and {len(self.steps)} output times")

    def _initial_vectors(self, deviations, seed, saved):
        """(W0 (M, 2N, k), seed): the given vectors, checked as the
        indicator requires, or seeded random orthonormal ones."""
        ind, model = self.indicator, self.model
        m, dim = self.x0.shape
        if deviations is None:
            k = ind.vectors(model, self.options, None)
            seed = self._seed(seed, saved)
            # The vectors, their copies and the QR workspace, before any.
            check.check_memory(check.array_bytes((4, m, dim, k)),
                               f"a run of {m} orbit(s) of {model.name} with {k} deviation "
                               "vectors")
            return initial_deviations(dim, k, m, seed), seed
        W0 = check.deviations(deviations, dim, m)
        if ind.renorm != Renorm.NONE:
            check.n_vectors(W0.shape[2], dim, "the number of deviation vectors "
                            "(columns of deviations)")
        ind.vectors(model, self.options, W0.shape[2])
        if ind.require == "orthonormal":
            check.orthonormal(W0)
        elif ind.require == "unit":
            check.full_rank(W0)
            # Columns of unit length to round-off (e.g. seeded orthonormal
            # ones) are kept as given: a run given the vectors its seed
            # would draw (as a chaos map's chunk is) is the seeded run, bit
            # for bit.
            norms = np.linalg.norm(W0, axis=1, keepdims=True)
            W0 = np.where(np.abs(norms - 1.0) <= 8 * np.finfo(float).eps, W0, W0 / norms)
        return W0, None

    def checked_vectors(self, deviations):
        """``deviations`` (([M,] 2N, k)) checked as this run's given vectors
        were (:meth:`_initial_vectors`, the same errors), for as many
        orbits as this run's: W0 (M, 2N, k)."""
        return self._initial_vectors(deviations, None, None)[0]

    @staticmethod
    def _seed(seed, saved):
        """The run's seed: the given one, else the one a checkpoint drew
        (resuming must continue with the same vectors), else a new one."""
        if seed is not None:
            return seed
        stored = None if saved is None else saved.parameters.get("seed")
        return stored if isinstance(stored, int) else int(np.random.SeedSequence().entropy)

    def parameters(self):
        """Everything that determines the result, as JSON: what a checkpoint
        must match to be resumed (package versions and the digest of
        varint's sources included, since a different NumPy, numba or varint
        may change the last bits)."""
        x0 = self.x0.tolist() if self.x0.size <= _SHOWN_X0 else digest(self.x0)
        return {"kind": self.indicator.name, "model": self.model.describe(), "x0": x0,
                "t_end": self.t_end, "tau": self.tau, "t_out": digest(self.steps),
                "method": self.method, "method_options": self.propagator.describe(),
                "seed": self.seed,
                "deviations": None if self.seed is not None else digest(self.W0),
                "options": {**self.options, **self.run_options}, "versions": self.versions(),
                "code": identity.source_digest()}

    def versions(self):
        """Versions of the packages the run depends on."""
        versions = dict(package_versions())
        versions.update(self.propagator.versions())
        return versions

    def record(self, rows):
        """The indicator's values at every row (a :class:`~varint.state.Rows`:
        one per orbit, and per output time when several outputs are read at
        once), and the relative errors of the conserved quantities (for a
        time-dependent V, of the extended energy K = H(x, t) + p_t, p_t the
        momenta conjugate to time in ``extra[TIME_MOMENTUM]``). An orbit
        where they are not finite is marked failed
        (:func:`varint.accuracy.flag_nonfinite`)."""
        t = rows.step * self.tau
        rec = self.indicator.read(rows, self.model, t, self.options)
        errors = self.reference.errors(rows.x, t, rows.extra.get(TIME_MOMENTUM, 0.0),
                                       rows.energy)
        accuracy.flag_nonfinite(self.state, errors, rows.step)
        rec.update(errors)
        return rec

    def execute(self):
        """Drive the run to its last output time and return its result."""
        records, stop, wall = self.drive()
        if self.errors == "raise":
            records = self._before_failure(records)
        result = self._result(records, stop == "interrupted", wall)
        self._report_failures(result)
        accuracy.warn(result.accuracy, self.method)
        return result

    def _before_failure(self, records):
        """The records made before the first failure: a failure found when
        recording (:func:`varint.accuracy.flag_nonfinite`) has made one
        record holding NaN, which a partial result must not pass on."""
        failed = is_failure(self.state.status)
        if not records or not failed.any():
            return records
        first = self.state.fail_step[failed].min()
        n = len(next(iter(records.values())))
        keep = int(np.searchsorted(self.steps[:n], first))
        return records if keep == n else {k: v[:keep] for k, v in records.items()}

    def drive(self, record=None, decide=None, cancelled=None, stack=True):
        """Advance to every output time, recording there.

        Parameters
        ----------
        record : callable, optional
            ``record(rows) -> dict`` of arrays, one row per row of the
            :class:`~varint.state.Rows`; :meth:`record` by default (chaos maps
            record only their one value).
        decide : callable, optional
            ``decide(record) -> bool array (M,)``: orbits to stop early (see
            :func:`varint.driver.drive`).
        cancelled : callable, optional
            ``cancelled() -> bool``: stop as after Ctrl-C (see
            :func:`varint.driver.drive`).
        stack : bool
            False: the records as :class:`~varint.records.Records`, not
            joined (see :func:`varint.driver.drive`).

        Returns
        -------
        records, stop, wall
            As :func:`varint.driver.drive`.
        """
        self._begin_checkpoint()
        cpu = time.process_time()
        try:
            with self.clock.part("run"):
                return drive(self.propagator, self.state, self.steps, record or self.record,
                             records=self.records, progress=self.progress,
                             desc=self.indicator.name, errors=self.errors,
                             checkpoint=self.checkpoint, decide=decide,
                             renorm=self.indicator.renorm,
                             cancelled=cancelled, stack=stack)
        except NumbaError as exc:
            # A model kernel that does not fit the protocol fails to compile
            # into the stepper; say so instead of showing numba's internals.
            first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
            raise TypeError(
                f"the kernels of model {self.model.name!r} could not be compiled into the "
                f"{self.method!r} integrator ({first}); they must be numba functions "
                "grad(q, par, g), hess(q, par, B), third(q, par, v, B) writing float64 arrays "
                "in place, see varint.models.base") from exc
        finally:
            self.cpu_session = time.process_time() - cpu

    def _begin_checkpoint(self):
        if self.checkpoint is None:
            return
        self.checkpoint.begin(self.parameters(), self.wall_before, self.cpu_before)
        if self.resumed:
            self.checkpoint.mark_saved(self.state, self.records)
        else:
            # Before any work: an unusable path fails now, not hours later.
            self.checkpoint.save(self.state, self.records, strict=True)

    def _result(self, records, interrupted, wall):
        if not records:
            # Nothing recorded yet: empty series of the right shapes.
            now = self.record(Rows.of(self.state))
            records = {key: np.asarray(v)[None][:0] for key, v in now.items()}
        n_done = len(next(iter(records.values())))
        # Records are (n_out, M, ...); results (M, n_out, ...).
        fields = {key: self.squeeze(arr.swapaxes(0, 1)) for key, arr in records.items()}
        errors = {key: records[key].swapaxes(0, 1) for key in records
                  if key == "energy_error" or key.startswith("conserved_error:")}
        for key in errors:
            fields.pop(key)
        t = self.steps[:n_done] * self.tau
        verdict = accuracy.annotate(
            accuracy.assess(t, errors, self.state.status, self.energy_tol, self.tau,
                            self.single), self.model, self.propagator)
        fields = self.indicator.finish(fields, self.options)
        cls = self.indicator.result
        if "deviations" in getattr(cls, "__dataclass_fields__", {}):
            fields["deviations"] = self.squeeze(self.final_vectors())
        return cls(t=t, energy_error=self.squeeze(errors["energy_error"]),
                   state=self.squeeze(self.state.x), provenance=self.provenance(wall),
                   status=self.squeeze(self.state.status), interrupted=interrupted,
                   accuracy=verdict, **fields)

    def final_vectors(self):
        """The deviation vectors at the end, renormalised as the indicator
        renormalises them (a propagator that renormalises sparsely may have
        left them raw)."""
        W = self.state.W
        if getattr(self.propagator, "sparse", 0) and W.shape[-1]:
            W, _, _ = renormalized_copy(W, self.state.acc_m, self.state.acc_e,
                                        self.indicator.renorm)
        return W

    def _report_failures(self, result):
        failed = is_failure(self.state.status)
        if not failed.any():
            return
        msg, info = failure_message(self.state, self.tau, self.single)
        msg += self._escape_hint(info["orbit"])
        if self.errors == "raise":
            if failed.sum() > 1:
                msg += f" ({failed.sum()} orbits failed; pass errors='flag' to keep the others)"
            raise IntegrationError(msg, partial=result, **info)
        warnings.warn(f"{int(failed.sum())} of {failed.size} orbits failed and were frozen "
                      f"(their status is non-zero, their later outputs NaN); first: {msg}",
                      RuntimeWarning, stacklevel=accuracy.user_stacklevel())

    def _escape_hint(self, orbit):
        # Hénon–Heiles above 1/6 (any model with an escape energy): say why.
        e_esc = getattr(self.model, "escape_energy", None)
        e0 = float(self.energy0[orbit])
        if e_esc is None or not e0 > e_esc:
            return ""
        return (f"; its energy {e0:.6g} is above the escape energy {e_esc:.6g} of "
                f"{self.model.name}, so it can leave the potential well (escape_radius= stops "
                "such orbits as soon as |q| exceeds it)")

    def squeeze(self, arr):
        """``arr`` without its orbit axis when the caller passed one state."""
        return arr[0] if self.single else arr

    def provenance(self, wall):
        """The :class:`~varint.results.Provenance` of the run after ``wall``
        seconds of this session (with a checkpoint, its clock: it started
        before the session's first write, so the result never reports less
        time than its checkpoint does)."""
        total = (self.wall_before + wall if self.checkpoint is None
                 else max(self.wall_before + wall, self.checkpoint.wall_time()))
        # A run over new orbits (with_orbits) copies the parts worked out
        # once: each result gets its own (:func:`_copied`).
        fixed = (self._fixed_provenance() if self._fixed is None
                 else {key: _copied(value) for key, value in self._fixed.items()})
        return Provenance(
            kind=self.indicator.name, x0=self.squeeze(self.x0).tolist(), method=self.method,
            tau=self.tau, t_end=self.t_end, seed=self.seed, **fixed,
            counts=dict(self.state.counts),
            wall_time=total, tau_choice=dict(self.tau_choice),
            code=dict(self.code), machine=dict(self.machine), timing=self.timing(),
            cpu_time=None if self.cpu_before is None else self.cpu_before + self.cpu_session)

    def _fixed_provenance(self):
        """The parts of the provenance no orbit changes: the model's and the
        method's descriptions, the options and the versions."""
        return {"model": self.model.describe(), "method_options": self.propagator.describe(),
                "options": canonical({**self.options, **self.run_options}),
                "versions": self.versions()}

    def timing(self):
        """Seconds of this session's compilation, pilot, setup and run
        (each without the compilations inside it; :mod:`varint.compiling`)."""
        return {k: round(v, 6) for k, v in self.clock.timing.items()}

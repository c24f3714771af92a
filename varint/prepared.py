"""A run prepared once and run from many initial conditions:
:func:`prepare` → :class:`PreparedRun`, called with each ``x0``.

A researcher's short runs are mostly the same model, indicator, method,
scheme, τ and times from different initial states (a scan, a bisection, a
Monte Carlo sample), and a one-shot call (:func:`varint.run`) checks and
builds all of that again every time. A prepared run checks the arguments
once (:func:`varint.runspec.specify_call`, output steps fixed), builds its
propagator at the first call and keeps it; each call then only checks its
states (shape, finite, the model's kernels finite there, what the
indicator requires), measures their reference energy, starts the state and
drives it (:meth:`varint.run.Run.with_orbits`). A short call (one expected
to last less than one of the driver's chunks, 0.2 s, by a generated TM
stepper on the CPU) takes a shorter path, :class:`_ShortCall`: the whole
run in one stepper call on buffers kept per thread, the outputs read once,
the energy errors and the verdict in one compiled pass, the result
assembled directly, everything that does not depend on the states made
once (issue 28: the fixed cost of a call). The result is the one-shot
call's, bitwise, with the same type and provenance (heyoka's counterpart
is a built integrator's ``propagate_until`` from a new state).
"""

from __future__ import annotations

import pickle
import threading
import time
from typing import Any, cast

import numpy as np
from numpy.typing import ArrayLike

from . import _validate as check
from . import accuracy, floating_errors, identity
from .driver import CHUNK_SECONDS, SNAPSHOT_BYTES
from .indicators import Indicator
from .kernels.energy_errors import SEQUENTIAL_TERMS, energy_errors, state_energy_errors
from .kernels.resolved import Resolved
from .methods.fresh_run import FreshRun
from .models.base import Model
from .protocol import COUNTERS
from .results import Provenance, _Result
from .run import Run
from .runspec import RunSpec, specify_call
from .state import renormalized_copy

__all__ = ["prepare", "PreparedRun"]


def prepare(model: Model, indicator: str | Indicator, t_end: float, tau: float | None = None,
            *, deviations: ArrayLike | None = None, progress: bool | None = None,
            errors: str = "raise", **options: Any) -> PreparedRun:
    """A run of ``indicator`` along ``model`` to ``t_end`` with step ``tau``,
    checked once, to be called with each initial state.

    Parameters
    ----------
    model, indicator, t_end
        As for :func:`varint.run`.
    tau : float
        The step (renormalisation interval); required for a flow (the
        automatic step is chosen per orbit by a pilot run: give the τ a
        one-shot run chose, ``result.provenance.tau``); for a map, one
        iteration by default.
    deviations : array_like, shape ([M,] 2N, k), optional
        Initial deviation vectors of every call that passes none (else
        seeded random ones, ``seed``); they fix how many vectors each call
        carries.
    progress : bool, optional
        As for :func:`varint.run`: a progress bar on stderr (after a second)
        and the announcement of a long first compilation, by default only
        on a terminal.
    errors : {"raise", "flag"}
        As for :func:`varint.run`.
    **options
        As for :func:`varint.run` (``method``, ``scheme``, ``t_out``,
        ``seed``, ``escape_radius``, ``energy_tol``, the indicator's and the
        method's options); not ``checkpoint`` (a file belongs to one run).

    Returns
    -------
    PreparedRun
        Call it with ``x0`` ((2N,) or (M, 2N)) and optionally
        ``deviations``: the result of ``varint.run(model, x0, indicator,
        t_end, tau, ...)``, bitwise.

    Raises
    ------
    ValueError
        For bad arguments, before any work (as :func:`varint.run`), and for
        ``tau=None`` on a flow.

    Examples
    --------
    >>> import varint
    >>> model, x0 = varint.paper_orbit("R1")
    >>> run = varint.prepare(model, "megno", t_end=100.0, tau=0.05)
    >>> ys = [run(x0 + [0.0, 0.0, dp, 0.0]).mean_megno[-1] for dp in (0.0, 1e-3, 2e-3)]
    >>> bool(ys[0] == varint.megno(model, x0, 100.0, tau=0.05).mean_megno[-1])
    True
    """
    if "checkpoint" in options or "checkpoint_interval" in options:
        raise ValueError("a prepared run takes no checkpoint (a checkpoint file belongs to one "
                         "run); use varint.run(..., checkpoint=path) for a long run")
    spec = specify_call(model, indicator, t_end, tau, **options)
    if spec.tau is None:
        raise ValueError("a prepared run needs tau= (the automatic step is chosen per orbit by "
                         "a pilot run); give the step a one-shot run chose "
                         "(result.provenance.tau)")
    return PreparedRun(spec.with_step(spec.tau), deviations, check.flag(progress, "progress"),
                       check.choice(errors, ("raise", "flag"), "errors"))


class PreparedRun:
    """A run checked once, called with each initial state (built by
    :func:`prepare`).

    Attributes
    ----------
    spec : varint.runspec.RunSpec
        What every call runs, τ and the output steps fixed, without states.
    """

    def __init__(self, spec: RunSpec, deviations: ArrayLike | None, progress: bool | None,
                 errors: str) -> None:
        self.spec = spec
        self._deviations = deviations
        self._progress, self._errors = progress, errors
        # The kernels' check at each call's states, its buffers kept.
        self._kernel_check = check.KernelCheck(spec.model)
        # The first call's run: its propagator and set-up serve every later
        # call (Run.with_orbits).
        self._first: Run | None = None
        # The short calls' path over the first run, where it has one.
        self._short: _ShortCall | None = None

    def __call__(self, x0: ArrayLike, deviations: ArrayLike | None = None) -> _Result:
        """The result of the run from ``x0`` ((2N,) or (M, 2N)), with
        ``deviations`` (([M,] 2N, k), as many vectors as the prepared run
        carries) or the prepared run's vectors."""
        first, short = self._first, self._short
        if short is not None and deviations is None:
            # Its reference is measured with its outputs, after its run; it
            # needs the checked states, not a specification over them.
            x, single = self.spec.checked_states(x0, self._kernel_check)
            if short.takes(x):
                result = short(x, single)
                if result is not None:
                    return result
        spec = self.spec.with_states(x0, kernel_check=self._kernel_check)
        if first is None:
            vectors = self._deviations if deviations is None else deviations
            self._first = first = Run(spec, deviations=vectors, progress=self._progress,
                                      errors=self._errors)
            result = first.execute()
            self._short = _ShortCall.over(first, result)
            return result
        if deviations is None and spec.x0.shape[0] != first.x0.shape[0]:
            # The prepared vectors checked again for another number of
            # orbits (with as many, the first run's checked ones are used).
            deviations = self._deviations
        result = first.with_orbits(spec, deviations).execute()
        if short is not None:
            short.timed(result)
        return result

    def __repr__(self):
        s = self.spec
        return (f"PreparedRun({s.indicator.name} of {s.model.name} by {s.method}, "
                f"tau={s.tau:g}, t_end={s.t_end:g})")


class _ShortCall:
    """A prepared run's call whose whole run is one compiled call: its
    orbits stepped from their start to the last output by the propagator's
    :meth:`~varint.methods.tm.TangentMapPropagator.fresh_run` (one thread's
    buffers kept between calls), every output copied inside it, then
    recorded, assessed and returned with the minimum of Python; everything
    that does not depend on the states (the vectors, the accumulator's
    start, the schedule's, the provenance's fixed part) made once, from the
    first call's run.

    The arithmetic is the general path's (:meth:`Run.with_orbits` then
    :meth:`Run.execute`): the same compiled stepper from the same state,
    the outputs read by the same indicator, the energy errors from the
    model's own V and T by the same operations, T's compiled with them
    where they round the same as NumPy's
    (:func:`varint.kernels.energy_errors.state_energy_errors`, else
    :func:`~varint.kernels.energy_errors.energy_errors`; the verdict's
    largest errors with them), the rest of the verdict by
    :func:`~varint.accuracy.assess`'s rules; one chunk instead of the
    driver's chunks, which the propagator protocol makes bitwise (rule 3).
    So the result is the one-shot call's, bitwise; its provenance's parts
    that no state changes stay pickled until read
    (:meth:`varint.results.Provenance.with_pickled`). Taken only for calls
    expected to last under the driver's chunk (``CHUNK_SECONDS``, from the
    time per step of the calls before: Ctrl-C and a progress bar would wait
    no longer there) and whose snapshots fit its bound; a call in which an
    orbit fails, or a conserved quantity is not finite, is left to the
    general path, which reports it as a one-shot call does. Ctrl-C during
    a short call raises ``KeyboardInterrupt`` (as between two calls)
    instead of returning what it has: the general path's guard costs more
    than the fraction of a chunk it would save.
    """

    def __init__(self, first: Run) -> None:
        self.first = first
        self.prop = prop = first.propagator
        m, _, k = first.W0.shape
        self.m, self.k = m, k
        self.tau = cast(float, first.tau)      # fixed by then
        self.outs = np.asarray(first.steps, dtype=np.int64)
        #: The steps of every call: the last output's.
        self.steps = int(self.outs[-1])
        #: The output times (each result gets its own copy) and those of
        #: the snapshots' rows (output-major), which the indicators read.
        self.t = self.outs * self.tau
        self.t_rows = np.repeat(self.outs, m) * self.tau
        self.t_rows.flags.writeable = False
        acc = first.accumulator
        self.aux0 = (np.empty((m, 0, 0)) if acc is None else
                     np.tile(np.array(acc.initial, dtype=np.float64), (m, k, 1)))
        #: Bytes of the snapshots of every output (as the driver counts them).
        self.snapshot_bytes = len(self.outs) * (8 * m * (first.x0.shape[1] * (k + 1) + 2 * k)
                                                + self.aux0.nbytes)
        #: Seconds per step of the calls so far (:meth:`timed`).
        self.per_step = np.inf
        self.has_deviations = "deviations" in getattr(first.indicator.result,
                                                      "__dataclass_fields__", {})
        self.sparse = bool(prop.sparse) and k > 0
        #: The energy errors and the verdict's largest ones in one compiled
        #: call (:func:`_energy_verdict`) where the model's energy is
        #: T + V; otherwise by :func:`varint.accuracy.reference_and_errors`.
        self.plain = accuracy.plain_energy(first.model)
        self.errors_kernel = Resolved(energy_errors)
        #: T computed in that call too, from the states (bitwise NumPy's
        #: where T is the base model's over fewer than SEQUENTIAL_TERMS
        #: degrees of freedom, :mod:`varint.kernels.energy_errors`);
        #: otherwise the model's own NumPy T.
        model = first.model
        self.state_kernel = (Resolved(state_energy_errors) if self.plain
                             and type(model).kinetic is Model.kinetic
                             and model.n_dof < SEQUENTIAL_TERMS
                             and _float_vector(model.inverse_mass, model.n_dof) else None)
        # Each thread's runs (FreshRun: buffers and the stepper's compiled
        # version made at its first call).
        self._local = threading.local()
        # The provenance's parts that no state changes, pickled: each
        # result unpickles its own copy of every dict and list in one call,
        # at its first read (Provenance.with_pickled).
        self.fixed = pickle.dumps({**first._fixed_provenance(), "seed": first.seed,
                                   "tau_choice": first.tau_choice, "code": first.code},
                                  protocol=pickle.HIGHEST_PROTOCOL)

    @classmethod
    def over(cls, first: Run, result: _Result) -> _ShortCall | None:
        """The short path over the prepared run's first run (``result`` its
        result), or None where it cannot take its calls."""
        prop, spec = first.propagator, first.spec
        m, _, k = first.W0.shape
        runs_fresh = getattr(prop, "runs_fresh", None)
        if (runs_fresh is None or first.checkpoint is not None or first.model.time_dependent
                or (first.seed is not None and spec.seed is None) or not runs_fresh(m, k)):
            return None
        short = cls(first)
        if short.snapshot_bytes > SNAPSHOT_BYTES:
            return None     # the driver's bound on one chunk's snapshots
        short.timed(result)
        return short

    def timed(self, result: _Result) -> None:
        """Take the time per step of a call's ``result`` as the next calls'
        estimate."""
        self.per_step = result.provenance.timing.get("run", np.inf) / max(self.steps, 1)

    def takes(self, x: np.ndarray) -> bool:
        """Whether the call from the checked states ``x`` (M, 2N) is a
        short one."""
        return (x.shape[0] == self.m
                and (self.steps <= 64 or self.per_step * self.steps <= CHUNK_SECONDS))

    #: Most bytes of snapshots whose buffers a thread keeps between calls:
    #: larger ones are made at each call (their making costs little beside
    #: such a run, and a prepared run then holds no large buffers).
    KEEP_BYTES = 1 << 20

    def _run(self) -> FreshRun:
        """This thread's :class:`~varint.methods.fresh_run.FreshRun` (a new
        one for snapshots over :attr:`KEEP_BYTES`)."""
        run = getattr(self._local, "run", None)
        if run is None:
            run = self.prop.fresh_run(self.m, self.k, self.outs, self.aux0)
            if self.snapshot_bytes <= self.KEEP_BYTES:
                self._local.run = run
        return run

    def __call__(self, x0: np.ndarray, single: bool) -> _Result | None:
        """The result of the run from the checked states ``x0`` (M, 2N)
        (``single``: the caller's one state, its axis dropped in the
        result), or None where the general path must make it (a failure)."""
        first, ind, tau = self.first, self.first.indicator, self.tau
        m = self.m
        machine = identity.machine()        # the machine when the run starts
        cpu, start = time.process_time(), time.perf_counter()
        run = self._run()
        run(x0, first.W0)
        if np.count_nonzero(run.status):    # (ndarray.any's reduction costs 4x more)
            return None
        rows = run.rows(ind.renorm)
        options = dict(first.options)
        rec = ind.read(rows, first.model, self.t_rows, options)
        energies = self._energy_verdict(run.states, single)
        if energies is None:
            return None
        energy_error, verdict, over = energies
        wall = time.perf_counter() - start
        cpu = time.process_time() - cpu
        outs = self.outs
        self.per_step = wall / self.steps
        s = len(outs)
        # As the driver's records (its copy per key, (n_out, M, ...)) and
        # Run._result (results (M, n_out, ...), the orbit axis dropped for
        # one state).
        fields = {}
        for key, arr in rec.items():
            block = np.array(arr)
            # (One state: the one orbit's block, (n_out, ...) as it is.)
            fields[key] = (block if single else
                           block.reshape((s, m) + block.shape[1:]).swapaxes(0, 1))
        accuracy.annotate(verdict, first.model, self.prop)
        fields = ind.finish(fields, options)
        x, status = run.x.copy(), run.status[0] if single else run.status.copy()
        if self.has_deviations:
            W = (renormalized_copy(run.W, run.acc_m, run.acc_e, ind.renorm)[0] if self.sparse
                 else run.W.copy())
            fields["deviations"] = W[0] if single else W
        # (No orbit failed: each made every step.)
        counters = run.counters[0] if m == 1 else np.add.reduce(run.counters, axis=0)
        counts = {"steps": m * self.steps,
                  **dict(zip(COUNTERS, counters.tolist(), strict=True))}
        provenance = Provenance.with_pickled(
            self.fixed, kind=ind.name, x0=(x0[0] if single else x0).tolist(),
            method=first.method, tau=tau, t_end=first.t_end, counts=counts, wall_time=wall,
            machine=machine, timing={"compile": 0.0, "run": round(wall, 6)},
            cpu_time=cpu)
        result = ind.result(t=self.t.copy(), energy_error=energy_error,
                            state=x[0] if single else x, provenance=provenance, status=status,
                            interrupted=False, accuracy=verdict, **fields)
        if over:
            accuracy.warn(verdict, first.method)
        return result

    def _energy_verdict(self, states: np.ndarray, single: bool
                        ) -> tuple[np.ndarray, accuracy.Accuracy, bool] | None:
        """(energy errors ([M,] n_out), the accuracy verdict, whether to
        warn) of a call's ``states``: its M start states, then its outputs'
        (n_out·M, output-major; :attr:`FreshRun.states
        <varint.methods.fresh_run.FreshRun.states>`), the orbit axis dropped
        where ``single``, bitwise those of the general path
        (:meth:`varint.accuracy.Reference.errors`, :func:`varint.accuracy.assess`);
        None where an error is not finite (the general path reports it;
        H not finite at ``x0``: it refuses the state)."""
        first, m = self.first, self.m
        model, tol = first.model, first.energy_tol
        if self.plain:
            n, rows = model.n_dof, len(states)
            state_kernel = self.state_kernel
            # (np.errstate(all="ignore")'s handling, for less:
            # varint.floating_errors.)
            quiet = floating_errors.ignoring()
            try:
                # The model's own V (Reference's operations), once over the
                # states and the outputs, and its T (or T's operations,
                # compiled with the errors).
                potential = model.potential(states[:, :n])
                kinetic = None if state_kernel is not None else model.kinetic(states[:, n:])
            finally:
                floating_errors.restore(quiet)
            if not _float_vector(potential, rows):
                computed = None
            elif state_kernel is not None:
                computed = state_kernel(states, potential, model.inverse_mass, m, self.t)
            elif _float_vector(kinetic, rows):
                computed = self.errors_kernel(kinetic, potential, m, self.t)
            else:
                computed = None
            if computed is not None:
                packed, finite = computed
                if not finite:
                    return None
                if single:
                    # (m = 1; NumPy scalars, as the general path's verdict
                    # holds.)
                    largest, t_worst, errors = packed[0], packed[1], packed[2:]
                else:
                    largest, t_worst = packed[:m], packed[m:2 * m]
                    errors = packed[2 * m:].reshape(m, len(self.t))
                accurate = largest <= tol       # (assess's comparison)
                verdict = accuracy.Accuracy(
                    energy_error=largest, conserved={"energy": largest}, t_worst=t_worst,
                    energy_tol=tol, accurate=accurate, tau=self.tau)
                return errors, verdict, not accurate if single else bool(
                    np.count_nonzero(accurate) < m)
        # Other conserved quantities (or T and V of another kind): the
        # general path's functions.
        _, found = accuracy.reference_and_errors(model, states[:m], states[m:])
        if not all(np.isfinite(v).all() for v in found.values()):
            return None
        s = len(self.outs)
        blocks = {key: np.array(v).reshape(s, m).swapaxes(0, 1) for key, v in found.items()}
        verdict = accuracy.assess(self.t, blocks, np.zeros(m, dtype=np.int64), tol, self.tau,
                                  single)
        energy_error = blocks["energy_error"]
        return energy_error[0] if single else energy_error, verdict, True


def _float_vector(a: Any, size: int) -> bool:
    """Whether ``a`` is a C-contiguous float64 array of shape (size,): what
    :func:`varint.kernels.energy_errors.energy_errors` takes, and what a
    model's T and V of (R, N) rows are."""
    return (type(a) is np.ndarray and (a.dtype is _FLOAT64 or a.dtype == _FLOAT64)
            and a.shape == (size,) and a.flags.c_contiguous)


#: NumPy's float64 (the one object its arrays of native float64 share,
#: which ``is`` tests ~10x faster than ``==``).
_FLOAT64 = np.dtype(np.float64)

"""A run's set-up run again from other initial states: :class:`Rerun`,
the calls of a prepared run (:mod:`varint.prepared`) after its first and a
one-shot call (:func:`varint.run.run`) that repeats an earlier one's
arguments but its states, and :class:`ShortCall`, their path for a short
run (issue 28: the fixed cost of a call).

Both work over a finished :class:`varint.run.Run` (the first run), through
its methods only (:meth:`~varint.run.Run.with_orbits`,
:meth:`~varint.run.Run.checked_vectors`), so that the run module can keep
them without importing this module's users.
"""

from __future__ import annotations

import pickle
import threading
import time
from typing import Any, cast

import numpy as np

from . import _validate as check
from . import accuracy, floating_errors, identity
from .driver import CHUNK_SECONDS, SNAPSHOT_BYTES
from .kernels.energy_errors import (SEQUENTIAL_TERMS, energy_errors, hamiltonian_errors,
                                    state_energy_errors)
from .kernels.resolved import Resolved
from .methods.fresh_run import FreshRun
from .models.base import Model
from .models.potential_rows import NumPyPowers, Rows
from .results import Provenance, _Result

# The first run is a :class:`varint.run.Run`, annotated ``Any``: naming it
# here, even for the type checker only, would tie this module and the run
# module (which imports :mod:`varint.remembered`, which imports this one)
# into a circle.
FirstRun = Any

__all__ = ["Rerun", "ShortCall"]


class ShortCall:
    """A call of a :class:`Rerun` (a prepared run's, or a remembered
    one-shot call's) whose whole run is one compiled call: its
    orbits stepped from their start to the last output by the propagator's
    :meth:`~varint.methods.tm.TangentMapPropagator.fresh_run` (or the part
    stepper's, :meth:`~varint.methods.parts.PartsPropagator.fresh_run`, one
    call per output; one thread's buffers kept between calls), every output
    copied inside it, then
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

    def __init__(self, first: FirstRun) -> None:
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
        #: Where the energy is a HamiltonianModel's own (H, not T + V), the
        #: scale, the errors and the verdict's largest ones in one compiled
        #: call from its H and V
        #: (:func:`~varint.kernels.energy_errors.hamiltonian_errors`; V
        #: zeros where its scale is |H|).
        self.hamiltonian = accuracy.hamiltonian_energy(first.model)
        self.hamiltonian_kernel = Resolved(hamiltonian_errors)
        self.no_potential = np.zeros(m)
        #: What the verdict cannot check (the model's and propagator's,
        #: :func:`varint.accuracy.notes`), each verdict given a copy.
        self.notes = accuracy.notes(first.model, prop)
        #: T computed in that call too, from the states (bitwise NumPy's
        #: where T is the base model's over fewer than SEQUENTIAL_TERMS
        #: degrees of freedom, :mod:`varint.kernels.energy_errors`);
        #: otherwise the model's own NumPy T.
        model = first.model
        self.state_kernel = (Resolved(state_energy_errors) if self.plain
                             and type(model).kinetic is Model.kinetic
                             and model.n_dof < SEQUENTIAL_TERMS
                             and _float_vector(model.inverse_mass, model.n_dof) else None)
        #: V compiled, where the model has it (:attr:`Model.potential_rows
        #: <varint.models.base.Model.potential_rows>`, bitwise its NumPy V;
        #: on some CPUs compiled but for its powers, :class:`NumPyPowers`)
        #: and does not override ``potential``: called with
        #: :attr:`FreshRun.states <varint.methods.fresh_run.FreshRun.states>`,
        #: a C-contiguous (R, 2N) float64 array at every call, so through
        #: its compiled versions (:class:`Resolved`).
        rows_v = (model.potential_rows if self.plain
                  and type(model).potential is Model.potential else None)
        self.potential_kernel = (None if rows_v is None else rows_v.resolved()
                                 if isinstance(rows_v, (Rows, NumPyPowers))
                                 else Resolved(rows_v))
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
    def over(cls, first: FirstRun, run_seconds: float) -> ShortCall | None:
        """The short path over a first run (executed, ``run_seconds`` the
        time of its run), or None where it cannot take its calls."""
        prop, spec = first.propagator, first.spec
        m, _, k = first.W0.shape
        runs_fresh = getattr(prop, "runs_fresh", None)
        if (runs_fresh is None or first.checkpoint is not None or first.model.time_dependent
                or (first.seed is not None and spec.seed is None) or not runs_fresh(m, k)):
            return None
        short = cls(first)
        if short.snapshot_bytes > SNAPSHOT_BYTES:
            return None     # the driver's bound on one chunk's snapshots
        short.per_step = run_seconds / max(short.steps, 1)
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

    def vectors(self, deviations: Any) -> np.ndarray | None:
        """The vectors of a call from checked states of as many orbits as
        the first run's: the first run's for None; else ``deviations``
        checked as the general path checks them (the same errors), or
        None where the general path must run them (another number of
        vectors, or a first run whose vectors were seeded: its provenance
        records the seed)."""
        first = self.first
        if deviations is None:
            return first.W0
        if first.seed is not None:
            return None
        if first.indicator.require != "unit" and _equal_vectors(deviations, first.W0):
            # The first run's vectors, checked then: checking them again
            # (~15 µs, a tenth of a short call on the rotating bar) would
            # give them as they are.
            return first.W0
        W0 = first.checked_vectors(deviations)
        return W0 if W0.shape[2] == self.k else None

    #: Most bytes of snapshots whose buffers a thread keeps between calls:
    #: larger ones are made at each call (their making costs little beside
    #: such a run, and a prepared run then holds no large buffers).
    KEEP_BYTES = 1 << 20

    def _run(self) -> FreshRun:
        """This thread's :class:`~varint.methods.fresh_run.FreshRun` (or the
        part stepper's :class:`~varint.methods.fresh_parts_run.FreshPartsRun`,
        which has its interface; a new one for snapshots over
        :attr:`KEEP_BYTES`)."""
        run = getattr(self._local, "run", None)
        if run is None:
            run = self.prop.fresh_run(self.m, self.k, self.outs, self.aux0)
            if self.snapshot_bytes <= self.KEEP_BYTES:
                self._local.run = run
        return run

    def __call__(self, x0: np.ndarray, single: bool, W0: np.ndarray) -> _Result | None:
        """The result of the run from the checked states ``x0`` (M, 2N)
        (``single``: the caller's one state, its axis dropped in the
        result) and the checked vectors ``W0`` (M, 2N, k), or None where
        the general path must make it (a failure)."""
        first, ind, tau = self.first, self.first.indicator, self.tau
        m = self.m
        machine = identity.machine()        # the machine when the run starts
        cpu, start = time.process_time(), time.perf_counter()
        run = self._run()
        run(x0, W0)
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
        if self.notes:
            verdict.notes.update(self.notes)     # (accuracy.annotate's notes)
        fields = ind.finish(fields, options)
        x, status = run.x.copy(), run.status[0] if single else run.status.copy()
        if self.has_deviations:
            W = run.renormalized(ind.renorm)[0] if self.sparse else run.W.copy()
            fields["deviations"] = W[0] if single else W
        # (No orbit failed: each made every step.)
        counters = (run.counters.tolist()[0] if m == 1
                    else np.add.reduce(run.counters, axis=0).tolist())
        counts = dict(zip(run.count_keys, [m * self.steps, *counters], strict=True))
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
        computed = (self._plain_errors(states) if self.plain else
                    self._hamiltonian_errors(states) if self.hamiltonian else None)
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

    def _plain_errors(self, states: np.ndarray) -> tuple[np.ndarray, bool] | None:
        """(packed, finite) of :func:`~varint.kernels.energy_errors.energy_errors`
        for a model whose energy is T + V (:func:`varint.accuracy.plain_energy`),
        or None where T or V is not a float vector (the general path)."""
        model, m = self.first.model, self.m
        n, rows = model.n_dof, len(states)
        state_kernel, potential_kernel = self.state_kernel, self.potential_kernel
        # V compiled (it warns about nothing), else the model's own
        # (Reference's operations, once over the states and the outputs);
        # T's operations compiled with the errors, else the model's own T:
        # NumPy's parts under ignoring() (np.errstate's handling, for less:
        # varint.floating_errors).
        potential = None if potential_kernel is None else potential_kernel(states)
        kinetic = None
        if potential is None or state_kernel is None:
            quiet = floating_errors.ignoring()
            try:
                if potential is None:
                    potential = model.potential(states[:, :n])
                if state_kernel is None:
                    kinetic = model.kinetic(states[:, n:])
            finally:
                floating_errors.restore(quiet)
        if potential_kernel is None and not _float_vector(potential, rows):
            # (The compiled V's is such a vector: np.empty(rows) filled.)
            return None
        if state_kernel is not None:
            return state_kernel(states, potential, model.inverse_mass, m, self.t)
        if _float_vector(kinetic, rows):
            return self.errors_kernel(kinetic, potential, m, self.t)
        return None

    def _hamiltonian_errors(self, states: np.ndarray) -> tuple[np.ndarray, bool] | None:
        """(packed, finite) of :func:`~varint.kernels.energy_errors.hamiltonian_errors`
        for a model whose energy is a HamiltonianModel's own
        (:func:`varint.accuracy.hamiltonian_energy`): its H and V
        (:meth:`~varint.models.hamiltonian.HamiltonianModel.row_energies`)
        under :func:`varint.accuracy.reference_and_errors`' floating-point
        handling; None where they are not float vectors (the general path)."""
        m = self.m
        quiet = floating_errors.ignoring()
        try:
            h, v = self.first.model.row_energies(states, m)
        finally:
            floating_errors.restore(quiet)
        if v is None:
            v = self.no_potential
        if not (_float_vector(h, len(states)) and _float_vector(v, m)):
            return None
        return self.hamiltonian_kernel(h, v, m, self.t)


def _equal_vectors(given: Any, W0: np.ndarray) -> bool:
    """Whether ``given`` is a float64 array of W0's (M, 2N, k) values bit for
    bit, for every orbit (shaped (M, 2N, k), or (2N, k) or (2N,) shared by
    the orbits): what :func:`varint._validate.deviations` would make of it
    is then W0 (a copy of a broadcast of the same values) and passes the
    checks W0 passed, all of which read only its values."""
    if type(given) is not np.ndarray or given.dtype != np.float64:
        return False
    m, dim, k = W0.shape
    if given.shape == W0.shape:
        return given.tobytes() == W0.tobytes()
    if given.shape == (dim, k) or (k == 1 and given.shape == (dim,)):
        return given.tobytes() * m == W0.tobytes()
    return False


class Rerun:
    """A finished run's set-up run again from other initial states: the
    calls of a prepared run after its first, and a one-shot call that
    repeats an earlier one's arguments but its states and vectors
    (:func:`varint.run.run`).

    Each call checks its states (and its vectors, where given) as a
    one-shot call does, with the same messages, then takes the short path
    (:class:`ShortCall`) where it can and the general one
    (:meth:`varint.run.Run.with_orbits`) otherwise: the result is the
    one-shot call's, bitwise.

    Parameters
    ----------
    first : varint.run.Run
        The first run, executed.
    run_seconds : float
        The time of its run (its result's ``provenance.timing["run"]``):
        the short path's first estimate of the time per step.
    kernel_check : varint._validate.KernelCheck
        The check of the model's kernels at each call's states.
    """

    def __init__(self, first: FirstRun, run_seconds: float, kernel_check: check.KernelCheck
                 ) -> None:
        self.first = first
        self.kernel_check = kernel_check
        #: The short calls' path, where the first run has one.
        self.short = ShortCall.over(first, run_seconds)

    def __call__(self, x0: Any, deviations: Any = None, default: Any = None) -> _Result:
        """The result from ``x0`` ((2N,) or (M, 2N)) with ``deviations``
        (([M,] 2N, k)) or, for None, the first run's vectors (for as many
        orbits as it had; else ``default``, checked again, or seeded
        ones)."""
        first, short = self.first, self.short
        if short is not None:
            # Its reference is measured with its outputs, after its run; it
            # needs the checked states, not a specification over them.
            x, single = first.spec.checked_states(x0, self.kernel_check)
            if short.takes(x):
                W0 = short.vectors(deviations)
                if W0 is not None:
                    result = short(x, single, W0)
                    if result is not None:
                        return result
        spec = first.spec.with_states(x0, kernel_check=self.kernel_check)
        if deviations is None and spec.x0.shape[0] != first.x0.shape[0]:
            # The default vectors checked again for another number of
            # orbits (with as many, the first run's checked ones are used).
            deviations = default
        result = first.with_orbits(spec, deviations).execute()
        if short is not None:
            short.timed(result)
        return result


def _float_vector(a: Any, size: int) -> bool:
    """Whether ``a`` is a C-contiguous float64 array of shape (size,): what
    :func:`varint.kernels.energy_errors.energy_errors` takes, and what a
    model's T and V of (R, N) rows are."""
    return (type(a) is np.ndarray and (a.dtype is _FLOAT64 or a.dtype == _FLOAT64)
            and a.shape == (size,) and a.flags.c_contiguous)


#: NumPy's float64 (the one object its arrays of native float64 share,
#: which ``is`` tests ~10x faster than ``==``).
_FLOAT64 = np.dtype(np.float64)

"""The tangent map (TM) method: ``method="tm"``.

Any registered splitting scheme integrates the orbit and, through the tangent
maps of its drift, kick and corrector flows, the deviation vectors (Skokos &
Gerlach 2010, Sect. V.C, eqs. 46–47 and 53). One step of length τ is one
renormalisation interval (or, with sparse renormalisation, the grid on which
the vectors may be renormalised).

Models that know their potential symbolically and are small get a stepper
generated for them and for the scheme (:mod:`varint.codegen`):
stages unrolled, straight-line derivatives, state in registers, outputs
copied inside the compiled loop, cached on disk. One orbit at a time, a
run's first :attr:`TangentMapPropagator.COMPACT_WORK` orbit-steps take the
compact stepper (its stages a loop: the same bits, a fraction of the
compile), which spares short runs most of the compile. Others use the generic
stepper (:mod:`varint.kernels.tm`).
"""

from __future__ import annotations

import functools
import math
import numbers
import weakref

import numpy as np
import numba

from ..codegen.expressions import symbolic_fits
from ..codegen.interval import (LANE_WIDTH, CompensatedOrbit, LaneBlock, Outputs, StepperOrbit,
                                StepperSetup)
from ..codegen.stepper import symbolic_stepper, written_out_ready
from ..codegen.tm import LEVELS, compact_shape, step_counts
from ..kernels import tm as K
from ..gpu import device
from ..kernels.interval import Call, no_accumulator, use_parallel
from ..kernels.lanes import gather, scatter, scatter_outputs
from ..kernels.processor import processor_map
from ..protocol import COUNTERS, STATUS_OK, Renorm, Status
from ..schemes import (DEFAULT_SCHEME, DRIFT, ProcessedScheme, default_for, get_scheme,
                       stage_arrays, stage_times)
from ..state import Snapshots
from .._validate import steps_arguments
from .fresh_run import FreshRun
from .options import method_options

__all__ = ["TangentMapPropagator", "tangent_map_steps"]


class TangentMapPropagator:
    """Advance orbits and deviation vectors with the TM method.

    Parameters
    ----------
    model : Model
    tau : float
        Integration step.
    renorm : Renorm
    accumulator : Accumulator, optional
        Updated after every step (see :class:`varint.protocol.Accumulator`).
    scheme : str or SplittingScheme, default "SBAB2C"
        The paper's S_B2^c by default.
    parallel : bool, optional
        Run the orbits of a batch on all cores (:mod:`varint.threads`). By
        default, when there is more than one orbit and more than one thread.
    renormalize_every : None, int or float, optional
        How often the vectors are renormalised. ``None`` (default): as often
        as needed — every step when an accumulator needs the stretching of
        every step, otherwise on an adaptive schedule that keeps every
        vector's growth below 1e50 and, for QR, the spread of the
        stretchings below 32 and the interval at most 64 steps
        (:func:`varint.kernels.interval.next_interval`); the exponents,
        GALIs and SALI are those of renormalising every step, to round-off.
        An int n: at most every n steps; a float: at most every that much
        time (rounded to steps). A given interval is *capped* by the same
        rule, never trusted beyond it: it starts at one step, at most
        doubles, and shortens whenever the growth or the spread would pass
        those bounds, so vectors renormalised too seldom cannot lose their
        independence (with ``renormalize_every=10**6`` C1's X2..X4 came out
        +0.039, +0.041, +0.039 instead of 0.0019, −0.0025, −0.0575).
        Vectors that grow beyond 1e100 are renormalised at once whatever
        the schedule. Only generated steppers renormalise sparsely; the
        generic one renormalises every step.
    backend : {"cpu", "cuda", "auto"}, default "cpu"
        Where a generated stepper runs a batch: "cuda" on a CUDA GPU, one
        orbit per thread (:mod:`varint.gpu`; refused in one line where
        numba-cuda or a GPU is missing, or where the indicator's
        accumulator has no update rule to write out, as FLI's and MEGNO's
        (with OFLI) have); "auto" on the GPU where one is present and at least
        :data:`~varint.gpu.device.AUTO_MIN_ORBITS` orbits are active,
        else on the CPU. The same arithmetic as the CPU's stepper: bitwise
        its results on numba's CUDA simulator; on an H100 (the kernel as
        emitted before its port onto :mod:`varint.codegen`) the
        Hénon–Heiles FLI map differed by up to 1e-11 relative at t = 100
        (not yet explained; ``studies/results/bench_gpu_h100.md``).
    compensated : {False, True, "orbit", "step"}, default False
        Add every drift and kick of the orbit and of the vectors by Kahan's
        compensated summation (:mod:`varint.codegen.tm`; Hairer, McLachlan
        & Razakarivony 2008): the round-off of a long run then grows like a
        random walk instead of linearly, which lowers the smallest
        reachable error (``studies/compensated_floor.py``). The
        compensations are part of the run state (``extra["tm_compensation"]``,
        (M, 2N, 1 + k): the state's and each vector's), so chunked and
        resumed runs stay bitwise. Generated steppers only, one orbit at a
        time on the CPU (no SIMD lanes, no GPU). ``"orbit"``: only the
        orbit's drifts and kicks are compensated, the vectors' updates are
        plain; the orbit is bitwise True's, and where the vectors' error
        follows the orbit's (Hénon–Heiles: ``studies/compensation_levels.py``)
        the vectors nearly match True's too, for fewer operations per step.
        Its state is True's (the vectors' compensations stay zero).
        ``"step"``: the orbit's drifts and kicks add plainly to its
        displacement since the step began, added to the state once per
        step by compensated summation; the vectors' updates are plain.
        Fewer operations on a step's critical path than ``"orbit"`` (one
        addition per drift instead of two per drift and kick) for a floor
        near its (``tests/test_compensated.py``,
        ``studies/compensation_levels.py``); other bits than ``"orbit"``.
        Its state is True's (the orbit's compensations those of the
        step's additions, the vectors' zero).

    Notes
    -----
    A :class:`~varint.schemes.ProcessedScheme` steps its kernel K and
    reads the state through its processor P (:meth:`_processed`): the run
    keeps the kernel's state x̃ = P⁻¹(x) and its vectors W̃ = DP⁻¹ W in
    ``extra["tm_kernel_x"]`` and ``["tm_kernel_W"]``, so chunking and resuming never
    change a bit, and ``state.x``, ``state.W`` are P(x̃), DP(x̃) W̃ after
    every call. Vectors are renormalised (and their stretchings summed) in
    the kernel's coordinates, which differ from the true ones by the
    near-identity DP = I + O(τ³): a bounded difference, so exponents agree
    in the limit. No snapshots inside the compiled loop (the driver stops
    at every output); time-independent V only, CPU only. With
    ``compensated=True`` the kernel's drifts and kicks are compensated
    (its Kahan terms kept as for any scheme); the processor, applied once
    per output and not accumulated, is not.
    """

    method = "tm"
    OPTIONS = ("scheme", "parallel", "renormalize_every", "backend", "compensated")

    def __init__(self, model, tau, renorm, accumulator=None, **options):
        opts = method_options(self.method, options, self.OPTIONS)
        self.model = model
        self.tau = float(tau)
        scheme = opts.get("scheme")
        # A small chain whose own scheme takes the stepper generated for it
        # (varint.methods.parts.runs_parts) runs that scheme here.
        self.scheme = get_scheme(default_for(model) if scheme is None else scheme, n_parts=2,
                                 processed=True)
        processed = isinstance(self.scheme, ProcessedScheme)
        kernel = self.scheme.kernel_scheme if processed else self.scheme
        self.renorm = Renorm.parse(renorm)
        self.parallel = opts.get("parallel")
        self.accumulator = accumulator
        self.every = self._every(opts.get("renormalize_every"))
        self.compensated = opts.get("compensated", False)
        if not (isinstance(self.compensated, (bool, np.bool_))
                or (isinstance(self.compensated, str) and self.compensated in LEVELS)):
            raise ValueError(f"compensated must be True, False, 'orbit' or 'step', got "
                             f"{self.compensated!r}")
        if not isinstance(self.compensated, str):
            self.compensated = bool(self.compensated)
        if self.compensated and opts.get("backend") == "cuda":
            raise ValueError(f"compensated={self.compensated!r} runs on the CPU only: use "
                             "backend='cpu' or 'auto'")
        self.backend = device.check_backend(opts.get("backend", "cpu"))
        if processed and (model.time_dependent or self.backend == "cuda"):
            raise ValueError(f"scheme {self.scheme.name!r} is processed: it runs a "
                             "time-independent V on the CPU; got time_dependent="
                             f"{model.time_dependent}, backend={self.backend!r}")
        #: P and P⁻¹ as stage tables (None for an unprocessed scheme).
        self._processor = ((self.scheme.processor_stages(self.tau),
                            self.scheme.processor_stages(self.tau, inverse=True))
                           if processed else None)
        self._kinds, self._h, self._hc = stage_arrays(kernel, self.tau)
        self._corrected = (self._hc != 0.0) & (self._kinds != DRIFT)
        # A time-dependent V: the time of every stage (kernels/tm.py).
        self._ctime = stage_times(kernel) if model.time_dependent else np.empty(0)
        r = model.escape_radius
        self._escape_r2 = np.inf if r is None else float(r) ** 2
        self._generated = {}
        self._counts = {}
        #: Per k: whether the written-out stepper costs no compile (:meth:`_ready`).
        self._readiness = {}
        #: Whether the stages fit the compact loop (:func:`compact_shape`),
        #: asked once: a short run asks at every call (issue 28).
        self._compact_fits = None

    def _every(self, every):
        if every is None:
            return None
        if isinstance(every, bool) or not isinstance(every, numbers.Real) \
                or not (np.isfinite(every) and every > 0):
            raise ValueError(f"renormalize_every must be None, a positive number of steps "
                             f"(int) or a positive time (float), got {every!r}")
        steps = every if isinstance(every, numbers.Integral) else round(every / self.tau)
        steps = max(1, int(steps))
        if steps > 1 and self.accumulator is not None:
            raise ValueError(f"renormalize_every = {every!r}: this indicator accumulates the "
                             "stretching of every step, so its vectors are renormalised every "
                             "step")
        return steps

    @property
    def sparse(self):
        """Whether the vectors are renormalised on a schedule (0: every step;
        -1: adaptive; n > 1: adaptive, at most every n steps)."""
        if self.renorm == Renorm.NONE or self.accumulator is not None:
            return 0
        if self.every is None:
            return -1
        return 0 if self.every == 1 else self.every

    def describe(self):
        d = {"scheme": self.scheme.describe()}
        if self.every is not None:
            d["renormalize_every"] = self.every
        if self.backend != "cpu":
            d["backend"] = self.backend
        if self.compensated:
            d["compensated"] = self.compensated
        return d

    def versions(self):
        return {"numba": numba.__version__}

    # -- which stepper ----------------------------------------------------------------
    #: Orbit-steps (steps × orbits) this propagator runs one orbit at a
    #: time with k vectors by the compact stepper
    #: (:meth:`~varint.codegen.tm.TMBody.compact_stages`) before it takes
    #: the stepper with its stages written out: a call that would reach it
    #: runs written out. Both give the same bits, so a run's chunks may
    #: take either. The compact stepper compiles in a fraction of the time
    #: and runs slower per step, most on small models (a loop and a branch
    #: per stage: ``studies/compact_steps.py``,
    #: ``results/suite18/compact_steps.json``), so a run that stays below
    #: this saves most of a compile of seconds at the cost of at most this
    #: many slower steps (~0.1 s), and a long run (from ~0.05 s of steps on)
    #: runs written out, at its full speed. Lanes always run written out:
    #: a loop over stages inside the loop over lanes would not vectorise.
    #: The work is counted per model and stepper in this process, not per
    #: propagator, and a stepper written out that an earlier run (or
    #: process: its file in the cache) has compiled is taken whatever the
    #: work: short runs are slow only until the compile is worth paying.
    #: A prepared run's or a repeated call's calls count as one-orbit
    #: calls do (:meth:`fresh_run`).
    COMPACT_WORK = 10 ** 6

    def _stepper(self, k, compact=False):
        """The generated stepper module for k vectors, or None (generic):
        ``compact`` where the scheme's stages fit the compact loop
        (:func:`~varint.codegen.tm.compact_shape`)."""
        # Per k, the modules by form, or None: the generic stepper.
        forms = self._generated.setdefault(k, {})
        if forms is None:
            return None
        if compact and self._compact_fits is None:
            self._compact_fits = compact_shape(self._kinds, self._corrected) is not None
        compact = bool(compact) and self._compact_fits
        if compact not in forms:
            forms[compact] = _generated_stepper(self.model, self._kinds, self._hc, k,
                                                self.accumulator, self.compensated, compact)
        return forms[compact]

    def _ready(self, k):
        """Whether the written-out stepper for k vectors is compiled already
        (:func:`~varint.codegen.stepper.written_out_ready`), asked once per
        propagator and k."""
        if k not in self._readiness:
            self._readiness[k] = (symbolic_fits(self.model, k) and written_out_ready(
                self.model, self._kinds, self._corrected, k, self.accumulator, self.compensated))
        return self._readiness[k]

    def _orbit_stepper(self, k, work):
        """The module whose one-orbit stepper runs a call of ``work``
        orbit-steps: written out where that is compiled already, else
        compact while the one-orbit work of this model's stepper with k
        vectors in this process, this call's included, stays below
        :attr:`COMPACT_WORK`."""
        if self._ready(k):
            return self._stepper(k)
        done = _WORK.setdefault(self.model, {})
        key = (self._kinds.tobytes(), self._corrected.tobytes(), int(k), self.accumulator,
               self.compensated, np.asarray(self.model.params, dtype=float).tobytes(),
               np.asarray(self.model.inverse_mass, dtype=float).tobytes())
        done[key] = done.get(key, 0) + work
        return self._stepper(k, compact=done[key] < self.COMPACT_WORK)

    def takes_snapshots(self, state):
        """Whether :meth:`advance` can copy ``state`` at output steps inside
        the compiled loop (a generated stepper for this model and k; not
        for a processed scheme, whose outputs pass through its processor)."""
        return (self._processor is None
                and self._stepper(state.k, compact=not self._ready(state.k)) is not None)

    #: Orbits per block of the SIMD kernel (``lanes``): a multiple of the
    #: vector width (8 doubles with AVX-512), small enough that a block's
    #: state stays in the L1 cache.
    LANES = LANE_WIDTH
    #: Fewer orbits than one vector's width run one at a time: lanes would
    #: compute padding.
    MIN_LANES = 8

    def advance(self, state, n, outputs=None):
        """Advance every active orbit of ``state`` by ``n`` steps.

        Parameters
        ----------
        state : RunState
        n : int
        outputs : ndarray of int, optional
            Steps in (state.step, state.step + n] at which to copy the state
            (only if :meth:`takes_snapshots`).

        Returns
        -------
        Snapshots or None
        """
        if self._processor is not None:
            return self._processed(state, n)
        return self._advance_steps(state, n, outputs)

    def _advance_steps(self, state, n, outputs=None):
        """:meth:`advance` by the scheme's steps (the kernel's, for a
        processed scheme)."""
        active = np.flatnonzero(state.status == STATUS_OK)
        # Whether there is a generated stepper; this module reruns an orbit
        # that failed in the lanes or on the GPU (either form: the same bits).
        module = self._stepper(state.k, compact=not self._ready(state.k))
        if module is None and self.backend == "cuda":
            raise ValueError(f"backend='cuda' runs generated steppers; {self.model.name} with "
                             f"{state.k} vectors has none (a model without a symbolic potential,"
                             " time-dependent, or too large): use backend='cpu'")
        if module is None and self.compensated:
            raise ValueError(f"compensated={self.compensated!r} runs generated steppers; "
                             f"{self.model.name} with "
                             f"{state.k} vectors has none (a model without a symbolic potential,"
                             " time-dependent, or too large): leave compensated=False")
        if module is None and getattr(self.model, "structure", None) == "integrable":
            # The generic stepper's drift is free motion, not a rotating frame's.
            raise ValueError(f"{self.model.name} with {state.k} vectors has no generated "
                             f"stepper (too many values to hold), and the generic stepper's "
                             f"drift is not its rotating frame's: use at most "
                             f"{self.model.dim} vectors")
        if module is None:
            if outputs is not None and len(outputs):
                raise ValueError("this model has no generated stepper: no snapshots")
            self._advance_generic(state, n)
            return None
        # Many orbits run as SIMD lanes (bitwise the one-orbit stepper) or
        # on the GPU (the same arithmetic; see the ``backend`` option);
        # compensated ones one at a time.
        if self.compensated:
            snaps = self._snapshots(state, outputs)
            self._advance_generated(self._orbit_stepper(state.k, n * len(active)), state, n,
                                    snaps)
            return snaps
        if len(active) and device.use_gpu(self.backend, len(active)):
            # The CUDA emitter (SymPy's printers) is imported for a GPU run
            # only: a CPU process that loads cached steppers never needs it.
            from ..gpu import host
            from ..gpu.advance import advance_cuda
            from ..gpu.emit import emittable

            if self.backend == "cuda" or emittable(self.accumulator):
                # A GPU call of every orbit writes every number of every
                # snapshot (varint.gpu.advance): no blank to fill first, and
                # buffers whose pages are mapped already.
                every = len(active) == state.n_orbits
                snaps = self._snapshots(state, outputs, host.empty if every else None)
                advance_cuda(self, module, state, n, snaps, active)
                return snaps
        snaps = self._snapshots(state, outputs)
        if len(active) >= self.MIN_LANES:
            self._advance_lanes(module, state, n, snaps, active)
        else:
            self._advance_generated(self._orbit_stepper(state.k, n * len(active)), state, n,
                                    snaps)
        return snaps

    def runs_fresh(self, m, k):
        """Whether :meth:`fresh_run` can run ``m`` orbits with ``k``
        vectors: a generated stepper, one orbit at a time on the CPU (fewer
        orbits than :attr:`MIN_LANES`, or compensated), no processor."""
        return (self._processor is None and self.backend == "cpu"
                and (m < self.MIN_LANES or self.compensated)
                and self._stepper(k, compact=not self._ready(k)) is not None)

    def fresh_run(self, m, k, outs, aux0):
        """A :class:`~varint.methods.fresh_run.FreshRun`: orbits started at
        step 0 advanced to step ``outs[-1]`` in one call of the stepper,
        copied at the output steps ``outs``, with one thread's buffers kept
        between runs (a prepared run's short call, :mod:`varint.prepared`):
        what :meth:`advance` does for a fresh
        :class:`~varint.state.RunState` driven by :func:`varint.driver.drive`,
        in one chunk (bitwise the driver's chunks, rule 3 of the propagator
        protocol). Only where :meth:`runs_fresh`.

        Parameters
        ----------
        m, k : int
            Orbits and vectors.
        outs : ndarray of int64
            Increasing output steps, the last one the end.
        aux0 : ndarray, shape (M, k, c)
            The accumulator's start ((M, 0, 0) without one).
        """
        # Each call takes the stepper a one-orbit call of its work would
        # (:meth:`_orbit_stepper`): compact until this stepper's work in
        # this process reaches COMPACT_WORK, unless the written-out one is
        # compiled; then written out for good (the same bits either way).
        # A prepared run, or a repeated call, whose first call ran compact
        # thus compiles the stages written out only once its calls have
        # run enough steps to repay the compile, not at its second call
        # (suite24: the compensation levels' quick test compiled four
        # s35odr10 steppers of 71 stages written out, ~58 of its 77 CPU s
        # cold, for a few calls each).
        parallel = use_parallel(self.parallel, m)
        work = m * int(outs[-1])

        def kernel():
            module = self._orbit_stepper(k, work)
            return (module.batch_parallel if parallel else module.batch_serial,
                    module is self._generated[k].get(False))

        call = Call(int(outs[-1]), 0, self.tau, int(self.renorm), self._escape_r2)
        return FreshRun(kernel, self._setup(), call, outs, (m, self.model.dim, k), aux0,
                        None if self.accumulator is None else self.accumulator.key,
                        self.sparse == 0, self.compensated)

    def _accumulator(self, state):
        acc = self.accumulator
        if acc is None:
            return np.empty((state.n_orbits, 0, 0))
        return state.extra[acc.key]

    def _schedule(self, state):
        """Per orbit: the next renormalisation step and the current interval
        (continuation state, so it lives in the run state)."""
        if "tm_schedule" not in state.extra:
            # The first interval is one step, also for a given interval:
            # nothing is known yet of the stretching it must bound.
            # (Filled by column, not np.tile: a prepared run's call makes one.)
            sched = np.empty((state.n_orbits, 2), dtype=np.int64)
            sched[:, 0], sched[:, 1] = state.step + 1, 1
            state.extra["tm_schedule"] = sched
        return state.extra["tm_schedule"]

    def _compensation(self, state):
        """Per orbit: the Kahan compensations of the state and the vectors
        (continuation state, zero at the start of a run)."""
        if "tm_compensation" not in state.extra:
            m, d, k = state.W.shape
            state.extra["tm_compensation"] = np.zeros((m, d, 1 + k))
        return state.extra["tm_compensation"]

    def _step_counts(self, k):
        """:func:`~varint.codegen.tm.step_counts` for k vectors (worked
        out once per propagator, :func:`_scheme_step_counts` once per
        scheme: a map with early stopping calls the stepper at every check
        time, and a pilot's ladder builds a propagator for each of its
        steps)."""
        if k not in self._counts:
            corrected = (self._hc != 0.0) & (self._kinds != DRIFT)
            self._counts[k] = _scheme_step_counts(
                tuple(self._kinds.tolist()), tuple(corrected.tolist()), int(k),
                self.accumulator is not None and self.accumulator.needs_flow)
        return self._counts[k]

    def _snapshots(self, state, outputs, empty=None):
        """Empty snapshot arrays (NaN) for the output steps of this call;
        ``empty(shape, dtype)``, where given, makes them, not filled: for a
        call that writes every number of every snapshot (a GPU call of
        every orbit, :func:`varint.gpu.host.empty`: at 1e6 orbits the fill
        was a pass over ~100 MB per call)."""
        m, d, k = state.W.shape
        outs = np.zeros(0, dtype=np.int64) if outputs is None else np.asarray(outputs, np.int64)
        s = len(outs)
        blank = empty is None
        empty = np.empty if blank else empty
        # Fresh arrays at every call (the records copy them, but a
        # propagator holds no state of a run), filled in place: cheaper
        # than np.full for the few numbers of a short call.
        x, W = empty((s, m, d), float), empty((s, m, d, k), float)
        acc_m = empty((s, m, k), float)
        acc_e = np.zeros((s, m, k), dtype=np.int64) if blank else empty((s, m, k), np.int64)
        extra = {}
        if self.accumulator is not None:
            extra[self.accumulator.key] = empty((s,) + self._accumulator(state).shape, float)
        if blank:
            x.fill(np.nan)
            W.fill(np.nan)
            acc_m.fill(1.0)
            for aux in extra.values():
                aux.fill(np.nan)
        return Snapshots(steps=outs, x=x, W=W, acc_m=acc_m, acc_e=acc_e, extra=extra,
                         renormalized=self.sparse == 0)

    def _setup(self):
        """What a generated stepper reads besides the call's numbers."""
        return StepperSetup(self._h, self._hc, self.sparse)

    def _call(self, state, n):
        return Call(int(n), int(state.step), self.tau, int(self.renorm), self._escape_r2)

    def _snap_aux(self, snaps, s, m):
        if self.accumulator is None:
            return np.empty((s, m, 0, 0))
        return snaps.extra[self.accumulator.key]

    def _advance_generated(self, module, state, n, snaps, orbits=None):
        """One orbit at a time (all of them, or those of ``orbits``), by the
        one-orbit stepper."""
        m, d, k = state.W.shape
        sched = self._schedule(state)
        counters = np.zeros((m, len(COUNTERS)), dtype=np.int64)
        done = np.zeros(m, dtype=np.int64)
        was_active = state.status == STATUS_OK
        if orbits is not None:
            was_active &= np.isin(np.arange(m), orbits)
        status = np.where(was_active, state.status, -1)   # others are skipped
        parallel = use_parallel(self.parallel, int(was_active.sum()))
        kernel = module.batch_parallel if parallel else module.batch_serial
        record = (state.x, state.W, state.acc_m, state.acc_e, self._accumulator(state), counters,
                  sched)
        record = CompensatedOrbit(*record, self._compensation(state)) if self.compensated \
            else StepperOrbit(*record)
        kernel(record, self._setup(), self._call(state, n),
               Outputs(snaps.steps, snaps.x, snaps.W, snaps.acc_m, snaps.acc_e,
                       self._snap_aux(snaps, len(snaps.steps), m)), status, done)
        state.status[was_active] = status[was_active]
        if orbits is None:
            state.after_kernel(n, was_active, done, counters, COUNTERS)
        return done, counters

    def _advance_lanes(self, module, state, n, snaps, active):
        """The ``active`` orbits as blocks of SIMD lanes (``lanes`` of
        :mod:`varint.codegen.interval`). An orbit that fails is rerun alone
        by the one-orbit stepper from the call's start: it fails at the same
        step with the same bits, and is left exactly as that stepper leaves
        it."""
        m, d, k = state.W.shape
        # Blocks of equal width, a multiple of MIN_LANES: little padding.
        blocks = -(-len(active) // self.LANES)
        width = -(-len(active) // (blocks * self.MIN_LANES)) * self.MIN_LANES
        lanes = _Lanes(active, width)
        sched = self._schedule(state)     # first: part of the state to restore
        aux = self._accumulator(state)
        X, W = lanes.soa(state.x), lanes.soa(state.W)
        am, ae = lanes.soa(state.acc_m), lanes.soa(state.acc_e)
        nxt, itv = lanes.soa(sched[:, 0]), lanes.soa(sched[:, 1])
        st = np.zeros((lanes.blocks, lanes.width), dtype=np.int64)
        fs = np.zeros_like(st)
        lane_aux = lanes.rows_by_lane(aux)
        s = len(snaps.steps)
        shape = (lanes.blocks, s)
        sx = np.full(shape + (d, lanes.width), np.nan)
        sW = np.full(shape + (d, k, lanes.width), np.nan)
        sm = np.ones(shape + (k, lanes.width))
        se = np.zeros(shape + (k, lanes.width), dtype=np.int64)
        saux = np.full(shape + (lanes.width,) + aux.shape[1:], np.nan)
        parallel = use_parallel(self.parallel, lanes.blocks)
        # Lanes run the stages written out (COMPACT_WORK); an orbit that
        # fails is rerun by ``module``'s one-orbit stepper, the same bits.
        written_out = self._stepper(k)
        # In parallel, threads take the blocks one at a time
        # (:func:`varint.codegen.interval.blocks_in_threads`).
        kernel = written_out.blocks_parallel if parallel else written_out.blocks_serial
        kernel(LaneBlock(X, W, am, ae, lane_aux, st, fs, nxt, itv), self._setup(),
               self._call(state, n), Outputs(snaps.steps, sx, sW, sm, se, saux))
        failed = active[lanes.aos(st) != 0]
        # The call's start, for the orbits that fail (rare): the kernel
        # stepped copies (the lanes), so the state's rows are still the start
        # until they are written back below.
        start, extra_start = {}, {}
        if failed.size:
            start = {name: getattr(state, name)[active] for name in ("x", "W", "acc_m", "acc_e")}
            extra_start = {key: arr[active] for key, arr in state.extra.items()}
        for lane_array, target in ((X, state.x), (W, state.W), (am, state.acc_m),
                                   (ae, state.acc_e)):
            lanes.put(lane_array, target)
        sched[active, 0], sched[active, 1] = lanes.aos(nxt), lanes.aos(itv)
        if aux.size:
            aux[active] = lanes.from_rows_by_lane(lane_aux)
        if s:
            for lane_array, target in ((sx, snaps.x), (sW, snaps.W), (sm, snaps.acc_m),
                                       (se, snaps.acc_e)):
                lanes.put_outputs(lane_array, target)
            if aux.size:
                snaps.extra[self.accumulator.key][:, active] = lanes.snapshot_rows_by_lane(saux)
        per, first = self._step_counts(k)
        done = np.zeros(m, dtype=np.int64)
        counters = np.zeros((m, len(COUNTERS)), dtype=np.int64)
        done[active], counters[active] = n, per * int(n) + first
        self._rerun_failed(module, state, n, snaps, active, failed, start, extra_start, done,
                           counters)

    def _rerun_failed(self, module, state, n, snaps, active, failed, start, extra_start, done,
                      counters):
        """After the lanes (or the GPU) advanced the ``active`` orbits: the
        ``failed`` ones put back at the call's ``start`` and rerun by the
        one-orbit stepper; then the state's steps and counters."""
        m = state.n_orbits
        if failed.size:
            rows = np.searchsorted(active, failed)
            for name, arr in start.items():
                getattr(state, name)[failed] = arr[rows]
            for key, arr in extra_start.items():
                state.extra[key][failed] = arr[rows]
            snaps.x[:, failed] = snaps.W[:, failed] = np.nan
            f_done, f_counters = self._advance_generated(module, state, n, snaps, failed)
            done[failed], counters[failed] = f_done[failed], f_counters[failed]
        was_active = np.zeros(m, dtype=bool)
        was_active[active] = True
        state.after_kernel(n, was_active, done, counters, COUNTERS)

    def _processed(self, state, n):
        """``n`` kernel steps of a processed scheme from the kernel's state
        (``extra["tm_kernel_x"]``, ``["tm_kernel_W"]``, see the class
        notes), then the outputs P(x̃) and DP(x̃) W̃. An orbit whose state
        differs from what the last call wrote (``["tm_kernel_out_x"]``,
        ``["tm_kernel_out_W"]``: a new run, or a state set from outside)
        starts from P⁻¹(x), DP⁻¹ W."""
        forward, inverse = self._processor
        m = state.n_orbits
        extra = state.extra
        if "tm_kernel_x" not in extra:
            extra["tm_kernel_x"], extra["tm_kernel_W"] = np.empty_like(state.x), \
                np.empty_like(state.W)
            extra["tm_kernel_out_x"] = np.full_like(state.x, np.nan)
            extra["tm_kernel_out_W"] = np.full_like(state.W, np.nan)
        kx, kW = extra["tm_kernel_x"], extra["tm_kernel_W"]
        active = state.status == STATUS_OK
        fresh = active & ~((state.x == extra["tm_kernel_out_x"]).all(axis=1)
                           & (extra["tm_kernel_out_W"] == state.W).reshape(m, -1).all(axis=1))
        if fresh.any():
            kx[fresh], kW[fresh] = state.x[fresh], state.W[fresh]
            self._apply(kx, kW, fresh, inverse)
        # Step the kernel from its own state (compensations, when kept,
        # are the kernel's; an orbit processed afresh starts without).
        state.x[active], state.W[active] = kx[active], kW[active]
        if self.compensated:
            self._compensation(state)[fresh] = 0.0
        self._advance_steps(state, n)
        kx[active], kW[active] = state.x[active], state.W[active]
        self._apply(state.x, state.W, active, forward)
        extra["tm_kernel_out_x"][active] = state.x[active]
        extra["tm_kernel_out_W"][active] = state.W[active]
        return None

    def _apply(self, x, W, rows, stages):
        """The map of ``stages`` (a processor's tables) and its tangent map
        applied in place to the orbits ``rows`` of ``x`` (M, 2N) and ``W``
        (M, 2N, k) (:func:`varint.kernels.processor.processor_map`)."""
        model = self.model
        kinds, h, _ = stages
        processor_map(x, W, rows, kinds, h, model.inverse_mass, model.params, model.bandwidth,
                      model.grad_kernel, model.hess_kernel)

    def _advance_generic(self, state, n):
        m = state.n_orbits
        model = self.model
        acc = self.accumulator
        update, flow = (no_accumulator, False) if acc is None else (acc.update, acc.needs_flow)
        kernel = K.batch_kernel(model.n_dof, state.k, model.bandwidth,
                                use_parallel(self.parallel, m), K.model_kernels(model), update,
                                flow, model.time_dependent)
        time = model.time_dependent
        pt = state.time_momentum()[:, None] if time else np.empty((m, 0))
        counters = np.zeros((m, len(COUNTERS)), dtype=np.int64)
        done = np.zeros(m, dtype=np.int64)
        was_active = state.status == STATUS_OK
        orbits = K.TMOrbit(state.x, state.W, state.acc_m, state.acc_e, self._accumulator(state),
                           counters, pt, np.empty((m, 0, 0)))
        setup = K.TMSetup(self._kinds, self._h, self._hc, model.inverse_mass, model.params,
                          model.bandwidth, self._ctime)
        kernel(orbits, setup, self._call(state, n), state.status, done)
        state.after_kernel(n, was_active, done, counters, COUNTERS)


def tangent_map_steps(model, x, W=None, tau=0.05, n_steps=1, scheme=DEFAULT_SCHEME):
    """Low-level: ``n_steps`` steps of the numerical map S and its tangent
    map TS, without renormalisation; τ may be negative (S(−τ) is the inverse
    of S(τ) for the symmetric schemes). A time-dependent V starts at t = 0.

    Parameters
    ----------
    model : Model
    x : array_like, shape (2N,)
    W : array_like, shape (2N, k), optional
        Deviation vectors; none by default.
    tau : float
        Non-zero step.
    n_steps : int
    scheme : str or SplittingScheme

    Returns
    -------
    x : ndarray, shape (2N,)
    W : ndarray, shape (2N, k)

    Raises
    ------
    FloatingPointError
        If the map fails (the message gives the step and the reason).
    """
    from ..protocol import REASONS
    from ..state import RunState

    x, W = steps_arguments(model, x, W, tau)
    state = RunState.start(x, W[None])
    TangentMapPropagator(model, float(tau), Renorm.NONE, scheme=scheme, parallel=False).advance(
        state, int(n_steps))
    if state.status[0] != Status.OK:
        raise FloatingPointError(f"the map failed in step {state.fail_step[0]}: "
                                 f"{REASONS.get(Status(state.status[0]), state.status[0])}")
    return state.x[0], state.W[0]


@functools.lru_cache(maxsize=64)
def _scheme_step_counts(kinds, corrected, k, flow):
    """:func:`~varint.codegen.tm.step_counts` of a scheme's stage kinds and
    corrected stages (tuples), read-only: shared by every propagator of
    that scheme (~0.1 ms each on a pilot's rungs, which differ in τ alone,
    and τ does not change which stages are corrected)."""
    per, first = step_counts(kinds, corrected, k, flow)
    per.flags.writeable = first.flags.writeable = False
    return per, first


#: Generated stepper modules per model (:func:`_generated_stepper`).
_STEPPERS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
#: Per model: the one-orbit orbit-steps each of its steppers ran compact in
#: this process (:meth:`TangentMapPropagator._orbit_stepper`).
_WORK: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _generated_stepper(model, kinds, hc, k, accumulator, compensated=False, compact=False):
    """The generated stepper module of (model, scheme stages, k,
    accumulator, compensation, compact), or None when the model has none
    (:func:`varint.codegen.expressions.symbolic_fits`). Remembered per
    model, keyed by what the module depends on (its parameters and masses
    included), so that repeated runs skip the lookup (~50 µs)."""
    corrected = (hc != 0.0) & (kinds != DRIFT)
    # Beside the model, not in it: a model must stay picklable (Dask).
    memo = _STEPPERS.setdefault(model, {})
    key = (kinds.tobytes(), corrected.tobytes(), int(k), accumulator, compensated, compact,
           np.asarray(model.params, dtype=float).tobytes(),
           np.asarray(model.inverse_mass, dtype=float).tobytes())
    if key not in memo:
        memo[key] = (symbolic_stepper(model, kinds, corrected, k, accumulator, compensated,
                                      compact)
                     if symbolic_fits(model, k) else None)
    return memo[key]


class _Lanes:
    """The layout of orbits as blocks of SIMD lanes: arrays (M, ...) of the
    run state become (blocks, ..., lanes) and back; the last block is
    padded with copies of the last orbit (computed, never read)."""

    def __init__(self, active, width):
        self.n = len(active)
        self.active = active
        self.width = width
        self.blocks = -(-self.n // width)
        self.index = np.concatenate([active, np.full(self.blocks * width - self.n, active[-1])])

    def soa(self, a):
        """Rows of ``a`` (M, ...) -> (blocks, ..., lanes)."""
        out = np.empty((self.blocks,) + a.shape[1:] + (self.width,), dtype=a.dtype)
        f = math.prod(a.shape[1:])
        gather(a.reshape(len(a), f), self.index, out.reshape(self.blocks, f, self.width))
        return out

    def aos(self, a):
        """(blocks, ..., lanes) -> the active orbits' rows (n, ...)."""
        rows = np.moveaxis(a, -1, 1).reshape((self.blocks * self.width,) + a.shape[1:-1])
        return rows[:self.n]

    def put(self, a, target):
        """Write lanes ``a`` (blocks, ..., lanes) into the active orbits'
        rows of ``target`` (M, ...), in place."""
        if target.flags.c_contiguous:
            f = math.prod(target.shape[1:])
            scatter(a.reshape(self.blocks, f, self.width), self.active,
                    target.reshape(len(target), f))
        else:
            target[self.active] = self.aos(a)

    def put_outputs(self, a, target):
        """Write the lanes' outputs ``a`` (blocks, S, ..., lanes) into the
        active orbits' rows of ``target`` (S, M, ...), in place."""
        if target.flags.c_contiguous:
            s, m = target.shape[:2]
            f = math.prod(target.shape[2:])
            scatter_outputs(a.reshape(self.blocks, s, f, self.width), self.active,
                            target.reshape(s, m, f))
        else:
            target[:, self.active] = self.snapshot_rows(a)

    def rows_by_lane(self, a):
        """Rows of ``a`` (M, ...) -> (blocks, lanes, ...): per-lane arrays
        (an indicator's accumulators, read by its own code one lane at a
        time)."""
        return np.ascontiguousarray(a[self.index].reshape((self.blocks, self.width)
                                                          + a.shape[1:]))

    def from_rows_by_lane(self, a):
        return a.reshape((self.blocks * self.width,) + a.shape[2:])[:self.n]

    def snapshot_rows(self, a):
        """(blocks, S, ..., lanes) -> (S, n, ...)."""
        b = np.moveaxis(a, -1, 2)   # (blocks, S, lanes, ...)
        s = a.shape[1]
        return np.swapaxes(b, 0, 1).reshape((s, self.blocks * self.width)
                                            + a.shape[2:-1])[:, :self.n]

    def snapshot_rows_by_lane(self, a):
        """(blocks, S, lanes, ...) -> (S, n, ...)."""
        s = a.shape[1]
        return np.swapaxes(a, 0, 1).reshape((s, self.blocks * self.width)
                                            + a.shape[3:])[:, :self.n]

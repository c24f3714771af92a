"""The paper's Runge–Kutta baseline: ``method="dop853"``.

SciPy's DOP853 (the explicit 8(5,3) pair of Dormand & Prince in Hairer's
formulation; Hairer, Nørsett & Wanner, *Solving ODEs I*, Sect. II.10) on the
orbit and its variational equations, with the right-hand side compiled from
the model's kernels (:mod:`varint.baselines.rhs`). As in the paper, the integrator
is restarted every τ from the renormalised state (blocks of one interval,
:mod:`baselines.blocks`).

The paper's local error threshold δ is Hairer's scalar tolerance with
``ITOL = 0``, i.e. ``rtol = atol = δ``: SciPy's error norm is Hairer's
(per-component scale atol + rtol·max(|y|, |y_new|), the combined 5th/3rd
order estimate, root mean square over components). When τ is below the
natural step (about 0.9 at δ = 1e-5 and 0.2 at δ = 1e-10 on Hénon–Heiles at
H = 1/8) every interval is a single step truncated to τ, so δ then hardly
matters: the method is in effect an 8th-order fixed-step method with h = τ.

Two engines run the same solver. ``engine="compiled"`` (the default) is
:mod:`varint.baselines.dop853_kernel`: SciPy's ``DOP853`` stepping repeated in numba
with SciPy's own coefficients and order of arithmetic, the right-hand side
compiled in, a whole chunk of intervals per orbit in one call. On
Hénon–Heiles it reproduces ``engine="scipy"`` bit for bit
(``tests/baselines/test_dop853_compiled.py``) and runs tens of times faster
(``studies/bench_dop853.py``, ``studies/bench_baselines.py``; against SciPy
driven directly, ``studies/bench_libraries.py``), so the paper's runs to
t = 1e8 take hours instead of days. ``engine="scipy"`` drives
``scipy.integrate.DOP853`` itself, which calls Python at every step.
``engine="lanes"`` (:mod:`varint.baselines.dop853_lanes`) integrates the
orbits of a batch together in SIMD lanes, the same method in plain loops:
not SciPy's bits, but the same bits for an orbit alone or in any batch.
"""

from __future__ import annotations

import warnings

import numba
import numpy as np
import scipy
from scipy.integrate import DOP853

from varint.kernels.interval import no_accumulator, orbit_loop
from varint.protocol import Status
from varint._validate import choice, positive_float

from .blocks import BlockPropagator, output_body
from .dop853_kernel import COUNTS, POWERS, RTOL_MIN, advance_orbit
from .dop853_lanes import LANES, lanes_kernel
from .rhs import tangent_rhs

__all__ = ["DOP853Propagator", "ENGINES"]

#: Values of the ``engine`` option.
ENGINES = ("compiled", "scipy", "lanes")


class DOP853Propagator(BlockPropagator):
    """Orbits and deviation vectors by DOP853, restarted every τ.

    Parameters
    ----------
    model : Model
    tau : float
        Renormalisation interval: every interval is one call of the
        integrator, starting from the state renormalised at its start.
    renorm : Renorm
    accumulator : Accumulator, optional
        Updated after every interval (:class:`varint.protocol.Accumulator`).
    delta : float, optional
        The paper's local error threshold: ``rtol = atol = delta``. 1e-5 by
        default, the paper's value.
    rtol, atol : float, optional
        Explicit tolerances instead of ``delta``. As in SciPy, an rtol below
        100 ε is raised to 100 ε, with a warning.
    engine : {"compiled", "scipy", "lanes"}, optional
        The compiled copy of SciPy's solver (default), SciPy's solver, or
        the same method over the orbits of a batch in SIMD lanes
        (:mod:`varint.baselines.dop853_lanes`; not SciPy's bits).

    Notes
    -----
    The first step of each interval is the step size DOP853 proposed at the
    end of the previous one (capped at τ), as when Hairer's code is called
    again with its returned H; it is kept per orbit in ``state.extra`` so
    runs resume exactly, with either engine.

    Work counts: ``blocks`` (intervals integrated), ``rhs_evaluations``
    (SciPy's ``nfev``), ``dop853_steps`` (calls of the step routine:
    accepted steps, plus the failing call of a failed interval) and
    ``dop853_rejected`` (rejected trial steps).
    """

    method = "dop853"
    OPTIONS = {"delta": None, "rtol": None, "atol": None, "engine": "compiled"}
    PAPER_DELTA = 1e-5

    def __init__(self, model, tau, renorm, accumulator=None, **options):
        opts = self._options(options)
        if opts["delta"] is not None and (opts["rtol"] is not None or opts["atol"] is not None):
            raise ValueError("give either delta (rtol = atol = delta) or rtol/atol, not both")
        if opts["delta"] is not None or (opts["rtol"] is None and opts["atol"] is None):
            delta = positive_float(opts["delta"] or self.PAPER_DELTA, "delta")
            opts.update(delta=delta, rtol=delta, atol=delta)
        else:
            rtol = opts["rtol"] if opts["rtol"] is not None else opts["atol"]
            atol = opts["atol"] if opts["atol"] is not None else opts["rtol"]
            opts.update(rtol=positive_float(rtol, "rtol"), atol=positive_float(atol, "atol"))
        if opts["rtol"] < RTOL_MIN:
            # SciPy would do the same, warning at every interval.
            warnings.warn(f"rtol = {opts['rtol']!r} is below DOP853's floor 100 eps; using "
                          f"rtol = {RTOL_MIN!r}", RuntimeWarning, stacklevel=3)
            opts["rtol"] = RTOL_MIN
        opts["engine"] = choice(opts["engine"], ENGINES, "engine")
        opts["block"] = 1
        self._setup(model, tau, renorm, opts, accumulator)
        self._rhs, self._fun = tangent_rhs(model)

    def versions(self):
        return {"scipy": scipy.__version__, "numba": numba.__version__}

    def _prepare(self, state):
        # The compiled engines keep no block outputs: with blocks of one
        # interval none is ever pending between calls.
        if self.options["engine"] == "scipy":
            super()._prepare(state)
        state.extra.setdefault("dop853_h", np.full(state.n_orbits, np.nan))

    def advance(self, state, n):
        """Advance every active orbit by ``n`` intervals τ (the ``lanes``
        engine: :data:`~varint.baselines.dop853_lanes.LANES` orbits at a
        time)."""
        if self.options["engine"] != "lanes":
            return super().advance(state, n)
        self._prepare(state)
        active = np.flatnonzero(state.status == Status.OK)
        acc = self.accumulator
        d, k = state.W.shape[1:]
        # The one-orbit kernel that takes each lane's output (renormalise,
        # accumulate, check) on the stepping skeleton.
        take = orbit_loop(output_body(self.model.grad_kernel),
                          acc.update if acc is not None else no_accumulator,
                          acc is not None and acc.needs_flow)
        advance_lanes = lanes_kernel(self._rhs, take)
        model, steps, total = self.model, 0, np.zeros(len(COUNTS), dtype=np.int64)
        h_all = state.extra["dop853_h"]
        for first in range(0, len(active), LANES):
            idx = active[first:first + LANES]
            L = len(idx)
            X, W = state.x[idx], state.W[idx]
            acc_m, acc_e, h = state.acc_m[idx], state.acc_e[idx], h_all[idx]
            aux = (state.extra[acc.key][idx] if acc is not None else np.empty((L, 0, 0)))
            clock = (np.stack([np.array(self.clock(state, m, state.step)) for m in idx])
                     if self._clock else np.empty((L, 0)))
            status = np.empty(L, dtype=np.int64)
            done = np.empty(L, dtype=np.int64)
            counts = np.zeros((L, len(COUNTS)), dtype=np.int64)
            advance_lanes(X, W, acc_m, acc_e, h, status, done, int(n), self.tau,
                          self.options["rtol"], self.options["atol"], POWERS, self._mode,
                          self._escape_r2, counts, aux, model.params, model.inverse_mass,
                          state.step, clock)
            state.x[idx], state.W[idx] = X, W
            state.acc_m[idx], state.acc_e[idx], h_all[idx] = acc_m, acc_e, h
            if acc is not None:
                state.extra[acc.key][idx] = aux
            if self._clock:
                state.time_momentum()[idx] = clock[:, 1]
            for lane, m in enumerate(idx):
                steps += int(done[lane])
                if status[lane] != Status.OK:
                    state.status[m] = status[lane]
                    state.fail_step[m] = state.step + done[lane] + 1
                    steps += 1
            total += counts.sum(axis=0)
        state.step += int(n)
        if total[COUNTS.index("blocks")]:
            state.add_counts(**dict(zip(COUNTS, total.tolist(), strict=True)))
        state.add_counts(steps=steps)

    def _advance_orbit(self, state, m, n):
        if self.options["engine"] == "scipy":
            return super()._advance_orbit(state, m, n)
        counts = np.zeros(len(COUNTS), dtype=np.int64)
        accumulate, aux, flow = self._accumulator(state, m)
        model = self.model
        clock = (np.array(self.clock(state, m, state.step)),) if self._clock else ()
        done, status = advance_orbit(
            self._rhs, state.x[m], state.W[m], state.acc_m[m], state.acc_e[m],
            state.extra["dop853_h"][m:m + 1], n, self.tau, self.options["rtol"],
            self.options["atol"], POWERS, self._mode, self._escape_r2, counts, accumulate, aux,
            model.grad_kernel, model.params, model.inverse_mass, flow, state.step, *clock)
        if clock:
            state.time_momentum()[m] = clock[0][1]
        if counts[COUNTS.index("blocks")]:
            # As the SciPy engine counts: per interval integrated.
            state.add_counts(**dict(zip(COUNTS, counts.tolist(), strict=True)))
        return int(done), int(status)

    def _integrate(self, state, m, y0, n_out):
        h = state.extra["dop853_h"]
        first = None if np.isnan(h[m]) else min(h[m], self.tau)
        solver = DOP853(self._fun, 0.0, y0, self.tau, rtol=self.options["rtol"],
                        atol=self.options["atol"], first_step=first)
        steps = 0
        while solver.status == "running":
            solver.step()
            steps += 1
        # Every trial step costs n_stages evaluations after the one of f(y0)
        # (and the one of the initial-step selection).
        trials = (solver.nfev - 1 - (first is None)) // solver.n_stages
        accepted = steps - (solver.status != "finished")
        counts = {"rhs_evaluations": solver.nfev, "dop853_steps": steps,
                  "dop853_rejected": trials - accepted}
        if solver.status != "finished" or not np.isfinite(solver.y).all():
            status = Status.ORBIT_NONFINITE if not np.isfinite(solver.y).all() else Status.INTEGRATOR_FAILED
            return np.empty((0, y0.size)), status, counts
        # The step DOP853 proposes next (SciPy keeps it in h_abs).
        h[m] = solver.h_abs
        return solver.y[None, :], Status.OK, counts

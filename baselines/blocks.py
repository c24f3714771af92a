"""What the baselines share: restart an ODE integrator from the run state,
renormalise every τ, and keep all continuation state in the RunState.

Each baseline integrates the orbit together with its deviation vectors
(:mod:`varint.baselines.rhs`) from the current state over a *block* of B intervals
of length τ, asking its integrator for the state at every multiple of τ.
The outputs are then taken one interval at a time, exactly as the TM method
steps: the orbit is checked (escape, non-finite), and the deviation vectors
are renormalised with :func:`varint.kernels.checks.renormalize` — QR for Lyapunov
spectra (paper eq. 10), unit length for GALI/SALI (eq. 15), or not at all.

Why blocks: the variational equations are linear, so the vectors
renormalised after interval j of a block are the raw vectors integrated from
the block start times a k×k matrix C_j (upper triangular), with
C_j = C_{j−1} R_j⁻¹ from the QR factor R_j. Renormalising *virtually* like
this lets an integrator take its natural steps through a block instead of
restarting every τ; the state is written back (and the integrator restarted
from it) only at the block end. With B = 1 this is the paper's scheme,
restarting every τ (DOP853). On R1 with τ = 0.05 (``studies/bench_baselines.py``)
blocks make CVODE 15–20× cheaper and 7–13× more accurate (every restart of a
multistep method costs low-order starting steps), and double-precision heyoka
20–80× cheaper at the same round-off-level error.

Rules 3 and 8 of :class:`varint.protocol.Propagator` hold because a block is always
integrated whole from the state at its start, and its outputs, the matrix C
and the position in the block live in ``state.extra``: how a run is chunked
into ``advance`` calls, or resumed from a checkpoint, cannot change a bit.
A block also ends early, deterministically, once C has become so
ill-conditioned (condition > :data:`COND_LIMIT`, or the propagator's own
``cond_limit``) that the virtual renormalisation would lose accuracy in the
weakest directions; the rest of
it is discarded and a new block starts from the renormalised state. The
next block is then only as long as the part used, and each block used
whole makes the next a quarter longer, up to the block size
(:data:`BLOCK_GROWTH`): a chaotic orbit's spectrum cuts blocks after a few
Lyapunov times, and integrating far beyond that would be wasted. For the
same reason no block reaches past the run's last interval once the run has
told the propagator where that is (:meth:`BlockPropagator.set_horizon`).
"""

from __future__ import annotations

from collections import namedtuple
from functools import cache

import numpy as np
from numba import njit

from varint.kernels.checks import orbit_status
from varint.kernels.inlining import into_kernels
from varint.kernels.interval import (Call, StepBody, no_accumulator, orbit_loop, orbit_record)
from varint.methods.options import method_options
from varint.protocol import Renorm, Status

from .rhs import clock_size, pack

__all__ = ["BlockPropagator", "consume", "output_body", "take_output", "COND_LIMIT"]

_OK = int(Status.OK)
_QR = int(Renorm.QR)
_NONE = int(Renorm.NONE)
#: Returned by :func:`consume` when the block should end early.
END_BLOCK = -1
#: Largest condition number (ratio of the extreme diagonal entries) of the
#: virtual QR matrix C before a block ends early: a larger one amplifies the
#: integrator's error in the weakest directions by as much.
COND_LIMIT = 100.0
#: Largest block, in float64 numbers stored per orbit (16 MiB), and for all
#: the orbits of a run together (128 MiB).
MAX_BLOCK_VALUES = 1 << 21
MAX_BLOCK_TOTAL = 1 << 24
#: A block used whole makes the next one this much longer (up to the block
#: size); one cut by COND_LIMIT makes the next as long as the part used.
BLOCK_GROWTH = 1.25

#: One orbit's record (:mod:`varint.kernels.interval`): ``C`` (k, k), the
#: virtual renormalisation so far (identity at the block start).
BlockOrbit = orbit_record("BlockOrbit", ("C",))

#: What a call reads: the block's flat states ``ys`` (B, 2N(1 + k) + clock)
#: at τ, 2τ, … (:func:`varint.baselines.rhs.pack`), the first output to take,
#: the condition limit (:data:`COND_LIMIT` by default), the model's parameters and inverse masses, and the
#: entries of the clock (t, p_t) ending each row (0 unless V depends on t).
BlockSetup = namedtuple("BlockSetup", ("ys", "start", "cond_limit", "par", "minv", "clock"))

_Work = namedtuple("_Work", ("n", "k", "d", "xe", "V", "R", "q", "g", "pl"))


@njit(inline=into_kernels)
def take_output(row, C, x, W, d, k):
    """The orbit and the vectors of one output: x ← the row's orbit and
    W ← its raw vectors times the virtual renormalisation ``C`` (upper
    triangular)."""
    for i in range(d):
        x[i] = row[i]
    for i in range(d):
        for a in range(k):
            s = 0.0
            for b in range(a + 1):  # C is upper triangular
                s += row[d + i * k + b] * C[b, a]
            W[i, a] = s


@njit(inline=into_kernels)
def output_flow(grad, row, clock, x, par, minv, q, g, out):
    """The phase-space velocity (M⁻¹p, −∇V) at the orbit ``x`` of an output
    ``row``, for a time-dependent V at the row's t (its clock)."""
    n = q.shape[0]
    for i in range(n):
        q[i] = x[i]
    if clock > 0:
        par[par.shape[0] - 1] = row[row.shape[0] - clock]
    grad(q, par, g)
    for i in range(n):
        out[i] = minv[i] * x[n + i]
        out[n + i] = -g[i]


@cache
def output_body(grad):
    """The step body that takes the outputs of a block integrated by an
    ODE solver (:class:`BlockPropagator`): interval ``s`` is output
    ``setup.start + s``, whose raw vectors are renormalised *virtually*
    (see the module docstring); ``grad`` is the model's gradient kernel, for
    the accumulator's flow. After each renormalisation C becomes C R⁻¹, and
    an ill-conditioned C ends the block (status :data:`END_BLOCK`)."""

    @njit(inline="always")
    def begin(state, setup, call):
        d, k = state.W.shape
        n = d // 2
        return _Work(n, k, d, state.x, np.empty((d, k)), np.empty((k, k)), np.empty(n),
                     np.empty(n), setup.par.copy()), 0

    @njit(inline="always")
    def step(state, setup, ws, carry, s, call):
        take_output(setup.ys[setup.start + s], state.C, state.x, state.W, ws.d, ws.k)
        if call.renorm != _NONE:
            V, W = ws.V, state.W
            for i in range(ws.d):
                for a in range(ws.k):
                    V[i, a] = W[i, a]
        return _OK, carry

    @njit(inline="always")
    def check(state, setup, ws, xe, call):
        return orbit_status(xe, ws.n, call.escape_r2)

    @njit(inline="always")
    def flow(state, setup, ws, carry, xe, s, call, out):
        output_flow(grad, setup.ys[setup.start + s], setup.clock, xe, ws.pl, setup.minv, ws.q,
                    ws.g, out)
        return carry

    @njit(inline="always")
    def after(state, setup, ws, s, call):
        mode = call.renorm
        if mode == _NONE:
            return _OK
        W, V, R, C, d, k = state.W, ws.V, ws.R, state.C, ws.d, ws.k
        # W = V R⁻¹ with R = WᵀV (upper triangular for QR, diagonal when
        # only normalising), so the next raw output needs C R⁻¹.
        for b in range(k):
            for a in range(k):
                t = 0.0
                if a == b or (mode == _QR and b < a):
                    for i in range(d):
                        t += W[i, b] * V[i, a]
                R[b, a] = t
        for rr in range(k):
            for a in range(k):
                t = C[rr, a]
                for b in range(a):
                    t -= C[rr, b] * R[b, a]
                C[rr, a] = t / R[a, a]
        # Only QR mixes columns (normalising just scales them, exactly).
        # Checked after every output, whatever ``stop`` is, so where a block
        # ends never depends on how the run is chunked.
        if mode == _QR:
            cmax = 0.0
            cmin = np.inf
            for a in range(k):
                c = abs(C[a, a])
                cmax = max(cmax, c)
                cmin = min(cmin, c)
            if cmax > setup.cond_limit * cmin:
                return END_BLOCK
        return _OK

    # Raw vectors are checked for overflow at every output (no later check
    # sees them).
    return StepBody(begin=begin, step=step, check=check, flow=flow, after=after, check_every=1)


def consume(ys, C, start, stop, x, W, mode, acc_m, acc_e, escape_r2, cond_limit, accumulate,
            aux, grad, par, minv, flow, step_first, tau, clock=0):
    """Take the outputs ``start … stop−1`` of a block for one orbit.

    Parameters
    ----------
    ys : ndarray, shape (B, 2N(1 + k))
        Flat states (:func:`varint.baselines.rhs.pack`) at τ, 2τ, … integrated
        from the block start.
    C : ndarray, shape (k, k)
        Virtual renormalisation so far (identity at the block start);
        updated in place.
    x, W : ndarray, shapes (2N,) and (2N, k)
        Receive the orbit and the renormalised vectors of each output.
    mode : int
        A :class:`~varint.protocol.Renorm`.
    acc_m, acc_e : ndarray, shape (k,)
        Stretching accumulators (see :mod:`varint.kernels.checks`).
    escape_r2 : float
        Squared escape radius of |q|.
    cond_limit : float
        Largest condition of C before the block ends (:data:`COND_LIMIT`
        unless the propagator sets its own).
    accumulate, aux :
        The indicator's accumulator and its array (k, columns), updated
        after each renormalisation (an empty ``aux`` for none).
    grad, par, minv :
        The model's gradient kernel, parameters and inverse mass, for the
        phase-space velocity the accumulator may read.
    flow : bool
        Whether it reads it.
    step_first : int
        The run's interval count at output ``start`` (its time is
        ``step_first · tau``: from an integer, so it does not depend on how
        the run is chunked).
    tau : float
    clock : int
        Entries of the clock (t, p_t) ending each row of ``ys`` for a
        time-dependent V (:mod:`varint.baselines.rhs`), 0 otherwise; the
        flow is then evaluated at the row's t.

    Returns
    -------
    status : int
        ``OK``; a failure :class:`~varint.protocol.Status` (output ``j``
        failed, its state is in x, W); or ``END_BLOCK`` (outputs up to
        ``j − 1`` were taken and the rest of the block must be discarded).
    j : int
        See ``status``; ``stop`` when all were taken.
    """
    orbit = orbit_loop(output_body(grad), accumulate, bool(flow))
    status, steps = orbit(
        BlockOrbit(x, W, acc_m, acc_e, aux, np.zeros(0, dtype=np.int64), C),
        BlockSetup(ys, int(start), float(cond_limit), par, minv, int(clock)),
        Call(int(stop - start), int(step_first) - 1, float(tau), int(mode), float(escape_r2)))
    if status == END_BLOCK:
        return status, start + steps + 1
    return status, start + steps


class BlockPropagator:
    """Base of the baseline propagators (the protocol of
    :mod:`varint.methods`).

    Subclasses set :attr:`method` and :attr:`OPTIONS` (name → default),
    call :meth:`_setup` from ``__init__``, and implement
    ``_integrate(state, m, y0, n_out) -> (ys, status, counts)``: integrate
    the flat state ``y0`` of orbit ``m`` from t = 0 and return the flat
    states at τ, 2τ, …, n_out·τ (fewer rows if it failed, with ``status``
    saying why; ``Status.OK`` otherwise) and a dict of work counts.

    For a time-dependent V the flat states end with the clock (t, p_t)
    (:mod:`varint.baselines.rhs`), which carries the absolute time: a block
    starts at t = step·τ, from the integer step, and p_t of the last output
    taken is written back to ``RunState.extra[TIME_MOMENTUM]``.
    """

    method = None
    OPTIONS = {}
    #: Time spanned by a block when the ``block`` option is not given.
    BLOCK_SPAN = 0.0
    #: Condition of the virtual renormalisation at which a block is cut.
    cond_limit = COND_LIMIT

    def _setup(self, model, tau, renorm, options, accumulator=None):
        self.model = model
        self.tau = float(tau)
        self.renorm = Renorm.parse(renorm)
        self._mode = int(self.renorm)
        self.accumulator = accumulator
        block = options.get("block")
        integer = isinstance(block, (int, np.integer)) and not isinstance(block, bool)
        if block is not None and not (integer and block >= 1):
            raise ValueError(f"block must be a positive integer (intervals of tau), got {block!r}")
        self.options = options
        self._horizon = np.iinfo(np.int64).max
        self._clock = clock_size(model)
        r = model.escape_radius
        self._escape_r2 = np.inf if r is None else float(r) ** 2

    @classmethod
    def _options(cls, given):
        """The options with defaults filled in; rejects unknown ones."""
        if "scheme" in given:
            raise ValueError(
                f"method {cls.method!r} takes no scheme: it integrates the variational "
                "equations directly; scheme= selects the splitting scheme of 'tm' and the TDH "
                "methods")
        return {**cls.OPTIONS, **method_options(cls.method, given, tuple(cls.OPTIONS))}

    def block_size(self, dim, k):
        """Intervals per block for states of dimension ``dim`` with ``k``
        vectors: the ``block`` option if given, else enough for
        :attr:`BLOCK_SPAN` time units; at most :data:`MAX_BLOCK_VALUES`
        stored numbers per orbit (and :data:`MAX_BLOCK_TOTAL` for all the
        orbits of a run, which ``_prepare`` applies)."""
        block = self.options.get("block")
        if block is None:
            block = max(1, int(round(self.BLOCK_SPAN / self.tau)))
        return int(max(1, min(block, MAX_BLOCK_VALUES // (dim * (1 + k)))))

    def describe(self):
        return dict(self.options)

    def set_horizon(self, step):
        """Integrate no block beyond interval ``step`` (the run's last): the
        intervals a block would integrate past it are never used. The same
        for every chunking and every resume of the run, so no bit depends
        on it."""
        self._horizon = int(step)

    # -- the protocol --------------------------------------------------------
    def advance(self, state, n):
        """Advance every active orbit of ``state`` by ``n`` intervals τ."""
        self._prepare(state)
        steps = 0
        for m in np.flatnonzero(state.status == Status.OK):
            done, status = self._advance_orbit(state, m, int(n))
            steps += done
            if status != Status.OK:
                state.status[m] = status
                state.fail_step[m] = state.step + done + 1
                steps += 1
        state.step += int(n)
        state.add_counts(steps=steps)

    def _key(self, name):
        return f"{self.method}_{name}"

    def _prepare(self, state):
        """Create the block storage in ``state.extra`` on first use."""
        if self._key("next") in state.extra:
            return
        m, d, k = state.W.shape
        size = d * (1 + k) + self._clock
        b = max(1, min(self.block_size(d, k), MAX_BLOCK_TOTAL // (m * size)))
        state.extra.update({
            self._key("y"): np.zeros((m, b, d * (1 + k) + self._clock)),
            self._key("C"): np.zeros((m, k, k)),
            # Outputs taken / outputs held / why a short block stopped.
            self._key("next"): np.zeros(m, dtype=np.int64),
            self._key("filled"): np.zeros(m, dtype=np.int64),
            self._key("failed"): np.zeros(m, dtype=np.int64),
            # Length of the next block; negative after a cut (see _new_block).
            self._key("length"): np.full(m, b, dtype=np.int64),
        })

    def _advance_orbit(self, state, m, n):
        ex = state.extra
        ys, C = ex[self._key("y")], ex[self._key("C")]
        nxt, filled = ex[self._key("next")], ex[self._key("filled")]
        failed = ex[self._key("failed")]
        accumulate, aux, flow = self._accumulator(state, m)
        model = self.model
        done = 0
        while done < n:
            if nxt[m] == filled[m]:
                if failed[m] != Status.OK:
                    return done, int(failed[m])
                self._new_block(state, m, state.step + done)
            start = nxt[m]
            status, j = consume(ys[m], C[m], start, min(filled[m], start + n - done), state.x[m],
                                state.W[m], self._mode, state.acc_m[m], state.acc_e[m],
                                self._escape_r2, self.cond_limit, accumulate, aux,
                                model.grad_kernel,
                                model.params, model.inverse_mass, flow,
                                state.step + done + 1, self.tau, self._clock)
            if self._clock:
                # p_t of the last output taken (the failing one if it failed).
                last = j if status not in (Status.OK, END_BLOCK) else j - 1
                if last >= start:
                    state.time_momentum()[m] = ys[m, last, -1]
            done += j - start
            nxt[m] = j
            if status == END_BLOCK:
                # A failure of the integrator beyond this point is moot now.
                filled[m], failed[m] = j, Status.OK
                ex[self._key("length")][m] = -max(1, j)
            elif status != Status.OK:
                return done, int(status)
        return done, Status.OK

    def _accumulator(self, state, m):
        """The accumulator's update, its array for orbit ``m`` and whether
        it reads the flow."""
        acc = self.accumulator
        if acc is None:
            return no_accumulator, np.empty((0, 0)), False
        return acc.update, state.extra[acc.key][m], acc.needs_flow

    def clock(self, state, m, step):
        """The clock (t, p_t) of orbit ``m`` at interval ``step`` for a
        time-dependent V (t from the integer step), else ()."""
        if not self._clock:
            return ()
        return (step * self.tau, state.time_momentum()[m])

    def _new_block(self, state, m, step):
        ex = state.extra
        cap = ex[self._key("y")].shape[1]
        length = ex[self._key("length")]
        # After a cut, as long as the part used; after a block used whole
        # (not the first), a quarter longer.
        b = int(length[m])
        b = -b if b < 0 else (min(cap, int(b * BLOCK_GROWTH) + 1)
                              if ex[self._key("filled")][m] else b)
        length[m] = b
        b = max(1, min(b, self._horizon - step))
        y0 = pack(state.x[m], state.W[m], clock=self.clock(state, m, step))
        ys, status, counts = self._integrate(state, m, y0, b)
        filled = len(ys)
        ex[self._key("y")][m, :filled] = ys
        ex[self._key("filled")][m] = filled
        ex[self._key("next")][m] = 0
        ex[self._key("failed")][m] = (Status.OK if filled == b
                                      else (status or Status.INTEGRATOR_FAILED))
        ex[self._key("C")][m] = np.eye(state.k)
        state.add_counts(blocks=1, **counts)

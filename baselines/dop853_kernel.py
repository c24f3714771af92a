"""SciPy's DOP853 solver, compiled: the paper's Runge–Kutta baseline without
Python in the step loop.

The method is the explicit Runge–Kutta pair of order 8 of Prince & Dormand
(1981), an embedded pair with local extrapolation in the manner of Dormand
& Prince (1980), with the 5th- and 3rd-order error estimators of Hairer's
DOP853 (Hairer, Nørsett & Wanner, *Solving ODEs I*, 2nd ed., Sect. II.10),
as SciPy's ``scipy.integrate.DOP853`` codes it. This module repeats,
operation by operation, what that SciPy solver does on one renormalisation
interval [0, τ] when :mod:`varint.baselines.dop853` calls it:

* the 12-stage step (SciPy's ``rk_step``): stage s evaluates f at
  y + h Σ_{j<s} a_sj k_j, the solution is y₁ = y + h Σ b_j k_j, and the
  13th evaluation f(y₁) is the first stage of the next step (FSAL);
* the error measure of DOP853 (Sect. II.10): with
  sc_i = atol + rtol·max(|y_i|, |y₁_i|), e₅ = Σ E5_j k_j / sc and
  e₃ = Σ E3_j k_j / sc,

      err = |h| ‖e₅‖² / √(n (‖e₅‖² + 0.01 ‖e₃‖²));

* the step-size control (Sect. II.4, eq. 4.13, with q = 7): accept when
  err < 1 and multiply h by min(10, 0.9 err^(−1/8)) (at most 1 right after
  a rejection), else multiply it by max(0.2, 0.9 err^(−1/8)) and retry;
  give up once h falls below ten units in the last place of t;
* the starting step when none is given (Sect. II.4, "Starting Step Size";
  SciPy's ``select_initial_step``), the last step truncated to end at τ,
  and the step proposed after it, which :mod:`varint.baselines.dop853` carries to
  the next interval.

Nothing is retyped: the tableau, the error weights, the control constants
and the exponents are read from SciPy at import. The arithmetic is done in
SciPy's order too, so that the result is not only the same method but the
same bits:

* SciPy forms every Σ a_sj k_j with ``np.dot`` (BLAS ``dgemv`` on the
  column-major transpose of the stage array) and every ‖·‖ with
  ``np.linalg.norm`` (BLAS ``ddot``). A plain loop adds in another order
  and rounds differently in about 40 % of the components (measured), so the
  kernels call BLAS too, through numba's ``np.dot`` on arrays of the same
  layout. Numba's BLAS is SciPy's OpenBLAS, not NumPy's; on the machine
  measured (OpenBLAS 0.3.30 and 0.3.31, AMD EPYC) they agree bit for bit,
  and ``tests/baselines/test_dop853_compiled.py`` checks where they do.
* NumPy's float64 ``**`` calls libm's ``pow``, also for the square
  ``‖e‖**2``, where ``pow(x, 2)`` differs from x·x about once in 10³
  (measured). The exponents therefore reach the kernels as run-time values
  (:data:`POWERS`), so that LLVM cannot turn ``pow(x, 2.0)`` into x·x.
* Python's ``min``/``max`` and NumPy's ``maximum`` treat NaN differently;
  :func:`_pymin`, :func:`_pymax` and :func:`_maximum` copy each.

Where SciPy would loop for ever — a NaN step size, which it never finds
below its minimum — the kernel gives up instead.

The model's right-hand side (:func:`baselines.rhs.tangent_rhs`) is compiled
into the kernels, and :func:`advance_orbit` integrates and renormalises a
whole chunk of intervals of one orbit in one call: :func:`dop853_body`, one
interval, is a step body of the stepping skeleton
(:mod:`varint.kernels.interval`). ``studies/bench_dop853.py`` measures the
speed against SciPy's solver and the TM method.
"""

from __future__ import annotations

import math
from collections import namedtuple
from functools import cache

import numpy as np
from numba import njit
from scipy.integrate import DOP853
from scipy.integrate._ivp import common, rk

from varint.kernels.checks import orbit_status
from varint.kernels.interval import Call, StepBody, orbit_loop, orbit_record
from varint.protocol import Status

from .blocks import output_flow, take_output

__all__ = ["advance_orbit", "dop853_body", "dop853_engine", "Engine", "COUNTS", "POWERS",
           "RTOL_MIN"]

_OK = int(Status.OK)
_NONFINITE = int(Status.ORBIT_NONFINITE)
_FAILED = int(Status.INTEGRATOR_FAILED)

#: Stages of a step (the 13th evaluation, f(y₁), is the next step's first).
N_STAGES = DOP853.n_stages
#: Butcher tableau and error weights: the arrays SciPy's solver uses, which
#: its DOP853 class takes from ``scipy.integrate._ivp.dop853_coefficients``.
A = np.ascontiguousarray(DOP853.A)
B = np.ascontiguousarray(DOP853.B)
C = np.ascontiguousarray(DOP853.C)
E3 = np.ascontiguousarray(DOP853.E3)
E5 = np.ascontiguousarray(DOP853.E5)
SAFETY, MIN_FACTOR, MAX_FACTOR = float(rk.SAFETY), float(rk.MIN_FACTOR), float(rk.MAX_FACTOR)
#: SciPy raises a smaller rtol to this (with a warning) before integrating.
RTOL_MIN = float(100 * common.EPS)
#: Exponents of the control, as SciPy computes them: the square of the norms,
#: −1/(q + 1) of the step-size factor and 1/(q + 1) of the initial step, with
#: q = 7 the order of the error estimator, and the ½ of √n in the RMS norm
#: (``x.size ** 0.5``). Passed to the kernels as arguments (see the module
#: notes).
POWERS = (2.0, -1 / (DOP853.error_estimator_order + 1), 1 / (DOP853.error_estimator_order + 1),
          0.5)

#: Work counted by :func:`advance_orbit`, in the order of its ``counts``:
#: intervals integrated (one integrator call each, as ``blocks`` of
#: :mod:`baselines.blocks`), right-hand-side evaluations (SciPy's ``nfev``),
#: calls of the step routine (accepted steps, and the failing call of an
#: interval that failed), and rejected trial steps.
COUNTS = ("blocks", "rhs_evaluations", "dop853_steps", "dop853_rejected")
_BLOCKS, _NFEV, _STEPS, _REJECTED = range(len(COUNTS))


@njit(inline="always")
def _pymin(a, b):
    # Python's min(a, b): b only if b < a, so a NaN ``a`` is kept.
    return b if b < a else a


@njit(inline="always")
def _pymax(a, b):
    # Python's max(a, b): b only if b > a.
    return b if b > a else a


@njit(inline="always")
def _maximum(a, b):
    # np.maximum: NaN if either is NaN.
    return a if (a >= b or a != a) else b


@njit
def _rms_norm(x, root_n):
    """SciPy's ``norm``: ‖x‖₂ / √n, the 2-norm as ``np.linalg.norm`` forms
    it (√ of the BLAS dot product)."""
    return np.sqrt(np.dot(x, x)) / root_n


@njit
def _error_norm(Ks, h, y, y_new, rtol, atol, powers, scale, e5, e3):
    """DOP853's error measure (Hairer et al. Sect. II.10; SciPy's
    ``_estimate_error_norm``): the 5th-order estimate damped by the 3rd,
    err = |h| ‖e₅‖² / √(n (‖e₅‖² + 0.01 ‖e₃‖²)) in 2-norms, with
    e = Σ E_j k_j / sc and sc = atol + rtol·max(|y|, |y₁|) per component.
    Leaves sc in ``scale`` and the e's in ``e5``, ``e3``."""
    for i in range(y.size):
        scale[i] = atol + _maximum(abs(y[i]), abs(y_new[i])) * rtol
    np.dot(Ks.T, E5, e5)
    np.dot(Ks.T, E3, e3)
    for i in range(y.size):
        e5[i] /= scale[i]
        e3[i] /= scale[i]
    # ``np.linalg.norm(e)**2``: the root of the dot product, squared by pow.
    n5 = math.pow(np.sqrt(np.dot(e5, e5)), powers[0])
    n3 = math.pow(np.sqrt(np.dot(e3, e3)), powers[0])
    if n5 == 0 and n3 == 0:
        return 0.0
    return abs(h) * n5 / np.sqrt((n5 + 0.01 * n3) * y.size)


#: SciPy's solver compiled for one right-hand side (:func:`dop853_engine`).
Engine = namedtuple("Engine", ("initial_step", "try_step", "integrate_interval"))


@cache
def dop853_engine(rhs):
    """SciPy's DOP853 solver compiled for the right-hand side ``rhs(t, y,
    yp)`` (:func:`baselines.rhs.tangent_rhs`): its initial-step selection,
    its step with rejections, and one interval [0, τ].

    ``rhs`` is compiled in (closed over, called directly), not passed as an
    argument: the address of a function passed as a value is a constant of
    this process in the compiled code, which numba never caches, so every
    process compiled the engine again (≈ 25 s). Compiled in, it is cached
    across processes with the stepping skeleton's kernel that calls it
    (:mod:`varint.kernels.closures`).

    Returns
    -------
    Engine
        ``initial_step``, ``try_step`` and ``integrate_interval``, numba
        functions documented below.
    """

    @njit
    def initial_step(y0, f0, tau, rtol, atol, root_n, powers, scale, y1, f1):
        """SciPy's ``select_initial_step`` on [0, τ] (Hairer et al. Sect.
        II.4, "Starting Step Size"): h₀ = 0.01 ‖y₀‖/‖f₀‖ in the RMS norm
        weighted by atol + rtol·|y₀|, one Euler step to f₁ = f(y₀ + h₀ f₀),
        then h₁ = (0.01 / max(‖f₀‖, ‖f₁ − f₀‖/h₀))^{1/8}; the step is
        min(100 h₀, h₁, τ).

        Parameters
        ----------
        y0, f0 : ndarray
            State and its derivative at t = 0.
        tau, rtol, atol, root_n : float
            Interval end, tolerances and √(len(y0)).
        powers : tuple of float
            :data:`POWERS`.
        scale, y1, f1 : ndarray
            Work arrays of the size of ``y0``.

        Returns
        -------
        float
            The first step; one evaluation of ``rhs``.
        """
        for i in range(y0.size):
            scale[i] = atol + abs(y0[i]) * rtol
            y1[i] = y0[i] / scale[i]
        d0 = _rms_norm(y1, root_n)
        for i in range(y0.size):
            y1[i] = f0[i] / scale[i]
        d1 = _rms_norm(y1, root_n)
        h0 = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
        h0 = _pymin(h0, tau)
        for i in range(y0.size):
            y1[i] = y0[i] + h0 * f0[i]
        rhs(h0, y1, f1)
        for i in range(y0.size):
            y1[i] = (f1[i] - f0[i]) / scale[i]
        d2 = _rms_norm(y1, root_n) / h0
        if d1 <= 1e-15 and d2 <= 1e-15:
            h1 = _pymax(1e-6, h0 * 1e-3)
        else:
            h1 = math.pow(0.01 / _pymax(d1, d2), powers[2])
        # SciPy also takes the minimum with max_step, which is infinite here.
        return _pymin(_pymin(100 * h0, h1), tau)

    @njit
    def rk_stages(t, y, h, Ks, y_new, ys, dy):
        """SciPy's ``rk_step``: stages k₁ … k₁₂ into ``Ks[1:12]`` (k₀ = f(y)
        is in ``Ks[0]``), y₁ = y + h Σ b_j k_j into ``y_new`` and f(y₁) into
        ``Ks[12]``; 12 evaluations of ``rhs``."""
        n = y.size
        for s in range(1, N_STAGES):
            # Σ_{j<s} a_sj k_j as SciPy forms it: np.dot(K[:s].T, a[:s]),
            # BLAS gemv on the column-major transpose (see the module notes).
            np.dot(Ks[:s].T, A[s, :s], dy)
            for i in range(n):
                ys[i] = y[i] + dy[i] * h
            rhs(t + C[s] * h, ys, Ks[s])
        np.dot(Ks[:N_STAGES].T, B, dy)
        for i in range(n):
            y_new[i] = y[i] + h * dy[i]
        rhs(t + h, y_new, Ks[N_STAGES])

    @njit
    def try_step(t, y, h_abs, tau, rtol, atol, powers, Ks, y_new, work, counts):
        """One step of SciPy's ``RungeKutta._step_impl`` from (t, y), f(y)
        in ``Ks[0]``: trial steps of h_abs (truncated to end at τ), shrunk
        after each rejection, until one is accepted (Hairer et al. Sect.
        II.4).

        Parameters
        ----------
        t : float
            Current time, < τ.
        y : ndarray
            Current state.
        h_abs : float
            Proposed step.
        tau, rtol, atol : float
            Interval end and tolerances.
        powers : tuple of float
            :data:`POWERS`.
        Ks : ndarray, shape (13, len(y))
            Stages; ``Ks[0]`` = f(t, y) on entry, ``Ks[12]`` = f(t_new,
            y_new) on an accepted step.
        y_new : ndarray
            Receives the new state.
        work : ndarray, shape (5, len(y))
            Scratch.
        counts : ndarray of int64
            :data:`COUNTS`, incremented.

        Returns
        -------
        accepted : bool
            False if the step size fell below SciPy's minimum (10 ulp of t)
            or became NaN.
        t_new : float
        h_abs : float
            The step proposed next.
        """
        min_step = 10 * abs(np.nextafter(t, np.inf) - t)
        if h_abs < min_step:
            h_abs = min_step
        rejected = False
        ys, dy, scale, e5, e3 = work[0], work[1], work[2], work[3], work[4]
        while True:
            # SciPy tests ``h_abs < min_step``, which a NaN never fails.
            if not h_abs >= min_step:
                return False, t, h_abs
            t_new = t + h_abs
            if t_new - tau > 0:
                t_new = tau
            h = t_new - t
            h_abs = abs(h)
            rk_stages(t, y, h, Ks, y_new, ys, dy)
            counts[_NFEV] += N_STAGES
            err = _error_norm(Ks, h, y, y_new, rtol, atol, powers, scale, e5, e3)
            if err < 1:
                if err == 0:
                    factor = MAX_FACTOR
                else:
                    factor = _pymin(MAX_FACTOR, SAFETY * math.pow(err, powers[1]))
                if rejected:
                    factor = _pymin(1.0, factor)
                return True, t_new, h_abs * factor
            h_abs *= _pymax(MIN_FACTOR, SAFETY * math.pow(err, powers[1]))
            rejected = True
            counts[_REJECTED] += 1

    @njit
    def integrate_interval(y, h_abs, tau, rtol, atol, powers, Ks, y_new, work, counts):
        """Integrate ``y`` in place from t = 0 to τ as SciPy's ``DOP853``
        solver stepped to its ``t_bound``.

        Parameters
        ----------
        y : ndarray
            State at t = 0; on return the state at τ, or the last accepted
            state if the integration failed.
        h_abs : float
            First step (capped at τ), or NaN for SciPy's initial-step
            selection.
        tau, rtol, atol : float
        powers : tuple of float
            :data:`POWERS`.
        Ks, y_new, work : ndarray
            Work arrays as in ``try_step``.
        counts : ndarray of int64
            :data:`COUNTS`, incremented.

        Returns
        -------
        status : int
            ``OK``, ``ORBIT_NONFINITE`` (the state is not finite) or
            ``INTEGRATOR_FAILED`` (the step size fell below its minimum).
        h_abs : float
            The step DOP853 proposes after the last one (SciPy's ``h_abs``).
        """
        rhs(0.0, y, Ks[0])
        counts[_NFEV] += 1
        if h_abs != h_abs:
            h_abs = initial_step(y, Ks[0], tau, rtol, atol, math.pow(y.size, powers[3]), powers,
                                 work[0], work[1], work[2])
            counts[_NFEV] += 1
        else:
            h_abs = _pymin(h_abs, tau)
        t = 0.0
        ok = True
        while ok and t - tau < 0:
            counts[_STEPS] += 1
            ok, t, h_abs = try_step(t, y, h_abs, tau, rtol, atol, powers, Ks, y_new, work,
                                    counts)
            if ok:
                for i in range(y.size):
                    y[i] = y_new[i]
                    Ks[0, i] = Ks[N_STAGES, i]
        for i in range(y.size):
            if not np.isfinite(y[i]):
                return _NONFINITE, h_abs
        return (_OK if ok else _FAILED), h_abs

    return Engine(initial_step, try_step, integrate_interval)


#: One orbit's record (:mod:`varint.kernels.interval`): ``counters`` are
#: :data:`COUNTS`; ``h`` (1,), the step proposed at the end of the previous
#: interval (NaN before the first); ``clock`` (2,), (t, p_t) of the orbit for
#: a time-dependent V ((0,) otherwise).
DOPOrbit = orbit_record("DOPOrbit", ("h", "clock"))

#: What a call reads: tolerances, :data:`POWERS`, and the model's parameters
#: and inverse masses (for the accumulator's flow).
DOPSetup = namedtuple("DOPSetup", ("rtol", "atol", "powers", "par", "minv"))

_Work = namedtuple("_Work", ("n", "k", "d", "xe", "size", "c", "y", "Ks", "y_new", "work", "C",
                             "q", "g", "pl"))


@cache
def dop853_body(rhs, grad):
    """The step body of the compiled DOP853 baseline: one interval τ
    integrated from the renormalised state, restarting DOP853 every τ (the
    paper's scheme; :mod:`varint.baselines.dop853`). ``rhs(t, y, yp)`` is
    :func:`baselines.rhs.tangent_rhs`, ``grad`` the model's gradient kernel
    (for the accumulator's flow); both are compiled in, so the kernel is
    cached across processes where they can be named
    (:mod:`varint.kernels.closures`).

    A failed integration leaves x, W as they were at the interval's start;
    the end of the interval is the stepping skeleton's, as for the TM
    method, with the integrated vectors taken as a block of one output
    (:func:`varint.baselines.blocks.take_output`, C = I)."""
    integrate_interval = dop853_engine(rhs).integrate_interval

    @njit(inline="always")
    def begin(state, setup, call):
        d, k = state.W.shape
        c = state.clock.shape[0]
        size = d * (1 + k) + c
        C = np.zeros((k, k))
        for a in range(k):
            C[a, a] = 1.0
        return _Work(d // 2, k, d, state.x, size, c, np.empty(size),
                     np.empty((N_STAGES + 1, size)), np.empty(size), np.empty((5, size)), C,
                     np.empty(d // 2), np.empty(d // 2), setup.par.copy()), 0

    @njit(inline="always")
    def step(state, setup, ws, carry, s, call):
        x, W, clock, counts, y = state.x, state.W, state.clock, state.counters, ws.y
        d, k, c, size = ws.d, ws.k, ws.c, ws.size
        # The layout of baselines.rhs.pack. Element loops, not slice
        # assignments: those doubled numba's compile time (8 s → 4 s).
        for i in range(d):
            y[i] = x[i]
            for a in range(k):
                y[d + i * k + a] = W[i, a]
        if c:
            # From the integer step, as every method's time.
            y[size - 2] = (call.step0 + s) * call.tau
            y[size - 1] = clock[1]
        counts[_BLOCKS] += 1
        status, h_next = integrate_interval(y, state.h[0], call.tau, setup.rtol, setup.atol,
                                            setup.powers, ws.Ks, ws.y_new, ws.work, counts)
        if status != _OK:
            return status, carry
        state.h[0] = h_next
        take_output(y, ws.C, x, W, d, k)
        if c:
            clock[0] = y[size - 2]
            clock[1] = y[size - 1]
        return _OK, carry

    @njit(inline="always")
    def check(state, setup, ws, xe, call):
        return orbit_status(xe, ws.n, call.escape_r2)

    @njit(inline="always")
    def flow(state, setup, ws, carry, xe, s, call, out):
        output_flow(grad, ws.y, ws.c, xe, ws.pl, setup.minv, ws.q, ws.g, out)
        return carry

    # Raw vectors are checked for overflow after every interval.
    return StepBody(begin=begin, step=step, check=check, flow=flow, check_every=1)


def advance_orbit(rhs, x, W, acc_m, acc_e, h, n, tau, rtol, atol, powers, mode, escape_r2,
                  counts, accumulate, aux, grad, par, minv, flow, step0, clock=None):
    """Advance one orbit by ``n`` intervals τ, restarting DOP853 every τ
    from the renormalised state (:func:`dop853_body` on the stepping
    skeleton).

    Parameters
    ----------
    rhs : numba function ``rhs(t, y, yp)``
        :func:`baselines.rhs.tangent_rhs`.
    x, W : ndarray, shapes (2N,) and (2N, k)
        Orbit and deviation vectors, advanced in place.
    acc_m, acc_e : ndarray, shape (k,)
        Stretching accumulators (:func:`varint.kernels.checks.renormalize`).
    h : ndarray, shape (1,)
        The step proposed at the end of the previous interval (NaN before
        the first); updated after every interval integrated.
    n : int
    tau, rtol, atol : float
    powers : tuple of float
        :data:`POWERS`.
    mode : int
        A :class:`~varint.protocol.Renorm`.
    escape_r2 : float
        Squared escape radius of |q|.
    counts : ndarray of int64
        :data:`COUNTS`, incremented.
    accumulate, aux, grad, par, minv, flow :
        The indicator's accumulator, its array, and what its flow needs, as
        for :func:`varint.baselines.blocks.consume`.
    step0 : int
        The run's interval count at the start.
    clock : ndarray, shape (2,), optional
        For a time-dependent V: (t, p_t) of the orbit, appended to the flat
        state (:mod:`varint.baselines.rhs`); t is set to (step0 + j)·τ at
        the start of interval j and p_t updated after it.

    Returns
    -------
    done : int
        Intervals completed.
    status : int
        ``OK`` after ``n`` intervals, else why interval ``done + 1``
        failed: the integrator's status (x, W unchanged) or that of the end
        of the interval (x, W hold the failing state).
    """
    orbit = orbit_loop(dop853_body(rhs, grad), accumulate, bool(flow))
    status, done = orbit(
        DOPOrbit(x, W, acc_m, acc_e, aux, counts, h, np.zeros(0) if clock is None else clock),
        DOPSetup(float(rtol), float(atol), powers, par, minv),
        Call(int(n), int(step0), float(tau), int(mode), float(escape_r2)))
    return done, status

"""The state every integration method advances: orbits, deviation vectors and
the accumulated logarithms of their stretching."""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np

from . import _validate as check
from .kernels.checks import renormalized_rows
from .protocol import TIME_MOMENTUM, Renorm, Status
from .seeds import standard_normals

__all__ = ["RunState", "Rows", "Snapshots", "initial_deviations", "output_steps",
           "renormalized_copy"]


@dataclass
class RunState:
    """Orbits and deviation vectors part-way through a run.

    Attributes
    ----------
    x : ndarray, shape (M, 2N)
        The orbits.
    W : ndarray, shape (M, 2N, k)
        Their deviation vectors (renormalised, or raw for ``renorm="none"``
        and between the renormalisations of a sparse schedule: read them
        through :meth:`renormalized`).
    acc_m, acc_e : ndarray, shape (M, k)
        Σ log(stretching) of each vector = log(acc_m) + acc_e · ln 2
        (mantissa and binary exponent kept apart so no log is taken per step).
    step : int
        Renormalisation intervals τ completed.
    status : ndarray of int, shape (M,)
        A :class:`~varint.protocol.Status`: 0 while an orbit is fine, a
        failure code once it failed (it is then frozen), −1 once early
        stopping decided it.
    fail_step : ndarray of int, shape (M,)
        The interval (1-based) in which an orbit failed, or −1.
    counts : dict
        Work done so far, summed over orbits (force and Hessian evaluations
        for TM; right-hand-side evaluations for the baselines; ...).
    extra : dict of str -> ndarray
        Method-specific arrays that determine how a run continues (e.g. the
        last step size of an adaptive integrator, per orbit). Propagators
        keep such state here, never on themselves, so that a checkpoint of
        the RunState is a checkpoint of the run.
    """

    x: np.ndarray
    W: np.ndarray
    acc_m: np.ndarray
    acc_e: np.ndarray
    step: int = 0
    status: np.ndarray | None = None
    fail_step: np.ndarray | None = None
    counts: dict = field(default_factory=dict)
    extra: dict = field(default_factory=dict)

    @classmethod
    def start(cls, x0, W0):
        """A state at t = 0 from orbits (M, 2N) and vectors (M, 2N, k)."""
        x = np.array(x0, dtype=np.float64, order="C")
        W = np.array(W0, dtype=np.float64, order="C")
        m, k = W.shape[0], W.shape[2]
        return cls(x=x, W=W, acc_m=np.ones((m, k)), acc_e=np.zeros((m, k), dtype=np.int64),
                   status=np.zeros(m, dtype=np.int64), fail_step=np.full(m, -1, dtype=np.int64))

    @property
    def n_orbits(self):
        return self.x.shape[0]

    @property
    def k(self):
        return self.W.shape[2]

    def time_momentum(self):
        """The orbits' momenta conjugate to time, (M,), created as zeros on
        first use (``extra[TIME_MOMENTUM]``; for a time-dependent V)."""
        if TIME_MOMENTUM not in self.extra:
            self.extra[TIME_MOMENTUM] = np.zeros(self.n_orbits)
        return self.extra[TIME_MOMENTUM]

    def log_growth(self):
        """Σ log of the stretching of each vector so far, shape (M, k) (up to
        the last renormalisation: see :meth:`renormalized`)."""
        return np.log(self.acc_m) + self.acc_e * math.log(2.0)

    def renormalized(self, renorm):
        """The vectors as an indicator reads them: copies renormalised by
        ``renorm`` (a :class:`~varint.protocol.Renorm`), with the
        stretching since the last renormalisation folded into the
        accumulators, as :class:`Rows`. A propagator that renormalises
        sparsely (``renormalize_every``) leaves raw vectors in the state
        between renormalisations; vectors renormalised already change by
        round-off only."""
        renorm = Renorm.parse(renorm) if isinstance(renorm, str) else Renorm(renorm)
        rows = Rows.of(self)
        if renorm == Renorm.NONE or not self.k:
            return rows
        W, acc_m, acc_e = renormalized_copy(self.W, self.acc_m, self.acc_e, renorm)
        return Rows(x=rows.x, W=W, acc_m=acc_m, acc_e=acc_e, step=rows.step, extra=rows.extra)

    def problems(self, like, renorm, last_step):
        """Why this state (read back from a file) cannot continue the run
        that starts at ``like``, as ``(field, reason)`` pairs; empty if it
        can.

        A state handed to a compiled stepper must have the shapes and dtypes
        the stepper was built for (a wrong shape makes it write out of
        bounds), and numbers a run can reach: the orbits and vectors of a
        running orbit finite, the stretching mantissas finite and positive
        (their logarithm is the exponents), the binary exponents multiples
        of 500 (:mod:`varint.kernels.checks` rescales by 2^±500 only), codes
        that exist, failure steps within the run, and for a Lyapunov
        spectrum (``renorm`` QR) independent vectors.

        Parameters
        ----------
        like : RunState
            The state the same call starts from (shapes and dtypes; its
            ``extra`` holds what the run adds before any work).
        renorm : Renorm
        last_step : int
            The run's last step.
        """
        out = []
        for name in ("x", "W", "acc_m", "acc_e", "status", "fail_step"):
            a, b = getattr(self, name), getattr(like, name)
            if not isinstance(a, np.ndarray) or a.shape != b.shape or a.dtype != b.dtype:
                got = (f"{a.dtype}{list(a.shape)}" if isinstance(a, np.ndarray)
                       else type(a).__name__)
                out.append((name, f"{got}, expected {b.dtype}{list(b.shape)}"))
        if out:
            return out
        if isinstance(self.step, bool) or not isinstance(self.step, int) \
                or not 0 <= self.step <= last_step:
            return [("step", f"{self.step!r}, expected an integer in 0..{last_step}")]
        known = {int(s) for s in Status}
        codes = set(np.unique(self.status).tolist())
        if not codes <= known:
            return [("status", f"unknown code {sorted(codes - known)[0]}")]
        running = self.status == int(Status.OK)
        fs = self.fail_step
        if np.any(running & (fs != -1)) or np.any(~running & ((fs < 1) | (fs > self.step))):
            out.append(("fail_step", f"not -1 for a running orbit and 1..{self.step} for a "
                        "stopped one"))
        checks = (("x", ~np.isfinite(self.x).all(axis=1)),
                  ("W", ~np.isfinite(self.W).all(axis=(1, 2))),
                  ("acc_m", ~((self.acc_m > 0) & np.isfinite(self.acc_m)).all(axis=1)),
                  ("acc_e", (self.acc_e % 500 != 0).any(axis=1)))
        for name, bad in checks:
            bad &= running
            if bad.any():
                out.append((name, f"impossible values for running orbit {int(np.argmax(bad))}"))
        if renorm == Renorm.QR and self.k > 1 and running.any() and not out:
            W = self.W[running]
            s = np.linalg.svd(W / np.linalg.norm(W, axis=1, keepdims=True), compute_uv=False)
            if not (s[:, -1] > 1e-12 * s[:, 0]).all():
                out.append(("W", "the deviation vectors of a running orbit are dependent"))
        counts = self.counts
        if not isinstance(counts, dict) or not all(
                isinstance(v, int) and not isinstance(v, bool) and v >= 0
                for v in counts.values()):
            out.append(("counts", "expected non-negative integer counts"))
        missing = sorted(set(like.extra) - set(self.extra))
        if missing:
            out.append((f"extra.{missing[0]}", "missing"))
        for key, a in self.extra.items():
            if not isinstance(a, np.ndarray) or a.dtype.kind not in "biuf" \
                    or a.ndim == 0 or a.shape[0] != self.n_orbits:
                out.append((f"extra.{key}", "not a numeric array with one row per orbit"))
                continue
            ref = like.extra.get(key)
            if ref is not None and (a.shape != ref.shape or a.dtype != ref.dtype):
                out.append((f"extra.{key}", f"{a.dtype}{list(a.shape)}, expected "
                            f"{ref.dtype}{list(ref.shape)}"))
            elif a.dtype.kind == "f" and not np.isfinite(a[running]).all():
                out.append((f"extra.{key}", "not finite for a running orbit"))
        return out

    def add_counts(self, **counts):
        for key, value in counts.items():
            self.counts[key] = self.counts.get(key, 0) + int(value)

    def after_kernel(self, n, was_active, done, counters, names):
        """Bookkeeping after a compiled batch kernel advanced the orbits that
        were ``was_active`` by up to ``n`` intervals: mark new failures with
        the interval they failed in (``done[m]`` intervals completed before
        it), move the clock on by ``n``, and add the per-orbit ``counters``
        (M, len(names)) to :attr:`counts`."""
        failed = was_active & (self.status != 0)
        n_failed = int(np.count_nonzero(failed))
        if n_failed:
            self.fail_step[failed] = self.step + done[failed] + 1
        self.step += int(n)
        # Some kernels (the TDH methods) keep spare counter columns beyond
        # the named ones: only the named columns are counts (summed as
        # Python ints, one conversion for all).
        counts = self.counts
        for key, value in zip(("steps", *names),
                              (int(done[was_active].sum()) + n_failed,
                               *counters.sum(axis=0).tolist()), strict=False):
            counts[key] = counts.get(key, 0) + int(value)


@dataclass
class Rows:
    """What an indicator reads at output times: one row per orbit and output
    time (the rows of a :class:`RunState` at one time, or of several
    :class:`Snapshots` at once, so reading many outputs costs one call).

    Attributes
    ----------
    x : ndarray, shape (R, 2N)
    W : ndarray, shape (R, 2N, k)
        Renormalised deviation vectors (orthonormal after QR, unit columns
        after normalisation), or the raw ones for ``renorm="none"``.
    acc_m, acc_e : ndarray, shape (R, k)
        Σ log(stretching) = log(acc_m) + acc_e · ln 2, up to this time.
    step : ndarray of int, shape (R,)
        Intervals τ completed at each row's time.
    extra : dict of str -> ndarray
        Accumulator arrays, rows first (e.g. ``extra["acc_megno"]`` (R, k, c)).
    energy : ndarray, shape (R,), optional
        H(x) of every row where the propagator computed it where the state
        was (on the GPU, :mod:`varint.gpu.energy`); None: the reader
        computes it from ``x``.
    """

    x: np.ndarray
    W: np.ndarray
    acc_m: np.ndarray
    acc_e: np.ndarray
    step: np.ndarray
    extra: dict = field(default_factory=dict)
    energy: np.ndarray | None = None

    @classmethod
    def of(cls, state):
        """The rows of ``state`` at its current time."""
        return cls(x=state.x, W=state.W, acc_m=state.acc_m, acc_e=state.acc_e,
                   step=np.full(state.n_orbits, state.step, dtype=np.int64),
                   extra=state.extra)

    def log_growth(self):
        """Σ log of the stretching of each vector so far, shape (R, k)."""
        return np.log(self.acc_m) + self.acc_e * math.log(2.0)


@dataclass
class Snapshots:
    """Copies of a run's state taken inside a compiled stepper at output
    steps, axes (output, orbit, ...).

    ``renormalized`` is False when the vectors were copied between two
    renormalisations (sparse renormalisation): :meth:`rows` then renormalises
    the copies, so indicators read the same values as if the vectors had
    been renormalised at that step. ``energy`` (output, orbit), where not
    None, is H of every snapshot, computed by the propagator
    (:attr:`Rows.energy`).
    """

    steps: np.ndarray
    x: np.ndarray
    W: np.ndarray
    acc_m: np.ndarray
    acc_e: np.ndarray
    extra: dict
    renormalized: bool = True
    energy: np.ndarray | None = None

    def rows(self, renorm):
        """All snapshots as :class:`Rows` (output-major), with the vectors
        renormalised by ``renorm`` (a :class:`~varint.protocol.Renorm`) if
        they were copied between renormalisations."""
        s, m = self.x.shape[:2]
        W = self.W.reshape((s * m,) + self.W.shape[2:])
        acc_m = self.acc_m.reshape(s * m, -1)
        acc_e = self.acc_e.reshape(s * m, -1)
        if not self.renormalized and W.shape[-1] and renorm:
            W, acc_m, acc_e = renormalized_copy(W, acc_m, acc_e, renorm)
        return Rows(x=self.x.reshape(s * m, -1), W=W, acc_m=acc_m, acc_e=acc_e,
                    step=np.repeat(self.steps, m),
                    extra={k: v.reshape((s * m,) + v.shape[2:]) for k, v in self.extra.items()},
                    energy=None if self.energy is None else self.energy.reshape(s * m))


def renormalized_copy(W, acc_m, acc_e, renorm):
    """Copies of vectors ``W`` (R, 2N, k) renormalised (modified Gram–Schmidt
    for ``Renorm.QR``, unit columns for ``Renorm.NORMALIZE``: the steppers'
    own :func:`~varint.kernels.checks.renormalize`), the stretching folded
    into new accumulators (mantissa, exponent). Rows of failed orbits
    (non-finite or overflowing vectors) give NaN: their records are
    blanked."""
    W = np.ascontiguousarray(W, dtype=float)
    return renormalized_rows(W, int(renorm), np.ascontiguousarray(acc_m, dtype=float),
                             np.ascontiguousarray(acc_e, dtype=np.int64))


def initial_deviations(dim, k, n_orbits, seed, indices=None):
    """Seeded random orthonormal deviation vectors, shape (M, 2N, k).

    Orbit m draws from ``numpy.random.default_rng([seed, indices[m]])``
    (``indices`` = 0 … M−1 by default), so its vectors do not depend on how
    many orbits share the call; a chunk of a chaos map passes the orbits'
    indices in the whole map, so the map does not depend on its chunking.
    """
    indices = np.arange(n_orbits) if indices is None else indices
    # The same numbers as a generator per orbit, drawn ~4x faster.
    A = standard_normals(seed, indices, (dim, k))
    if n_orbits == 0 or k == 0:
        return A
    # One stacked QR (LAPACK per matrix, as a loop of single QRs would be).
    Q, R = np.linalg.qr(A)
    return Q * np.sign(np.diagonal(R, axis1=1, axis2=2))[:, None, :]


def output_steps(t_end, tau, t_out=None, per_decade=10):
    """Step indices (multiples of τ) at which results are recorded.

    Parameters
    ----------
    t_end, tau : float
    t_out : None, int or array_like
        ``None``: log-spaced, ``per_decade`` per decade from τ to t_end (the
        paper's log-log plots). An int n: n evenly spaced times ending at
        t_end. An array: those times, each rounded to the nearest multiple of
        τ (the renormalisation grid); results report the times used.

    Returns
    -------
    ndarray of int64, strictly increasing, last = round(t_end / τ).

    Raises
    ------
    ValueError
        For more steps than the int64 step counter holds
        (:func:`varint._validate.step_count`), a count of outputs above the
        number of steps or beyond the memory, or times outside [τ, t_end].
    """
    n_end = check.step_count(t_end, tau)
    if t_out is None:
        # A copy: the caller owns its steps (the cached array stays intact).
        return _log_steps(n_end, per_decade).copy()
    if np.ndim(t_out) == 0:
        if isinstance(t_out, (bool, np.bool_)) or not float(t_out).is_integer() or t_out < 1:
            raise ValueError(f"t_out as a count must be a positive integer, got {t_out!r}")
        n = int(t_out)
        if n > n_end:
            raise ValueError(f"t_out = {n} output times, more than the {n_end} steps of the "
                             f"run (t_end / tau = {t_end:g} / {tau:g}); give at most {n_end}")
        if n <= _CACHED_COUNT:
            return _even_steps(n_end, n).copy()
        # linspace, its rounding and np.unique: three arrays of n numbers.
        check.check_memory(check.array_bytes((3, n)), f"t_out = {n} output times")
        return _spaced(n_end, n)
    else:
        t = np.asarray(t_out, dtype=float).reshape(-1)
        if t.size == 0 or not np.isfinite(t).all():
            raise ValueError("t_out must be a non-empty array of finite times")
        if t.size > 1 and (np.diff(t) <= 0).any():
            raise ValueError("t_out must be strictly increasing")
        # t_end is rounded to whole steps: times up to the rounded end are in.
        if t[0] < tau * (1 - 1e-12) or t[-1] > max(t_end, n_end * tau) * (1 + 1e-12):
            raise ValueError(
                f"t_out must lie in [tau, t_end] = [{tau!r}, {t_end!r}], "
                f"got {float(t[0])!r}..{float(t[-1])!r}")
        steps = np.round(t / tau).astype(np.int64)
        if steps.size > 1 and (np.diff(steps) <= 0).any():
            raise ValueError(f"t_out has two times within one step tau = {tau!r} of each other")
        return steps


@functools.lru_cache(maxsize=64)
def _log_steps(n_end, per_decade):
    """The log-spaced output steps of :func:`output_steps` (read-only):
    worked out once per (n_end, per_decade), since building them
    (logspace, rounding, np.unique) is ~30 µs of every short run's fixed
    cost."""
    decades = max(math.log10(n_end), 0.0)
    steps = np.logspace(0, decades, max(2, int(math.ceil(decades * per_decade)) + 1))
    steps = _ending_at(np.unique(np.round(steps).astype(np.int64)), n_end)
    steps.flags.writeable = False
    return steps


#: Evenly spaced output steps of at most this many outputs are kept
#: (:func:`_even_steps`); more are worked out at every call.
_CACHED_COUNT = 1024


@functools.lru_cache(maxsize=64)
def _even_steps(n_end, n):
    """``n`` evenly spaced output steps ending at ``n_end`` (``t_out`` as a
    count in :func:`output_steps`), read-only: worked out once per
    (n_end, n) when n is small (``integrate`` records one output, and
    linspace, rounding and np.unique are ~20 µs of a short run's fixed
    cost)."""
    steps = _spaced(n_end, n)
    steps.flags.writeable = False
    return steps


def _spaced(n_end, n):
    """``n`` evenly spaced output steps ending at ``n_end``."""
    steps = np.unique(np.round(np.linspace(n_end / n, n_end, n)).astype(np.int64))
    return _ending_at(steps, n_end)


def _ending_at(steps, n_end):
    """``steps`` within [1, n_end], ending at ``n_end``."""
    steps = steps[(steps >= 1) & (steps <= n_end)]
    if steps.size == 0 or steps[-1] != n_end:
        steps = np.append(steps, n_end)
    return steps

"""Runs of a few orbits from step 0 to their last output in one call of a
generated stepper, with one thread's buffers made once and kept between
runs (a prepared run's short call, :mod:`varint.prepared`).

A one-step run's arithmetic takes ~5 µs; making its eleven bookkeeping
arrays, their views, the stepper's named tuples and the snapshots' record
took ~40 µs more, at every call, on 1–4-element arrays (issue 28: the fixed
cost of a call). Here they are made once per thread and reset at each
run: one copy of a template for the floats (NaN snapshots, unit
stretching mantissas) and one for the integers (zero counters and
exponents, the renormalisation schedule at its start), the state and
vectors copied into kept arrays. The stepper gets the same values as from
fresh arrays, so the same bits; the whole run is one chunk, which the
propagator protocol makes bitwise the driver's chunks (rule 3).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..codegen.interval import CompensatedOrbit, Outputs, StepperOrbit
from ..kernels.checks import renormalized_rows
from ..kernels.resolved import Resolved
from ..protocol import COUNTERS
from ..state import Rows, Snapshots

__all__ = ["FreshRun", "fresh_rows", "kept_rows", "start"]


@njit(cache=True)
def _reset(floats, floats_start, ints, ints_start, x0_kept, x, W, aux, aux0, x0, W0):
    """A run's start in the kept buffers, in one compiled call (five NumPy
    ``copyto`` calls cost ~3 µs on these few numbers): the templates of the
    floats and the integers, the start states (twice: kept as rows of
    :attr:`FreshRun.states` and as the stepper's state), the vectors and
    the accumulator's start."""
    floats[:] = floats_start
    ints[:] = ints_start
    x0_kept[:] = x0
    x[:] = x0
    W[:] = W0
    aux[:] = aux0


def start(reset, buffers, x0, W0):
    """A fresh run's start: ``reset`` (:func:`_reset`'s compiled version)
    of its kept ``buffers`` from the states ``x0`` (M, 2N) and vectors
    ``W0`` (M, 2N, k). The compiled reset takes writable C-contiguous x0
    and W0, its one signature: other layouts are copied, and so are
    read-only arrays (a caller's vectors made read-only), which numba would
    type apart and compile the reset again for (~3 s cold). A copy of these
    few numbers, the same values, costs less than numba's dispatch."""
    if not (x0.flags.c_contiguous and x0.flags.writeable):
        x0 = np.array(x0, order="C")
    if not (W0.flags.c_contiguous and W0.flags.writeable):
        W0 = np.array(W0, order="C")
    reset(*buffers, x0, W0)


def kept_rows(snapshots):
    """``snapshots.rows(None)`` with its arrays read-only: views of a fresh
    run's kept buffers, made once; each run hands out :func:`fresh_rows` of
    them."""
    r = snapshots.rows(None)
    for v in (r.x, r.W, r.acc_m, r.acc_e, r.step, *r.extra.values()):
        v.flags.writeable = False
    return r


def fresh_rows(r):
    """A new :class:`~varint.state.Rows` of the same read-only views as
    ``r`` (:func:`kept_rows`), its own ``extra`` dict."""
    return Rows(x=r.x, W=r.W, acc_m=r.acc_m, acc_e=r.acc_e, step=r.step, extra=dict(r.extra))


class FreshRun:
    """One thread's runs of ``m`` orbits with ``k`` vectors from step 0 to
    ``outs[-1]``, copied at the output steps ``outs``, by one stepper call.

    Parameters
    ----------
    kernel : callable
        ``kernel() -> (stepper, final)``, asked before each run until it
        says ``final``, then never again: the stepper function that run
        takes (a generated stepper's ``batch_serial``, called through its
        compiled version after its first run,
        :class:`~varint.kernels.resolved.Resolved`: every run passes the
        same arrays, made here; or its ``batch_parallel``, a function that
        runs ``batch_serial`` on threads, :mod:`varint.threads`), and
        whether every later run takes it too (the compact stepper's runs
        until the work repays the written-out one's compile,
        :meth:`varint.methods.tm.TangentMapPropagator.fresh_run`: the same
        bits).
    setup, call
        The stepper's :class:`~varint.codegen.interval.StepperSetup` and the
        run's :class:`~varint.kernels.interval.Call` (all ``outs[-1]`` steps
        from step 0).
    outs : ndarray of int64
        Increasing output steps, the last one the end.
    shape : (int, int, int)
        (M, 2N, k).
    aux0 : ndarray, shape (M, k, c)
        The accumulator's start ((M, 0, 0) without one).
    accumulator : str or None
        The accumulator's key in the snapshots' ``extra``.
    renormalized : bool
        Whether the snapshots' vectors are renormalised (not for sparse
        renormalisation: :meth:`varint.state.Snapshots.rows`).
    compensated : bool
        Kahan terms carried (zero at the start).

    Attributes
    ----------
    count_keys : tuple of str
        The provenance's counts: "steps", then the stepper's counters.
    x, W : ndarray
        The state (M, 2N) and vectors (M, 2N, k) after the last run, kept:
        copy what outlives the next run.
    states : ndarray, shape (M + n_out·M, 2N)
        The last run's start states, then its outputs' (output-major, the
        snapshots' rows): the rows whose energies a short call measures,
        one view of the kept buffer (no concatenation per run).
    status, counters, acc_m, acc_e : ndarray
        The last run's status (M,), counters (M, 4) and the vectors'
        stretching (M, k), likewise kept.
    """

    #: The keys of a result's ``provenance.counts``, in the general path's
    #: order (:meth:`varint.run.Run.provenance`).
    count_keys = ("steps", *COUNTERS)

    def __init__(self, kernel, setup, call, outs, shape, aux0, accumulator, renormalized,
                 compensated):
        m, d, k = shape
        s = len(outs)
        c = aux0[0].size
        # Floats: the start states (copied in at each run), the snapshots
        # (NaN until written), then the stretching's mantissas (1): one
        # block, reset from its template. The start states just before the
        # snapshots' states make both one (M + s·M, 2N) view (:attr:`states`).
        n_snap = m * d + s * m * (d * (k + 1) + c)
        self._floats = np.empty(n_snap + (s + 1) * m * k)
        self._floats_start = np.empty_like(self._floats)
        self._floats_start[:n_snap] = np.nan
        self._floats_start[n_snap:] = 1.0
        f = self._floats
        self._x0 = f[:m * d].reshape(m, d)
        self.states = f[:(s + 1) * m * d].reshape((s + 1) * m, d)
        f = f[m * d:]
        n_snap -= m * d
        sx = f[:s * m * d].reshape(s, m, d)
        sW = f[s * m * d:s * m * d * (k + 1)].reshape(s, m, d, k)
        s_aux = f[s * m * d * (k + 1):n_snap].reshape((s,) + aux0.shape)
        s_acc_m = f[n_snap:n_snap + s * m * k].reshape(s, m, k)
        self.acc_m = f[n_snap + s * m * k:].reshape(m, k)
        # Integers: the snapshots' exponents, the stretching's exponents,
        # counters, steps done, status (all 0) and the schedule (1, 1: as
        # the general path starts it at step 0).
        n_c = len(COUNTERS)
        self._ints = np.zeros((s + 1) * m * k + m * (n_c + 4), dtype=np.int64)
        i = self._ints
        s_acc_e = i[:s * m * k].reshape(s, m, k)
        rest = i[s * m * k:]
        self.acc_e = rest[:m * k].reshape(m, k)
        rest = rest[m * k:]
        self.counters = rest[:m * n_c].reshape(m, n_c)
        done, self.status = rest[m * n_c:m * (n_c + 1)], rest[m * (n_c + 1):m * (n_c + 2)]
        rest[m * (n_c + 2):] = 1
        self._ints_start = i.copy()
        self.x, self.W = np.empty((m, d)), np.empty((m, d, k))
        self._aux, self._aux0 = np.empty_like(aux0), aux0
        self._kahan = np.zeros((m, d, 1 + k)) if compensated else None
        orbit = (self.x, self.W, self.acc_m, self.acc_e, self._aux, self.counters,
                 rest[m * (n_c + 2):].reshape(m, 2))
        orbit = CompensatedOrbit(*orbit, self._kahan) if compensated else StepperOrbit(*orbit)
        self._args = (orbit, setup, call, Outputs(outs, sx, sW, s_acc_m, s_acc_e, s_aux),
                      self.status, done)
        self._choose = kernel
        self._stepper = self._kernel = None
        # The reset's buffers (:func:`_reset`), all made here, C-contiguous
        # (the start states a view of the floats' first M·2N).
        self._buffers = (self._floats, self._floats_start, self._ints, self._ints_start,
                         self._x0, self.x, self.W, self._aux, self._aux0)
        self._reset = Resolved(_reset)
        extra = {} if accumulator is None else {accumulator: s_aux}
        self.snapshots = Snapshots(steps=outs, x=sx, W=sW, acc_m=s_acc_m, acc_e=s_acc_e,
                                   extra=extra, renormalized=renormalized)
        # The snapshots' rows (Snapshots.rows) where no renormalised copy is
        # needed, as read-only views of the kept buffers: made once, a
        # fresh Rows of them at each run (:meth:`rows`).
        self._rows = kept_rows(self.snapshots) if renormalized or not k else None
        # Otherwise (sparse renormalisation): read-only views for the rows
        # but their vectors, and the vectors' views, which each run's rows
        # renormalise into new arrays (:meth:`rows`), as
        # varint.state.renormalized_copy does, by its kernel's compiled
        # version (the views, like the state's vectors, C-contiguous and
        # writeable at every call: its one set of types).
        self._sparse = (None if self._rows is not None else
                        (kept_rows(self.snapshots), self.snapshots.rows(None)))
        self._renormalized = Resolved(renormalized_rows)

    def __call__(self, x0, W0):
        """Run the orbits from states ``x0`` (M, 2N) with vectors ``W0``
        (M, 2N, k), both float64; the results are in the kept arrays
        (:attr:`x`, :attr:`W`, :attr:`status`, ... and :attr:`snapshots`)."""
        start(self._reset, self._buffers, x0, W0)
        if self._kahan is not None:
            self._kahan.fill(0.0)
        if self._choose is not None:
            self._take(*self._choose())
        self._kernel(*self._args)

    def _take(self, stepper, final):
        """Run ``stepper`` from this run on (resolved anew where it is
        another function), and no longer ask which after a ``final`` one."""
        if stepper is not self._stepper:
            self._stepper, self._kernel = stepper, Resolved.of(stepper)
        if final:
            self._choose = None

    def rows(self, renorm):
        """The last run's snapshots as :class:`~varint.state.Rows`, as
        :meth:`varint.state.Snapshots.rows` gives them (read-only views of
        the kept buffers where no renormalised copy is made)."""
        if self._rows is not None:
            return fresh_rows(self._rows)
        if not renorm:
            return self.snapshots.rows(renorm)
        shown, views = self._sparse
        W, acc_m, acc_e = self._renormalized(views.W, int(renorm), views.acc_m, views.acc_e)
        return Rows(x=shown.x, W=W, acc_m=acc_m, acc_e=acc_e, step=shown.step,
                    extra=dict(shown.extra))

    def renormalized(self, renorm):
        """Renormalised copies of the last run's vectors and their
        stretching, (W, acc_m, acc_e), as
        :func:`varint.state.renormalized_copy` makes them (by its kernel's
        compiled version, as :meth:`rows`)."""
        return self._renormalized(self.W, int(renorm), self.acc_m, self.acc_e)

"""Runs of a few orbits of the part stepper from step 0 to their last
output, with one thread's buffers made once and kept between runs: the
part stepper's counterpart of :class:`~varint.methods.fresh_run.FreshRun`
(a prepared run's or a repeated call's short call, :class:`varint.rerun.ShortCall`).

The general path of a one-step call on a model run by the part stepper (a
general H(q, p) by Gauss–Legendre steps, a T(p) + V(q), a lattice) built
a run state, its seeded vectors and the stepper's tables, and drove it
through the driver: ~0.4 ms a call, against ~10 µs of arithmetic (issue
28: the fixed cost of a call). Here the stage tables, the stepper's
records and the buffers are made once; a run resets the state from its
templates (:func:`~varint.methods.fresh_run._reset`, one compiled call),
advances it to each output by one call of the very kernel the propagator's
:meth:`~varint.methods.parts.PartsPropagator.advance` calls (through its
compiled version, :class:`~varint.kernels.resolved.Resolved`) and copies
the state there, as the driver records it (:func:`varint.driver.drive`,
``Rows.of(state)``). Advancing to each output in one call instead of the
driver's chunks gives the same bits (rule 3 of the propagator protocol).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..kernels import parts as K
from ..kernels.interval import Call
from ..kernels.resolved import Resolved
from ..state import Snapshots
from .fresh_run import _reset, fresh_rows, kept_rows, start

__all__ = ["FreshPartsRun"]


@njit(cache=True)
def _snapshot(x_out, x, W_out, W, acc_m_out, acc_m, acc_e_out, acc_e, aux_out, aux):
    """The state, vectors, stretching and accumulator copied into an
    output's snapshot, in one compiled call (five NumPy ``copyto`` calls
    cost ~3 µs on these few numbers): the same values."""
    x_out[:] = x
    W_out[:] = W
    acc_m_out[:] = acc_m
    acc_e_out[:] = acc_e
    aux_out[:] = aux


class FreshPartsRun:
    """One thread's runs of ``m`` orbits with ``k`` vectors through the part
    stepper from step 0 to ``outs[-1]``, copied at the output steps.

    Parameters
    ----------
    kernel : numba dispatcher
        The part stepper with checks (:func:`varint.kernels.parts.parts_batch`
        with ``checks=True``), the one :meth:`PartsPropagator.advance
        <varint.methods.parts.PartsPropagator.advance>` runs.
    setup : varint.kernels.parts.CheckedPartsSetup
        Its stage tables, parameters and scratch size, without checks.
    tau, renorm, escape_r2
        The step, the renormalisation (int) and the squared escape radius
        of the run's :class:`~varint.kernels.interval.Call`.
    outs : ndarray of int64
        Increasing output steps, the last one the end.
    shape : (int, int, int)
        (M, 2N, k).
    aux0 : ndarray, shape (M, k, c)
        The accumulator's start ((M, 0, 0) without one).
    accumulator : str or None
        The accumulator's key in the snapshots' ``extra``.
    count_keys : tuple of str
        "steps", then the counts of the stepper's counters (one per part:
        ``flow_<name>``), as the general path's provenance names them.

    Attributes
    ----------
    x, W, status, counters, acc_m, acc_e, states, snapshots, count_keys
        As :class:`~varint.methods.fresh_run.FreshRun`'s (``counters``:
        (M, parts)).
    """

    def __init__(self, kernel, setup, tau, renorm, escape_r2, outs, shape, aux0, accumulator,
                 count_keys):
        m, d, k = shape
        s = len(outs)
        n_c = len(count_keys) - 1
        self.count_keys = count_keys
        # The start states, then the outputs' states: one (M + s·M, 2N)
        # block whose rows a short call measures (FreshRun.states).
        self.states = np.empty(((s + 1) * m, d))
        self._x0 = self.states[:m]
        sx = self.states[m:].reshape(s, m, d)
        sW, s_acc_m = np.empty((s, m, d, k)), np.empty((s, m, k))
        s_acc_e = np.empty((s, m, k), dtype=np.int64)
        s_aux = np.empty((s,) + aux0.shape)
        # Reset at each run from templates: the stretching's mantissas (1)
        # and the integers (its exponents, counters, status, steps done,
        # the checks' index: 0).
        self._floats, self._floats_start = np.empty(m * k), np.ones(m * k)
        self.acc_m = self._floats.reshape(m, k)
        self._ints = np.zeros(m * (k + n_c + 3), dtype=np.int64)
        self._ints_start = self._ints.copy()
        i = self._ints
        self.acc_e = i[:m * k].reshape(m, k)
        self.counters = i[m * k:m * (k + n_c)].reshape(m, n_c)
        self.status = i[m * (k + n_c):m * (k + n_c + 1)]
        done = i[m * (k + n_c + 1):m * (k + n_c + 2)]
        at = i[m * (k + n_c + 2):].reshape(m, 1)
        self.x, self.W = np.empty((m, d)), np.empty((m, d, k))
        self._aux, self._aux0 = np.empty_like(aux0), aux0
        orbit = K.CheckedPartsOrbit(self.x, self.W, self.acc_m, self.acc_e, self._aux,
                                    self.counters, np.empty((m, 0, d)), at)
        # One call per output, from the last output's step (the arguments
        # made once: the same types at every call, as Resolved needs).
        starts = np.concatenate([[0], outs[:-1]])
        self._calls = [(orbit, setup, Call(int(b - a), int(a), tau, renorm, escape_r2),
                        self.status, done) for a, b in zip(starts, outs, strict=True)]
        # Each output's snapshot and what it copies (_snapshot's arguments:
        # C-contiguous views of kept buffers, the same types at every call).
        self._copies = [(sx[j], self.x, sW[j], self.W, s_acc_m[j], self.acc_m,
                         s_acc_e[j], self.acc_e, s_aux[j], self._aux) for j in range(s)]
        self._snapshot = Resolved(_snapshot)
        self._kernel = Resolved(kernel)
        self._buffers = (self._floats, self._floats_start, self._ints, self._ints_start,
                         self._x0, self.x, self.W, self._aux, self._aux0)
        self._reset = Resolved(_reset)
        extra = {} if accumulator is None else {accumulator: s_aux}
        self.snapshots = Snapshots(steps=outs, x=sx, W=sW, acc_m=s_acc_m, acc_e=s_acc_e,
                                   extra=extra, renormalized=True)
        # The snapshots' rows as read-only views of the kept buffers (made
        # once; a fresh Rows of them at each run, :meth:`rows`).
        self._rows = kept_rows(self.snapshots)

    def __call__(self, x0, W0):
        """Run the orbits from states ``x0`` (M, 2N) with vectors ``W0``
        (M, 2N, k), both float64, to the last output, or to the output
        where an orbit failed (:attr:`status` nonzero: the general path
        then runs the call)."""
        start(self._reset, self._buffers, x0, W0)
        kernel, status, snapshot = self._kernel, self.status, self._snapshot
        for args, copies in zip(self._calls, self._copies, strict=True):
            kernel(*args)
            if np.count_nonzero(status):
                return
            snapshot(*copies)

    def rows(self, renorm):
        """The last run's snapshots as :class:`~varint.state.Rows` (read-only
        views of the kept buffers; their vectors renormalised at every
        step, so ``renorm`` changes nothing)."""
        return fresh_rows(self._rows)

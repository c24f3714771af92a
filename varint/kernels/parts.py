"""The compiled stepper of split Hamiltonians H = P_1 + … + P_k: one kernel
for every scheme (a word of flows, :func:`varint.schemes.part_stages`) and
every model that declares its parts (:class:`varint.models.lattice.Parts`).

A step applies the scheme's flows in order; each flow is the model's exact
flow of one part, fused with its tangent map, so one pass over the sites
moves the orbit and every deviation vector (the TM method of Skokos &
Gerlach 2010, Sect. V.C, for any number of parts). This module is that
step body (:func:`parts_body`); the loop over steps and the end of every
step are the stepping skeleton's (:mod:`varint.kernels.interval`), as for
every other method.

Speed comes from four choices, measured in studies/bench_lattices.py and
studies/fpu_gap.py:

* the stepper is compiled with the model's ``apply`` kernel built in (one
  stepper per model class), so its flows are inlined into the step loop;
* the number of deviation vectors is a compile-time constant up to
  :data:`SPECIALISE_K`, so the per-vector loops unroll;
* the vectors are held as contiguous rows (k, 2N) while the steps run, so
  the site loops of the flows vectorise (with the run's (2N, k) layout and
  a run-time k, a Klein–Gordon kick took 5–7 times longer);
* the orbit's end-of-step check adds its squares in vector lanes
  (:func:`~varint.kernels.checks.orbit_status_wide`, the chained check's
  answer on every state): chained, it took 3.4 µs of a 42 µs FPU-β step
  at N = 4096.
"""

from __future__ import annotations

from collections import namedtuple
from functools import cache

import numpy as np
from numba import njit

from .checks import orbit_status_wide
from .interval import StepBody, batch_loop, no_accumulator, orbit_record

__all__ = ["parts_body", "parts_batch", "PartsOrbit", "TimedPartsOrbit", "PartsSetup",
           "CheckedPartsOrbit", "TimedCheckedPartsOrbit", "CheckedPartsSetup", "SPECIALISE_K"]

#: Largest number of deviation vectors compiled as a constant.
SPECIALISE_K = 8

#: One orbit's record (:mod:`varint.kernels.interval`); ``counters`` counts
#: the flows of each part.
PartsOrbit = orbit_record("PartsOrbit")
#: The record of a time-dependent H (flows that advance the time): ``pt``
#: (1,) the momentum conjugate to time, as :data:`varint.kernels.tm.TMOrbit`'s.
TimedPartsOrbit = orbit_record("TimedPartsOrbit", ("pt",))

#: The records of a stepper that copies the orbit at given steps (the
#: checks of :mod:`varint.stepsize`'s pilot, in one call): ``sx`` (C, 2N)
#: the orbit at each check step, ``spt`` (C,) its time momentum (timed
#: H), ``at`` (1,) the index of the next check (:func:`parts_body`).
CheckedPartsOrbit = orbit_record("CheckedPartsOrbit", ("sx", "at"))
TimedCheckedPartsOrbit = orbit_record("TimedCheckedPartsOrbit", ("pt", "sx", "spt", "at"))

#: What a call reads: the word of flows (part index ``parts`` and length
#: ``h`` of each), the model's parameters and the scratch it needs.
PartsSetup = namedtuple("PartsSetup", ("parts", "h", "par", "n_work"))
#: :data:`PartsSetup` and the increasing steps ``checks`` (C,) at which a
#: :data:`CheckedPartsOrbit` is copied.
CheckedPartsSetup = namedtuple("CheckedPartsSetup", ("parts", "h", "par", "n_work", "checks"))

# Work space: sizes, the orbit (the end point), the vectors as rows, scratch.
# ``par``: the parameters the flows read (a private copy for a
# time-dependent H, whose last entry is the time).
_Work = namedtuple("_Work", ("n", "k", "d", "xe", "V", "work", "par"))


@cache
def parts_body(apply, field, K_C, TIME=False, CHECKS=False):
    """The step body of the model whose flows are ``apply`` (and vector
    field ``field``); ``K_C`` ≥ 0 fixes the number of vectors at compile
    time, −1 reads it from ``W``.

    With ``CHECKS`` (records :data:`CheckedPartsOrbit`, setup
    :data:`CheckedPartsSetup`) the orbit (and its time momentum) is copied
    to ``sx[i]`` (``spt[i]``) at the end of the run's step ``checks[i]``
    once the step's checks passed, ``i`` from ``at[0]``: a pilot's 50
    checks in one call instead of 50 (each a Python call of ~40 µs, as
    much as a short orbit's steps between two checks). An orbit that
    stopped before a check has no copy there. The copies change no bit of
    the steps.

    Each deviation vector is held as one contiguous row of ``V`` (k, 2N)
    while the steps run (the site loops of the flows then vectorise) and
    written back to ``W`` (2N, k) at the end of the call.

    With ``TIME`` (a time-dependent H whose flows integrate the whole H,
    :attr:`varint.models.lattice.Parts.timed`) every flow starts at its own
    time, (step0 + s)·τ plus the lengths of the flows before it in the
    step (the step's start from the integer step, so that it does not
    depend on chunking), written to the last entry of a private copy of
    ``par``; the momentum conjugate to time, ``state.pt[0]``, travels in
    and out of the flow in the last float of ``work`` (the flow advances it
    by −∫∂_tH dt, so that K = H + p_t is conserved).
    """

    @njit(inline="always")
    def begin(state, setup, call):
        n = state.x.shape[0] // 2
        k = K_C if K_C >= 0 else state.W.shape[1]
        V = np.ascontiguousarray(state.W.T)
        par = setup.par.copy() if TIME else setup.par
        return _Work(n, k, 2 * n, state.x, V, np.empty(setup.n_work), par), 0

    @njit(inline="always")
    def step(state, setup, ws, carry, s, call):
        parts, h, counters = setup.parts, setup.h, state.counters
        if TIME:
            t = float(call.step0 + s) * call.tau
            last, slot = ws.par.shape[0] - 1, ws.work.shape[0] - 1
            for st in range(parts.shape[0]):
                ws.par[last] = t
                ws.work[slot] = state.pt[0]
                apply(parts[st], h[st], state.x, ws.V, K_C if K_C >= 0 else ws.k, ws.par,
                      ws.work)
                state.pt[0] = ws.work[slot]
                t += h[st]
                counters[parts[st]] += 1
        else:
            for st in range(parts.shape[0]):
                apply(parts[st], h[st], state.x, ws.V, K_C if K_C >= 0 else ws.k, setup.par,
                      ws.work)
                counters[parts[st]] += 1
        return 0, carry

    @njit(inline="always")
    def check(state, setup, ws, xe, call):
        return orbit_status_wide(xe, ws.n, call.escape_r2)

    @njit(inline="always")
    def flow(state, setup, ws, carry, xe, s, call, out):
        if TIME:
            ws.par[ws.par.shape[0] - 1] = float(call.step0 + s + 1) * call.tau
        field(xe, ws.par, out)
        return carry

    @njit(inline="always")
    def vectors(state, ws):
        return ws.V.T   # the (2N, k) view the checks and accumulators read

    @njit(inline="always")
    def copy_at_checks(state, setup, ws, s, call):
        i = state.at[0]
        if i < setup.checks.shape[0] and setup.checks[i] == call.step0 + s + 1:
            for j in range(ws.d):
                state.sx[i, j] = ws.xe[j]
            if TIME:
                state.spt[i] = state.pt[0]
            state.at[0] = i + 1
        return 0

    @njit(inline="always")
    def end(state, ws):
        # Element by element: a slice assignment makes numba compile its
        # shape-mismatch error message (4-7 s a process, kern18), for
        # shapes that match by construction.
        W, V = state.W, ws.V
        for c in range(V.shape[0]):
            for i in range(V.shape[1]):
                W[i, c] = V[c, i]

    return StepBody(begin=begin, step=step, check=check, flow=flow, vectors=vectors, end=end,
                    **({"after": copy_at_checks} if CHECKS else {}))


def parts_batch(apply, field, k, parallel, accumulate=no_accumulator, flow=False, time=False,
                checks=False):
    """The batch stepper of a model's flows ``apply`` (and vector field
    ``field``) for ``k`` deviation vectors, compiled once per model class,
    k (up to :data:`SPECIALISE_K`), accumulator and options:
    ``batch(states, setup, call, status, done)``
    (:func:`varint.kernels.interval.batch_loop`) with a batch of
    :class:`PartsOrbit` and a :class:`PartsSetup` (with ``time``, a
    time-dependent H: a batch of :class:`TimedPartsOrbit`, :func:`parts_body`).

    Flow ``st`` of a step is ``apply(parts[st], h[st], x, V, k, par,
    work)`` (V: the vectors as rows, ``work``: ``n_work`` floats of scratch
    per orbit); ``counters[m, part]`` receives the flows of each part orbit
    m ran. ``accumulate`` updates ``aux[m]`` after every step; with
    ``flow`` it is given ``field(x, par, out)``, the phase-space velocity.
    With ``checks``, records :data:`CheckedPartsOrbit` (or
    :data:`TimedCheckedPartsOrbit`) and a :data:`CheckedPartsSetup`: the
    orbits are also copied at the setup's check steps (:func:`parts_body`).
    """
    body = parts_body(apply, field, k if k <= SPECIALISE_K else -1, bool(time), bool(checks))
    return batch_loop(body, bool(parallel), accumulate, bool(flow))

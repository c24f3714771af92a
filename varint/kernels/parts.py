"""The compiled stepper of split Hamiltonians H = P_1 + … + P_k: one kernel
for every scheme (a word of flows, :func:`varint.schemes.part_stages`) and
every model that declares its parts (:class:`varint.models.lattice.Parts`).

A step applies the scheme's flows in order; each flow is the model's exact
flow of one part, fused with its tangent map, so one pass over the sites
moves the orbit and every deviation vector (the TM method of Skokos &
Gerlach 2010, Sect. V.C, for any number of parts). After every step the
orbit is checked, the vectors are renormalised and the indicator's
accumulator is updated, with the same compiled functions as the generic
stepper (:mod:`varint.kernels.checks`, :mod:`varint.kernels.tm`), so an
orbit fails for the same reasons with the same status codes whatever
stepper advanced it.

Speed comes from three choices, measured in studies/bench_lattices.py:

* the stepper is compiled with the model's ``apply`` kernel built in (one
  stepper per model class), so its flows are inlined into the step loop;
* the number of deviation vectors is a compile-time constant up to
  :data:`SPECIALISE_K`, so the per-vector loops unroll;
* the vectors are held as contiguous rows (k, 2N) while the steps run, so
  the site loops of the flows vectorise (with the run's (2N, k) layout and
  a run-time k, a Klein–Gordon kick took 5–7 times longer).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from numba import njit, prange

from ..protocol import Renorm, Status
from .checks import CHECK_EVERY, orbit_status, renormalize, tangent_overflow

__all__ = ["parts_batch", "SPECIALISE_K"]

_OK = int(Status.OK)
_OVERFLOW = int(Status.TANGENT_OVERFLOW)
_NONE = int(Renorm.NONE)

#: Largest number of deviation vectors compiled as a constant.
SPECIALISE_K = 8


def _make_orbit_kernel(apply, field, K_C, FLOW):
    """The one-orbit stepper of the model whose flows are ``apply`` (and
    vector field ``field``); ``K_C`` ≥ 0 fixes the number of vectors at
    compile time, −1 reads it from ``W``. With ``FLOW`` the phase-space
    velocity at the end of each step is passed to the accumulator."""

    @njit
    def steps(x, V, acc_m, acc_e, n_steps, parts, h, par, work, renorm, escape_r2,
              counters, accumulate, aux, step0, tau):
        n = x.shape[0] // 2
        d = 2 * n
        k = K_C if K_C >= 0 else V.shape[0]
        W = V.T  # the (2N, k) view the checks and accumulators read
        r = np.empty(k if aux.shape[0] > 0 else 0)   # stretching, for the accumulator
        flow = np.empty(d if FLOW else 0)
        tangent = k > 0
        for s in range(n_steps):
            for st in range(parts.shape[0]):
                apply(parts[st], h[st], x, V, k, par, work)
                counters[parts[st]] += 1
            status = orbit_status(x, n, escape_r2)
            if status != _OK:
                return status, s
            if renorm != _NONE:
                status = renormalize(W, renorm, acc_m, acc_e, r, d, k)
                if status != _OK:
                    return status, s
                if aux.shape[0] > 0:
                    if FLOW:
                        field(x, par, flow)
                    # The time from the integer step, so it does not depend on chunking.
                    accumulate(aux, r, x, W, flow, (step0 + s + 1) * tau)
            elif tangent and s % CHECK_EVERY == CHECK_EVERY - 1:
                if tangent_overflow(W):
                    return _OVERFLOW, s
        if renorm == _NONE and tangent and tangent_overflow(W):
            return _OVERFLOW, n_steps - 1
        return _OK, n_steps

    @njit
    def parts_orbit(x, W, acc_m, acc_e, n_steps, parts, h, par, n_work, renorm, escape_r2,
                    counters, accumulate, aux, step0, tau):
        # Each deviation vector as one contiguous row while the steps run
        # (the site loops of the flows then vectorise), back at the end.
        V = np.ascontiguousarray(W.T)
        work = np.empty(n_work)
        out = steps(x, V, acc_m, acc_e, n_steps, parts, h, par, work, renorm, escape_r2,
                    counters, accumulate, aux, step0, tau)
        W[:, :] = V.T
        return out

    return parts_orbit


@lru_cache(maxsize=None)
def _batch(apply, field, K_C, parallel, flow):
    parts_orbit = _make_orbit_kernel(apply, field, K_C, flow)

    @njit(parallel=parallel)
    def batch(X, W, acc_m, acc_e, n_steps, parts, h, par, n_work, renorm, escape_r2, counters,
              status, done, accumulate, aux, step0, tau):
        for m in prange(X.shape[0]):
            if status[m] != _OK:
                done[m] = 0
                continue
            st, steps = parts_orbit(X[m], W[m], acc_m[m], acc_e[m], n_steps, parts, h, par,
                                    n_work, renorm, escape_r2, counters[m], accumulate, aux[m],
                                    step0, tau)
            status[m] = st
            done[m] = steps

    return batch


def parts_batch(apply, field, k, parallel, flow=False):
    """The batch stepper of a model's flows ``apply`` (and vector field
    ``field``) for ``k`` deviation vectors, compiled once per model class,
    k (up to :data:`SPECIALISE_K`) and options.

    The returned function advances every orbit of ``X`` (M, 2N) whose
    ``status`` is OK by ``n_steps`` steps of the word (``parts``, ``h``):
    flow ``st`` is ``apply(parts[st], h[st], x, V, k, par, work)`` (V: the
    vectors as rows, ``work``: ``n_work`` floats of scratch per orbit).
    ``done[m]`` receives the steps orbit m completed, ``status[m]`` its
    status and ``counters[m, part]`` the flows of each part it ran.
    ``accumulate`` updates ``aux[m]`` after every step (pass
    :func:`varint.kernels.tm.no_accumulator` and an empty ``aux`` (M, 0, 0)
    for none); with ``flow`` it is given ``field(x, par, out)``, the
    phase-space velocity.
    """
    return _batch(apply, field, k if k <= SPECIALISE_K else -1, bool(parallel), bool(flow))

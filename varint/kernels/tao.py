"""The step body of Tao's explicit method for a general H(q, p)
(:mod:`varint.flows.tao`) on the stepping skeleton.

Tao's method carries a second copy of phase space, (x, y), and the matrix
G that maps the first copy's tangent vectors to the second's, from step to
step (Tao 2016; :mod:`varint.flows.tao`). They are the method's own state:
the orbit record holds them beside the orbit (``x2`` (2N,), ``G``
(2N, 2N)), the run keeps them in ``RunState.extra`` between calls, so that
a run cut into chunks, checkpointed and resumed gives the same bits as one
in a single call. The loop over steps, the checks, the renormalisation of
the first copy's vectors and the accumulators are the skeleton's
(:mod:`varint.kernels.interval`), as for every other method.
"""

from __future__ import annotations

from collections import namedtuple
from functools import cache

import numpy as np
from numba import njit

from ..flows.tao import tao_stepper
from .checks import orbit_status
from .interval import StepBody, batch_loop, no_accumulator, orbit_record

__all__ = ["tao_body", "tao_batch", "TaoOrbit", "TaoSetup"]

#: One orbit's record (:mod:`varint.kernels.interval`) with Tao's second
#: copy ``x2`` (2N,) and the map ``G`` (2N, 2N) of the first copy's
#: tangent to the second's; ``counters`` (1,) counts the steps.
TaoOrbit = orbit_record("TaoOrbit", ("x2", "G"))

#: What a call reads: the flows of one step (``parts``: 0 = H_A, 1 = H_B,
#: 2 = ω H_C; ``h`` their lengths), the binding ω, the model's parameters
#: and the scratch size.
TaoSetup = namedtuple("TaoSetup", ("parts", "h", "omega", "par", "n_work"))

_Work = namedtuple("_Work", ("n", "k", "d", "xe", "V", "work"))


@cache
def tao_body(grad_hess, field):
    """The step body of Tao's method with the model's kernel
    ``grad_hess(x, par, g, D)`` = ∇H, D²H (and vector field ``field`` for
    the accumulators that need it). The vectors are held as rows of ``V``
    (k, 2N) while the steps run, as the part stepper does."""
    tao_step = tao_stepper(grad_hess)

    @njit(inline="always")
    def begin(state, setup, call):
        n = state.x.shape[0] // 2
        V = np.ascontiguousarray(state.W.T)
        return _Work(n, state.W.shape[1], 2 * n, state.x, V, np.empty(setup.n_work)), 0

    @njit(inline="always")
    def step(state, setup, ws, carry, s, call):
        status = tao_step(setup.parts, setup.h, setup.omega, state.x, state.x2, ws.V, ws.k,
                          state.G, setup.par, ws.work)
        state.counters[0] += 1
        return status, carry

    @njit(inline="always")
    def check(state, setup, ws, xe, call):
        return orbit_status(xe, ws.n, call.escape_r2)

    @njit(inline="always")
    def flow(state, setup, ws, carry, xe, s, call, out):
        field(xe, setup.par, out)
        return carry

    @njit(inline="always")
    def vectors(state, ws):
        return ws.V.T

    @njit(inline="always")
    def end(state, ws):
        state.W[:, :] = ws.V.T

    return StepBody(begin=begin, step=step, check=check, flow=flow, vectors=vectors, end=end)


def tao_batch(grad_hess, field, parallel, accumulate=no_accumulator, flow=False):
    """The batch stepper of Tao's method on a model with kernels
    ``grad_hess`` and ``field``: ``batch(states, setup, call, status, done)``
    (:func:`varint.kernels.interval.batch_loop`) with a batch of
    :class:`TaoOrbit` and a :class:`TaoSetup`."""
    return batch_loop(tao_body(grad_hess, field), bool(parallel), accumulate, bool(flow))

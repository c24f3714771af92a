"""``method="tm"`` on a general H(q, p): Gauss–Legendre steps through the
part stepper (:class:`~varint.methods.parts.PartsPropagator`), Tao's
explicit method (:data:`varint.flows.general.TAO_SCHEMES`) through its own
step body (:mod:`varint.kernels.tao`) on the same stepping skeleton.

Tao's method carries a second copy of phase space and the map G of the
first copy's tangent vectors to the second's (:mod:`varint.flows.tao`).
They live in ``RunState.extra`` (:data:`TAO_COPY`, :data:`TAO_TANGENT`),
start as the orbit's own state and the identity at the run's first
interval, and are checkpointed with the state, so a run resumes bit for
bit.
"""

from __future__ import annotations

import numpy as np

from ..flows.general import TaoScheme
from ..flows.split import hamiltonian_field
from ..flows.tao import tao_work
from ..kernels import tao as K
from ..kernels.interval import Call, no_accumulator, use_parallel
from ..protocol import STATUS_OK, Renorm
from ..schemes import part_stages
from .options import method_options
from .parts import PartsPropagator

__all__ = ["GeneralPropagator", "TAO_COPY", "TAO_TANGENT"]

#: ``RunState.extra`` keys of Tao's second copy (M, 2N) and of G (M, 2N, 2N).
TAO_COPY = "tao_copy"
TAO_TANGENT = "tao_tangent"


class GeneralPropagator(PartsPropagator):
    """The part stepper of a general H, or Tao's method when the scheme is
    one of :data:`varint.flows.general.TAO_SCHEMES` (parameters as
    :class:`~varint.methods.parts.PartsPropagator`).

    Raises
    ------
    ValueError
        For Tao's method on a time-dependent H (its flows take no time).
    """

    def __init__(self, model, tau, renorm, accumulator=None, **options):
        scheme = model.parts.resolve(options.get("scheme"), model.name)
        self._tao = isinstance(scheme, TaoScheme)
        if not self._tao:
            super().__init__(model, tau, renorm, accumulator, **options)
            return
        opts = method_options(self.method, options, self.OPTIONS)
        if model.time_dependent:
            raise ValueError(f"scheme {scheme.name!r}: Tao's method takes no time-dependent H; "
                             "use GL4, GL6 or GL8, which integrate it in the extended phase space")
        self.model = model
        self.tau = float(tau)
        self.scheme = scheme
        self.renorm = Renorm.parse(renorm)
        self.parallel = opts.get("parallel")
        self.accumulator = accumulator
        self._parts, self._h = part_stages(scheme, self.tau, {0: 0, 1: 1, 2: 2})
        self._par = np.ascontiguousarray(model.parameters_at(None), dtype=np.float64)
        r = model.escape_radius
        self._escape_r2 = np.inf if r is None else float(r) ** 2

    def describe(self):
        if not self._tao:
            return super().describe()
        return {"scheme": self.scheme.describe(), "stepper": "tao", "omega": self.scheme.omega}

    def advance(self, state, n):
        """Advance every active orbit of ``state`` by ``n`` steps."""
        if not self._tao:
            super().advance(state, n)
            return
        m, d = state.n_orbits, self.model.dim
        if TAO_COPY not in state.extra:
            # The run's first interval: the second copy on the diagonal.
            state.extra[TAO_COPY] = state.x.copy()
            state.extra[TAO_TANGENT] = np.tile(np.eye(d), (m, 1, 1))
        acc = self.accumulator
        if acc is None:
            update, aux, flow = no_accumulator, np.empty((m, 0, 0)), False
        else:
            update, aux, flow = acc.update, state.extra[acc.key], acc.needs_flow
        kernel = K.tao_batch(self.model.grad_hess_h, hamiltonian_field(self.model.grad_h),
                             use_parallel(self.parallel, m), update, flow)
        counters = np.zeros((m, 1), dtype=np.int64)
        done = np.zeros(m, dtype=np.int64)
        was_active = state.status == STATUS_OK
        kernel(K.TaoOrbit(state.x, state.W, state.acc_m, state.acc_e, aux, counters,
                          state.extra[TAO_COPY], state.extra[TAO_TANGENT]),
               K.TaoSetup(self._parts, self._h, self.scheme.omega, self._par,
                          tao_work(self.model.n_dof, state.k)),
               Call(int(n), state.step, self.tau, int(self.renorm), self._escape_r2),
               state.status, done)
        state.after_kernel(n, was_active, done, counters, ("tao_steps",))

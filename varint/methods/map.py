"""The TM method for maps: ``method="tm"`` on a map model.

A map model (:mod:`varint.models.maps`) is iterated by its own map F and
its deviation vectors by its own tangent map DF (w' = DF(x) w), exact up to
round-off: the map is its own "numerical integrator" and DF is the exact
derivative of it, which is what the TM method provides for flows (Skokos &
Gerlach 2010, Sect. V.C). :func:`varint.methods.make_propagator` builds
this propagator when ``method="tm"`` is asked for a map.

The run's interval τ is a whole number of iterations (1 by default, see
:func:`varint.run.default_tau`), after each of which the vectors are
renormalised and the indicator's accumulator is updated, as for a flow; the
run's times t count iterations.
"""

from __future__ import annotations

import numbers

import numba
import numpy as np

from ..kernels import map_stepper as K
from ..kernels.interval import Call, no_accumulator, use_parallel
from ..protocol import STATUS_OK, Renorm
from .options import method_options

__all__ = ["MapPropagator", "iterations"]


def iterations(tau):
    """The number of map iterations in an interval τ: τ must be a positive
    whole number (a map has no step to choose; τ only sets how often the
    vectors are renormalised)."""
    if isinstance(tau, bool) or not isinstance(tau, numbers.Real) or not (
            np.isfinite(tau) and tau >= 1 and float(tau).is_integer()):
        raise ValueError(f"a map advances by whole iterations: tau must be a positive integer "
                         f"(iterations per renormalisation interval, 1 by default), got {tau!r}")
    return int(tau)


class MapPropagator:
    """Advance orbits and deviation vectors of a map model.

    Parameters
    ----------
    model : MapModel
    tau : int
        Iterations per renormalisation interval.
    renorm : Renorm
    accumulator : Accumulator, optional
        Updated after every interval (:class:`varint.protocol.Accumulator`).
        One that reads the flow (MEGNO's, for OFLI) is given none: a map has
        no phase-space velocity (see :mod:`varint.indicators.megno`).
    parallel : bool, optional
        Run the orbits of a batch on all cores (as for flows).
    """

    method = "tm"
    OPTIONS = ("parallel",)

    def __init__(self, model, tau, renorm, accumulator=None, **options):
        if "scheme" in options:
            raise ValueError(f"{model.name} is a map: it is iterated by its own tangent map, "
                             "with no splitting scheme (drop scheme=)")
        opts = method_options(self.method, options, self.OPTIONS)
        if getattr(model, "kind", "flow") != "map":
            raise ValueError(f"MapPropagator iterates map models, got the flow {model.name}")
        self.model = model
        self.iters = iterations(tau)
        self.tau = float(self.iters)
        self.renorm = Renorm.parse(renorm)
        self.parallel = opts.get("parallel")
        self.accumulator = accumulator
        r = model.escape_radius
        self._escape_r2 = np.inf if r is None else float(r) ** 2

    def describe(self):
        return {"map": True, "iterations_per_interval": self.iters}

    def versions(self):
        return {"numba": numba.__version__}

    def advance(self, state, n):
        """Advance every active orbit of ``state`` by ``n`` intervals."""
        m = state.n_orbits
        model = self.model
        acc = self.accumulator
        update, aux = ((no_accumulator, np.empty((m, 0, 0))) if acc is None
                       else (acc.update, state.extra[acc.key]))
        kernel = K.batch_kernel(model.dim, state.k, use_parallel(self.parallel, m),
                                model.iterate_kernel, model.jacobian_kernel, update)
        counters = np.zeros((m, len(K.COUNTERS)), dtype=np.int64)
        done = np.zeros(m, dtype=np.int64)
        was_active = state.status == STATUS_OK
        kernel(K.MapOrbit(state.x, state.W, state.acc_m, state.acc_e, aux, counters),
               K.MapSetup(self.iters, model.params, model.periods),
               Call(int(n), state.step, self.tau, int(self.renorm), self._escape_r2),
               state.status, done)
        state.after_kernel(n, was_active, done, counters, K.COUNTERS)

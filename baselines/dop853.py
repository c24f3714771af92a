"""The paper's Runge–Kutta baseline: ``method="dop853"``.

SciPy's DOP853 (the explicit 8(5,3) pair of Dormand & Prince in Hairer's
formulation) on the orbit and its variational equations, with the
right-hand side compiled from the model's kernels (:mod:`varint.baselines.rhs`).
As in the paper, the integrator is restarted every τ from the renormalised
state (blocks of one interval, :mod:`baselines.blocks`).

The paper's local error threshold δ is Hairer's scalar tolerance with
``ITOL = 0``, i.e. ``rtol = atol = δ``: SciPy's error norm is Hairer's
(per-component scale atol + rtol·max(|y|, |y_new|), the combined 5th/3rd
order estimate, root mean square over components). When τ is below the
natural step (about 0.9 at δ = 1e-5 and 0.2 at δ = 1e-10 on Hénon–Heiles at
H = 1/8) every interval is a single step truncated to τ, so δ then hardly
matters: the method is in effect an 8th-order fixed-step method with h = τ.
"""

from __future__ import annotations

import numba
import numpy as np
import scipy
from scipy.integrate import DOP853

from varint.protocol import Status
from varint._validate import positive_float

from .blocks import BlockPropagator
from .rhs import tangent_rhs

__all__ = ["DOP853Propagator"]


class DOP853Propagator(BlockPropagator):
    """Orbits and deviation vectors by SciPy's DOP853, restarted every τ.

    Parameters
    ----------
    model : Model
    tau : float
        Renormalisation interval: every interval is one call of the
        integrator, starting from the state renormalised at its start.
    renorm : Renorm
    accumulator : Accumulator, optional
        Updated after every interval (:class:`varint.protocol.Accumulator`).
    delta : float, optional
        The paper's local error threshold: ``rtol = atol = delta``. 1e-5 by
        default, the paper's value.
    rtol, atol : float, optional
        Explicit tolerances instead of ``delta``.

    Notes
    -----
    The first step of each interval is the step size DOP853 proposed at the
    end of the previous one (capped at τ), as when Hairer's code is called
    again with its returned H; it is kept per orbit in ``state.extra`` so
    runs resume exactly.
    """

    method = "dop853"
    OPTIONS = {"delta": None, "rtol": None, "atol": None}
    PAPER_DELTA = 1e-5

    def __init__(self, model, tau, renorm, accumulator=None, **options):
        opts = self._options(options)
        if opts["delta"] is not None and (opts["rtol"] is not None or opts["atol"] is not None):
            raise ValueError("give either delta (rtol = atol = delta) or rtol/atol, not both")
        if opts["delta"] is not None or (opts["rtol"] is None and opts["atol"] is None):
            delta = positive_float(opts["delta"] or self.PAPER_DELTA, "delta")
            opts.update(delta=delta, rtol=delta, atol=delta)
        else:
            rtol = opts["rtol"] if opts["rtol"] is not None else opts["atol"]
            atol = opts["atol"] if opts["atol"] is not None else opts["rtol"]
            opts.update(rtol=positive_float(rtol, "rtol"), atol=positive_float(atol, "atol"))
        opts["block"] = 1
        self._setup(model, tau, renorm, opts, accumulator)
        _, self._fun = tangent_rhs(model)

    def versions(self):
        return {"scipy": scipy.__version__, "numba": numba.__version__}

    def _prepare(self, state):
        super()._prepare(state)
        state.extra.setdefault("dop853_h", np.full(state.n_orbits, np.nan))

    def _integrate(self, state, m, y0, n_out):
        h = state.extra["dop853_h"]
        first = None if np.isnan(h[m]) else min(h[m], self.tau)
        solver = DOP853(self._fun, 0.0, y0, self.tau, rtol=self.options["rtol"],
                        atol=self.options["atol"], first_step=first)
        steps = 0
        while solver.status == "running":
            solver.step()
            steps += 1
        counts = {"rhs_evaluations": solver.nfev, "dop853_steps": steps}
        if solver.status != "finished" or not np.isfinite(solver.y).all():
            status = Status.ORBIT_NONFINITE if not np.isfinite(solver.y).all() else Status.INTEGRATOR_FAILED
            return np.empty((0, y0.size)), status, counts
        # The step DOP853 proposes next (SciPy keeps it in h_abs).
        h[m] = solver.h_abs
        return solver.y[None, :], Status.OK, counts

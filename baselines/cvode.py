"""SUNDIALS CVODE (through scikit-sundae): ``method="cvode"``.

CVODE's variable-order Adams–Moulton method (orders 1–12, the right family
for this non-stiff problem) on the orbit and its variational equations, with
the right-hand side compiled from the model's kernels
(:mod:`varint.baselines.rhs`).

A multistep method loses its history at every restart (scikit-sundae can
change the state only through ``CVodeReInit``): restarting every τ is an
order of magnitude slower and less accurate than taking the τ outputs from
CVODE's own interpolant and renormalising virtually, so this baseline
integrates blocks of ``block`` intervals (1000 time units by default,
shorter where the renormalisation cuts them, never past the run's end;
:mod:`varint.baselines.blocks`) and restarts only at block ends: each
restart costs accuracy as well as time.

The Newton iteration of the implicit Adams corrector (scikit-sundae offers
no fixed-point iteration) gets the exact Jacobian of the variational
system from the model's Hessian and third derivatives
(:func:`varint.baselines.rhs.tangent_jacobian`) instead of SUNDIALS'
difference quotients, which cost one right-hand side per equation at every
Jacobian update. Small systems use the dense linear solver; above
:attr:`CVODEPropagator.DENSE_MAX` equations matrix-free GMRES, where
products J·v by one difference of the right-hand side proved cheaper than
the exact product. ``studies/bench_baselines.py`` measures each of these
choices against its alternatives, and ``studies/bench_libraries.py`` this
baseline against one scikit-sundae solve of the same problem.

Counts: ``rhs_evaluations`` is CVODE's own count, which leaves out the
evaluations spent on difference quotients for the Newton iteration (a dense
Jacobian costs one per state component; ``jacobians`` counts those).
"""

from __future__ import annotations

import numba
import numpy as np
from importlib import metadata
from sksundae.cvode import CVODE, CVODEJacTimes

from varint.protocol import Status
from varint._validate import choice, positive_float

from .blocks import BlockPropagator
from .rhs import tangent_jacobian, tangent_rhs

__all__ = ["CVODEPropagator"]

_LINSOLVERS = ("dense", "gmres")
_JACOBIANS = ("exact", "differences")


class CVODEPropagator(BlockPropagator):
    """Orbits and deviation vectors by CVODE's Adams method.

    Parameters
    ----------
    model : Model
    tau : float
        Renormalisation interval (CVODE chooses its own steps).
    renorm : Renorm
    accumulator : Accumulator, optional
        Updated after every interval (:class:`varint.protocol.Accumulator`).
    rtol, atol : float, default 1e-10
        CVODE's relative and absolute tolerances (local error per step,
        weighted per component by rtol·|y_i| + atol).
    block : int, optional
        Longest block: intervals integrated between restarts; 1000 time
        units by default (fewer where the block would hold more than 16 MiB
        per orbit, 128 MiB in all).
    linsolver : {"dense", "gmres"}, optional
        Linear solver of the Newton iteration: dense for small systems,
        matrix-free GMRES when the flat state (orbit and vectors) has more
        than :attr:`DENSE_MAX` numbers (on FPU chains GMRES is several times
        faster from a few hundred numbers on; on Hénon–Heiles, 8–20 numbers,
        dense is as fast or faster).
    jacobian : {"exact", "differences"}, optional
        The Jacobian of the Newton iteration: exact (from the model's
        Hessian and third derivatives) or SUNDIALS' difference quotients.
        By default exact with the dense solver and differences with GMRES
        (each the faster, ``studies/bench_baselines.py``); always
        differences for a time-dependent V, whose kernels give no ∂_t∇V.
    """

    method = "cvode"
    OPTIONS = {"rtol": 1e-10, "atol": 1e-10, "block": None, "linsolver": None,
               "jacobian": None}
    BLOCK_SPAN = 1000.0
    #: Every restart costs a multistep method accuracy (it starts again at
    #: order one): on R1 to t = 1000 (k = 1) 100 blocks gave an orbit error
    #: of 1.8e-5, 20 blocks 8.1e-6, one block 1.4e-7. So blocks are long,
    #: and cut only at a condition of 1e4 (with 100, R1's k = 4 blocks were
    #: cut every ~150 time units and its error was twice as large).
    cond_limit = 1e4
    DENSE_MAX = 100

    def __init__(self, model, tau, renorm, accumulator=None, **options):
        opts = self._options(options)
        opts["rtol"] = positive_float(opts["rtol"], "rtol")
        opts["atol"] = positive_float(opts["atol"], "atol")
        if opts["linsolver"] is not None:
            opts["linsolver"] = choice(opts["linsolver"], _LINSOLVERS, "linsolver")
        if opts["jacobian"] is not None:
            opts["jacobian"] = choice(opts["jacobian"], _JACOBIANS, "jacobian")
        if opts["jacobian"] == "exact" and model.time_dependent:
            raise ValueError(f"jacobian='exact' needs a time-independent model; "
                             f"{model.name!r} depends on t: use jacobian='differences'")
        self._setup(model, tau, renorm, opts, accumulator)
        self._rhs, _ = tangent_rhs(model)
        self._jac = None if model.time_dependent else tangent_jacobian(model)
        self._solvers = {}

    def versions(self):
        return {"scikit-sundae": metadata.version("scikit-sundae"), "numba": numba.__version__}

    def _solver(self, size):
        # A cache, not continuation state: solve() re-initialises CVODE from
        # the block's start state every time.
        if size not in self._solvers:
            linsolver = self.options["linsolver"] or (
                "dense" if size <= self.DENSE_MAX else "gmres")
            exact = self.options["jacobian"] or (
                "exact" if linsolver == "dense" and self._jac is not None else "differences")
            jac = {}
            if exact == "exact":
                jac = ({"jacfn": self._jac[0]} if linsolver == "dense"
                       else {"jactimes": CVODEJacTimes(None, self._jac[1])})
            self._solvers[size] = CVODE(self._rhs, method="Adams", rtol=self.options["rtol"],
                                        atol=self.options["atol"], linsolver=linsolver,
                                        max_num_steps=100_000, **jac)
        return self._solvers[size]

    def _integrate(self, state, m, y0, n_out):
        solver = self._solver(y0.size)
        if n_out == 1:
            # solve() with two times returns CVODE's internal steps instead.
            solver.init_step(0.0, y0)
            res = solver.step(self.tau, tstop=self.tau)
            ys = res.y[None, :]
        else:
            res = solver.solve(self.tau * np.arange(n_out + 1), y0)
            ys = res.y[1:]
        counts = {"rhs_evaluations": res.nfev, "jacobians": res.njev}
        status = Status.OK
        if not res.success:
            # The last row is where CVODE stopped, not a grid point.
            stopped, ys = ys[-1], ys[:-1]
            status = Status.INTEGRATOR_FAILED if np.isfinite(stopped).all() else Status.ORBIT_NONFINITE
        finite = np.isfinite(ys).all(axis=1)
        if not finite.all():
            ys = ys[: np.argmin(finite)]
            status = Status.ORBIT_NONFINITE
        return ys, status, counts

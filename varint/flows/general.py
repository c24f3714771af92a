"""Gauss–Legendre steps of a general H(q, p) as the flows of the part
stepper, so that ``method="tm"`` with every indicator, map, section and
checkpoint runs a model without an exactly solvable split.

The part stepper (:mod:`varint.kernels.parts`) applies a word of flows per
step, each the model's ``apply(part, h, x, V, k, par, work)``. For a
:class:`~varint.models.hamiltonian.GeneralHamiltonian` the "parts" are the
whole-step integrators :data:`INTEGRATORS` — one implicit Gauss–Legendre
step of H (:func:`varint.flows.gauss.gauss_stepper`, orbit and exact tangent
map) — and a scheme of :data:`GENERAL_SCHEMES` is the word of one flow of
one of them for the whole step τ. The stepping loop, the checks, the
renormalisation and the accumulators are the part stepper's, unchanged.

Each step starts its fixed-point iteration from the explicit guess, never
from the previous step's stages: the step is then a function of the state
alone, so results do not depend on how a run is cut into chunks and resume
bit for bit from checkpoints (the extrapolated start saves about a fifth of
the iterations, GL8 on the magnetic bottle: 8.0 against 10.3, in
:mod:`varint.flows.gauss`). A step whose stage equations do not converge
(or whose linearisation is singular) leaves the orbit NaN, which the
stepper reports as a failed orbit.

Tao's extended-phase-space method (:mod:`varint.flows.tao`) carries its
second copy from step to step; that state has no place in the part
stepper, so its schemes (:data:`TAO_SCHEMES`) run on a step body of their
own (:mod:`varint.kernels.tao`), the copy kept in the run's state.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import numpy as np
from numba import njit

from ..schemes import CompositionScheme, get_scheme
from .gauss import GAUSS, gauss_stepper, gauss_work, no_dtime

__all__ = ["INTEGRATORS", "GENERAL_SCHEMES", "TAO_SCHEMES", "TAO_OMEGA", "TaoScheme", "WholeStep",
           "general_apply", "general_work"]

#: The whole-step integrators of a general H, by part index.
INTEGRATORS = ("GL4", "GL6", "GL8")


@dataclass(frozen=True)
class WholeStep(CompositionScheme):
    """One step of the integrator ``INTEGRATORS[slot]`` for the whole τ:
    the word ((slot, 1),) over the "parts" :data:`INTEGRATORS` of a general
    model (``n_parts`` is their number)."""

    slot: int = 0

    def word(self):
        return ((self.slot, 1.0),)

    @property
    def stages(self):
        return 1

    def describe(self) -> dict:
        d = super().describe()
        d["integrator"] = f"implicit Gauss–Legendre, {GAUSS[self.name].stages} stages"
        return d


#: Schemes of a general model by upper-cased name: GL4, GL6, GL8.
GENERAL_SCHEMES = {name: WholeStep(name, len(INTEGRATORS), (1.0,), GAUSS[name].order,
                                   GAUSS[name].reference + "; symplectic: Hairer, Lubich & "
                                   "Wanner 2006, Sect. VI.4", slot=i)
                   for i, name in enumerate(INTEGRATORS)}


#: Tao's binding ω (Tao 2016 takes ω ≈ 20 for steps of this size).
TAO_OMEGA = 20.0


@dataclass(frozen=True)
class TaoScheme(CompositionScheme):
    """Tao's explicit method (:mod:`varint.flows.tao`): a composition over
    his three flows H_A, H_B, ω H_C (the γ of a three-part composition of
    :data:`varint.schemes.SCHEMES`) with binding ``omega``. Its second copy
    and tangent travel from step to step, so it runs on its own step body
    (:mod:`varint.kernels.tao`, :class:`varint.methods.general.GeneralPropagator`)."""

    omega: float = TAO_OMEGA

    def describe(self) -> dict:
        d = super().describe()
        d["integrator"] = f"Tao's explicit extended-phase-space method, binding ω = {self.omega:g}"
        return d


def _tao(name, composition, order):
    base = get_scheme(composition)
    return TaoScheme(name, 3, base.gammas, order, f"M. Tao, Phys. Rev. E 94, 043303 (2016), "
                     f"composed as {base.name} ({base.reference})")


#: Tao's method of orders 4 and 6 (Yoshida's triple jumps of his second-order
#: map), by upper-cased name; their orders are measured in
#: tests/flows/test_general_methods.py.
TAO_SCHEMES = {"TAO4": _tao("TAO4", "ABC4_Y", 4), "TAO6": _tao("TAO6", "ABC6_Y", 6)}


def general_work(n_dof, n_par, timed=False):
    """Floats of scratch of :func:`general_apply`'s flows for N = ``n_dof``
    and ``n_par`` kernel parameters, for up to 2N deviation vectors (and,
    ``timed``, the momentum conjugate to time in the last)."""
    d = 2 * n_dof
    s = max(GAUSS[name].stages for name in INTEGRATORS)
    return (s + 1) * n_par + s * d + 1 + gauss_work(n_dof, s, d) + int(bool(timed))


@cache
def general_apply(grad, grad_hess, n_dof, n_par, dtime=None, used=None):
    """``apply(part, h, x, V, k, par, work)`` of a general model with
    kernels ``grad(x, par, g)`` and ``grad_hess(x, par, g, D)``: part i is
    one step of ``INTEGRATORS[i]`` (module docstring). Compiled once per
    kernels, size and ``used``: a frozenset of the part indices a scheme
    runs (the others do nothing), or None for all three (a scheme runs
    one: compiling the other two took half of a GL8 run's 30 s compile,
    ``studies/compile_cost.py --cases general``).

    With ``dtime(x, par)`` = ∂_tH (a time-dependent H, whose time is the
    last entry of ``par``) the step starts at the time ``par[-1]``, its
    stages at t₀ + c_i h, and the momentum conjugate to time, in the last
    float of ``work``, is advanced by the same Gauss–Legendre quadrature
    (:func:`varint.flows.gauss.gauss_stepper`): the method is then the
    Gauss–Legendre method of the autonomous K = H(q, p, t) + p_t in the
    extended phase space (t, q; p_t, p), which integrates ṫ = 1 exactly,
    with the same order and symplecticity, and the tangent map of (q, p)
    (δt = 0: the deviation vectors stay in phase space)
    (:attr:`varint.models.lattice.Parts.timed`)."""
    # The tables over immutable bytes (GaussLegendre.arrays): the kernels
    # that close over them are named by their content and cached on disk.
    (A4, b4, c4, d4, E4), (A6, b6, c6, d6, E6), (A8, b8, c8, d8, E8) = (
        GAUSS[name].arrays for name in INTEGRATORS)
    dim = 2 * n_dof
    timed = dtime is not None
    dt = dtime if timed else no_dtime

    # Each integrator's step with its stages and the state's size built in
    # (its loops unroll: gauss_stepper); a part not used, a step that does
    # nothing, so that numba does not compile its stages.
    step4, step6, step8 = (_step(gauss_stepper(grad, grad_hess, dt, GAUSS[name].stages, dim),
                                 n_par, dim, timed) if used is None or i in used else _unused
                           for i, name in enumerate(INTEGRATORS))

    @njit(error_model="numpy", inline="always")
    def apply(part, h, x, V, k, par, work):
        # k as a run-time integer: the part stepper passes its compile-time
        # k (a literal, 1 to SPECIALISE_K), and numba compiles a function
        # once per literal it is called with; the step's loops over the
        # vectors are the same arithmetic for any k (its cost is the stage
        # solves), so one compiled step serves every k.
        kr = np.int64(k)
        if part == 0:
            step4(h, x, V, kr, par, work, A4, b4, c4, d4, E4)
        elif part == 1:
            step6(h, x, V, kr, par, work, A6, b6, c6, d6, E6)
        else:
            step8(h, x, V, kr, par, work, A8, b8, c8, d8, E8)

    return apply


@njit(error_model="numpy")
def _unused(h, x, V, k, par, work, A, b, c, d, E):
    """The step of a part that the scheme of the compiled ``apply`` does
    not run (:func:`general_apply`'s ``used``): never called."""


def _step(gauss_step, n_par, dim, timed):
    """One step of :func:`general_apply` by ``gauss_step``: the stage
    parameters and the state of the iteration laid out in ``work``."""

    @njit(error_model="numpy", inline="always")
    def step(h, x, V, k, par, work, A, b, c, d, E):
        s = c.shape[0]
        pars = work[:(s + 1) * n_par].reshape((s + 1, n_par))
        # Element by element: a slice assignment compiles numba's error
        # message for mismatched shapes (4-6 CPU s per process).
        for j in range(s + 1):
            for i in range(n_par):
                pars[j, i] = par[i]
        if timed:
            for j in range(s):
                pars[j, n_par - 1] = par[n_par - 1] + c[j] * h
        off = (s + 1) * n_par
        prev = work[off:off + s * dim]
        prev[0] = np.nan               # the explicit guess: no state between steps
        off += s * dim
        end = work.shape[0] - 1 if timed else work.shape[0]
        pt = work[end:end + 1] if timed else work[off:off + 1]
        status, _ = gauss_step(h, x, V, k, pars, A, b, c, d, E, work[off + 1:end], prev, timed, pt)
        if status != 0:
            x[:] = np.nan

    return step


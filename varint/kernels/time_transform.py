"""The logarithmic-Hamiltonian (LH) step: a splitting scheme run in
fictitious time on a time-transformed Hamiltonian, explicit, symplectic and
with an exact tangent map (Mikkola & Tanikawa 1999; Preto & Tremaine 1999).

For H = A(q, p) + V(q), A with an exact flow that conserves A (½pᵀM⁻¹p, or
the rotating frame's quadratic of :func:`varint.flows.split.planar_flow`),
the extended phase space adds t and p_t = −E. With U(q) = C − V(q) > 0 (C a
constant of the orbit, above its energy) the Hamiltonian

    Γ = ln(A + p_t + C) − ln U(q)

vanishes on the orbit's energy shell and its flow in fictitious time s is
H's flow with dt/ds = 1/(A + p_t + C) = 1/U(q): steps uniform in s are
short where U is large (deep in the potential, near a singular centre) and
long where it is small. Both parts of Γ have exact flows:

* drift of length h: W = A + p_t + C is constant along A's flow, so the
  flow is A's exact flow over the physical time τ = h/W, and t += τ;
* kick of length h: p ← p − (h/U) ∇V(q) (q, hence U, unchanged).

So every two-part scheme and its order apply unchanged (Mikkola & Tanikawa
1999, Sect. 2; Preto & Tremaine 1999, eqs. 12–16). p_t is conserved.

Tangent map. Deviations (δq, δp) with δt carried per vector (``dt``; t is
cyclic, so δt never feeds back into δq, δp) and δp_t = −∇H(x)·δx, set when
a run starts from the vectors it is given: Γ's flow is H's only on the
shell Γ = 0, p_t = −H, so a deviation must stay on it (with δp_t = 0 the
off-shell flow scales the forces by (A + p_t + C)/U and the vectors are
those of another flow). δp_t is conserved. Each flow is its fixed-length map
plus a rank-one term from the state dependence of its length:

* drift: δx' = Dφ_A(τ) δx + f_A(x') δτ, δτ = −(τ/W)(∇A(x)·δx + δp_t),
  δt' = δt + δτ,
  with f_A = J∇A (A's vector field) at the end point;
* kick: δp' = δp − (h/U) D²V δq − (h/U²) ∇V (∇V·δq) (a symmetric term: the
  kick stays symplectic).

The deviation at equal physical time is δx − f_H(x) δt (Mikkola & Innanen
1999): the end point of the extended map is H's flow to t(x₀), so H's flow to
a fixed t is that point moved by f_H over t − t(x₀). :func:`lh_kernels`'
``project`` applies it and sets δt = 0; the vectors of every output are
projected, so indicators read physical-time deviations.

Landing on a physical time. Steps are uniform in s; ``advance`` takes LH
steps while they end before ``t_end``; the step that would pass it is undone
and replaced by a tail of m fixed steps of the same scheme in physical time
(Γ's parts with W = U = 1: the ordinary TM step), m the least number for
which each is no longer than the undone step's physical duration. The state
at ``t_end`` is therefore a function of the state at the previous output and
the output times alone: runs cut at the same output times are bitwise equal.

References
----------
S. Mikkola & K. Tanikawa, MNRAS 310, 745 (1999).
H. Preto & S. Tremaine, AJ 118, 2532 (1999).
S. Mikkola & P. Innanen, AJ 118, 1369 (1999) — tangent vectors of
time-transformed integrators.
"""

from __future__ import annotations

import math
from functools import cache

import numpy as np
from numba import njit

from ..protocol import Status

__all__ = ["lh_kernels", "free_flow"]

_OK = int(Status.OK)
_NONFINITE = int(Status.ORBIT_NONFINITE)
_GRAD = int(Status.GRADIENT_NONFINITE)
#: A kick found U = C − V(q) ≤ 0: C is not above V on this orbit.
U_NOT_POSITIVE = -1
#: The step budget ``max_steps`` ran out before t_end.
BUDGET = -2


@njit(cache=True, error_model="numpy")
def free_flow(tau, x, V, k, par):
    """The flow of A = ½pᵀM⁻¹p over time ``tau`` and its tangent map, in
    place (``par`` = diag M⁻¹; vectors as rows ``V`` (k, 2N))."""
    n = x.shape[0] // 2
    for i in range(n):
        a = tau * par[i]
        x[i] += a * x[n + i]
        for c in range(k):
            V[c, i] += a * V[c, n + i]


@cache
def lh_kernels(flow, kinetic, potential):
    """The LH stepper of a model: A's exact flow ``flow(tau, x, V, k,
    par)``, ``kinetic(x, gA) -> A`` (writing ∇A (2N,)) and ``potential(q,
    gV, HV, hess) -> V`` (writing ∇V (N,) and, with ``hess``, D²V (N, N)).

    Returns ``(advance, step, project, fli)``:

    ``advance(x, V, dt, clock, kinds, coef, h, t_end, max_steps, par, C, counts)
    -> status`` moves the orbit ``x`` (2N,), its vectors ``V`` (k, 2N) with
    their δt ``dt`` (k,) and ``clock`` = [t, p_t + C] to physical time
    ``t_end`` (module docstring): LH steps of fictitious length ``h``, the
    scheme's ``kinds`` (0 drift, 1 kick) and coefficients ``coef``, then
    the tail; on return the vectors are projected (δt = 0). ``counts`` [LH
    steps, tail steps, gradients] is added to. Status 0, or a
    :class:`~varint.protocol.Status`, :data:`U_NOT_POSITIVE` or
    :data:`BUDGET`, with the state of the last completed step.

    ``step(x, V, dt, dpt, clock, kinds, coef, h, par, log, C, counts, gA,
    gV, HV, dtau) -> status`` is one step (``dpt`` (k,): the vectors'
    δp_t; ``log``: LH, else the ordinary step of length ``h``; the last
    four are scratch: (2N,), (N,), (N, N), (k,)).

    ``project(x, V, dt, par, gA, gV, HV)`` turns the vectors into
    physical-time deviations: δx ← δx − f_H(x) δt, δt ← 0.

    ``fli``: the fast Lyapunov indicator of a batch of orbits (its
    docstring).
    """

    @njit(error_model="numpy")
    def drift(hs, x, V, dt, dpt, k, clock, par, gA, dtau, log):
        if not log:
            flow(hs, x, V, k, par)
            clock[0] += hs
            return
        d = x.shape[0]
        n = d // 2
        W = kinetic(x, gA) + clock[1]
        tau = hs / W
        for c in range(k):
            s = dpt[c]   # δW = ∇A·δx + δp_t
            for i in range(d):
                s += gA[i] * V[c, i]
            dtau[c] = -(tau / W) * s
        flow(tau, x, V, k, par)
        clock[0] += tau
        if k == 0:
            return
        kinetic(x, gA)   # f_A = (∇_p A, −∇_q A) at the end point
        for c in range(k):
            for i in range(n):
                V[c, i] += gA[n + i] * dtau[c]
                V[c, n + i] -= gA[i] * dtau[c]
            dt[c] += dtau[c]

    @njit(error_model="numpy")
    def step(x, V, dt, dpt, clock, kinds, coef, h, par, log, C, counts, gA, gV, HV, dtau):
        d = x.shape[0]
        n = d // 2
        k = V.shape[0]
        for st in range(kinds.shape[0]):
            hs = coef[st] * h
            if kinds[st] == 0:
                drift(hs, x, V, dt, dpt, k, clock, par, gA, dtau, log)
                continue
            v = potential(x[:n], gV, HV, k > 0)
            counts[2] += 1
            if v - v != 0.0:   # NaN or ±inf
                return _GRAD
            for i in range(n):
                if gV[i] - gV[i] != 0.0:
                    return _GRAD
            w = hs
            r = 0.0
            if log:
                u = C - v
                if not u > 0.0:
                    return U_NOT_POSITIVE
                w = hs / u
                r = w / u
            for i in range(n):
                x[n + i] -= w * gV[i]
            for c in range(k):
                s = 0.0
                for j in range(n):
                    s += gV[j] * V[c, j]
                for i in range(n):
                    acc = 0.0
                    for j in range(n):
                        acc += HV[i, j] * V[c, j]
                    V[c, n + i] -= w * acc + r * gV[i] * s
        for i in range(d):
            if x[i] - x[i] != 0.0:
                return _NONFINITE
        return _OK

    @njit(error_model="numpy")
    def project(x, V, dt, par, gA, gV, HV):
        """δx ← δx − f_H(x) δt, δt ← 0 (module docstring)."""
        d = x.shape[0]
        n = d // 2
        k = V.shape[0]
        if k == 0:
            return
        kinetic(x, gA)
        potential(x[:n], gV, HV, False)
        for c in range(k):
            for i in range(n):
                V[c, i] -= gA[n + i] * dt[c]
                V[c, n + i] += (gA[i] + gV[i]) * dt[c]
            dt[c] = 0.0

    @njit(error_model="numpy")
    def advance(x, V, dt, clock, kinds, coef, h, t_end, max_steps, par, C, counts):
        d = x.shape[0]
        n = d // 2
        k = V.shape[0]
        gA, gV, HV = np.empty(d), np.empty(n), np.empty((n, n))
        dtau = np.empty(k)
        # Each vector stays on the energy shell: δp_t = −∇H(x)·δx, constant.
        dpt = np.zeros(k)
        if k > 0:
            kinetic(x, gA)
            potential(x[:n], gV, HV, False)
            for c in range(k):
                s = 0.0
                for i in range(n):
                    s += (gA[i] + gV[i]) * V[c, i] + gA[n + i] * V[c, n + i]
                dpt[c] = -s
        x0, V0, dt0, c0 = x.copy(), V.copy(), dt.copy(), clock.copy()
        last = 0.0
        steps = 0
        while True:
            if steps >= max_steps:
                project(x, V, dt, par, gA, gV, HV)
                return BUDGET
            x0[:] = x
            V0[:, :] = V
            dt0[:] = dt
            c0[:] = clock
            status = step(x, V, dt, dpt, clock, kinds, coef, h, par, True, C, counts, gA, gV,
                          HV, dtau)
            if status != _OK:
                x[:] = x0
                V[:, :] = V0
                dt[:] = dt0
                clock[:] = c0
                project(x, V, dt, par, gA, gV, HV)
                return status
            if clock[0] > t_end:
                last = clock[0] - c0[0]
                x[:] = x0
                V[:, :] = V0
                dt[:] = dt0
                clock[:] = c0
                break
            steps += 1
            counts[0] += 1
        # The tail: m ordinary steps in physical time, each no longer than
        # the undone LH step.
        project(x, V, dt, par, gA, gV, HV)
        rest = t_end - clock[0]
        if rest <= 0.0:
            return _OK
        m = max(1, int(math.ceil(rest / last)))
        tau = rest / m
        for _ in range(m):
            status = step(x, V, dt, dpt, clock, kinds, coef, tau, par, False, C, counts, gA,
                          gV, HV, dtau)
            if status != _OK:
                return status
            counts[1] += 1
        clock[0] = t_end   # the tail's lengths sum to it up to round-off
        return _OK

    @njit(error_model="numpy")
    def fli(X, W0, pt, C, kinds, coef, h, t_end, every, max_steps, par, out, status, counts):
        """The fast Lyapunov indicator sup ln‖w(t)‖ over t = 0 and the
        multiples of ``every`` up to ``t_end`` (where the vector is
        normalised; Froeschlé, Lega & Gonczi 1997) of every orbit ``X[m]``
        (M, 2N) from the vector ``W0[m]`` (M, 2N); ``pt`` (M,) = −E and ``C`` (M,) per orbit; ``out`` (M,),
        ``status`` (M,), ``counts`` (M, 3) receive the results."""
        M, d = X.shape
        for m in range(M):
            x = X[m].copy()
            V = np.empty((1, d))
            V[0, :] = W0[m]
            dt = np.zeros(1)
            clock = np.array([0.0, pt[m] + C[m]])
            acc = best = 0.0
            j = 0
            st = _OK
            while clock[0] < t_end and st == _OK:
                j += 1
                stop = min(j * every, t_end)
                st = advance(x, V, dt, clock, kinds, coef, h, stop, max_steps, par, C[m],
                             counts[m])
                norm = 0.0
                for i in range(d):
                    norm += V[0, i] * V[0, i]
                norm = math.sqrt(norm)
                acc += math.log(norm)
                best = max(best, acc)
                for i in range(d):
                    V[0, i] /= norm
            out[m] = best
            status[m] = st

    return advance, step, project, fli

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
a fixed t is that point moved by f_H over t − t(x₀). ``project`` applies it
and sets δt = 0; the vectors of every output are projected, so indicators
read physical-time deviations.

Landing on a physical time. Steps are uniform in s; ``advance`` takes LH
steps while they end before ``t_end``; the step that would pass it is undone
and replaced by a tail of m fixed steps of the same scheme in physical time
(Γ's parts with W = U = 1: the ordinary TM step), m the least number for
which each is no longer than the undone step's physical duration. The state
at ``t_end`` is therefore a function of the state at the previous output and
the output times alone: runs cut at the same output times are bitwise equal.

The kernels. Each model × scheme gets its stepper emitted as straight-line
source, signed and cached on disk (:mod:`varint.codegen.lh`), with these
functions:

``advance(x, V, dt, clock, kinds, coef, h, t_end, max_steps, par, C, counts)
-> status`` moves the orbit ``x`` (2N,), its vectors ``V`` (k, 2N) with
their δt ``dt`` (k,) and ``clock`` = [t, p_t + C] to physical time
``t_end``: LH steps of fictitious length ``h`` (the scheme's coefficients
``coef``), then the tail; on return the vectors are projected (δt = 0).
``counts`` [LH steps, tail steps, gradients] is added to. Status 0, or a
:class:`~varint.protocol.Status`, :data:`U_NOT_POSITIVE` or
:data:`BUDGET`, with the state of the last completed step.

``step(x, V, dt, dpt, clock, kinds, coef, h, par, log, C, counts, gA, gV,
HV, dtau) -> status`` is one step (``dpt`` (k,): the vectors' δp_t;
``log``: LH, else the ordinary step of length ``h``; the last four are
scratch: (2N,), (N,), (N, N), (k,)).

``project(x, V, dt, par, gA, gV, HV)`` turns the vectors into
physical-time deviations: δx ← δx − f_H(x) δt, δt ← 0.

``outputs(X, W0, pt, C, h, t_end, every, max_steps, kinds, coef, par, fli,
status, counts, x_end, t_end_at, x_worst, t_worst)``: every orbit ``X[m]``
(M, 2N) with its vectors ``W0[m]`` (k, 2N; k = 0 or 1) and its own
fictitious step ``h[m]`` to ``t_end`` through outputs at the multiples of
``every``; ``pt`` (M,) = −E and ``C`` (M,) per orbit. ``fli`` (M,)
receives the fast Lyapunov indicator sup ln‖w(t)‖ over the outputs (where
the vector is normalised; Froeschlé, Lega & Gonczi 1997; NaN without a
vector), ``status`` (M,) and ``counts`` (M, 3) as ``advance``'s,
``x_end`` (M, 2N) and ``t_end_at`` (M,) the final states and their times,
``x_worst``, ``t_worst`` the output state whose H lies furthest from
H(x₀) = −p_t and its time.

``lanes0`` and ``lanes1`` (same arguments as ``outputs``, for orbits with
k = 0 and k = 1 vectors): ``outputs`` over SIMD lanes
(:mod:`varint.codegen.lh_lanes`), every orbit's results bitwise those of
``outputs``: every lane takes the same step with the same operations in
the same order (no fused multiply–adds), and the steps that pass an output
time or fail are finished by ``step`` and ``project`` one orbit at a time,
in ``advance``'s order.

References
----------
S. Mikkola & K. Tanikawa, MNRAS 310, 745 (1999).
H. Preto & S. Tremaine, AJ 118, 2532 (1999).
S. Mikkola & P. Innanen, AJ 118, 1369 (1999) — tangent vectors of
time-transformed integrators.
"""

from __future__ import annotations

__all__ = ["U_NOT_POSITIVE", "BUDGET"]

#: A kick found U = C − V(q) ≤ 0: C is not above V on this orbit.
U_NOT_POSITIVE = -1
#: The step budget ``max_steps`` ran out before t_end.
BUDGET = -2

"""Tao's explicit symplectic integrators for any H(q, p), and their tangent
maps.

Tao (2016) doubles phase space, (q, p) → (q, p, x, y), and integrates

    H̄ = H_A + H_B + ω H_C,   H_A = H(q, y),   H_B = H(x, p),
    H_C = ½|q − x|² + ½|p − y|²,

whose three parts are each exactly solvable: along H_A, q and y are
constant, so p ← p − h ∇_qH(q, y) and x ← x + h ∇_pH(q, y); along H_B,
x and p are constant, so q ← q + h ∇_pH(x, p) and y ← y − h ∇_qH(x, p);
H_C rotates (q − x, p − y) by the angle 2ωh and leaves q + x and p + y
unchanged. On the diagonal (q, p) = (x, y) the exact flow of H̄ is that of
H in each copy, and the binding ω H_C keeps the two numerical copies close.
Symmetric compositions of the second-order map
e^{h/2 A} e^{h/2 B} e^{h ωC} e^{h/2 B} e^{h/2 A} give any even order: they
are the compositions of :data:`varint.schemes.SCHEMES` over three
parts (ABC2 is Tao's second-order map, ABC4_Y and ABC6_Y his triple jumps).
The orbit is the first copy (q, p), as in Tao's paper; the second copy is
carried from step to step, never reset (no mixing).

Tangent map
-----------
Each flow is differentiated exactly (the flows of H_A and H_B need the full
Hessian D²H at (q, y) and (x, p); that of H_C is linear), so the step's
tangent map Φ on the doubled space (4N × 4N) is exact and symplectic. A
deviation vector of the physical system starts as (δ, δ) on the diagonal;
after any number of steps its image is (w, G w), where the 2N × 2N matrix
G maps the first copy's tangent to the second's. Writing
Φ [1; G] = [M; B] (2N extended vectors per step, the columns of [1; G]),
a step maps w ← M w and G ← B M⁻¹. The deviation vectors of a run are
then the first copy's tangent vectors w, which are renormalised as any
others (the map w ← M w is linear); G (and the second copy) are the
method's own state, starting from G = 1 and (x, y) = (q, p).

References
----------
M. Tao, Phys. Rev. E 94, 043303 (2016) — the method, the binding ω and the
error bound O(T δ^l ω) for integrable systems.
P. Pihajoki, Celest. Mech. Dyn. Astron. 121, 211 (2015) — the extended
phase space.
H. Yoshida, Phys. Lett. A 150, 262 (1990) — the compositions.
"""

from __future__ import annotations

import math

from functools import cache

from numba import njit

from ..protocol import Status
from .gauss import _lu, _lu_solve

__all__ = ["tao_stepper", "tao_work", "tao_flows", "tao_flow_c"]

_OK = int(Status.OK)
_FAILED = int(Status.INTEGRATOR_FAILED)


def tao_work(n_dof, k):
    """Floats of scratch the step of :func:`tao_stepper` needs for N =
    ``n_dof`` and ``k`` vectors."""
    d = 2 * n_dof
    return 2 * d + d * d + (3 * d * d + d if k else 0)


@cache
def tao_flows(grad_hess):
    """The flows of H_A and H_B, ``(tao_flow_a, tao_flow_b)``, of the model
    kernel ``grad_hess(x, par, g, D)`` = ∇H, D²H, which they call as a
    constant (:func:`tao_stepper` says why it is not an argument)."""

    @njit(error_model="numpy")
    def tao_flow_a(h, x, x2, E, m, par, z, g, D):
        """The flow of H_A = H(q, y) for time h on the copies ``x`` = (q, p)
        and ``x2`` = (x, y) and on the ``m`` extended tangent vectors, the rows
        of ``E`` (m, 4N) laid out (δq, δp, δx, δy)."""
        n = x.shape[0] // 2
        for i in range(n):
            z[i] = x[i]
            z[n + i] = x2[n + i]
        grad_hess(z, par, g, D)
        for i in range(n):
            x[n + i] -= h * g[i]
            x2[i] += h * g[n + i]
        for r in range(m):
            # (δq, δy) are constant along the flow: δz = (δq, δy).
            for i in range(n):
                dp = 0.0
                dx = 0.0
                for j in range(n):
                    dp += D[i, j] * E[r, j] + D[i, n + j] * E[r, 3 * n + j]
                    dx += D[n + i, j] * E[r, j] + D[n + i, n + j] * E[r, 3 * n + j]
                E[r, n + i] -= h * dp
                E[r, 2 * n + i] += h * dx

    @njit(error_model="numpy")
    def tao_flow_b(h, x, x2, E, m, par, z, g, D):
        """The flow of H_B = H(x, p) for time h (see :func:`tao_flow_a`)."""
        n = x.shape[0] // 2
        for i in range(n):
            z[i] = x2[i]
            z[n + i] = x[n + i]
        grad_hess(z, par, g, D)
        for i in range(n):
            x[i] += h * g[n + i]
            x2[n + i] -= h * g[i]
        for r in range(m):
            # (δx, δp) are constant along the flow: δz = (δx, δp).
            for i in range(n):
                dq = 0.0
                dy = 0.0
                for j in range(n):
                    dq += D[n + i, j] * E[r, 2 * n + j] + D[n + i, n + j] * E[r, n + j]
                    dy += D[i, j] * E[r, 2 * n + j] + D[i, n + j] * E[r, n + j]
                E[r, i] += h * dq
                E[r, 3 * n + i] -= h * dy

    return tao_flow_a, tao_flow_b


@njit(cache=True, error_model="numpy")
def tao_flow_c(h, omega, x, x2, E, m):
    """The flow of ω H_C for time h: (q − x, p − y) rotated by 2ωh, q + x
    and p + y unchanged; the same linear map on the tangent rows."""
    d = x.shape[0]
    n = d // 2
    cs = math.cos(2.0 * omega * h)
    sn = math.sin(2.0 * omega * h)
    for i in range(n):
        sq = x[i] + x2[i]
        sp = x[n + i] + x2[n + i]
        u = x[i] - x2[i]
        w = x[n + i] - x2[n + i]
        u2 = cs * u + sn * w
        w2 = -sn * u + cs * w
        x[i] = 0.5 * (sq + u2)
        x2[i] = 0.5 * (sq - u2)
        x[n + i] = 0.5 * (sp + w2)
        x2[n + i] = 0.5 * (sp - w2)
        for r in range(m):
            sq = E[r, i] + E[r, d + i]
            sp = E[r, n + i] + E[r, d + n + i]
            u = E[r, i] - E[r, d + i]
            w = E[r, n + i] - E[r, d + n + i]
            u2 = cs * u + sn * w
            w2 = -sn * u + cs * w
            E[r, i] = 0.5 * (sq + u2)
            E[r, d + i] = 0.5 * (sq - u2)
            E[r, n + i] = 0.5 * (sp + w2)
            E[r, d + n + i] = 0.5 * (sp - w2)


@cache
def tao_stepper(grad_hess):
    """The step ``tao_step(parts, h, omega, x, x2, V, k, G, par, work)`` of
    Tao's method for the model kernel ``grad_hess(x, par, g, D)`` = ∇H, D²H.

    The kernel is a constant of the step, not an argument: a dispatcher
    passed on as an argument to a function LLVM does not inline leaves its
    address, a pointer of this process, in the compiled code (numba's
    ``has_dynamic_globals``), so the step could not be cached on disk and
    was compiled again in every process (as
    :func:`varint.flows.gauss.gauss_stepper`, which says more).
    """
    tao_flow_a, tao_flow_b = tao_flows(grad_hess)

    @njit(error_model="numpy")
    def tao_step(parts, h, omega, x, x2, V, k, G, par, work):
        """One step of a composition of Tao's flows, in place.

        Parameters
        ----------
        parts : int64 array (n_flows,)
            The flow of each stage: 0 = H_A, 1 = H_B, 2 = ω H_C (the slots of a
            three-part composition, :func:`varint.schemes.part_stages`).
        h : float64 array (n_flows,)
            Their lengths.
        omega : float
            The binding ω.
        x, x2 : float64 arrays (2N,)
            The copies (q, p) (the orbit) and (x, y).
        V : float64 array (k, 2N)
            Deviation vectors of the first copy, as rows.
        G : float64 array (2N, 2N)
            The second copy's tangent in terms of the first's (module
            docstring); updated when k > 0.
        par
            The model's parameters (the kernel ∇H, D²H is that of
            :func:`tao_stepper`).
        work : float64 array
            At least :func:`tao_work` floats.

        Returns
        -------
        int
            ``Status.OK``, or ``Status.INTEGRATOR_FAILED`` if the first copy's
            tangent map M became singular (G cannot be carried on).
        """
        d = x.shape[0]
        z = work[:d]
        g = work[d:2 * d]
        off = 2 * d
        D = work[off:off + d * d].reshape((d, d))
        off += d * d
        m = 0
        if k > 0:
            m = d
            E = work[off:off + d * 2 * d].reshape((d, 2 * d))
            off += d * 2 * d
            for j in range(d):
                for i in range(d):
                    E[j, i] = 0.0
                    E[j, d + i] = G[i, j]
                E[j, j] = 1.0
        else:
            E = work[off:off].reshape((0, 2 * d))
        for st in range(parts.shape[0]):
            p = parts[st]
            if p == 0:
                tao_flow_a(h[st], x, x2, E, m, par, z, g, D)
            elif p == 1:
                tao_flow_b(h[st], x, x2, E, m, par, z, g, D)
            else:
                tao_flow_c(h[st], omega, x, x2, E, m)
        if k == 0:
            return _OK
        # M[:, j] = E[j, :d] (first copy), B[:, j] = E[j, d:] (second copy).
        Mt = work[off:off + d * d].reshape((d, d))     # Mᵀ, factorised in place
        off += d * d
        piv = work[off:off + d]
        off += d
        for v in range(k):
            for i in range(d):
                acc = 0.0
                for j in range(d):
                    acc += E[j, i] * V[v, j]
                z[i] = acc
            for i in range(d):
                V[v, i] = z[i]
        for j in range(d):
            for i in range(d):
                Mt[j, i] = E[j, i]
        if not _lu(Mt, piv, d):
            return _FAILED
        # G' = B M⁻¹  ⇔  Mᵀ G'ᵀ = Bᵀ: solve row by row of G'.
        for i in range(d):
            for j in range(d):
                g[j] = E[j, d + i]
            _lu_solve(Mt, piv, d, g)
            for j in range(d):
                G[i, j] = g[j]
        return _OK

    return tao_step

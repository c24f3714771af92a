"""Implicit Gauss–Legendre Runge–Kutta steps for any H(q, p), with the
tangent map of the converged step.

The s-stage Gauss–Legendre method (order 2s) is symplectic for every
Hamiltonian (its coefficients satisfy b_i a_ij + b_j a_ji = b_i b_j; Hairer,
Lubich & Wanner 2006, Thm. VI.4.3), so it is the implicit counterpart, for
non-separable H, of the explicit splittings of H = T + V.

A step of length h from x solves the stage equations for Z_i = Y_i − x,

    Z_i = h Σ_j a_ij f(x + Z_j),     f = J ∇H,

by fixed-point iteration — from the previous step's collocation polynomial
extrapolated (GL8 on the magnetic bottle at h = 0.05: 8.0 iterations per
step against 10.3 from Euler's guess; GL4: 10.6 against 11.2), or from
Z_i = h c_i f(x) at the first step — until the corrections reach round-off
(by Newton's method when it contracts slowly), and returns x' = x + Σ_i d_i Z_i with dᵀ = bᵀA⁻¹ (no further
evaluation of f; Hairer, Lubich & Wanner, Sect. VIII.6). Its tangent map is
the derivative of that map: differentiating the stage equations at the
converged stages gives the linear system

    U_i − h Σ_j a_ij Df(Y_j) U_j = δx,     Df = J D²H,

for the stage tangents U_i = δx + δZ_i, solved by one LU factorisation for
all k deviation vectors at once, and δx' = δx + Σ_i d_i (U_i − δx). The
tangent map is thus exact for the map actually computed (to the round-off
of the converged stages), and symplectic with it.

Coefficients are stored to 25 digits (computed from the roots of the
shifted Legendre polynomials at 40 digits) in :data:`GAUSS`; their order
conditions are checked in the tests.

References
----------
J. C. Butcher, Math. Comp. 18, 50 (1964); E. Hairer, C. Lubich & G. Wanner,
*Geometric Numerical Integration*, 2nd ed., Springer (2006), Sects. II.1.3,
VI.4 and VIII.6.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cache
from typing import Any, cast

import numpy as np
from numba import njit

from ..protocol import Status

__all__ = ["GaussLegendre", "GAUSS", "gauss_stepper", "gauss_work", "stage_parameters", "no_dtime",
           "MAX_ITERATIONS", "FIXED_POINT_VECTORS"]

#: Fixed-point iterations before a step is declared failed.
MAX_ITERATIONS = 100
#: Up to this many deviation vectors the tangent is found by fixed-point
#: iteration, beyond by an LU factorisation (magnetic bottle, GL8, τ = 0.05,
#: one vector: 8 iterations, a quarter of the factorisation's time).
FIXED_POINT_VECTORS = 2
_FAILED = int(Status.INTEGRATOR_FAILED)
_OK = int(Status.OK)
_EPS = np.finfo(np.float64).eps
#: The decorator of the step and its helpers, called only from compiled code:
#: no wrappers for calls from Python, whose lowering and optimisation each
#: compile paid (numba's typing stubs do not name these options).
_helper = cast(Any, njit)(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)


@dataclass(frozen=True)
class GaussLegendre:
    """The Butcher tableau of an s-stage Gauss–Legendre method.

    Parameters
    ----------
    name : str
        ``"GL4"``, ``"GL6"`` or ``"GL8"`` (the order).
    c : tuple of float, shape (s,)
        Nodes: the roots of the shifted Legendre polynomial P_s(2c − 1).
    b : tuple of float, shape (s,)
    a : tuple of tuple of float, shape (s, s)
    order : int
        2s.

    Raises
    ------
    ValueError
        If the shapes do not agree or the order is not 2s.
    """

    name: str
    c: tuple
    b: tuple
    a: tuple
    order: int
    reference: str = "Butcher, Math. Comp. 18, 50 (1964)"
    #: (A, b, c, d, E) as read-only float64 arrays over immutable bytes: the
    #: tableau, dᵀ = bᵀA⁻¹ and the extrapolation of :func:`_extrapolation`.
    arrays: tuple = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        s = len(self.c)
        if len(self.b) != s or len(self.a) != s or any(len(r) != s for r in self.a):
            raise ValueError(f"scheme {self.name!r}: c, b and the rows of a must all have "
                             f"{s} entries")
        if self.order != 2 * s:
            raise ValueError(f"scheme {self.name!r}: an {s}-stage Gauss–Legendre method has "
                             f"order {2 * s}, got {self.order}")
        A = np.array(self.a, dtype=np.float64)
        b = np.array(self.b, dtype=np.float64)
        c = np.array(self.c, dtype=np.float64)
        # x' = x + Σ d_i Z_i, dᵀ = bᵀA⁻¹: the step needs no f at the new stages.
        d = np.linalg.solve(A.T, b)
        object.__setattr__(self, "arrays", tuple(_immutable(a) for a in (A, b, c, d,
                                                                          _extrapolation(c))))

    @property
    def stages(self):
        return len(self.c)

    def describe(self):
        return {"name": self.name, "stages": self.stages, "order": self.order,
                "reference": self.reference}


def _immutable(a):
    """``a`` read-only over an immutable ``bytes`` copy: a kernel that
    closes over it can be named by its content
    (:mod:`varint.kernels.closures`), and cached on disk."""
    return np.frombuffer(np.ascontiguousarray(a).tobytes()).reshape(a.shape)


def _extrapolation(c):
    """E (s, s) with Z_new = E Z_prev: the previous step's collocation
    polynomial u (u(0) = x_{n−1}, u(c_i h) = x_{n−1} + Z_i) evaluated at the
    new stages, Z_new_j ≈ u((1 + c_j)h) − u(h) = Σ_i Z_i (ℓ_i(1 + c_j) − ℓ_i(1)),
    ℓ_i the Lagrange basis on the nodes 0, c_1 … c_s (Hairer, Lubich &
    Wanner, Sect. VIII.6.1: the starting approximation of the iteration)."""
    nodes = np.concatenate([[0.0], c])

    def basis(i, t):
        others = np.delete(nodes, i + 1)
        return np.prod((t - others) / (nodes[i + 1] - others))

    s = len(c)
    return np.array([[basis(i, 1 + c[j]) - basis(i, 1.0) for i in range(s)]
                     for j in range(s)])


GAUSS = {g.name: g for g in (
    GaussLegendre(
        "GL4",
        c=(0.2113248654051871177454256, 0.7886751345948128822545744),
        b=(0.5, 0.5),
        a=((0.25, -0.03867513459481288225457439),
           (0.5386751345948128822545744, 0.25)),
        order=4),
    GaussLegendre(
        "GL6",
        c=(0.1127016653792583114820735, 0.5, 0.8872983346207416885179265),
        b=(0.2777777777777777777777778, 0.4444444444444444444444444,
           0.2777777777777777777777778),
        a=((0.1388888888888888888888889, -0.03597666752493890345639547,
            0.009789444015308326049580042),
           (0.3002631949808645924380249, 0.2222222222222222222222222,
            -0.02248541720308681466024717),
           (0.2679883337624694517281977, 0.4804211119693833479008399,
            0.1388888888888888888888889)),
        order=6),
    GaussLegendre(
        "GL8",
        c=(0.06943184420297371238802676, 0.3300094782075718675986671,
           0.6699905217924281324013329, 0.9305681557970262876119732),
        b=(0.173927422568726928686532, 0.326072577431273071313468,
           0.326072577431273071313468, 0.173927422568726928686532),
        a=((0.08696371128436346434326599, -0.02660418008499879331338513,
            0.01262746268940472451505688, -0.003555149685795683156910982),
           (0.1881181174998680716506855, 0.163036288715636535656734,
            -0.02788042860247089522415111, 0.006735500594538155515398669),
           (0.1671919219741887731711333, 0.3539530060337439665376191,
            0.163036288715636535656734, -0.01419069493114114296415357),
           (0.177482572254522611843443, 0.3134451147418683467984111,
            0.3526767575162718646268532, 0.08696371128436346434326599)),
        order=8),
)}


def gauss_work(n_dof, stages, k):
    """Floats of scratch the step of :func:`gauss_stepper` needs for N = ``n_dof``, s =
    ``stages`` and ``k`` vectors."""
    d = 2 * n_dof
    sd = stages * d
    return 2 * sd + 2 * d + d * d + sd * sd + 2 * sd + sd * k


@njit(cache=True)
def no_dtime(x, par):
    """The ``dtime`` of :func:`gauss_stepper` for an autonomous H (not called)."""
    return 0.0


def stage_parameters(par, stages):
    """``pars`` of :func:`gauss_stepper`'s step for an autonomous H: ``par`` for every
    stage and the start."""
    par = np.asarray(par, dtype=np.float64)
    return np.ascontiguousarray(np.tile(par, (stages + 1, 1)))


@njit(error_model="numpy", inline="always")
def _field(y, par, g, out, grad):
    # out = J ∇H(y)
    n = y.shape[0] // 2
    grad(y, par, g)
    for i in range(n):
        out[i] = g[n + i]
        out[n + i] = -g[i]


@_helper
def _lu(M, piv, m):
    """In-place LU factorisation with partial pivoting of M[:m, :m];
    returns False if M is singular."""
    for col in range(m):
        p = col
        big = abs(M[col, col])
        for r in range(col + 1, m):
            if abs(M[r, col]) > big:
                big = abs(M[r, col])
                p = r
        if big == 0.0 or big != big:
            return False
        piv[col] = p
        if p != col:
            for j in range(m):
                M[col, j], M[p, j] = M[p, j], M[col, j]
        inv = 1.0 / M[col, col]
        for r in range(col + 1, m):
            f = M[r, col] * inv
            if f != 0.0:
                M[r, col] = f
                for j in range(col + 1, m):
                    M[r, j] -= f * M[col, j]
            else:
                M[r, col] = 0.0
    return True


@_helper
def _lu_solve(M, piv, m, rhs):
    """Solve in place for the right-hand side ``rhs`` (m,) given the
    factors of :func:`_lu`."""
    for i in range(m):
        p = int(piv[i])
        if p != i:
            rhs[i], rhs[p] = rhs[p], rhs[i]
    for i in range(m):
        acc = rhs[i]
        for j in range(i):
            acc -= M[i, j] * rhs[j]
        rhs[i] = acc
    for i in range(m - 1, -1, -1):
        acc = rhs[i]
        for j in range(i + 1, m):
            acc -= M[i, j] * rhs[j]
        rhs[i] = acc / M[i, i]


@_helper
def _converged(delta, last, size):
    # At round-off: the corrections reached a few ulps of Z, or stopped
    # shrinking once they were small (rounding noise).
    return delta <= 4.0 * _EPS * size or (delta >= last and delta <= 1e-10 * size)


@_helper
def _update(V, v, U, d, s, dim):
    for m in range(dim):
        acc = 0.0
        for i in range(s):
            acc += d[i] * (U[v, i * dim + m] - V[v, m])
        V[v, m] += acc


@cache
def _linear_solves(grad_hess):
    """``(linearisation, tangent_by_lu, tangent_by_iteration)`` of the model
    kernel ``grad_hess(x, par, g, D)`` = ∇H, D²H, which they call as a
    constant (see :func:`gauss_stepper` for why it is not an argument).
    Called, not inlined by numba: numba's inlining types and lowers a
    function again at each call site, while LLVM inlines the compiled
    helper where it pays (the step's cost and bits are the same)."""

    @_helper
    def linearisation(h, x, Z, A, M, s, dim, pars, y, g, D, F):
        """M = 1 − h (A ⊗ 1) blockdiag(Df(Y_j)) at the stages Y_j = x + Z_j, and
        F_j = f(Y_j) (f = J∇H, Df = J D²H; stage j's parameters ``pars[j]``)."""
        n = dim // 2
        sd = s * dim
        for r in range(sd):
            for col in range(sd):
                M[r, col] = 0.0
            M[r, r] = 1.0
        for j in range(s):
            for m in range(dim):
                y[m] = x[m] + Z[j * dim + m]
            grad_hess(y, pars[j], g, D)
            for m in range(n):
                F[j * dim + m] = g[n + m]
                F[j * dim + n + m] = -g[m]
            # Df = J D²H: rows q̇ = (H_pq, H_pp), ṗ = −(H_qq, H_qp).
            for i in range(s):
                f = -h * A[i, j]
                for r in range(n):
                    for col in range(dim):
                        M[i * dim + r, j * dim + col] += f * D[n + r, col]
                        M[i * dim + n + r, j * dim + col] -= f * D[r, col]

    @_helper
    def tangent_by_lu(h, x, V, k, pars, A, d, Z, U, M, piv, y, g, D, F, s, dim):
        """The stage tangents U from one LU factorisation of the linearised
        stage equations at the converged stages; V ← V + Σ d_i (U_i − V).
        False if the system is singular."""
        sd = s * dim
        linearisation(h, x, Z, A, M, s, dim, pars, y, g, D, F)
        if not _lu(M, piv, sd):
            return False
        for v in range(k):
            for i in range(s):
                for m in range(dim):
                    U[v, i * dim + m] = V[v, m]
            _lu_solve(M, piv, sd, U[v])
            _update(V, v, U, d, s, dim)
        return True

    @_helper
    def tangent_by_iteration(h, x, V, k, pars, A, d, Z, U, H, R, y, g, s, dim):
        """The stage tangents by fixed-point iteration of U_i = δx + h Σ_j a_ij
        Df(Y_j) U_j to round-off (cheaper than the LU for a few vectors: s d²
        per vector and iteration against (s d)³/3); V ← V + Σ d_i (U_i − V),
        for all vectors or (returning False, when an iteration does not
        converge; the caller then factorises) for none. ``H`` (s, 2N, 2N) is
        scratch for D²H at the stages."""
        n = dim // 2
        for j in range(s):
            for m in range(dim):
                y[m] = x[m] + Z[j * dim + m]
            grad_hess(y, pars[j], g, H[j])
        for v in range(k):
            for i in range(s):
                for m in range(dim):
                    U[v, i * dim + m] = V[v, m]
            last = np.inf
            converged = False
            for _ in range(MAX_ITERATIONS):
                # R_j = Df(Y_j) U_j = J D²H(Y_j) U_j.
                for j in range(s):
                    for r in range(dim):
                        acc = 0.0
                        for c in range(dim):
                            acc += H[j, r, c] * U[v, j * dim + c]
                        if r < n:
                            R[j * dim + n + r] = -acc
                        else:
                            R[j * dim + r - n] = acc
                delta = 0.0
                size = 0.0
                for i in range(s):
                    for m in range(dim):
                        acc = 0.0
                        for j in range(s):
                            acc += A[i, j] * R[j * dim + m]
                        u = V[v, m] + h * acc
                        delta = max(delta, abs(u - U[v, i * dim + m]))
                        size = max(size, abs(u))
                        U[v, i * dim + m] = u
                if delta != delta:
                    return False
                if _converged(delta, last, size):
                    converged = True
                    break
                last = delta
            if not converged:
                return False
        for v in range(k):
            _update(V, v, U, d, s, dim)
        return True

    return linearisation, tangent_by_lu, tangent_by_iteration


@cache
def gauss_stepper(grad, grad_hess, dtime=no_dtime, S=-1, DIM=-1):
    """The Gauss–Legendre step ``gauss_step(h, x, V, k, pars, A, b, c, d, E,
    work, prev, timed, pt)`` of the model with kernels ``grad(x, par, g)`` =
    ∇H, ``grad_hess(x, par, g, D)`` = ∇H, D²H and ``dtime(x, par)`` = ∂_tH
    (:func:`no_dtime` for an autonomous H), for ``S`` stages and a state of
    ``DIM`` = 2N floats as compile-time constants (−1: read from ``c`` and
    ``x`` at run time).

    The kernels are constants of the step, not arguments: a function whose
    constant (a closure's cell) is a dispatcher passed on as an argument to
    a function LLVM does not inline keeps that dispatcher's address, a
    pointer of this process, in its code (numba's ``has_dynamic_globals``),
    and numba cannot cache it on disk — so a part stepper that passed its
    model's kernels on was compiled again in every process (16–20 s for
    GL8; :mod:`varint.kernels.closures`). Called, a constant dispatcher
    leaves no address.

    The step's loops run over s and 2N (4 and 4 for GL8 on two degrees of
    freedom); with both constant, LLVM unrolls them and keeps the stages in
    registers: GL8 on the held-out angular coupling at τ = 0.2, 3.16 → 1.94
    µs per step (``studies/gauss_step_cost.py``, CPU time), bit for bit the
    same arithmetic (same operations in the same order). Compiled once per
    kernels and (S, DIM); LLVM inlines the helpers the step calls (numba
    does not: its inlining typed and lowered each again per call site, a
    sixth of a new model's compile, ``studies/compile_cost.py --cases
    general``).

    Parameters
    ----------
    grad, grad_hess, dtime : numba dispatchers
        The model's kernels.
    S : int
        Stages (2, 3 or 4), or −1.
    DIM : int
        2N, or −1.

    Returns
    -------
    numba dispatcher
        ``gauss_step``: see its docstring.
    """
    linearisation, tangent_by_lu, tangent_by_iteration = _linear_solves(grad_hess)

    @_helper
    def gauss_step(h, x, V, k, pars, A, b, c, d, E, work, prev, timed, pt):
        """One Gauss–Legendre step of length h, in place on the orbit ``x``
        (2N,) and its tangent map on the ``k`` rows of ``V`` (k, 2N) (module
        docstring); ``A``, ``b``, ``c``, ``d``, ``E`` from
        :attr:`GaussLegendre.arrays`, ``work`` at least :func:`gauss_work`
        floats; the model's kernels those of :func:`gauss_stepper`.

        ``pars`` (s + 1, P) holds the kernels' parameters at each stage and, in
        its last row, at the step's start: for a time-dependent H the caller
        sets their last entries to the times t₀ + c_i h and t₀. Then (``timed``)
        the momentum conjugate to time ``pt[0]`` is advanced by the same
        method, p_t ← p_t − h Σ b_i ∂_tH(Y_i, t_i) (``dtime``), so
        K = H + p_t is conserved as H is for an autonomous one.

        ``prev`` (s·2N,) holds the stages Z of the previous step of the same
        length (the method's state: the iteration starts from their
        extrapolation, ``E``), or NaN in ``prev[0]`` for none (it starts from
        the explicit Euler guess); it receives this step's stages.

        The stage equations are solved by fixed-point iteration while it
        contracts fast (hL small: cheap, no Jacobian), else by Newton's method
        with the Jacobian at the current stages (stiff steps: a strong magnetic
        field, a close approach).

        Returns
        -------
        status : int
            ``Status.OK``, or ``Status.INTEGRATOR_FAILED`` when the stage
            equations did not converge in :data:`MAX_ITERATIONS` iterations or
            their linearisation is singular (``x`` and ``V`` are then left as
            they were).
        iterations : int
            Iterations done (each evaluates ∇H, or ∇H and D²H for Newton's, at
            the s stages).
        """
        dim = x.shape[0] if DIM < 0 else DIM
        s = c.shape[0] if S < 0 else S
        sd = s * dim
        Z = work[:sd]
        F = work[sd:2 * sd]
        y = work[2 * sd:2 * sd + dim]
        g = work[2 * sd + dim:2 * sd + 2 * dim]
        off = 2 * sd + 2 * dim
        D = work[off:off + dim * dim].reshape((dim, dim))
        off += dim * dim
        off_m = off
        M = work[off:off + sd * sd].reshape((sd, sd))
        off += sd * sd
        piv = work[off:off + sd]
        off += sd
        R = work[off:off + sd]      # Newton's residual and correction
        off += sd
        if prev[0] == prev[0]:
            # The previous step's collocation polynomial, extrapolated.
            for j in range(s):
                for m in range(dim):
                    acc = 0.0
                    for i in range(s):
                        acc += E[j, i] * prev[i * dim + m]
                    Z[j * dim + m] = acc
        else:
            # The explicit Euler guess Z_i = h c_i f(x).
            _field(x, pars[s], g, y, grad)
            for i in range(s):
                for m in range(dim):
                    Z[i * dim + m] = h * c[i] * y[m]
        last = np.inf
        iterations = 0
        converged = False
        newton = False
        while iterations < MAX_ITERATIONS:
            iterations += 1
            if newton:
                # Z ← Z − M⁻¹ (Z − h (A ⊗ 1) F), M and F at the current stages.
                linearisation(h, x, Z, A, M, s, dim, pars, y, g, D, F)
                if not _lu(M, piv, sd):
                    return _FAILED, iterations
                for i in range(s):
                    for m in range(dim):
                        acc = 0.0
                        for j in range(s):
                            acc += A[i, j] * F[j * dim + m]
                        R[i * dim + m] = h * acc - Z[i * dim + m]
                _lu_solve(M, piv, sd, R)
                delta = 0.0
                size = 0.0
                for r in range(sd):
                    Z[r] += R[r]
                    delta = max(delta, abs(R[r]))
                    size = max(size, abs(Z[r]))
            else:
                for j in range(s):
                    for m in range(dim):
                        y[m] = x[m] + Z[j * dim + m]
                    _field(y, pars[j], g, F[j * dim:(j + 1) * dim], grad)
                delta = 0.0
                size = 0.0
                for i in range(s):
                    for m in range(dim):
                        acc = 0.0
                        for j in range(s):
                            acc += A[i, j] * F[j * dim + m]
                        z = h * acc
                        delta = max(delta, abs(z - Z[i * dim + m]))
                        size = max(size, abs(z))
                        Z[i * dim + m] = z
            if delta != delta:
                break
            if _converged(delta, last, size):
                converged = True
                break
            if not newton and iterations >= 3 and delta > 0.25 * last:
                # Contracting slowly or not at all: Newton from here on.
                newton = True
                last = np.inf
                continue
            last = delta
        if not converged:
            return _FAILED, iterations
        if k > 0:
            U = work[off:off + sd * k].reshape((k, sd))
            iterate = not newton and k <= FIXED_POINT_VECTORS
            # D²H at the stages for the iteration, in M's room (s·4N² ≤ (s·2N)²).
            H = work[off_m:off_m + s * dim * dim].reshape((s, dim, dim))
            done = iterate and tangent_by_iteration(h, x, V, k, pars, A, d, Z, U, H, R, y, g, s,
                                                    dim)
            if not done and not tangent_by_lu(h, x, V, k, pars, A, d, Z, U, M, piv, y, g, D, F, s,
                                              dim):
                return _FAILED, iterations
        if timed:
            acc = 0.0
            for j in range(s):
                for m in range(dim):
                    y[m] = x[m] + Z[j * dim + m]
                acc += b[j] * dtime(y, pars[j])
            pt[0] -= h * acc
        for m in range(dim):
            acc = 0.0
            for i in range(s):
                acc += d[i] * Z[i * dim + m]
            x[m] += acc
        for r in range(sd):
            prev[r] = Z[r]
        return _OK, iterations

    return gauss_step


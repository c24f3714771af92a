"""The right-hand side of the orbit and k deviation vectors, compiled from a
model's own kernels (for H = ½pᵀM⁻¹p + V(q) below; for any H(q, p),
ẋ = J∇H and Ẇ = J D²H W from the model's ∇H and D²H).

For H = ½ pᵀM⁻¹p + V(q) the equations of motion and the variational
equations (Skokos & Gerlach 2010, eqs. 6 and 7) are

    q̇ = M⁻¹p,   ṗ = −∇V(q),   δq̇ = M⁻¹δp,   δṗ = −D²V(q) δq,

with D²V from the model's band kernel, so a lattice stays matrix-free. The
flat state is ``y = (x, W.ravel())``: the orbit x = (q, p) of length 2N,
then the deviation vectors as the (2N, k) matrix W in row-major order —
the layout of ``RunState.W[m]`` and of heyoka's variational state. k is read
from the length of y, so one compiled function serves every k.

A time-dependent V(q, t) is integrated in the extended phase space, as by
the TM method (:mod:`varint.kernels.tm`): the flat state ends with the
*clock* (t, p_t), with ṫ = 1 and ṗ_t = −∂_tV, so y carries its own time
(every integrator may start a block at its own t = 0) and the momentum
conjugate to time for the conserved extended energy K = H + p_t. The
deviation vectors have δt = 0, so their equations are those above with D²V
at (q, t).

For a model that knows its potential symbolically and has few degrees of
freedom (the paper's orbits), the right-hand side is *generated*
(:func:`generated_rhs`): ∇V and D²V as straight-line expressions of q with
common subexpressions eliminated, no array allocated, the vectors' loop
summing in the band kernels' order — the code the TM stepper gets
(:mod:`varint.codegen`). It is the same function; on Hénon–Heiles
it gives the kernels' bits and costs a sixth of their time (no scratch
arrays), which makes a DOP853 interval of the paper's configuration
measurably cheaper (``studies/bench_baselines.py``).

The Jacobian of this right-hand side (:func:`tangent_jacobian`, for an
implicit integrator's Newton iteration) is exact and also matrix-free in
the vectors: with J = ∂ẏ/∂y,

    ∂q̇/∂p = M⁻¹,   ∂ṗ/∂q = −D²V,   ∂δq̇_j/∂δp_j = M⁻¹,   ∂δṗ_j/∂δq_j = −D²V,
    ∂δṗ_j/∂q = −D³V[δq_j],

the last from the model's third-derivative kernel (D³V[v] = Σ_k v_k
D²(∂_kV), symmetric), so J·v costs one Hessian and one third-derivative
evaluation.
"""

from __future__ import annotations

from functools import cache

import numpy as np
import sympy as sp
from numba import njit

from varint.models.symbolic import KernelPrinter

__all__ = ["tangent_rhs", "tangent_jacobian", "generated_rhs", "kernel_rhs", "pack", "unpack", "clock_size",
           "CLOCK", "GENERATED_MAX_N"]

#: Entries of the clock (t, p_t) at the end of the flat state of a
#: time-dependent model.
CLOCK = 2
#: Largest N for which the right-hand side is generated as straight-line
#: code (that of the generated TM steppers); larger models use the kernels.
GENERATED_MAX_N = 16


def clock_size(model):
    """Length of the clock in the flat state of ``model``'s orbits: 2 for a
    time-dependent V, else 0."""
    return CLOCK if model.time_dependent else 0


def pack(x, W, out=None, clock=()):
    """The flat state (x, W.ravel(), *clock) of one orbit; ``W`` has shape
    (2N, k), ``clock`` is (t, p_t) for a time-dependent V."""
    d = x.shape[0]
    c = len(clock)
    if out is None:
        out = np.empty(d * (1 + W.shape[1]) + c, dtype=np.result_type(x, W))
    out[:d] = x
    out[d:len(out) - c] = W.ravel()
    if c:
        out[len(out) - c:] = clock
    return out


def unpack(y, d, clock=0):
    """Views (x, W) of a flat state with orbit dimension ``d`` = 2N and a
    clock of ``clock`` entries at its end."""
    return y[:d], y[d:len(y) - clock].reshape(d, -1)


def _with_fun(rhs):
    """``(rhs, fun)``: the in-place right-hand side ``rhs(t, y, yp)`` (the
    form SUNDIALS calls) and ``fun(t, y) -> yp`` around it (SciPy's form)."""

    @njit
    def fun(t, y):
        yp = np.empty_like(y)
        rhs(t, y, yp)
        return yp

    return rhs, fun


@cache
def _compiled(grad, hess, n, bw, minv_bytes, par_bytes, dtime=None):
    minv = np.frombuffer(minv_bytes)
    par_model = np.frombuffer(par_bytes)
    d = 2 * n
    c = 0 if dtime is None else CLOCK

    @njit
    def rhs(t, y, yp):
        if c:
            # The clock (t, p_t) ends y; the kernels read t from par[-1].
            par = par_model.copy()
            par[-1] = y[y.shape[0] - 2]
        else:
            par = par_model
        # Orbit (eq. 6).
        q = y[:n].copy()
        g = np.empty(n)
        grad(q, par, g)
        for i in range(n):
            yp[i] = minv[i] * y[n + i]
            yp[n + i] = -g[i]
        if c:
            gt = np.empty(n)
            yp[y.shape[0] - 2] = 1.0
            yp[y.shape[0] - 1] = -dtime(q, par, gt)
        k = (y.shape[0] - d - c) // d
        if k == 0:
            return
        # Variational equations (eq. 7), D²V in band storage.
        B = np.zeros((bw + 1, n))
        hess(q, par, B)
        for i in range(n):
            a = minv[i]
            for j in range(k):
                yp[d + i * k + j] = a * y[d + (n + i) * k + j]
        for i in range(n):
            a = B[0, i]
            for j in range(k):
                yp[d + (n + i) * k + j] = -a * y[d + i * k + j]
        for b in range(1, bw + 1):
            for i in range(n - b):
                a = B[b, i]
                for j in range(k):
                    yp[d + (n + i) * k + j] -= a * y[d + (i + b) * k + j]
                    yp[d + (n + i + b) * k + j] -= a * y[d + i * k + j]

    return _with_fun(rhs)


@cache
def _compiled_hamiltonian(grad_hess, d, par_bytes, dtime=None):
    """The right-hand side of any H(q, p): ẋ = J∇H, Ẇ = J D²H W (from the
    model's kernel ``grad_hess(x, par, g, D)``), and the clock (t, p_t) of a
    time-dependent H, ṫ = 1, ṗ_t = −∂_tH."""
    par_model = np.frombuffer(par_bytes)
    n = d // 2
    c = 0 if dtime is None else CLOCK

    @njit
    def rhs(t, y, yp):
        if c:
            par = par_model.copy()
            par[-1] = y[y.shape[0] - 2]
        else:
            par = par_model
        x = y[:d].copy()
        g = np.empty(d)
        D = np.empty((d, d))
        grad_hess(x, par, g, D)
        for i in range(n):
            yp[i] = g[n + i]
            yp[n + i] = -g[i]
        if c:
            yp[y.shape[0] - 2] = 1.0
            yp[y.shape[0] - 1] = -dtime(x, par)
        k = (y.shape[0] - d - c) // d
        # Row i of W is y[d + i·k : d + (i + 1)·k]; (J D W)_i = (D W)_{n+i}, −(D W)_{i−n}.
        for i in range(d):
            src = n + i if i < n else i - n
            sign = 1.0 if i < n else -1.0
            for j in range(k):
                acc = 0.0
                for m in range(d):
                    acc += D[src, m] * y[d + m * k + j]
                yp[d + i * k + j] = sign * acc

    return _with_fun(rhs)


def _generated_source(V, n, minv):
    """Source of ``rhs(t, y, yp)`` for the SymPy potential ``V`` in
    q0 … q{n−1} and the inverse masses ``minv``."""
    q = sp.symbols(f"q0:{n}")
    g = [sp.diff(V, qi) for qi in q]
    H = {(i, j): sp.diff(g[i], q[j]) for i in range(n) for j in range(i, n)}
    H = {ij: e for ij, e in H.items() if e != 0}
    bw = max((j - i for i, j in H), default=0)
    printer = KernelPrinter()
    d = 2 * n
    lines = ["def rhs(t, y, yp):"]
    lines += [f"    q{i} = y[{i}]" for i in range(n)]
    for names, exprs, label in (([f"g{i}" for i in range(n)], g, "o"),
                                ([f"H{i}_{j}" for i, j in H], list(H.values()), "w")):
        temps, reduced = sp.cse(exprs, symbols=sp.numbered_symbols(f"t{label}_"))
        lines += [f"    {t} = {printer.doprint(e)}" for t, e in temps]
        lines += [f"    {name} = {printer.doprint(e)}" for name, e in zip(names, reduced,
                                                                          strict=True)]

    def mass(i, term):
        return term if minv[i] == 1.0 else f"{minv[i]!r} * {term}"

    for i in range(n):
        lines.append(f"    yp[{i}] = {mass(i, f'y[{n + i}]')}")
        lines.append(f"    yp[{n + i}] = -g{i}")
    lines += [f"    k = (y.shape[0] - {d}) // {d}", "    for j in range(k):"]
    lines += [f"        a{i} = y[{d} + {i} * k + j]" for i in range(n)]
    for i in range(n):
        lines.append(f"        yp[{d} + {i} * k + j] = {mass(i, f'y[{d} + {n + i} * k + j]')}")
    for r in range(n):
        # The band kernels' order (baselines.rhs._compiled): for each
        # offset b, the entry left of the diagonal, then the right one.
        terms = []
        for b in range(bw + 1):
            for i, j, other in ((r - b, r, r - b), (r, r + b, r + b)):
                if b == 0 and i != r - b:
                    continue
                if i >= 0 and j < n and (i, j) in H and (b > 0 or not terms):
                    terms.append(f"H{i}_{j} * a{other}")
        lines.append(f"        yp[{d} + {n + r} * k + j] = "
                     + ("-" + " - ".join(terms) if terms else "0.0"))
    return "\n".join(lines) + "\n"


@cache
def _compiled_generated(V, n, minv):
    # Keyed by the expression itself (SymPy expressions hash by structure):
    # no text is parsed back into an expression.
    namespace = {"math": __import__("math")}
    exec(compile(_generated_source(V, n, minv), "<varint generated rhs>", "exec"),
         namespace)
    rhs = njit(namespace["rhs"])

    return _with_fun(rhs)


def generated_rhs(model):
    """The right-hand side of :func:`tangent_rhs` as straight-line code
    generated from the model's SymPy potential, or None where it does not
    apply (no ``symbolic()``, a time-dependent V, N > :data:`GENERATED_MAX_N`).

    Returns
    -------
    (rhs, fun) or None
        As :func:`tangent_rhs`.
    """
    symbolic = getattr(model, "symbolic", None)
    if not callable(symbolic) or model.time_dependent or model.n_dof > GENERATED_MAX_N:
        return None
    s = symbolic()
    n = len(s.q)
    V = s.V.xreplace(dict(zip(s.q, sp.symbols(f"q0:{n}"), strict=True)))
    minv = tuple(float(m) for m in model.inverse_mass)
    return _compiled_generated(V, n, minv)


def tangent_rhs(model):
    """Compiled right-hand sides of the orbit plus deviation vectors.

    Parameters
    ----------
    model : Model

    Returns
    -------
    rhs : numba function ``rhs(t, y, yp)``
        Fills ``yp`` in place (the form SUNDIALS calls).
    fun : numba function ``fun(t, y) -> yp``
        Returns a new array (the form SciPy calls).

    Notes
    -----
    Generated from the model's potential where :func:`generated_rhs`
    applies, else from its kernels; compiled once per model (cached for the
    process), so every propagator built for the same model shares them.
    For a time-dependent V the flat state ends with the clock (t, p_t)
    (see the module docstring) and ``t`` is not read. A model of any H(q, p)
    (:class:`~varint.models.hamiltonian.HamiltonianModel`) gives Hamilton's
    equations ẋ = J∇H and the variational equations Ẇ = J D²H W from its
    kernel of ∇H and D²H.
    """
    if callable(getattr(model, "grad_hess_h", None)):
        return _compiled_hamiltonian(
            model.grad_hess_h, model.dim,
            np.ascontiguousarray(model.params, dtype=np.float64).tobytes(),
            model.dtime_h if model.time_dependent else None)
    generated = generated_rhs(model)
    if generated is not None:
        return generated
    return kernel_rhs(model)


def kernel_rhs(model):
    """:func:`tangent_rhs` from the model's own kernels (every model but one of any H(q, p))."""
    return _compiled(model.grad_kernel, model.hess_kernel, model.n_dof, model.bandwidth,
                     np.ascontiguousarray(model.inverse_mass, dtype=np.float64).tobytes(),
                     np.ascontiguousarray(model.params, dtype=np.float64).tobytes(),
                     model.time_kernel if model.time_dependent else None)


@cache
def _compiled_jacobian(hess, third, n, bw, minv_bytes, par_bytes):
    minv = np.frombuffer(minv_bytes)
    par = np.frombuffer(par_bytes)
    d = 2 * n

    @njit
    def jac(t, y, yp, J):
        k = (y.shape[0] - d) // d
        J[:, :] = 0.0
        q = y[:n].copy()
        B = np.zeros((bw + 1, n))
        hess(q, par, B)
        # Block 0 is the orbit, block j + 1 deviation vector j: the same
        # [[0, M⁻¹], [−D²V, 0]] on the diagonal (row i + n of block b at
        # index o + i·s + c, with s = 1 for the orbit, s = k for vectors).
        for blk in range(k + 1):
            o, s, c = (0, 1, 0) if blk == 0 else (d, k, blk - 1)
            for i in range(n):
                J[o + i * s + c, o + (n + i) * s + c] = minv[i]
            for b in range(bw + 1):
                for i in range(n - b):
                    a = B[b, i]
                    J[o + (n + i) * s + c, o + (i + b) * s + c] -= a
                    if b:
                        J[o + (n + i + b) * s + c, o + i * s + c] -= a
        # ∂δṗ_j/∂q = −D³V[δq_j].
        v = np.empty(n)
        T = np.empty((bw + 1, n))
        for c in range(k):
            for m in range(n):
                v[m] = y[d + m * k + c]
            T[:, :] = 0.0
            third(q, par, v, T)
            for b in range(bw + 1):
                for i in range(n - b):
                    a = T[b, i]
                    J[d + (n + i) * k + c, i + b] -= a
                    if b:
                        J[d + (n + i + b) * k + c, i] -= a

    @njit
    def jac_times(t, y, yp, v, Jv):
        k = (y.shape[0] - d) // d
        q = y[:n].copy()
        B = np.zeros((bw + 1, n))
        hess(q, par, B)
        T = np.zeros((bw + 1, n))
        third(q, par, v[:n].copy(), T)
        for blk in range(k + 1):
            o, s, c = (0, 1, 0) if blk == 0 else (d, k, blk - 1)
            for i in range(n):
                Jv[o + i * s + c] = minv[i] * v[o + (n + i) * s + c]
                Jv[o + (n + i) * s + c] = 0.0
            for b in range(bw + 1):
                for i in range(n - b):
                    a = B[b, i]
                    Jv[o + (n + i) * s + c] -= a * v[o + (i + b) * s + c]
                    if b:
                        Jv[o + (n + i + b) * s + c] -= a * v[o + i * s + c]
            if blk:
                # −D³V[v_q] δq_c: D³V[v_q] δq_c = D³V[δq_c] v_q (symmetry).
                for b in range(bw + 1):
                    for i in range(n - b):
                        a = T[b, i]
                        Jv[d + (n + i) * k + c] -= a * y[d + (i + b) * k + c]
                        if b:
                            Jv[d + (n + i + b) * k + c] -= a * y[d + i * k + c]

    return jac, jac_times


def tangent_jacobian(model):
    """The exact Jacobian ∂ẏ/∂y of :func:`tangent_rhs`'s right-hand side.

    Parameters
    ----------
    model : Model
        Time-independent (a time-dependent V has no kernel for ∂_t∇V).

    Returns
    -------
    jac : numba function ``jac(t, y, yp, J)``
        Fills the dense (len(y), len(y)) matrix ``J`` (the form of
        scikit-sundae's ``jacfn``).
    jac_times : numba function ``jac_times(t, y, yp, v, Jv)``
        Fills ``Jv`` with J·v without forming J (the form of
        scikit-sundae's ``CVODEJacTimes`` for its iterative solvers).

    Raises
    ------
    ValueError
        For a time-dependent model.
    """
    if model.time_dependent:
        raise ValueError(f"no exact Jacobian for the time-dependent model {model.name!r} "
                         "(its kernels give no derivative of the force in t)")
    return _compiled_jacobian(model.hess_kernel, model.third_kernel, model.n_dof,
                              model.bandwidth,
                              np.ascontiguousarray(model.inverse_mass, dtype=np.float64).tobytes(),
                              np.ascontiguousarray(model.params, dtype=np.float64).tobytes())

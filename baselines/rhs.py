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
"""

from __future__ import annotations

from functools import cache, lru_cache

import numpy as np
from numba import njit

__all__ = ["tangent_rhs", "pack", "unpack", "clock_size", "CLOCK"]

#: Entries of the clock (t, p_t) at the end of the flat state of a
#: time-dependent model.
CLOCK = 2


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


@lru_cache(maxsize=None)
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

    @njit
    def fun(t, y):
        yp = np.empty_like(y)
        rhs(t, y, yp)
        return yp

    return rhs, fun


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

    @njit
    def fun(t, y):
        yp = np.empty_like(y)
        rhs(t, y, yp)
        return yp

    return rhs, fun


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
    Compiled once per model kernels, size and parameters (cached for the
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
    return _compiled(model.grad_kernel, model.hess_kernel, model.n_dof, model.bandwidth,
                     np.ascontiguousarray(model.inverse_mass, dtype=np.float64).tobytes(),
                     np.ascontiguousarray(model.params, dtype=np.float64).tobytes(),
                     model.time_kernel if model.time_dependent else None)

"""The right-hand side of the orbit and k deviation vectors, compiled from a
model's own kernels.

For H = ½ pᵀM⁻¹p + V(q) the equations of motion and the variational
equations (Skokos & Gerlach 2010, eqs. 6 and 7) are

    q̇ = M⁻¹p,   ṗ = −∇V(q),   δq̇ = M⁻¹δp,   δṗ = −D²V(q) δq,

with D²V from the model's band kernel, so a lattice stays matrix-free. The
flat state is ``y = (x, W.ravel())``: the orbit x = (q, p) of length 2N,
then the deviation vectors as the (2N, k) matrix W in row-major order —
the layout of ``RunState.W[m]`` and of heyoka's variational state. k is read
from the length of y, so one compiled function serves every k.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from numba import njit

__all__ = ["tangent_rhs", "pack", "unpack"]


def pack(x, W, out=None):
    """The flat state (x, W.ravel()) of one orbit; ``W`` has shape (2N, k)."""
    d = x.shape[0]
    if out is None:
        out = np.empty(d * (1 + W.shape[1]), dtype=np.result_type(x, W))
    out[:d] = x
    out[d:] = W.ravel()
    return out


def unpack(y, d):
    """Views (x, W) of a flat state with orbit dimension ``d`` = 2N."""
    return y[:d], y[d:].reshape(d, -1)


@lru_cache(maxsize=None)
def _compiled(grad, hess, n, bw, minv_bytes, par_bytes):
    minv = np.frombuffer(minv_bytes)
    par = np.frombuffer(par_bytes)
    d = 2 * n

    @njit
    def rhs(t, y, yp):
        # Orbit (eq. 6).
        q = y[:n].copy()
        g = np.empty(n)
        grad(q, par, g)
        for i in range(n):
            yp[i] = minv[i] * y[n + i]
            yp[n + i] = -g[i]
        k = (y.shape[0] - d) // d
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
    """
    return _compiled(model.grad_kernel, model.hess_kernel, model.n_dof, model.bandwidth,
                     np.ascontiguousarray(model.inverse_mass, dtype=np.float64).tobytes(),
                     np.ascontiguousarray(model.params, dtype=np.float64).tobytes())

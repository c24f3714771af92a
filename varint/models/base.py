"""The model protocol: H = ½ pᵀM⁻¹p + V(q) with a diagonal inverse mass.

A model is a small object that carries three numba kernels and the data
they need; the integrators call the kernels, never Python methods:

``grad(q, par, g)``
    ``g[:] = ∇V(q)``.
``hess(q, par, B)``
    ``B`` = D²V(q) in symmetric band storage (:mod:`varint.kernels.banded`),
    shape ``(bandwidth + 1, N)``.
``third(q, par, v, B)``
    ``B = Σ_k v_k D²(∂_k V)(q)``, the third-derivative tensor contracted
    with ``v``, in the same band storage (its sparsity is that of D²V).

From these the integrators build the corrector terms of
C = {B,{B,A}} = ∇Vᵀ M⁻¹ ∇V (Skokos & Gerlach 2010, eq. 26 with a mass):
∇C = 2 D²V M⁻¹ ∇V and D²C = 2 (D²V M⁻¹ D²V + Σ_k (M⁻¹∇V)_k D²(∂_kV)).

Kernels run with NumPy's floating-point error model: a division by zero
gives an infinity, not a ``ZeroDivisionError`` raised from inside a
compiled loop, and the steppers' checks turn the non-finite value into a
failure with its time and step (:class:`varint.protocol.Status`). A user's
kernel compiled with numba's default (Python) error model is recompiled
from its Python source with NumPy's when the model is built — once per
kernel: models built from the same kernels share the recompiled one, and
so every stepper compiled for them.
"""

from __future__ import annotations

import functools
import numbers
from collections.abc import Callable
from typing import Any

import numpy as np
from numba.core.dispatcher import Dispatcher
from numpy.typing import ArrayLike

import numba

from ..kernels.banded import band_kick_block, band_matvec, band_square_add, band_to_dense
from .._validate import array_bytes, check_memory, real_array

__all__ = ["Model"]


@functools.cache
def _numpy_errors(kernel):
    """``kernel`` compiled with NumPy's error model (see the module
    docstring); itself if it already is. One dispatcher per kernel: the
    steppers are compiled per kernel dispatcher (``functools.cache`` on
    it), so a new one per model would compile them all again for every
    model built from the same functions (two parameter sets, say)."""
    options = dict(kernel.targetoptions)
    if options.get("error_model") == "numpy":
        return kernel
    options.pop("nopython", None)
    options["error_model"] = "numpy"
    # Not cached on disk: numba's cache does not tell error models apart.
    return numba.njit(**options)(kernel.py_func)


class Model:
    """A Hamiltonian H = ½ pᵀM⁻¹p + V(q) with compiled derivative kernels.

    V may depend on time (``time_dependent``; e.g. from
    :func:`~varint.models.from_potential` with ``time=``): the kernels then
    read t from the last parameter, ``par[-1]``, which the integrators set
    to the time of each kick, and ``time_kernel(q, par, gt)`` returns ∂_tV
    and writes ∂_t∇V into ``gt``, for the momentum p_t conjugate to time and
    the conserved extended energy K = H + p_t (:mod:`varint.kernels.tm`).

    Subclasses pass their potential and kernels; everything else is
    generic. State vectors are ``x = (q, p)`` of length 2N (paper eq. 2).

    Parameters
    ----------
    n_dof : int
        Number of degrees of freedom N.
    potential : callable
        V(q) for ``q`` of shape (..., N), vectorised over leading axes
        (NumPy; used for energies at output times, not in the hot loop).
    grad, hess, third : numba dispatchers
        The kernels described in the module docstring.
    bandwidth : int
        Bandwidth of D²V (``N − 1`` for a dense Hessian).
    params : array_like of float
        Parameters passed to the kernels as ``par``.
    inverse_mass : array_like of float, shape (N,), optional
        Diagonal of M⁻¹; all ones by default. Must be positive and finite.
    name : str
        Name used in results and messages.
    escape_radius : float, optional
        Runs stop with an error when |q| exceeds this (the orbit escaped).
    """

    n_dof: int
    name: str
    bandwidth: int
    params: np.ndarray
    inverse_mass: np.ndarray

    #: A Hamiltonian flow (map models, :mod:`varint.models.maps`, say "map").
    kind = "flow"
    #: Whether V depends on t (then ``time_kernel`` is set and ``potential``
    #: takes t).
    time_dependent = False
    time_kernel = None
    #: V compiled over rows of states, where the model has it: a numba
    #: dispatcher taking states (R, 2N), C-contiguous float64, and
    #: returning V at each row, bitwise ``potential(states[:, :N])`` on this
    #: CPU (a prepared run's short call measures V with it,
    #: :class:`varint.rerun.ShortCall`); None here. A model whose NumPy V is
    #: one expression emits it from that expression
    #: (:func:`varint.models.potential_rows.rows_from`).
    potential_rows: Any = None

    def __init__(self, n_dof: int, potential: Callable[[np.ndarray], np.ndarray],
                 grad: Dispatcher, hess: Dispatcher, third: Dispatcher, bandwidth: int,
                 params: ArrayLike = (), inverse_mass: ArrayLike | None = None,
                 name: str = "model", escape_radius: float | None = None) -> None:
        if (isinstance(n_dof, (bool, np.bool_)) or not isinstance(n_dof, numbers.Real)
                or not float(n_dof).is_integer() or n_dof < 1):
            raise ValueError(f"n_dof must be a positive integer, got {n_dof!r}")
        n_dof = int(n_dof)
        if not isinstance(bandwidth, numbers.Integral) or isinstance(bandwidth, bool) \
                or bandwidth < 0:
            raise ValueError(f"bandwidth must be an integer >= 0, got {bandwidth!r}")
        # Before the first array of size N: the model's inverse mass, then
        # one orbit's state, gradient and Hessian band, at the least.
        check_memory(array_bytes(n_dof, 2 * n_dof, n_dof, (min(bandwidth, n_dof - 1) + 1, n_dof)),
                     f"model {name} ({n_dof} degrees of freedom)")
        self.n_dof = n_dof
        self.name = name
        self._potential = potential
        for label, kernel in (("grad", grad), ("hess", hess), ("third", third)):
            # A plain Python function would fail deep inside numba at the
            # first run; refuse it here with the remedy.
            if not isinstance(kernel, Dispatcher):
                raise ValueError(f"the {label} kernel must be a numba-compiled function "
                                 f"(decorate it with numba.njit), got {kernel!r}")
        self.grad_kernel, self.hess_kernel, self.third_kernel = (
            _numpy_errors(k) for k in (grad, hess, third))
        self.bandwidth = min(int(bandwidth), n_dof - 1)
        self.params = real_array(params, "params").reshape(-1)
        if not np.isfinite(self.params).all():
            raise ValueError(f"params must be finite, got {self.params.tolist()}")
        if inverse_mass is None:
            inverse_mass = np.ones(n_dof)
        minv = np.array(inverse_mass, dtype=np.float64)
        if minv.ndim == 0:
            minv = np.full(n_dof, float(minv))
        if minv.shape != (n_dof,):
            raise ValueError(
                f"inverse_mass must have shape ({n_dof},) (the diagonal of M⁻¹), got {minv.shape}")
        bad = ~np.isfinite(minv) | (minv <= 0)
        if bad.any():
            raise ValueError(
                f"inverse_mass must be positive and finite; got {float(minv[bad][0])!r} "
                f"at index {int(np.flatnonzero(bad)[0])}")
        self.inverse_mass = minv
        if escape_radius is not None and (
                isinstance(escape_radius, (bool, np.bool_))
                or not isinstance(escape_radius, numbers.Real)
                or not (np.isfinite(escape_radius) and escape_radius > 0)):
            raise ValueError(f"escape_radius must be positive and finite, got {escape_radius!r}")
        self.escape_radius = escape_radius

    def potential(self, q, t=0.0):
        """V(q) (V(q, t) if time-dependent) for ``q`` of shape (..., N),
        vectorised over leading axes."""
        q = np.asarray(q, dtype=float)
        return self._potential(q, t) if self.time_dependent else self._potential(q)

    def describe(self) -> dict:
        """JSON-serialisable description: enough to rebuild the model."""
        return {"name": self.name, "class": type(self).__name__, "n_dof": self.n_dof,
                "params": self.params.tolist(), "inverse_mass": self.inverse_mass.tolist()}

    # -- generic -------------------------------------------------------------
    @property
    def dim(self) -> int:
        """Phase-space dimension 2N."""
        return 2 * self.n_dof

    @property
    def corrector_bandwidth(self) -> int:
        """Bandwidth of D²C: twice that of D²V, at most N − 1."""
        return min(2 * self.bandwidth, self.n_dof - 1)

    def kinetic(self, p):
        """½ pᵀM⁻¹p for ``p`` of shape (..., N)."""
        p = np.asarray(p, dtype=float)
        # add.reduce is what np.sum calls (same bits), without its wrapper.
        return 0.5 * np.add.reduce(self.inverse_mass * p * p, axis=-1)

    def energy(self, x, t=0.0, p_t=0.0):
        """H(x) for states ``x`` of shape (..., 2N); for a time-dependent V
        the extended energy K = H(x, t) + p_t, conserved along an orbit
        whose momentum conjugate to time is p_t at time t."""
        x = np.asarray(x, dtype=float)
        n = self.n_dof
        e = self.kinetic(x[..., n:]) + self.potential(x[..., :n], t)
        return e + p_t if self.time_dependent else e

    def energy_scale(self, x):
        """The scale against which energy errors are relative, per state
        (``x`` of shape (..., 2N)): |T| + |V|, which is |H| for an orbit in a
        well (T, V ≥ 0) and stays meaningful when H = 0 or H < 0; 1 (an
        absolute error) for a state at rest where V = 0. V's additive
        constant enters it, so a model whose V carries a large constant
        should override this (see :mod:`varint.accuracy`)."""
        x = np.asarray(x, dtype=float)
        n = self.n_dof
        scale = np.abs(self.kinetic(x[..., n:])) + np.abs(self.potential(x[..., :n]))
        return np.where(scale > 0, scale, 1.0)

    def conserved(self, x, t=0.0, p_t=0.0):
        """Quantities the exact flow conserves, for states ``x`` of shape
        (..., 2N): a dict name → values of shape (...). Runs record the
        relative error of each and their accuracy verdict checks it
        (:mod:`varint.accuracy`). The energy (H) always; a model with
        another first integral (e.g. the norm of the DDNLS lattice, an
        angular momentum) adds it here. Errors of quantities other than the
        energy are relative to their value at t = 0 (absolute where that is
        0). For a time-dependent V, the extended energy K = H(x, t) + p_t
        (``t``, ``p_t``: the time and the momentum conjugate to it)."""
        return {"energy": self.energy(x, t, p_t) if self.time_dependent else self.energy(x)}

    def _q(self, q):
        q = np.ascontiguousarray(q, dtype=np.float64)
        if q.shape != (self.n_dof,):
            raise ValueError(f"q must have shape ({self.n_dof},), got {q.shape}")
        return q

    def parameters_at(self, t=None):
        """The kernels' ``par``: :attr:`params`, with the last entry set to
        ``t`` for a time-dependent V (t = 0 when None)."""
        if not self.time_dependent:
            return self.params
        par = self.params.copy()
        par[-1] = 0.0 if t is None else float(t)
        return par

    def gradient(self, q, t=None):
        """∇V(q) (at time t for a time-dependent V), shape (N,)."""
        q = self._q(q)
        g = np.empty(self.n_dof)
        self.grad_kernel(q, self.parameters_at(t), g)
        return g

    def time_derivatives(self, q, t=0.0):
        """(∂_tV, ∂_t∇V) at (q, t) of a time-dependent V."""
        if not self.time_dependent:
            raise ValueError(f"{self.name} does not depend on time")
        gt = np.empty(self.n_dof)
        dv = self.time_kernel(self._q(q), self.parameters_at(t), gt)
        return float(dv), gt

    def hessian_band(self, q, t=None):
        """D²V(q) in band storage, shape (bandwidth + 1, N)."""
        q = self._q(q)
        B = np.zeros((self.bandwidth + 1, self.n_dof))
        self.hess_kernel(q, self.parameters_at(t), B)
        return B

    def hessian(self, q, t=None):
        """Dense D²V(q), shape (N, N); for small N and tests."""
        return band_to_dense(self.hessian_band(q, t))

    def hvp(self, q, W):
        """D²V(q) · W for a block ``W`` of shape (N, k), matrix-free."""
        W = np.asarray(W, dtype=np.float64)
        X = W.reshape(self.n_dof, -1)
        # The stepper's own kick on (δq; δp) = (W; 0) leaves δp = −D²V W.
        stacked = np.concatenate([X, np.zeros_like(X)])
        band_kick_block(self.hessian_band(q), stacked, self.n_dof, X.shape[1], self.bandwidth)
        return -stacked[self.n_dof:].reshape(W.shape)

    def third_band(self, q, v, t=None):
        """Σ_k v_k D²(∂_k V)(q) in band storage."""
        q = self._q(q)
        v = np.ascontiguousarray(v, dtype=np.float64)
        B = np.zeros((self.bandwidth + 1, self.n_dof))
        self.third_kernel(q, self.parameters_at(t), v, B)
        return B

    def corrector(self, q):
        """C(q) = ∇Vᵀ M⁻¹ ∇V (paper eq. 26)."""
        g = self.gradient(q)
        return float(np.sum(self.inverse_mass * g * g))

    def corrector_gradient(self, q):
        """∇C = 2 D²V M⁻¹ ∇V, shape (N,)."""
        g = self.gradient(q)
        out = np.empty(self.n_dof)
        band_matvec(self.hessian_band(q), self.inverse_mass * g, out, self.n_dof, self.bandwidth)
        return 2.0 * out

    def corrector_hessian_band(self, q):
        """D²C = 2 (D²V M⁻¹ D²V + Σ_k (M⁻¹∇V)_k D²(∂_kV)) in band storage."""
        H = self.hessian_band(q)
        T = self.third_band(q, self.inverse_mass * self.gradient(q))
        S = np.zeros((self.corrector_bandwidth + 1, self.n_dof))
        band_square_add(H, self.inverse_mass, T, S, self.n_dof, self.bandwidth,
                        self.corrector_bandwidth)
        return S

    def corrector_hessian(self, q):
        """Dense D²C(q), shape (N, N); for small N and tests."""
        return band_to_dense(self.corrector_hessian_band(q))

    def __repr__(self):
        return f"<{type(self).__name__} {self.name!r}, N={self.n_dof}>"

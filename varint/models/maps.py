"""Symplectic maps x_{n+1} = F(x_n) with their tangent maps: a second kind
of model beside the Hamiltonian flows of :mod:`varint.models.base`.

A map model carries two numba kernels and the data they need:

``iterate(x, par, out)``
    ``out[:] = F(x)``, without any reduction modulo a period.
``jacobian(x, par, J)``
    ``J[:, :] = DF(x)``, the tangent map at ``x``, dense (2N, 2N).

and ``periods`` (2N,): a component with a positive period P is taken
modulo P (into [0, P)) after every iteration, so an angle stays small and
its sine accurate however long the run; 0 leaves a component unbounded.
The tangent map is unaffected (DF is periodic in such a component).

The deviation vectors follow w_{n+1} = DF(x_n) w_n: the map's own tangent
map, exact to round-off, is the TM method for maps (``method="tm"``,
:class:`varint.methods.map.MapPropagator`). A run's interval τ is a whole
number of iterations (1 by default), so its times t count iterations, and
every indicator reads the same run state as for a flow.

A map conserves no energy: :meth:`MapModel.energy` is 0, so the
``energy_error`` of a map's results is 0 — not a verdict of accuracy (a map
is iterated exactly up to round-off; there is nothing integrated to check).

References
----------
B. V. Chirikov, Phys. Rep. 52, 263 (1979) — the standard map.
Ch. Skokos, T. Bountis & Ch. Antonopoulos, Physica D 231, 30 (2007) — GALI
and the 4D map of two coupled standard maps.
"""

from __future__ import annotations

import math
import numbers

import numpy as np
from numba import njit
from numba.core.dispatcher import Dispatcher

from .._validate import real_array
from .base import _numpy_errors

__all__ = ["MapModel", "StandardMap", "CoupledStandardMaps"]

_TWO_PI = 2.0 * math.pi


class MapModel:
    """A map x' = F(x) of a 2N-dimensional phase space with compiled
    kernels (see the module docstring).

    Parameters
    ----------
    dim : int
        Phase-space dimension 2N (even: a symplectic map).
    iterate, jacobian : numba dispatchers
        The kernels of the module docstring.
    params : array_like of float
        Passed to the kernels as ``par``.
    periods : array_like of float, shape (2N,), optional
        Period of each component (0: none); none by default.
    name : str
    escape_radius : float, optional
        Runs stop an orbit as escaped once |x| exceeds this (the whole
        state: a map's components need not split into q and p).
    variables : sequence of str, optional
        Names of the components, in state order (for messages and
        documentation); x_0 … x_{2N−1} by default.
    """

    #: What the integrators see: iterated by its own tangent map.
    kind = "map"
    #: Maps have no time-dependent potential (see ``Model.time_dependent``).
    time_dependent = False

    def __init__(self, dim, iterate, jacobian, params=(), periods=None, name="map",
                 escape_radius=None, variables=None):
        if (isinstance(dim, (bool, np.bool_)) or not isinstance(dim, numbers.Integral)
                or dim < 2 or dim % 2):
            raise ValueError(f"dim must be an even integer >= 2 (a symplectic map of 2N "
                             f"variables), got {dim!r}")
        dim = int(dim)
        for label, kernel in (("iterate", iterate), ("jacobian", jacobian)):
            if not isinstance(kernel, Dispatcher):
                raise ValueError(f"the {label} kernel must be a numba-compiled function "
                                 f"(decorate it with numba.njit), got {kernel!r}")
        self.iterate_kernel = _numpy_errors(iterate)
        self.jacobian_kernel = _numpy_errors(jacobian)
        self.n_dof = dim // 2
        self.name = name
        self.params = real_array(params, "params").reshape(-1)
        if not np.isfinite(self.params).all():
            raise ValueError(f"params must be finite, got {self.params.tolist()}")
        periods = np.zeros(dim) if periods is None else real_array(periods, "periods")
        if periods.shape != (dim,):
            raise ValueError(f"periods must have shape ({dim},) (one per variable, 0 for "
                             f"none), got {periods.shape}")
        if not (np.isfinite(periods).all() and (periods >= 0).all()):
            raise ValueError(f"periods must be finite and >= 0 (0: no period), got "
                             f"{periods.tolist()}")
        self.periods = np.ascontiguousarray(periods)
        if escape_radius is not None and not (np.isfinite(escape_radius) and escape_radius > 0):
            raise ValueError(f"escape_radius must be positive and finite, got {escape_radius!r}")
        self.escape_radius = escape_radius
        names = [f"x{i}" for i in range(dim)] if variables is None else [str(v) for v in
                                                                         variables]
        if len(names) != dim:
            raise ValueError(f"variables must name {dim} components, got {len(names)}")
        self.variables = tuple(names)

    @property
    def dim(self) -> int:
        """Phase-space dimension 2N."""
        return 2 * self.n_dof

    def describe(self) -> dict:
        """JSON-serialisable description: enough to rebuild the model."""
        return {"name": self.name, "class": type(self).__name__, "kind": self.kind,
                "dim": self.dim, "params": self.params.tolist(),
                "periods": self.periods.tolist(), "variables": list(self.variables),
                "escape_radius": self.escape_radius}

    # -- evaluation from Python (tests, helpers) ------------------------------------
    def _x(self, x):
        x = np.ascontiguousarray(x, dtype=np.float64)
        if x.shape != (self.dim,):
            raise ValueError(f"x must have shape ({self.dim},), got {x.shape}")
        return x

    def step(self, x):
        """F(x), with the periodic components reduced, shape (2N,)."""
        out = np.empty(self.dim)
        self.iterate_kernel(self._x(x), self.params, out)
        return wrap(out, self.periods)

    def jacobian(self, x):
        """The tangent map DF(x), shape (2N, 2N)."""
        J = np.zeros((self.dim, self.dim))
        self.jacobian_kernel(self._x(x), self.params, J)
        return J

    def energy(self, x, t=0.0, p_t=0.0):
        """0 for every state: a map conserves no energy (see the module
        docstring), so results' ``energy_error`` is 0."""
        return np.zeros(np.shape(x)[:-1])

    def energy_scale(self, x):
        """1 per state: the (zero) energy errors of a map are absolute."""
        return np.ones(np.shape(x)[:-1])

    def conserved(self, x):
        """No conserved quantity is checked for a map (its "energy" is 0)."""
        return {"energy": self.energy(x)}

    def __repr__(self):
        return f"<{type(self).__name__} {self.name!r}, dim={self.dim}>"


def wrap(x, periods):
    """``x`` with each component of positive period P reduced into [0, P)
    (NumPy, any leading axes; the compiled steppers do the same)."""
    x = np.array(x, dtype=np.float64)
    p = np.broadcast_to(periods, x.shape)
    on = p > 0
    x[on] = x[on] - p[on] * np.floor(x[on] / p[on])
    return x


# -- the standard map ------------------------------------------------------------------
@njit(cache=True, error_model="numpy")
def _standard_iterate(x, par, out):
    p = x[1] + par[0] * math.sin(x[0])
    out[0] = x[0] + p
    out[1] = p


@njit(cache=True, error_model="numpy")
def _standard_jacobian(x, par, J):
    kc = par[0] * math.cos(x[0])
    J[0, 0] = 1.0 + kc
    J[0, 1] = 1.0
    J[1, 0] = kc
    J[1, 1] = 1.0


class StandardMap(MapModel):
    """The Chirikov–Taylor standard map

        p' = p + K sin x,   x' = x + p'   (x mod 2π),

    state (x, p), tangent map [[1 + K cos x, 1], [K cos x, 1]].

    x is taken modulo 2π after every iteration: the dynamics is 2π-periodic
    in x, and a reduced angle keeps sin x accurate (an unreduced x grows
    like n·p and loses digits). p is left unreduced (the cylinder), so the
    diffusion in p of the chaotic sea stays visible; reducing it too would
    change neither x nor any Lyapunov exponent.

    For K ≫ 1 the largest Lyapunov exponent is ≈ ln(K/2) (Chirikov 1979,
    Sect. 5.1); the last invariant circle breaks at K ≈ 0.9716.

    Parameters
    ----------
    K : float
        Kick strength.
    """

    def __init__(self, K):
        if isinstance(K, bool) or not isinstance(K, numbers.Real) or not math.isfinite(K):
            raise ValueError(f"K must be a finite number, got {K!r}")
        self.K = float(K)
        super().__init__(2, _standard_iterate, _standard_jacobian, params=(self.K,),
                         periods=(_TWO_PI, 0.0), name=f"StandardMap(K={self.K:g})",
                         variables=("x", "p"))


# -- two coupled standard maps (4D) ------------------------------------------------------
@njit(cache=True, error_model="numpy")
def _coupled_iterate(x, par, out):
    k1, k2, beta = par[0], par[1], par[2]
    s = math.sin(_TWO_PI * (x[2] - x[0]))
    x2 = x[1] + k1 / _TWO_PI * math.sin(_TWO_PI * x[0]) - beta / math.pi * s
    x4 = x[3] + k2 / _TWO_PI * math.sin(_TWO_PI * x[2]) + beta / math.pi * s
    out[0] = x[0] + x2
    out[1] = x2
    out[2] = x[2] + x4
    out[3] = x4


@njit(cache=True, error_model="numpy")
def _coupled_jacobian(x, par, J):
    k1, k2, beta = par[0], par[1], par[2]
    c1 = k1 * math.cos(_TWO_PI * x[0])
    c3 = k2 * math.cos(_TWO_PI * x[2])
    cb = 2.0 * beta * math.cos(_TWO_PI * (x[2] - x[0]))
    # Rows of x2' and x4' (the kicks), then x1' = x1 + x2', x3' = x3 + x4'.
    J[1, 0], J[1, 1], J[1, 2], J[1, 3] = c1 + cb, 1.0, -cb, 0.0
    J[3, 0], J[3, 1], J[3, 2], J[3, 3] = -cb, 0.0, c3 + cb, 1.0
    J[0, 0], J[0, 1], J[0, 2], J[0, 3] = 1.0 + c1 + cb, 1.0, -cb, 0.0
    J[2, 0], J[2, 1], J[2, 2], J[2, 3] = -cb, 0.0, 1.0 + c3 + cb, 1.0


class CoupledStandardMaps(MapModel):
    """Two coupled standard maps: the 4D symplectic map of Skokos, Bountis &
    Antonopoulos (2007, Physica D 231, 30, Sect. 5; Skokos et al. 2004,
    J. Phys. A 37, 6269, eq. (10) with K1 = K2),

        x1' = x1 + x2'
        x2' = x2 + (K1/2π) sin(2πx1) − (β/π) sin[2π(x3 − x1)]
        x3' = x3 + x4'
        x4' = x4 + (K2/2π) sin(2πx3) − (β/π) sin[2π(x1 − x3)]    (mod 1),

    state (x1, x2, x3, x4) in the paper's order: x1, x3 are the angles and
    x2, x4 their momenta. Every variable is taken modulo 1 (the map lives
    on the torus T⁴). The two kicks are the gradient of one potential, so
    the map is symplectic; its regular orbits lie on 2-tori, on which
    GALI_2 stays constant and GALI_3 ∝ t⁻², GALI_4 ∝ t⁻⁴.

    Parameters
    ----------
    K1, K2 : float
        Kick strengths of the two maps.
    beta : float
        Coupling.
    """

    def __init__(self, K1, K2, beta):
        values = []
        for label, v in (("K1", K1), ("K2", K2), ("beta", beta)):
            if isinstance(v, bool) or not isinstance(v, numbers.Real) or not math.isfinite(v):
                raise ValueError(f"{label} must be a finite number, got {v!r}")
            values.append(float(v))
        self.K1, self.K2, self.beta = values
        super().__init__(4, _coupled_iterate, _coupled_jacobian, params=values,
                         periods=(1.0, 1.0, 1.0, 1.0),
                         name=f"CoupledStandardMaps(K1={values[0]:g}, K2={values[1]:g}, "
                              f"beta={values[2]:g})",
                         variables=("x1", "x2", "x3", "x4"))

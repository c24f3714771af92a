"""Planetary systems: a star and n planets under Newtonian gravity, in the
canonical coordinates of Wisdom–Holman maps.

:class:`Planetary` is a model like every other (every run, indicator,
chaos map and checkpoint takes it) whose Hamiltonian splits into an
integrable Kepler part and a small interaction (Wisdom & Holman 1991;
Laskar & Robutel 2001, H = A + εB with ε the planet-to-star mass ratio):

* ``coordinates="jacobi"`` (default): Jacobi positions and momenta,
  H = Σ p_i²/2m′_i + U(q) with U the potential of all pairs, split into
  the Kepler problems A (μ_i = G M_i) and the interaction B (a function of
  q alone). It is also of the form T(p) + V(q) with a diagonal mass, so
  every other method (DOP853, CVODE, TDH, heyoka's Taylor integrator
  through :meth:`Planetary.symbolic`) integrates the same model, e.g. as a
  reference.
* ``coordinates="democratic"``: heliocentric positions and barycentric
  momenta, H = H_K + H_I + H_J (Duncan, Levison & Lee 1998), three parts;
  only ``method="tm"`` runs it, with the compositions of three parts
  (:data:`varint.schemes.SCHEMES`; "ABC2" is the map of Duncan et al.).

The flows of the parts and their tangent maps are in
:mod:`varint.kernels.nbody` and :mod:`varint.kernels.kepler`. The energy and
the magnitude of the total angular momentum are the conserved quantities
of the accuracy verdict (:meth:`Planetary.conserved`).

Initial states come from orbital elements (:meth:`Planetary.from_elements`;
relative to the centre of mass of the bodies inside, as REBOUND's
``Simulation.add`` does by default, or to the star), from barycentric
positions and velocities, or from a ``rebound.Simulation``
(:meth:`Planetary.from_rebound`; REBOUND is optional and used only there
and in :meth:`Planetary.to_rebound`). :func:`varint.element_grid` makes a
grid of one planet's (a, e), (a, i), … for :func:`varint.chaos_map`.

Units are the caller's: with G = 1, lengths in AU and masses in solar
masses, a year is 2π time units (REBOUND's default units).

References
----------
J. Wisdom & M. Holman, Astron. J. 102, 1528 (1991); J. Laskar &
P. Robutel, Celest. Mech. Dyn. Astron. 80, 39 (2001); M. J. Duncan,
H. F. Levison & M. H. Lee, Astron. J. 116, 2067 (1998); H. Rein &
D. Tamayo, Mon. Not. R. Astron. Soc. 452, 376 (2015).
"""

from __future__ import annotations

import functools
import math
import numbers
from collections.abc import Mapping, Sequence

import numpy as np

from .._validate import real_array
from ..kernels import nbody as K
from ..kernels.nbody_unrolled import flows
from .base import Model
from .lattice import Parts, no_band_kernel, no_gradient_kernel, no_third_kernel

__all__ = ["Planetary", "COORDINATES", "ELEMENTS", "FRAMES", "JUPITER_SATURN"]

#: The coordinate systems a :class:`Planetary` integrates in.
COORDINATES = ("jacobi", "democratic")
#: Orbital elements, in the order of :meth:`Planetary.to_elements`.
ELEMENTS = ("a", "e", "inc", "Omega", "omega", "M")
#: Jupiter's and Saturn's Jacobi elements (au, radians; G = 1 with the Sun's
#: mass 1, so one year is 2π): the two-planet system of the command line's
#: ``varint map --model planetary``, whose default grid varies Saturn's
#: (a, e) over the 2:1 and 5:2 mean-motion resonances with Jupiter
#: (a ≈ 8.26 and 9.59), as studies/bench_planetary.py does.
JUPITER_SATURN = (dict(a=5.204, e=0.048, M=0.600, omega=0.257),
                  dict(a=9.555, e=0.056, M=0.871, omega=1.616))
#: Frames orbital elements refer to: the centre of mass of the bodies inside
#: (Jacobi, REBOUND's default primary) or the star.
FRAMES = ("jacobi", "heliocentric")


def _positive(value, name):
    if (isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real)
            or not math.isfinite(value) or value <= 0):
        raise ValueError(f"{name} must be a positive finite number, got {value!r}")
    return float(value)


def _choice(value, valid, name):
    if not isinstance(value, str) or value.lower() not in valid:
        raise ValueError(f"{name} must be one of {', '.join(valid)}, got {value!r}")
    return value.lower()


class Planetary(Model):
    """A star and n planets (see the module docstring).

    Parameters
    ----------
    masses : sequence of float
        m₀ (the star), m₁ … m_n (the planets, inside out for Jacobi
        coordinates); all positive.
    G : float, default 1
        The gravitational constant.
    coordinates : {"jacobi", "democratic"}
    name : str, optional
    escape_radius : float, optional
        Stop orbits (as escaped) once |q|, the norm of all planets'
        positions in these coordinates, exceeds it.
    close_encounter : float, optional
        Stop orbits (status ``CLOSE_ENCOUNTER``) once two planets come
        closer than this many mutual Hill radii
        ((m_i + m_j)/3m₀)^{1/3} r̄ after a kick, r̄² the mean of their squared
        distances from the star (:func:`varint.kernels.nbody.planetary_params`);
        by default never.

    Attributes
    ----------
    n_planets : int
    masses : ndarray, shape (n + 1,)
    kepler_mu, kepler_mass : ndarray, shape (n,)
        μ_i and m′_i of each planet's Kepler problem (p_i = m′_i q̇_i).
    parts : Parts
        The Wisdom–Holman split: ("Kepler", "Interaction") in Jacobi
        coordinates, ("Kepler", "Interaction", "Jump") in democratic
        heliocentric ones.

    Examples
    --------
    >>> import varint
    >>> model = varint.models.Planetary([1.0, 1e-3, 3e-4])
    >>> x0 = model.from_elements([dict(a=1.0, e=0.05), dict(a=1.6, e=0.02, M=2.0)])
    >>> x0.shape
    (12,)
    >>> [round(float(v), 12) for v in model.to_elements(x0)[1][:2]]
    [1.6, 0.02]
    """

    band_kernels = True
    #: What ``method="tm"`` runs on the parts: the part stepper with the
    #: correctors at outputs (:mod:`varint.methods.planetary`).
    parts_propagator = "varint.methods.planetary:PlanetaryPropagator"

    def __init__(self, masses: Sequence[float], G: float = 1.0, coordinates: str = "jacobi",
                 name: str | None = None, escape_radius: float | None = None,
                 close_encounter: float | None = None) -> None:
        m = np.array(masses, dtype=np.float64) if _numbers(masses) else None
        if m is None or m.ndim != 1 or len(m) < 2:
            raise ValueError(f"masses must be a sequence of at least two numbers (the star, "
                             f"then the planets), got {masses!r}")
        bad = ~np.isfinite(m) | (m <= 0)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise ValueError(f"masses must be positive and finite; got {float(m[i])!r} at "
                             f"index {i}")
        self.G = _positive(G, "G")
        self.coordinates = _choice(coordinates, COORDINATES, "coordinates")
        self.close_encounter = (None if close_encounter is None
                                else _positive(close_encounter, "close_encounter"))
        self.masses = m
        self.n_planets = n = len(m) - 1
        flag = K.JACOBI if self.coordinates == "jacobi" else K.DEMOCRATIC
        par = K.planetary_params(m, self.G, flag, self.close_encounter)
        interior = np.cumsum(m)
        if flag == K.JACOBI:
            self.kepler_mu = self.G * interior[1:]
            self.kepler_mass = m[1:] * interior[:-1] / interior[1:]
        else:
            self.kepler_mu = np.full(n, self.G * m[0])
            self.kepler_mass = m[1:].copy()
        name = name or (f"Planetary({n} planet{'s' if n > 1 else ''}, masses="
                        f"{[float(f'{v:.6g}') for v in m]}, G={self.G:g}, {self.coordinates})")
        jacobi = flag == K.JACOBI
        self.band_kernels = jacobi
        super().__init__(
            3 * n, self._potential_q,
            K.potential_gradient if jacobi else no_gradient_kernel,
            K.potential_hessian_band if jacobi else no_band_kernel,
            K.potential_third_band if jacobi else no_third_kernel,
            3 * n - 1 if jacobi else 0, params=par,
            inverse_mass=np.repeat(1.0 / self.kepler_mass, 3), name=name,
            escape_radius=escape_radius)
        names = ("Kepler", "Interaction") if jacobi else ("Kepler", "Interaction", "Jump")
        splits = {2: ("Kepler", "Interaction")} if jacobi else {3: ("Interaction", "Jump",
                                                                     "Kepler")}
        #: The kernels the start check evaluates (varint._validate.kernels):
        #: ∇U alone. U's singular states (two bodies at one place) are
        #: exactly those where ∇U is not finite (0·∞ there), and the part
        #: flows that run the model call neither D²U nor its third
        #: derivatives, whose compiles (12 CPU s) the check alone caused.
        self.checked_kernels = (K.potential_gradient if jacobi else no_gradient_kernel,
                                K.unchecked_hessian, K.unchecked_third)
        self.parts = Parts(names=names, apply=flows(n, jacobi), field=K.vector_field,
                           splits=splits, par=par, n_work=K.n_work(n),
                           default_scheme="SABA1" if jacobi else "ABC2")

    # -- the Hamiltonian -----------------------------------------------------
    def helio_positions(self, q):
        """Positions relative to the star, shape (..., n, 3), from the
        model's positions ``q`` (..., 3n)."""
        q = np.asarray(q, dtype=float)
        Q = q.reshape(q.shape[:-1] + (self.n_planets, 3))
        if self.coordinates == "democratic":
            return Q.copy()
        return _jacobi_to_helio(Q, self.masses)

    def _potential_q(self, q):
        u = self.helio_positions(q)
        m = self.masses
        U = -self.G * m[0] * np.sum(m[1:] / np.linalg.norm(u, axis=-1), axis=-1)
        for i in range(self.n_planets):
            for j in range(i + 1, self.n_planets):
                d = np.linalg.norm(u[..., i, :] - u[..., j, :], axis=-1)
                U = U - self.G * m[i + 1] * m[j + 1] / d
        return U

    def kinetic(self, p):
        """The kinetic energy: Σ p_i²/2m′_i, and |Σ P_i|²/2m₀ more in
        democratic heliocentric coordinates."""
        p = np.asarray(p, dtype=float)
        T = super().kinetic(p)
        if self.coordinates == "democratic":
            P = p.reshape(p.shape[:-1] + (self.n_planets, 3)).sum(axis=-2)
            T = T + 0.5 * np.sum(P * P, axis=-1) / self.masses[0]
        return T

    def angular_momentum(self, x):
        """The total angular momentum Σ q_i × p_i about the centre of mass,
        shape (..., 3) (both coordinate systems are point transformations,
        so this is Σ m_j X_j × V_j of the bodies)."""
        x = np.asarray(x, dtype=float)
        n = self.n_planets
        q = x[..., :3 * n].reshape(x.shape[:-1] + (n, 3))
        p = x[..., 3 * n:].reshape(x.shape[:-1] + (n, 3))
        return np.cross(q, p).sum(axis=-2)

    def conserved(self, x, t=0.0, p_t=0.0):
        """The energy and |L|, the magnitude of the total angular momentum."""
        return {"energy": self.energy(x),
                "angular_momentum": np.linalg.norm(self.angular_momentum(x), axis=-1)}

    def vector_field(self, x):
        """ẋ = J∇H at the state x (2N,)."""
        x = np.ascontiguousarray(x, dtype=np.float64)
        out = np.empty_like(x)
        K.vector_field(x, self.params, out)
        return out

    def interaction(self, q):
        """B(q), the interaction part of the Wisdom–Holman split (H_I in
        democratic heliocentric coordinates), shape (...)."""
        q = np.asarray(q, dtype=float)
        u = self.helio_positions(q)
        m, G = self.masses, self.G
        B = np.zeros(q.shape[:-1])
        for i in range(self.n_planets):
            for j in range(i + 1, self.n_planets):
                B = B - G * m[i + 1] * m[j + 1] / np.linalg.norm(u[..., i, :] - u[..., j, :],
                                                                 axis=-1)
        if self.coordinates == "jacobi":
            Q = q.reshape(q.shape[:-1] + (self.n_planets, 3))
            interior = np.cumsum(m)
            for i in range(1, self.n_planets):
                B = B + G * m[i + 1] * interior[i] / np.linalg.norm(Q[..., i, :], axis=-1)
                B = B - G * m[0] * m[i + 1] / np.linalg.norm(u[..., i, :], axis=-1)
        return B

    def interaction_gradient(self, q):
        """∇B(q), shape (N,) (compiled: what the kicks use)."""
        q = self._q(q)
        out = np.empty(self.n_dof)
        K.interaction_gradient(q, self.params, out, np.empty(K.n_work(self.n_planets)))
        return out

    def describe(self):
        d = super().describe()
        d.pop("inverse_mass", None)
        d.pop("params", None)
        d.update(masses=self.masses.tolist(), G=self.G, coordinates=self.coordinates)
        if self.close_encounter is not None:
            d["close_encounter"] = self.close_encounter
        if self.escape_radius is not None:
            d["escape_radius"] = self.escape_radius
        return d

    def symbolic(self):
        """The model in SymPy (Jacobi coordinates only): U written in the
        Jacobi positions, for the Taylor reference (``method="taylor"``).

        Raises
        ------
        ValueError
            In democratic heliocentric coordinates, whose kinetic energy is
            not diagonal.
        """
        if self.coordinates != "jacobi":
            raise ValueError(f"{self.name} has a non-diagonal kinetic energy (democratic "
                             "heliocentric coordinates); use coordinates='jacobi' for the "
                             "other methods")
        return _symbolic(tuple(self.masses.tolist()), self.G)

    # -- states --------------------------------------------------------------
    def from_cartesian(self, positions, velocities):
        """The state (2N,) of bodies at ``positions`` and ``velocities``
        (n + 1, 3) in any inertial frame (the star first); the centre of
        mass and its motion are removed.

        Raises
        ------
        ValueError
            For arrays of the wrong shape or non-finite values, or two
            bodies at the same place.
        """
        X = self._bodies(positions, "positions")
        Vb = self._bodies(velocities, "velocities")
        m = self.masses
        X = X - (m @ X) / m.sum()
        Vb = Vb - (m @ Vb) / m.sum()
        for a in range(len(m)):
            for b in range(a + 1, len(m)):
                if not np.any(X[a] != X[b]):
                    raise ValueError(f"bodies {a} and {b} are at the same position {X[a].tolist()}")
        n = self.n_planets
        if self.coordinates == "democratic":
            q = X[1:] - X[0]
            p = m[1:, None] * Vb[1:]
        else:
            q = _bary_to_jacobi(X, m)
            p = self.kepler_mass[:, None] * _bary_to_jacobi(Vb, m)
        return np.concatenate([q.reshape(3 * n), p.reshape(3 * n)])

    def to_cartesian(self, x):
        """Barycentric positions and velocities of the star and the planets,
        each of shape (n + 1, 3), of the state ``x`` (2N,)."""
        x = self._state(x)
        n, m = self.n_planets, self.masses
        q = x[:3 * n].reshape(n, 3)
        p = x[3 * n:].reshape(n, 3)
        if self.coordinates == "democratic":
            u = q
            Vp = p / m[1:, None]
            V0 = -(m[1:] @ Vp) / m[0]
            X0 = -(m[1:] @ u) / m.sum()
            return np.vstack([X0, X0 + u]), np.vstack([V0, Vp])
        u = _jacobi_to_helio(q, m)
        w = _jacobi_to_helio(p / self.kepler_mass[:, None], m)
        X0 = -(m[1:] @ u) / m.sum()
        V0 = -(m[1:] @ w) / m.sum()
        return np.vstack([X0, X0 + u]), np.vstack([V0, V0 + w])

    def from_elements(self, elements, frame="jacobi"):
        """The state (2N,) of planets with the given orbital elements.

        Parameters
        ----------
        elements : sequence of mappings
            One per planet, inside out: ``a`` (negative for a hyperbola),
            ``e`` (not exactly 1), and optionally ``inc``, ``Omega``,
            ``omega`` (radians, default 0) and either ``M`` (mean anomaly) or
            ``f`` (true anomaly), default M = 0.
        frame : {"jacobi", "heliocentric"}
            Planet i's elements relative to the centre of mass of the star
            and planets inside it with μ = G M_i (as REBOUND's
            ``Simulation.add`` without ``primary``), or to the star with
            μ = G(m₀ + m_i).

        Raises
        ------
        ValueError
            For a missing or invalid element (naming the planet and the
            element).
        """
        frame = _choice(frame, FRAMES, "frame")
        if isinstance(elements, Mapping) or not isinstance(elements, Sequence) \
                or len(elements) != self.n_planets:
            raise ValueError(f"elements must be a sequence of {self.n_planets} mappings (one "
                             f"per planet, e.g. dict(a=1.0, e=0.1)), got {elements!r}")
        m = self.masses
        interior = np.cumsum(m)
        rel = np.empty((self.n_planets, 3))
        vel = np.empty((self.n_planets, 3))
        for i, el in enumerate(elements):
            mu = self.G * (interior[i + 1] if frame == "jacobi" else m[0] + m[i + 1])
            rel[i], vel[i] = _elements_to_vectors(el, mu, f"planet {i + 1}")
        if frame == "jacobi":
            u = _jacobi_to_helio(rel, m)
            w = _jacobi_to_helio(vel, m)
        else:
            u, w = rel, vel
        X = np.vstack([np.zeros(3), u])
        Vb = np.vstack([np.zeros(3), w])
        return self.from_cartesian(X, Vb)

    def to_elements(self, x, frame="jacobi"):
        """Orbital elements (a, e, inc, Omega, omega, M) of every planet,
        shape (n, 6), in ``frame`` (see :meth:`from_elements`); angles in
        radians, M in [0, 2π) (the mean anomaly of a hyperbola is unbounded;
        Ω = 0 for a planar orbit and ω = 0 for a circular one)."""
        frame = _choice(frame, FRAMES, "frame")
        X, Vb = self.to_cartesian(x)
        m = self.masses
        interior = np.cumsum(m)
        out = np.empty((self.n_planets, 6))
        if frame == "jacobi":
            rel, vel = _bary_to_jacobi(X, m), _bary_to_jacobi(Vb, m)
        else:
            rel, vel = X[1:] - X[0], Vb[1:] - Vb[0]
        for i in range(self.n_planets):
            mu = self.G * (interior[i + 1] if frame == "jacobi" else m[0] + m[i + 1])
            out[i] = _vectors_to_elements(rel[i], vel[i], mu)
        return out

    @classmethod
    def from_rebound(cls, sim, coordinates="jacobi"):
        """The model and state of a ``rebound.Simulation``: its particles'
        masses (the first is the star), G, positions and velocities.

        Returns
        -------
        model : Planetary
        x0 : ndarray, shape (2N,)

        Raises
        ------
        ValueError
            If the simulation has fewer than two particles, or a particle
            without mass (test particles are not supported).
        """
        particles = list(sim.particles)
        if len(particles) < 2:
            raise ValueError(f"the simulation holds {len(particles)} particle(s); a planetary "
                             "system needs a star and at least one planet")
        masses = [p.m for p in particles]
        model = cls(masses, G=sim.G, coordinates=coordinates)
        X = np.array([[p.x, p.y, p.z] for p in particles])
        Vb = np.array([[p.vx, p.vy, p.vz] for p in particles])
        return model, model.from_cartesian(X, Vb)

    def to_rebound(self, x):
        """A ``rebound.Simulation`` with this model's bodies at the state
        ``x`` (barycentric), G and masses; the integrator is left as
        REBOUND's default.

        Raises
        ------
        ImportError
            Without REBOUND (an optional dependency: ``pip install
            "varint[rebound]"``).
        """
        try:
            import rebound  # type: ignore[import-untyped]  # optional, for comparisons
        except ImportError as exc:
            raise ImportError('to_rebound needs REBOUND, an optional dependency: pip install '
                              '"varint[rebound]"') from exc

        X, Vb = self.to_cartesian(x)
        sim = rebound.Simulation()
        sim.G = self.G
        for mj, pos, vel in zip(self.masses, X, Vb, strict=True):
            sim.add(m=float(mj), x=pos[0], y=pos[1], z=pos[2], vx=vel[0], vy=vel[1], vz=vel[2])
        return sim

    # -- helpers -------------------------------------------------------------
    def hill_radii(self, x):
        """Each planet's Hill radius |u_i| (m_i/3m₀)^{1/3} at its current
        distance from the star, shape (..., n)."""
        u = self.helio_positions(np.asarray(x, dtype=float)[..., :self.n_dof])
        return np.linalg.norm(u, axis=-1) * np.cbrt(self.masses[1:] / (3 * self.masses[0]))

    def periods(self, x):
        """Each planet's osculating Kepler period 2π√(a³/μ) in the model's
        Kepler problems (inf for an unbound orbit), shape (n,)."""
        el = self.to_elements(x, "jacobi" if self.coordinates == "jacobi" else "heliocentric")
        a = el[:, 0]
        mu = self.kepler_mu if self.coordinates == "jacobi" else \
            self.G * (self.masses[0] + self.masses[1:])
        with np.errstate(invalid="ignore"):
            return np.where(a > 0, 2 * np.pi * np.sqrt(np.abs(a) ** 3 / mu), np.inf)

    def pericentre_times(self, x):
        """Each planet's pericentre passage time √(q³/μ(1 + e)) — the
        pericentre distance over the pericentre speed — in its Kepler
        problem of these coordinates, for states ``x`` (..., 2N): shape
        (..., n)."""
        x = np.asarray(x, dtype=float)
        n = self.n_planets
        q = x[..., :3 * n].reshape(x.shape[:-1] + (n, 3))
        v = x[..., 3 * n:].reshape(x.shape[:-1] + (n, 3)) / self.kepler_mass[:, None]
        mu = self.kepler_mu
        r = np.linalg.norm(q, axis=-1)
        h2 = np.sum(np.cross(q, v) ** 2, axis=-1)
        energy = 0.5 * np.sum(v * v, axis=-1) - mu / r
        with np.errstate(invalid="ignore"):
            e = np.sqrt(np.maximum(1 + 2 * energy * h2 / mu ** 2, 0.0))
            peri = h2 / (mu * (1 + e))
            return np.sqrt(peri ** 3 / (mu * (1 + e)))

    def _bodies(self, value, name):
        arr = real_array(value, name)
        if arr.shape != (self.n_planets + 1, 3) or not np.isfinite(arr).all():
            raise ValueError(f"{name} must be finite, of shape ({self.n_planets + 1}, 3) (the "
                             f"star, then the planets), got shape {arr.shape}")
        return arr

    def _state(self, x):
        x = np.asarray(x, dtype=float)
        if x.shape != (self.dim,):
            raise ValueError(f"x must be one state of length {self.dim}, got shape {x.shape}")
        return x


def _numbers(values):
    try:
        arr = np.asarray(values)
    except (TypeError, ValueError):
        return False
    return arr.dtype.kind in "iuf"


def _jacobi_to_helio(Q, m):
    """Heliocentric vectors (..., n, 3) from Jacobi ones: u_i = Q_i +
    Σ_{j<i} m_j u_j / M_{i−1} (:func:`varint.kernels.nbody.jacobi_to_helio`)."""
    Q = np.asarray(Q, dtype=float)
    u = np.empty_like(Q)
    s = np.zeros(Q.shape[:-2] + (3,))
    interior = np.cumsum(m)
    for i in range(Q.shape[-2]):
        u[..., i, :] = Q[..., i, :] + s / interior[i]
        s = s + m[i + 1] * u[..., i, :]
    return u


def _bary_to_jacobi(X, m):
    """Jacobi vectors (n, 3) of bodies at X (n + 1, 3): each planet relative
    to the centre of mass of the bodies before it."""
    interior = np.cumsum(m)
    centre = np.cumsum(m[:, None] * X, axis=0) / interior[:, None]
    return X[1:] - centre[:-1]


def _element(el, key, where, default=None):
    value = el.get(key, default)
    if value is None:
        raise ValueError(f"{where}: the element {key!r} is missing")
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real) \
            or not math.isfinite(value):
        raise ValueError(f"{where}: {key} must be a finite number, got {value!r}")
    return float(value)


def _elements_to_vectors(el, mu, where):
    """Relative position and velocity of the conic with elements ``el``."""
    if not isinstance(el, Mapping):
        raise ValueError(f"{where}: elements must be a mapping such as dict(a=1.0, e=0.1), "
                         f"got {el!r}")
    unknown = sorted(set(el) - set(ELEMENTS) - {"f"})
    if unknown:
        raise ValueError(f"{where}: unknown element {unknown[0]!r}; expected "
                         f"{', '.join(ELEMENTS)} or f")
    a, e = _element(el, "a", where), _element(el, "e", where, 0.0)
    inc, Om, om = (_element(el, k, where, 0.0) for k in ("inc", "Omega", "omega"))
    if e < 0 or e == 1.0:
        raise ValueError(f"{where}: e must be >= 0 and not exactly 1 (a parabola has no "
                         f"semi-major axis; give its state with from_cartesian), got {e!r}")
    if a == 0 or (e < 1) != (a > 0):
        raise ValueError(f"{where}: a must be positive for e < 1 and negative for e > 1, "
                         f"got a = {a!r}, e = {e!r}")
    if "f" in el and "M" in el:
        raise ValueError(f"{where}: give the mean anomaly M or the true anomaly f, not both")
    if "f" in el:
        f = _element(el, "f", where)
        if not 1 + e * math.cos(f) > 0:
            raise ValueError(f"{where}: a hyperbola with e = {e!r} never reaches f = {f!r}")
    else:
        f = _true_anomaly(_element(el, "M", where, 0.0), e)
    p = a * (1 - e * e)
    r = p / (1 + e * math.cos(f))
    pos = r * np.array([math.cos(f), math.sin(f), 0.0])
    vel = math.sqrt(mu / p) * np.array([-math.sin(f), e + math.cos(f), 0.0])
    R = _rotation(inc, Om, om)
    return R @ pos, R @ vel


def _rotation(inc, Om, om):
    """R_z(Ω) R_x(i) R_z(ω): the perifocal frame to the reference frame."""
    cO, sO, ci, si, co, so = (math.cos(Om), math.sin(Om), math.cos(inc), math.sin(inc),
                              math.cos(om), math.sin(om))
    return np.array([[cO * co - sO * so * ci, -cO * so - sO * co * ci, sO * si],
                     [sO * co + cO * so * ci, -sO * so + cO * co * ci, -cO * si],
                     [so * si, co * si, ci]])


def _true_anomaly(M, e):
    """f from the mean anomaly M by Newton's method on Kepler's equation
    (E − e sin E = M, or e sinh H − H = M for e > 1)."""
    if e < 1:
        M = math.remainder(M, 2 * math.pi)
        E = M if e < 0.8 else math.copysign(math.pi, M) if M else 0.0
        for _ in range(100):
            d = (E - e * math.sin(E) - M) / (1 - e * math.cos(E))
            E -= d
            if abs(d) <= 4e-16 * max(1.0, abs(E)):
                break
        return 2 * math.atan2(math.sqrt(1 + e) * math.sin(E / 2),
                              math.sqrt(1 - e) * math.cos(E / 2))
    H = math.asinh(M / e)
    for _ in range(200):
        d = (e * math.sinh(H) - H - M) / (e * math.cosh(H) - 1)
        H -= d
        if abs(d) <= 4e-16 * max(1.0, abs(H)):
            break
    return 2 * math.atan(math.sqrt((e + 1) / (e - 1)) * math.tanh(H / 2))


def _vectors_to_elements(r, v, mu):
    """(a, e, inc, Omega, omega, M) of a relative position and velocity."""
    h = np.cross(r, v)
    rn, hn = np.linalg.norm(r), np.linalg.norm(h)
    ev = np.cross(v, h) / mu - r / rn
    e = float(np.linalg.norm(ev))
    a = 1.0 / (2.0 / rn - float(v @ v) / mu)
    inc = math.acos(max(-1.0, min(1.0, h[2] / hn)))
    node = np.array([-h[1], h[0], 0.0])
    nn = np.linalg.norm(node)
    Om = math.atan2(node[1], node[0]) if nn > 1e-14 * hn else 0.0
    # Angles in the orbital plane from the node line (the x axis if none).
    ref = node / nn if nn > 1e-14 * hn else np.array([1.0, 0.0, 0.0])
    perp = np.cross(h / hn, ref)
    if e > 1e-14:
        om = math.atan2(float(ev @ perp), float(ev @ ref))
        f = math.atan2(float(np.cross(ev, r) @ h) / (e * rn * hn), float(ev @ r) / (e * rn))
    else:
        om = 0.0
        f = math.atan2(float(r @ perp), float(r @ ref))
    if e < 1:
        E = 2 * math.atan2(math.sqrt(1 - e) * math.sin(f / 2), math.sqrt(1 + e) * math.cos(f / 2))
        M = (E - e * math.sin(E)) % (2 * math.pi)
    else:
        H = 2 * math.atanh(math.sqrt((e - 1) / (e + 1)) * math.tan(f / 2))
        M = e * math.sinh(H) - H
    return a, e, inc, Om % (2 * math.pi), om % (2 * math.pi), M


@functools.lru_cache(maxsize=32)
def _symbolic(masses, G):
    """U in the Jacobi positions as a SymPy expression, built once per
    process and system (every run and map chunk of ``method="taylor"`` asks
    for it)."""
    import sympy as sp  # type: ignore[import-untyped]

    from .symbolic import SymbolicPotential

    n = len(masses) - 1
    q = sp.symbols(f"q0:{3 * n}", real=True)
    # The doubles given, exactly (a wider reference rounds them once in its
    # own precision).
    m = [sp.Float(v, 40) for v in masses]
    Gs = sp.Float(G, 40)
    interior = [sum(m[:i + 1]) for i in range(n + 1)]
    u, s = [], [sp.Integer(0)] * 3
    for i in range(n):
        ui = [q[3 * i + a] + s[a] / interior[i] for a in range(3)]
        u.append(ui)
        s = [s[a] + m[i + 1] * ui[a] for a in range(3)]
    U = -sum(Gs * m[0] * m[i + 1] / sp.sqrt(sum(c * c for c in u[i])) for i in range(n))
    for i in range(n):
        for j in range(i + 1, n):
            d = [u[i][a] - u[j][a] for a in range(3)]
            U -= Gs * m[i + 1] * m[j + 1] / sp.sqrt(sum(c * c for c in d))
    kmass = [m[i + 1] * interior[i] / interior[i + 1] for i in range(n)]
    inverse = tuple(1 / kmass[i // 3] for i in range(3 * n))
    return SymbolicPotential(U, q, inverse)

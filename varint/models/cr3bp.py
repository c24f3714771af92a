"""The circular restricted three-body problem in the synodic (rotating)
frame.

Units: the primaries' separation, their total mass and the inverse of their
angular velocity are 1; the primaries of masses 1 − μ and μ sit at
(−μ, 0) and (1 − μ, 0). The Hamiltonian of the massless third body
(Szebehely 1967, Sect. 10.3) is

    H = ½ (p_x² + p_y² + p_z²) + y p_x − x p_y − (1 − μ)/r₁ − μ/r₂,

r₁, r₂ the distances to the primaries; p = v + (−y, x, 0), v the velocity in
the rotating frame. The Jacobi constant C = 2Ω − |v|² = −2H, with
Ω = ½(x² + y²) + (1 − μ)/r₁ + μ/r₂, is conserved; motion is possible only
where 2Ω ≥ C (the forbidden regions of a map lie outside the zero-velocity
curves 2Ω = C).

H is a rotating frame's kinetic term plus a potential: ``method="tm"`` runs
its exact flow (a rotation composed with free motion,
:func:`varint.flows.split.planar_flow`) and the kick of V with their tangent
maps, through every explicit two-part scheme, correctors included, on a
stepper generated for the model (:mod:`varint.codegen`: the drift written
out as straight-line code, one orbit and SIMD lanes).

References
----------
V. Szebehely, *Theory of Orbits*, Academic Press (1967).
R. F. Arenstorf, Am. J. Math. 85, 27 (1963); E. Hairer, S. P. Nørsett &
G. Wanner, *Solving Ordinary Differential Equations I*, 2nd ed., Springer
(1993), Sect. II.0, eq. (0.1) and Fig. 0.1 — the periodic Arenstorf orbit.
W. S. Koon, M. W. Lo, J. E. Marsden & S. D. Ross, *Dynamical Systems, the
Three-Body Problem and Space Mission Design* (2011), Sect. 2.4 — Lagrange
points and energy realms of the Earth–Moon system.
C. Froeschlé, E. Lega & R. Gonczi, Celest. Mech. Dyn. Astron. 67, 41 (1997)
— the fast Lyapunov indicator; E. Lega, M. Guzzo & C. Froeschlé, MNRAS 418,
107 (2011) — FLI maps of the restricted three-body problem.
"""

from __future__ import annotations

import functools
import numbers

import numpy as np

from ..grids import SectionGrid
from .hamiltonian import IntegrableHamiltonian, recognise

__all__ = ["CR3BP", "CR3BP_ORBITS", "cr3bp_orbit", "EARTH_MOON_MU", "SUN_JUPITER_MU",
           "ARENSTORF_MU", "ARENSTORF_PERIOD"]

#: μ of the Earth–Moon system (Koon et al. 2011).
EARTH_MOON_MU = 0.01215
#: μ of the Sun–Jupiter system, the setting of the FLI maps of asteroid
#: dynamics (Froeschlé, Lega & Gonczi 1997).
SUN_JUPITER_MU = 0.000954
#: μ and period of the Arenstorf orbit (Hairer, Nørsett & Wanner, eq. 0.1).
ARENSTORF_MU = 0.012277471
ARENSTORF_PERIOD = 17.0652165601579625588917206249


@functools.cache
def _expression(mu, spatial):
    import sympy as sp

    x, y, z, px, py, pz = sp.symbols("x y z p_x p_y p_z")
    m = sp.Float(mu, 17) if not isinstance(mu, sp.Basic) else mu
    zz = z ** 2 if spatial else 0
    r1 = sp.sqrt((x + m) ** 2 + y ** 2 + zz)
    r2 = sp.sqrt((x - 1 + m) ** 2 + y ** 2 + zz)
    kinetic = (px ** 2 + py ** 2 + (pz ** 2 if spatial else 0)) / 2
    H = kinetic + y * px - x * py - (1 - m) / r1 - m / r2
    q, p = ((x, y, z), (px, py, pz)) if spatial else ((x, y), (px, py))
    return H, q, p, recognise(H, q, p)


class CR3BP(IntegrableHamiltonian):
    """The circular restricted three-body problem (module docstring).

    Parameters
    ----------
    mu : float
        Mass ratio μ = m₂/(m₁ + m₂), 0 < μ ≤ 1/2.
    spatial : bool, default False
        The spatial problem (x, y, z) instead of the planar one (x, y).
    escape_radius : float, optional
        Stop orbits once |q| exceeds it (e.g. ejected ones).

    Examples
    --------
    >>> from varint.models import CR3BP
    >>> m = CR3BP(0.01215)
    >>> round(float(m.jacobi_at(*m.lagrange_points()["L4"])), 6)   # 3 − μ(1 − μ)
    2.987998
    """

    def __init__(self, mu: float, spatial: bool = False,
                 escape_radius: float | None = None) -> None:
        if (isinstance(mu, bool) or not isinstance(mu, numbers.Real)
                or not (0.0 < float(mu) <= 0.5)):
            raise ValueError(f"mu must be a mass ratio in (0, 1/2], got {mu!r}")
        if not isinstance(spatial, (bool, np.bool_)):
            raise ValueError(f"spatial must be True or False, got {spatial!r}")
        self.mu = float(mu)
        self.spatial = bool(spatial)
        H, q, p, found = _expression(self.mu, self.spatial)
        super().__init__(H, q, p, name=f"CR3BP(mu={self.mu:g}{', spatial' if spatial else ''})",
                         escape_radius=escape_radius, _found=found)

    def describe(self):
        d = super().describe()
        d.update(mu=self.mu, spatial=self.spatial)
        return d

    # -- the problem's own quantities ---------------------------------------------------
    def effective_potential(self, q):
        """Ω(q) = ½(x² + y²) + (1 − μ)/r₁ + μ/r₂ for positions (..., N)."""
        q = np.asarray(q, dtype=float)
        x, y = q[..., 0], q[..., 1]
        zz = q[..., 2] ** 2 if self.spatial else 0.0
        mu = self.mu
        r1 = np.sqrt((x + mu) ** 2 + y ** 2 + zz)
        r2 = np.sqrt((x - 1 + mu) ** 2 + y ** 2 + zz)
        return 0.5 * (x * x + y * y) + (1 - mu) / r1 + mu / r2

    def jacobi(self, x):
        """The Jacobi constant C = −2H of states (..., 2N)."""
        return -2.0 * self.hamiltonian(x)

    def jacobi_at(self, x, y, z=0.0):
        """2Ω(x, y, z): the Jacobi constant of a body at rest there (the
        zero-velocity surface through the point)."""
        q = np.stack(np.broadcast_arrays(x, y, z) if self.spatial
                     else np.broadcast_arrays(x, y), axis=-1)
        return 2.0 * self.effective_potential(q)

    def forbidden(self, x, y, jacobi, z=0.0):
        """Where motion with Jacobi constant C is impossible, 2Ω < C."""
        return self.jacobi_at(x, y, z) < jacobi

    def conserved(self, x, t=0.0, p_t=0.0):
        """The energy H and the Jacobi constant C = −2H (recorded, and checked
        by the accuracy verdict, relative to |C(0)|)."""
        h = self.hamiltonian(x)
        return {"energy": h, "jacobi": -2.0 * h}

    def state(self, position, velocity):
        """The state (q, p) of a body at ``position`` with ``velocity`` in the
        rotating frame: p = v + (−y, x, 0). Arrays (..., N)."""
        r = np.asarray(position, dtype=float)
        v = np.array(velocity, dtype=float)
        v[..., 0] -= r[..., 1]
        v[..., 1] += r[..., 0]
        return np.concatenate(np.broadcast_arrays(r, v), axis=-1)

    def velocity(self, x):
        """The velocity in the rotating frame of states (..., 2N)."""
        x = np.asarray(x, dtype=float)
        n = self.n_dof
        v = x[..., n:].copy()
        v[..., 0] += x[..., 1]
        v[..., 1] -= x[..., 0]
        return v

    def lagrange_points(self):
        """The five equilibria: {"L1": (x, y), …, "L5": (x, y)}. L1 lies
        between the primaries, L2 beyond the smaller one, L3 beyond the
        larger; L4 and L5 form equilateral triangles with them."""
        mu = self.mu

        def dx(x):   # ∂Ω/∂x on the x-axis
            r1, r2 = x + mu, x - 1 + mu
            return x - (1 - mu) * r1 / abs(r1) ** 3 - mu * r2 / abs(r2) ** 3

        def root(lo, hi):
            for _ in range(200):
                mid = 0.5 * (lo + hi)
                if np.sign(dx(mid)) == np.sign(dx(lo)):
                    lo = mid
                else:
                    hi = mid
            return 0.5 * (lo + hi)

        eps = 1e-12
        return {"L1": (root(-mu + eps, 1 - mu - eps), 0.0),
                "L2": (root(1 - mu + eps, 2.0 + mu), 0.0),
                "L3": (root(-2.0, -mu - eps), 0.0),
                "L4": (0.5 - mu, np.sqrt(3) / 2), "L5": (0.5 - mu, -np.sqrt(3) / 2)}

    def section_grid(self, jacobi, x, px):
        """Initial conditions on the section y = 0 crossed with ẏ > 0, at
        Jacobi constant ``jacobi``, on the grid of x and p_x (= ẋ on y = 0):
        p_y is solved from H = −C/2. Points in the forbidden region (no real
        ẏ) are masked out, so a map's image shows them blank.

        Returns
        -------
        SectionGrid
            For :func:`varint.chaos_map`; ``energy`` is H = −C/2.
        """
        if self.spatial:
            raise ValueError("section_grid is for the planar problem (spatial=False)")
        if isinstance(jacobi, bool) or not isinstance(jacobi, numbers.Real) \
                or not np.isfinite(jacobi):
            raise ValueError(f"jacobi must be a finite number, got {jacobi!r}")
        u = np.asarray(x, dtype=float).reshape(-1)
        v = np.asarray(px, dtype=float).reshape(-1)
        for g, name in ((u, "x"), (v, "px")):
            if g.size == 0 or not np.isfinite(g).all():
                raise ValueError(f"{name} must be a non-empty array of finite values")
        U, V = np.meshgrid(u, v)
        X = np.zeros(U.shape + (4,))
        X[..., 0], X[..., 2] = U, V
        energy = -0.5 * float(jacobi)
        X[..., 3] = self.momentum_from_energy(X, energy, 1)
        mask = np.isfinite(X[..., 3])
        return SectionGrid(states=np.ascontiguousarray(X[mask]), mask=mask, u=u, v=v, axes=(0, 2),
                           plane=1, value=0.0, energy=energy)


def _arenstorf():
    model = CR3BP(ARENSTORF_MU)
    # HNW eq. (0.1): y1 = 0.994, y1' = 0, y2 = 0, y2' = −2.0015851063790825…
    return model, model.state([0.994, 0.0], [0.0, -2.00158510637908252240537862224])


def _on_section(mu, jacobi, x):
    """A state on y = 0 with p_x = 0 (a turning point of x) and ẏ > 0 at
    Jacobi constant C."""
    model = CR3BP(mu)
    return model, model.section_grid(jacobi, [x], [0.0]).states[0]


#: Named orbits: name → (builder, description); :func:`cr3bp_orbit`.
CR3BP_ORBITS = {
    "arenstorf": (_arenstorf, "Arenstorf's periodic orbit, μ = 0.012277471, period "
                              "17.0652165601579625588917206249 (Hairer, Nørsett & Wanner, "
                              "Sect. II.0, Fig. 0.1); it passes close to the Moon, so a "
                              "fixed step must be small (~1e-4)"),
    "sun-jupiter-regular": (functools.partial(_on_section, SUN_JUPITER_MU, 3.05, 0.40),
                            "μ = 0.000954, C = 3.05, x = 0.40 on y = 0 with p_x = 0: an "
                            "inner orbit whose X1 falls as ln t / t (regular)"),
    "sun-jupiter-chaotic": (functools.partial(_on_section, SUN_JUPITER_MU, 3.05, 0.55),
                            "μ = 0.000954, C = 3.05, x = 0.55 on y = 0 with p_x = 0: "
                            "chaotic, X1 ≈ 0.044 at t = 2000 (studies/hamiltonians.py)"),
    "earth-moon-regular": (functools.partial(_on_section, EARTH_MOON_MU, 3.17, 0.30),
                           "μ = 0.01215, C = 3.17 (just below C(L2) = 3.1722: the Earth, Moon "
                           "and exterior realms joined), x = 0.30 on y = 0: regular about "
                           "the Earth"),
}


def cr3bp_orbit(name):
    """(model, x0) of a named orbit of :data:`CR3BP_ORBITS`.

    Raises
    ------
    ValueError
        For an unknown name (the message lists them).
    """
    if name not in CR3BP_ORBITS:
        raise ValueError(f"unknown CR3BP orbit {name!r}; expected one of: "
                         f"{', '.join(CR3BP_ORBITS)}")
    return CR3BP_ORBITS[name][0]()

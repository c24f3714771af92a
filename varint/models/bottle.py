"""A charged particle in a magnetic bottle (a magnetic mirror).

Units: the particle's charge and mass are 1, the field at the centre B₀ and
the mirror length L set the scales. The axisymmetric field

    B_z = B₀ (1 + z²/L²),   B_r = −(r/2) ∂_z B_z,

is the curl of the vector potential A = (B_z(z)/2)(−y, x, 0) (so div B = 0
exactly), and the Hamiltonian

    H = ½ |p − A(q)|²

is non-separable and not of the solvable rotating form (B_z depends on z),
but A_x does not depend on x nor A_y on y: H splits into the potential
B_z²(x² + y²)/8 and the parts of p_x, p_y and p_z, each solvable by a
straight-line update with its exact tangent map
(:class:`~varint.models.hamiltonian.TermwiseHamiltonian`; He, Sun, Liu & Qin
2017), so ``method="tm"`` runs the explicit four-part compositions; the
general methods (Gauss–Legendre, Tao's) run it too. Besides
the energy, the canonical angular momentum p_φ = x p_y − y p_x is conserved
(the field is axisymmetric) and checked by the accuracy verdict.

A slow particle (Larmor radius ρ = v_⊥/B small against the scale of the
field) conserves the magnetic moment v_⊥²/2B adiabatically and bounces
regularly between its mirror points; a faster one that reaches the strong
field far from the centre, where bounce and gyration resonate, breaks the
adiabatic invariant and moves chaotically (Chirikov 1979).

References
----------
B. V. Chirikov, Phys. Rep. 52, 263 (1979) — the breakdown of adiabatic
invariance in magnetic traps.
T. G. Northrop, *The Adiabatic Motion of Charged Particles*, Wiley (1963).
Y. He, Y. Sun, J. Liu & H. Qin, Phys. Lett. A 381, 568 (2017) — explicit
splitting of charged-particle Hamiltonians.
"""

from __future__ import annotations

import functools
import numbers

import numpy as np

from .hamiltonian import TermwiseHamiltonian, recognise

__all__ = ["MagneticBottle", "BOTTLE_ORBITS", "bottle_orbit"]


@functools.cache
def _expression(b0, length):
    import sympy as sp

    x, y, z, px, py, pz = sp.symbols("x y z p_x p_y p_z")
    Bz = sp.Float(b0, 17) * (1 + z ** 2 / sp.Float(length, 17) ** 2)
    H = ((px + Bz * y / 2) ** 2 + (py - Bz * x / 2) ** 2 + pz ** 2) / 2
    q, p = (x, y, z), (px, py, pz)
    return H, q, p, recognise(H, q, p)


class MagneticBottle(TermwiseHamiltonian):
    """A charged particle in the magnetic bottle of the module docstring.

    Parameters
    ----------
    b0 : float, default 1
        The field at the centre, B₀ > 0.
    length : float, default 1
        The mirror length L > 0 (B doubles at z = ±L).
    escape_radius : float, optional
    """

    def __init__(self, b0: float = 1.0, length: float = 1.0,
                 escape_radius: float | None = None) -> None:
        for value, name in ((b0, "b0"), (length, "length")):
            if (isinstance(value, bool) or not isinstance(value, numbers.Real)
                    or not (np.isfinite(value) and value > 0)):
                raise ValueError(f"{name} must be a positive finite number, got {value!r}")
        self.b0, self.length = float(b0), float(length)
        H, q, p, found = _expression(self.b0, self.length)
        super().__init__(H, q, p, name=f"MagneticBottle(b0={self.b0:g}, length={self.length:g})",
                         escape_radius=escape_radius, _found=found)

    def describe(self):
        d = super().describe()
        d.update(b0=self.b0, length=self.length)
        return d

    def field_strength(self, q):
        """(B_x, B_y, B_z) at positions (..., 3)."""
        q = np.asarray(q, dtype=float)
        x, y, z = q[..., 0], q[..., 1], q[..., 2]
        L2 = self.length ** 2
        dbz = self.b0 * 2 * z / L2          # ∂_z B_z
        return np.stack([-x * dbz / 2, -y * dbz / 2, self.b0 * (1 + z * z / L2)], axis=-1)

    def angular_momentum(self, x):
        """The canonical angular momentum p_φ = x p_y − y p_x."""
        x = np.asarray(x, dtype=float)
        return x[..., 0] * x[..., 4] - x[..., 1] * x[..., 3]

    def conserved(self, x, t=0.0, p_t=0.0):
        """The energy and the canonical angular momentum p_φ."""
        return {"energy": self.hamiltonian(x), "angular_momentum": self.angular_momentum(x)}

    def state(self, position, velocity):
        """The state (q, p) of a particle at ``position`` with ``velocity``:
        p = v + A(q)."""
        r = np.asarray(position, dtype=float)
        v = np.array(velocity, dtype=float)
        bz = self.b0 * (1 + r[..., 2] ** 2 / self.length ** 2)
        v[..., 0] -= bz * r[..., 1] / 2
        v[..., 1] += bz * r[..., 0] / 2
        return np.concatenate(np.broadcast_arrays(r, v), axis=-1)


def _gyrating(speed, pitch):
    """A particle on the axis's neighbourhood, guiding centre at the origin:
    it starts at x = ρ (its Larmor radius ρ = v_⊥/B₀) with velocity of
    ``speed`` at pitch angle ``pitch`` to the field."""
    model = MagneticBottle()
    vperp, vpar = speed * np.sin(pitch), speed * np.cos(pitch)
    rho = vperp / model.b0
    return model, model.state([rho, 0.0, 0.0], [0.0, -vperp, vpar])


#: Named orbits: name → (builder, description); :func:`bottle_orbit`.
BOTTLE_ORBITS = {
    "adiabatic": (functools.partial(_gyrating, 0.1, 1.0),
                  "speed 0.1 at pitch angle 1 rad (Larmor radius 0.084 L), guiding centre "
                  "on the axis: the magnetic moment is conserved and the bounce motion is "
                  "regular (X1 falls as ln t / t)"),
    "chaotic": (functools.partial(_gyrating, 0.5, 0.4),
                "speed 0.5 at pitch angle 0.4 rad, guiding centre on the axis: it mirrors "
                "near |z| = 2.4 where B ≈ 6.6 B₀, and moves chaotically (X1 ≈ 0.15, "
                "tests/models/test_hamiltonian_models.py)"),
}


def bottle_orbit(name):
    """(model, x0) of a named orbit of :data:`BOTTLE_ORBITS`.

    Raises
    ------
    ValueError
        For an unknown name (the message lists them).
    """
    if name not in BOTTLE_ORBITS:
        raise ValueError(f"unknown magnetic bottle orbit {name!r}; expected one of: "
                         f"{', '.join(BOTTLE_ORBITS)}")
    return BOTTLE_ORBITS[name][0]()

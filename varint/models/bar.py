"""A rotating barred galaxy: a Ferrers bar, a Miyamoto–Nagai disc and a
Plummer bulge, seen from the frame that rotates with the bar.

In that frame (Binney & Tremaine 2008, Sect. 3.3.2) the Hamiltonian, the
Jacobi energy E_J, is

    H = ½ |p|² − Ω_b (x p_y − y p_x) + Φ_D + Φ_S + Φ_B,

Φ_D = −G M_D / √(x² + y² + (A + √(z² + B²))²) the disc (Miyamoto & Nagai
1975), Φ_S = −G M_S / √(r² + ε_s²) the bulge and Φ_B the Ferrers (n = 2)
bar of semi-axes a > b > c along x, y, z (Pfenniger 1984;
:mod:`varint.models.ferrers`). The defaults are the model of Skokos, Patsis
& Athanassoula (2002, Sect. 2), also that of the SALI/GALI studies of
Manos & Athanassoula (2011): G = 1, M_D = 0.82, A = 3, B = 1, M_S = 0.08,
ε_s = 0.4, M_B = 0.1, (a, b, c) = (6, 1.5, 0.6), Ω_b = 0.054 (units: 1 kpc,
a total mass of 2·10¹⁰ M_⊙ and G = 1).

H is a rotating frame's kinetic term plus a potential, so ``method="tm"``
runs the exact flow of the rotating frame and the kick of the potential
with their tangent maps (:class:`~varint.models.hamiltonian.IntegrableHamiltonian`).
Its two-part schemes without corrector run on a stepper generated for the
closed part (the rotating frame's drift), whose kicks call one compiled
kernel of the disc, bulge (:mod:`varint.models.galactic`) and bar
(:attr:`RotatingBar.extra_force`,
:class:`~varint.codegen.expressions.ExtraForce`); compositions over more
parts run through the part flows.
The bar's potential has no closed form (λ is the root of an equation and
the W_ijk are elliptic integrals), so there is no SymPy expression of H:
``method="taylor"`` refuses this model, the other methods run it.

References
----------
D. Pfenniger, Astron. Astrophys. 134, 373 (1984); M. Miyamoto &
R. Nagai, Publ. Astron. Soc. Japan 27, 533 (1975); Ch. Skokos, P. A. Patsis
& E. Athanassoula, MNRAS 333, 847 (2002); T. Manos & E. Athanassoula,
MNRAS 415, 629 (2011); Ch. Skokos, T. Bountis & Ch. Antonopoulos, Physica
D 231, 30 (2007) (GALI); J. Binney & S. Tremaine, *Galactic Dynamics*,
2nd ed., Princeton (2008).
"""

from __future__ import annotations

import dataclasses
import functools
import numbers
from functools import cache

import numpy as np
from numba import njit

from ..codegen.expressions import ExtraForce
from . import ferrers, galactic
from .ferrers import (ferrers_add_potential, ferrers_derivatives, ferrers_kick, ferrers_potential,
                      inside_table)
from .galactic import disc_bulge_force
from .hamiltonian import IntegrableHamiltonian, recognise

__all__ = ["RotatingBar", "BAR_ORBITS", "bar_orbit", "SPA02"]

#: The model of Skokos, Patsis & Athanassoula (2002): G = 1.
SPA02 = {"disc_mass": 0.82, "disc_a": 3.0, "disc_b": 1.0, "bulge_mass": 0.08,
         "bulge_radius": 0.4, "bar_mass": 0.1, "axes": (6.0, 1.5, 0.6), "omega": 0.054}


@functools.cache
def _expression(disc_mass, disc_a, disc_b, bulge_mass, bulge_radius, omega):
    """H without the bar (closed form), its coordinates and structure."""
    import sympy as sp

    x, y, z, px, py, pz = sp.symbols("x y z p_x p_y p_z")
    f = functools.partial(sp.Float, dps=17)
    disc = -f(disc_mass) / sp.sqrt(x ** 2 + y ** 2 + (f(disc_a) + sp.sqrt(z ** 2 + f(disc_b) ** 2))
                                   ** 2)
    bulge = -f(bulge_mass) / sp.sqrt(x ** 2 + y ** 2 + z ** 2 + f(bulge_radius) ** 2)
    H = (px ** 2 + py ** 2 + pz ** 2) / 2 - f(omega) * (x * py - y * px) + disc + bulge
    q, p = (x, y, z), (px, py, pz)
    return H, q, p, recognise(H, q, p)


@cache
def _with_bar(grad, grad_hess, axes2, gm, offset):
    """Kernels ``grad(y, par, g)`` and ``grad_hess(y, par, g, D)`` of a
    closed-form part plus the bar's potential; the positions are y[offset:
    offset + 3] and the bar's derivatives are added to g and D there."""
    a2 = np.array(axes2)
    inside = inside_table(a2, gm)

    @njit(error_model="numpy")
    def grad_bar(y, par, g):
        grad(y, par, g)
        ferrers_kick(y[:3], a2, gm, g[offset:offset + 3], g[:0].reshape((0, 0)), False, inside)

    @njit(error_model="numpy")
    def grad_hess_bar(y, par, g, D):
        grad_hess(y, par, g, D)
        ferrers_kick(y[:3], a2, gm, g[offset:offset + 3], D, True, inside)

    return grad_bar, grad_hess_bar


@njit(cache=True, error_model="numpy", inline="always")
def galaxy_force(q, g, D, hessian, table):
    """The whole potential's gradient (and, if ``hessian``, Hessian) at
    ``q`` added to ``g`` (and ``D``), in the argument order of a generated
    stepper's extra force (:class:`~varint.codegen.expressions.ExtraForce`):
    the disc and bulge (:func:`~varint.models.galactic.disc_bulge_force`
    of ``table[:5]``: G·M_D, A, B, G·M_S, ε_s), then the bar
    (:func:`~varint.models.ferrers.ferrers_kick` of G·M = ``table[5]``,
    semi-axes² ``table[6:9]`` and its
    :func:`~varint.models.ferrers.inside_table` ``table[9:]``). Inlined
    into the stepper, and both parts into it, the constants in one array:
    in a compiled loop over the regular orbit's positions it took 47 ns
    an evaluation, 52–56 as a call, 71 calling the bar's kernel in turn
    (bar25)."""
    disc_bulge_force(q, g, D, hessian, table[0], table[1], table[2], table[3], table[4])
    ferrers_derivatives(q, table[6:9], table[5], g, D, hessian, table[9:], False)


class RotatingBar(IntegrableHamiltonian):
    """A Ferrers bar with a disc and a bulge in the bar's rotating frame
    (module docstring). Every argument defaults to the model of Skokos,
    Patsis & Athanassoula (2002), :data:`SPA02`.

    Parameters
    ----------
    disc_mass, disc_a, disc_b : float
        G·M_D and the Miyamoto–Nagai scale lengths A, B.
    bulge_mass, bulge_radius : float
        G·M_S and the Plummer radius ε_s.
    bar_mass : float
        G·M_B of the bar.
    axes : (float, float, float)
        The bar's semi-axes a > b > c.
    omega : float
        The pattern speed Ω_b.
    escape_radius : float, optional

    Attributes
    ----------
    extra_force : ExtraForce
        The whole potential's gradient and Hessian (:func:`galaxy_force`:
        disc, bulge and bar), which a generated stepper's kicks add to its
        closed part, the rotating frame alone (:meth:`closed_symbolic`).
    """

    def __init__(self, disc_mass=0.82, disc_a=3.0, disc_b=1.0, bulge_mass=0.08,
                 bulge_radius=0.4, bar_mass=0.1, axes=(6.0, 1.5, 0.6), omega=0.054,
                 escape_radius=None):
        values = dict(disc_mass=disc_mass, disc_a=disc_a, disc_b=disc_b, bulge_mass=bulge_mass,
                      bulge_radius=bulge_radius, bar_mass=bar_mass, omega=omega)
        for name, v in values.items():
            if (isinstance(v, bool) or not isinstance(v, numbers.Real) or not np.isfinite(v)
                    or (v <= 0 if name != "omega" else False)):
                raise ValueError(f"{name} must be a {'' if name == 'omega' else 'positive '}"
                                 f"finite number, got {v!r}")
        try:
            a, b, c = (float(s) for s in axes)
        except (TypeError, ValueError):
            raise ValueError(f"axes must be three numbers a > b > c > 0, got {axes!r}") from None
        if not (a > b > c > 0) or not np.isfinite(a):
            raise ValueError(f"axes must be three numbers a > b > c > 0 (a triaxial bar), got "
                             f"{axes!r}")
        self.values = {k: float(v) for k, v in values.items()}
        self.axes = (a, b, c)
        self._axes2 = np.array([a * a, b * b, c * c])
        # The bar's constants inside (K·W at λ = 0), once: every energy
        # check of a pilot or a run evaluates the bar's potential.
        self._inside = inside_table(self._axes2, bar_mass)
        v = self.values
        H, q, p, found = _expression(v["disc_mass"], v["disc_a"], v["disc_b"], v["bulge_mass"],
                                     v["bulge_radius"], v["omega"])
        super().__init__(H, q, p, name="RotatingBar", escape_radius=escape_radius, _found=found)
        key = (tuple(self._axes2), v["bar_mass"])
        self.grad_v, self.grad_hess_v = _with_bar(self.grad_v, self.grad_hess_v, *key, 0)
        self.grad_h, self.grad_hess_h = _with_bar(self.grad_h, self.grad_hess_h, *key, 0)
        # (Its callees name the stepper too: a changed disc, bulge or bar
        # must not run a stepper numba cached with the old code inlined.)
        self.extra_force = ExtraForce(galaxy_force, (tuple(
            [v[k] for k in ("disc_mass", "disc_a", "disc_b", "bulge_mass", "bulge_radius",
                            "bar_mass")] + self._axes2.tolist() + self._inside.tolist()),),
            callees=(galactic, ferrers))

    def closed_symbolic(self):
        """The closed part of a generated stepper as
        :meth:`HamiltonianModel.symbolic` gives a model's form: the rotating
        frame's A with V = 0, the whole potential added by
        :attr:`extra_force` in one compiled kernel. (With the disc and
        bulge in V, its SymPy gradient and Hessian, simplified apart, cost
        a kick more than the hand-written ones with their shared
        subexpressions: :mod:`varint.models.galactic`.)"""
        import sympy as sp

        s = super().symbolic()
        return self._memoised("closed", lambda: dataclasses.replace(s, H=s.A, V=sp.Integer(0)))

    def bar_potential(self, q):
        """Φ_B at positions (..., 3)."""
        q = np.asarray(q, dtype=float)
        Q = np.ascontiguousarray(q.reshape(-1, 3))
        out = np.empty(len(Q))
        ferrers_potential(Q, self._axes2, self.values["bar_mass"], self._inside, out)
        return out.reshape(q.shape[:-1])

    def _energy_term(self, rows, out):
        """Φ_B added to the closed part's energies (or potentials) ``out``
        of ``rows`` (:attr:`HamiltonianModel._energy_term`): H is the
        Jacobi energy E_J, V the whole potential."""
        ferrers_add_potential(rows, self._axes2, self.values["bar_mass"], self._inside, out)

    def symbolic(self):
        """Not available: the bar's potential has no closed form."""
        raise ValueError("the Ferrers bar's potential has no closed SymPy form (λ is the root "
                         "of an equation, the W_ijk elliptic integrals); method 'taylor' cannot "
                         "build Hamilton's equations for RotatingBar; use 'tm', 'dop853' or "
                         "'cvode'")

    def momentum_from_energy(self, X, energy, index, t=0.0):
        """See :meth:`HamiltonianModel.momentum_from_energy`; the bar's
        potential enters the energy."""
        X = np.asarray(X, dtype=float)
        return super().momentum_from_energy(X, energy - self.bar_potential(X[..., :3]), index,
                                            t)

    def describe(self):
        d = super().describe()
        d.pop("hamiltonian", None)
        d.update(self.values, axes=list(self.axes))
        return d

    def state_on_x_axis(self, x, energy, z=0.0, pz=0.0):
        """The state at (x, 0, z) with p_x = 0 (a turning point of the
        planar motion) and p_y solved from E_J = ``energy`` on the branch
        ẏ ≥ 0; NaN where the energy is too low."""
        X = np.zeros(6)
        X[0], X[2], X[5] = x, z, pz
        X[4] = self.momentum_from_energy(X, energy, 1)
        return X


def _orbit(x, energy, z=0.0):
    model = RotatingBar()
    return model, model.state_on_x_axis(x, energy, z)


#: Named orbits: name → (builder, description); :func:`bar_orbit`.
BAR_ORBITS = {
    "regular": (functools.partial(_orbit, 0.5, -0.40, 0.1),
                "E_J = −0.40, started at (0.5, 0, 0.1) with p_x = 0 and ẏ > 0: "
                "quasi-periodic (X1 falls as ln t / t: 7e-4 at t = 1e4)"),
    "chaotic": (functools.partial(_orbit, 0.5, -0.28, 0.1),
                "E_J = −0.28, started at (0.5, 0, 0.1) with p_x = 0 and ẏ > 0: chaotic "
                "(X1 ≈ 0.028 at t = 1e4)"),
}


def bar_orbit(name):
    """(model, x0) of a named orbit of :data:`BAR_ORBITS`.

    Raises
    ------
    ValueError
        For an unknown name (the message lists them).
    """
    if name not in BAR_ORBITS:
        raise ValueError(f"unknown bar orbit {name!r}; expected one of: {', '.join(BAR_ORBITS)}")
    return BAR_ORBITS[name][0]()

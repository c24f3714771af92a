"""The bar model's disc and bulge written out (varint.models.galactic) and
the whole potential in one kernel (varint.models.bar.galaxy_force): against
their SymPy forms in 30 digits, finite differences Φ → ∇Φ → D²Φ, and as
the generated stepper's extra force."""

import dataclasses

import numpy as np
import pytest
import sympy as sp

from varint.models.bar import SPA02, RotatingBar, bar_orbit, galaxy_force
from varint.models.ferrers import ferrers_kick
from varint.models.galactic import disc_bulge_force

DISC = tuple(SPA02[k] for k in ("disc_mass", "disc_a", "disc_b", "bulge_mass", "bulge_radius"))


def _points():
    """Positions inside and outside the bar, on the plane z = 0, on the
    z axis and far away."""
    rng = np.random.default_rng(25)
    P = rng.uniform(-1.0, 1.0, size=(40, 3)) * np.array([8.0, 4.0, 1.5])
    P[:4, 2] = 0.0
    P[4:8, :2] = 0.0
    P[8:12] *= 20.0
    return P


def _symbolic():
    """Φ_D + Φ_S, its gradient and Hessian in SymPy (the bar model's own
    closed part, :func:`varint.models.bar._expression`)."""
    x, y, z = sp.symbols("x y z")
    M, A, B, m, eps = (sp.Rational(str(v)) for v in DISC)
    phi = (-M / sp.sqrt(x ** 2 + y ** 2 + (A + sp.sqrt(z ** 2 + B ** 2)) ** 2)
           - m / sp.sqrt(x ** 2 + y ** 2 + z ** 2 + eps ** 2))
    q = (x, y, z)
    grad = [sp.diff(phi, v) for v in q]
    return q, phi, grad, [[sp.diff(g, v) for v in q] for g in grad]


def _kernel(P, hessian=True):
    g = np.zeros((len(P), 3))
    D = np.zeros((len(P), 3, 3))
    for k, p in enumerate(P):
        disc_bulge_force(p, g[k], D[k], hessian, *DISC)
    return g, D


def test_disc_bulge_matches_30_digit_values():
    """Gradient and Hessian to a few ulps of the largest entry (measured
    ≤ 6e-16 relative at these points), against SymPy's in 30 digits."""
    q, _, grad, hess = _symbolic()
    P = _points()
    g, D = _kernel(P)
    for k, p in enumerate(P):
        subs = {v: sp.Float(repr(float(c)), 30) for v, c in zip(q, p, strict=True)}
        g_ref = np.array([float(e.evalf(30, subs=subs)) for e in grad])
        D_ref = np.array([[float(e.evalf(30, subs=subs)) for e in row] for row in hess])
        assert np.max(np.abs(g[k] - g_ref)) <= 1e-15 * np.max(np.abs(g_ref))
        assert np.max(np.abs(D[k] - D_ref)) <= 1e-15 * np.max(np.abs(D_ref))
        assert np.array_equal(D[k], D[k].T)


def test_disc_bulge_finite_differences():
    """Φ → ∇Φ and ∇Φ → D²Φ by central differences (h = 1e-5: truncation
    ~h² |Φ'''|, round-off ~ε/h)."""
    q, phi, _, _ = _symbolic()
    potential = sp.lambdify(q, phi, "math")
    h = 1e-5
    P = _points()[:12]
    g, D = _kernel(P)
    for k, p in enumerate(P):
        fd_g = np.empty(3)
        fd_D = np.empty((3, 3))
        for j in range(3):
            e = np.zeros(3)
            e[j] = h
            fd_g[j] = (potential(*(p + e)) - potential(*(p - e))) / (2 * h)
            gp, _ = _kernel((p + e)[None], hessian=False)
            gm, _ = _kernel((p - e)[None], hessian=False)
            fd_D[:, j] = (gp[0] - gm[0]) / (2 * h)
        assert np.max(np.abs(fd_g - g[k])) <= 1e-8 * np.max(np.abs(g[k]))
        assert np.max(np.abs(fd_D - D[k])) <= 1e-8 * np.max(np.abs(D[k]))


def test_galaxy_force_is_disc_bulge_then_bar_bit_for_bit():
    """The extra force adds the disc and bulge, then the bar's kick: the
    same bits as the two kernels called in turn; the gradient alone is the
    gradient of the call with the Hessian."""
    model = RotatingBar()
    table = np.array(model.extra_force.constants[0])
    for p in _points():
        g, D = np.zeros(3), np.zeros((3, 3))
        galaxy_force(p, g, D, True, table)
        g2, D2 = np.zeros(3), np.zeros((3, 3))
        disc_bulge_force(p, g2, D2, True, *DISC)
        ferrers_kick(p, model._axes2, SPA02["bar_mass"], g2, D2, True, model._inside)
        assert np.array_equal(g, g2) and np.array_equal(D, D2)
        g3 = np.zeros(3)
        galaxy_force(p, g3, np.zeros((0, 0)), False, table)
        assert np.array_equal(g3, g)


def test_galaxy_force_is_the_models_own_potential_to_round_off():
    """The model's SymPy closed part plus the bar (``grad_hess_v``, what the
    part flows run) against the extra force: the same ∇V and D²V to
    1e-15 of the largest entry (measured ≤ 5.9e-16)."""
    model = RotatingBar()
    table = np.array(model.extra_force.constants[0])
    for p in _points():
        g, D = np.zeros(3), np.zeros((3, 3))
        model.grad_hess_v(p, np.empty(0), g, D)
        g2, D2 = np.zeros(3), np.zeros((3, 3))
        galaxy_force(p, g2, D2, True, table)
        assert np.max(np.abs(g2 - g)) <= 1e-15 * np.max(np.abs(g))
        assert np.max(np.abs(D2 - D)) <= 1e-15 * np.max(np.abs(D))


def test_generated_stepper_closed_part_is_the_rotating_frame_alone():
    """The stepper's closed part has V = 0 (its A is the model's), the
    whole potential coming from the extra force, whose identity names the
    disc's and bar's code as well as its own."""
    model, _ = bar_orbit("regular")
    closed = model.closed_symbolic()
    assert closed.V == 0 and closed.H == closed.A and closed.structure == "integrable"
    assert closed.A == super(RotatingBar, model).symbolic().A
    assert model.extra_force.function is galaxy_force
    own = dataclasses.replace(model.extra_force, callees=()).identity()
    identity = model.extra_force.identity()
    assert identity.startswith(own) and len(identity[len(own):].split()) == 2


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_disc_bulge_propagates_non_finite_positions(bad):
    """A non-finite position gives a non-finite gradient, which the
    stepper's check catches (no exception inside the kernel)."""
    g, D = _kernel(np.array([[bad, 0.0, 0.0]]))
    assert not np.all(np.isfinite(g))

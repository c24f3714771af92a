"""The restricted three-body problem, the Ferrers bar and the magnetic
bottle: published values, laws from theory, and conserved quantities."""

import itertools

import mpmath
import numpy as np
import pytest
from scipy.special import elliprd, elliprf

from tests.flows.steppers import gauss_steps, taylor_reference
from varint.methods.parts import parts_steps
from varint.models.bar import RotatingBar, bar_orbit
from varint.models.bottle import MagneticBottle, bottle_orbit
from varint.models.cr3bp import (ARENSTORF_PERIOD, CR3BP, EARTH_MOON_MU, cr3bp_orbit)
from varint.models.ferrers import (W_ORDER, carlson_rf_rd, ferrers_grad_hess, ferrers_kick,
                                   ferrers_lambda, ferrers_w, inside_table)


# -- the restricted three-body problem --------------------------------------------------
def test_lagrange_points_and_their_jacobi_constants():
    """∇Ω = 0 at the five points; their Jacobi constants are those of the
    Earth–Moon system in Koon, Lo, Marsden & Ross (2011), Sect. 2.4 (3.1883,
    3.1722, 3.0121, 2.9880), and C(L4) = 3 − μ(1 − μ) exactly."""
    m = CR3BP(EARTH_MOON_MU)
    points = m.lagrange_points()
    for x, y in points.values():
        g = m.gradient_h(m.state([x, y], [0.0, 0.0]))
        assert np.abs(g).max() < 1e-12       # at rest at an equilibrium: ẋ = J∇H = 0
    C = {k: float(m.jacobi_at(*v)) for k, v in points.items()}
    for name, published in (("L1", 3.1883), ("L2", 3.1722), ("L3", 3.0121), ("L4", 2.9880)):
        assert C[name] == pytest.approx(published, abs=5e-5)
    mu = EARTH_MOON_MU
    assert C["L4"] == pytest.approx(3 - mu * (1 - mu), rel=1e-15)
    assert C["L5"] == C["L4"]


def test_jacobi_constant_and_velocities():
    m = CR3BP(0.1)
    r, v = np.array([0.3, -0.2]), np.array([0.1, 0.4])
    x = m.state(r, v)
    assert np.allclose(m.velocity(x), v, rtol=0, atol=1e-16)
    assert m.jacobi(x) == pytest.approx(m.jacobi_at(*r) - v @ v, rel=1e-15)
    assert m.conserved(x)["jacobi"] == pytest.approx(-2 * m.energy(x), rel=1e-15)
    with pytest.raises(ValueError, match=r"mu must be a mass ratio in \(0, 1/2\]"):
        CR3BP(0.7)


def test_section_grid_masks_the_forbidden_region():
    m = CR3BP(EARTH_MOON_MU)
    g = m.section_grid(3.17, np.linspace(-1.5, 1.5, 31), np.linspace(-0.5, 0.5, 5))
    assert 0 < g.mask.sum() < g.mask.size
    assert np.abs(m.jacobi(g.states) - 3.17).max() < 1e-13
    assert (m.velocity(g.states)[:, 1] >= 0).all()
    # Points at rest (p_x = 0 row) in the forbidden region are exactly those masked.
    row = g.mask[2]
    assert np.array_equal(~row, m.forbidden(g.u, 0.0, 3.17))


def test_arenstorf_orbit_closes_after_its_published_period():
    """Arenstorf's orbit returns to its initial state after T =
    17.0652165601579625588917206249 (Hairer, Nørsett & Wanner, Sect. II.0,
    eq. 0.1, Fig. 0.1): to 1e-9 with the Taylor reference, and to the
    scheme's error with the TM stepper (ABA864, fixed step T/40000) and with
    Gauss–Legendre (GL8, T/20000)."""
    model, x0 = cr3bp_orbit("arenstorf")
    assert np.abs(taylor_reference(model, x0, ARENSTORF_PERIOD) - x0).max() < 1e-9
    x, _ = parts_steps(model, x0, None, ARENSTORF_PERIOD / 40000, 40000, "ABA864")
    assert np.abs(x - x0).max() < 1e-3
    x, _ = gauss_steps(model, x0, None, ARENSTORF_PERIOD / 20000, 20000, "GL8")
    assert np.abs(x - x0).max() < 1e-6


# -- the Ferrers bar -----------------------------------------------------------------------
def test_carlson_integrals_against_scipy():
    """One duplication sequence gives R_F(x, y, z), R_D(y, z, x) and
    R_D(z, x, y) to 8e-16 of SciPy's (as each integral's own duplication
    did), over twelve decades of arguments."""
    rng = np.random.default_rng(5)
    args = np.concatenate([rng.uniform(1e-3, 100.0, (300, 3)), 10 ** rng.uniform(-6, 6, (300, 3))])
    for x, y, z in args:
        rf, rd_x, rd_y = carlson_rf_rd(x, y, z)
        assert rf == pytest.approx(elliprf(x, y, z), rel=8e-16)
        assert rd_x == pytest.approx(elliprd(y, z, x), rel=8e-16)
        assert rd_y == pytest.approx(elliprd(z, x, y), rel=8e-16)


_AXES2 = np.array([36.0, 2.25, 0.36])


def _bar(q, axes2=_AXES2, gm=0.1):
    g, D = np.zeros(3), np.zeros((3, 3))
    phi = ferrers_grad_hess(np.asarray(q, float), axes2, gm, g, D, True, inside_table(axes2, gm))
    return phi, g, D


@pytest.mark.parametrize("q", [[1.0, 0.5, 0.2], [5.0, 1.4, 0.3], [7.0, 2.0, 1.0],
                               [0.3, 4.0, -2.0], [-20.0, 15.0, 9.0], [-3.0, 0.8, -0.25]])
def test_ferrers_potential_obeys_poisson_and_is_differentiated_exactly(q):
    """∇²Φ = 4πGρ with ρ = ρ_c(1 − m²)² inside and 0 outside (to 1e-16), and
    the gradient and Hessian equal central differences of Φ and ∇Φ."""
    q = np.asarray(q, float)
    a2 = np.array([36.0, 2.25, 0.36])
    phi, g, D = _bar(q)
    m2 = (q ** 2 / a2).sum()
    rho = 105 * 0.1 / (32 * np.pi * 6 * 1.5 * 0.6) * max(0.0, 1 - m2) ** 2
    assert abs(np.trace(D) - 4 * np.pi * rho) < 1e-15
    # Far out the W_ijk from partial fractions carry ~1e-12 of rounding
    # ((λ/(b² − c²))² ε), so the difference step grows with the distance.
    far = np.linalg.norm(q) > 10
    e = 1e-5 * (10 if far else 1)
    tol = 1e-6 if far else 1e-8
    fd_g = [(_bar(q + e * u)[0] - _bar(q - e * u)[0]) / (2 * e) for u in np.eye(3)]
    fd_D = [(_bar(q + e * u)[1] - _bar(q - e * u)[1]) / (2 * e) for u in np.eye(3)]
    assert np.abs(g - fd_g).max() < tol * np.abs(g).max()
    assert np.abs(D - np.array(fd_D)).max() < 10 * tol * np.abs(D).max()


def test_ferrers_kick_is_grad_hess_without_the_potential():
    """The kick's kernel (no Φ) adds the very g and D of ferrers_grad_hess,
    bit for bit, inside the bar (λ = 0) and outside, with and without the
    Hessian; the gradient alone is the one of the Hessian's call."""
    rng = np.random.default_rng(3)
    points = rng.uniform(-1, 1, (200, 3)) * np.array([9.0, 3.0, 1.2])
    inside = inside_table(_AXES2, 0.1)
    assert ((points ** 2 / _AXES2).sum(1) < 1).sum() > 20
    assert ((points ** 2 / _AXES2).sum(1) > 1).sum() > 20
    for q in points:
        g0, D0 = rng.normal(size=3), rng.normal(size=(3, 3))
        g, D, gk, Dk = g0.copy(), D0.copy(), g0.copy(), D0.copy()
        ferrers_grad_hess(q, _AXES2, 0.1, g, D, True, inside)
        ferrers_kick(q, _AXES2, 0.1, gk, Dk, True, inside)
        assert np.array_equal(g, gk) and np.array_equal(D, Dk)
        gk = g0.copy()
        ferrers_kick(q, _AXES2, 0.1, gk, D0[:0, :0], False, inside)
        assert np.array_equal(g, gk)


def test_ferrers_far_field_and_continuity():
    """Far away Φ → −GM/r; across the bar's surface Φ and ∇Φ are continuous
    (the inside formula at λ = 0 meets the outside one)."""
    far = np.array([300.0, 200.0, 100.0])
    assert _bar(far)[0] * np.linalg.norm(far) / 0.1 == pytest.approx(-1.0, abs=2e-4)
    surface = np.array([6.0, 0.0, 0.0])
    inner, outer = _bar(surface * (1 - 1e-9)), _bar(surface * (1 + 1e-9))
    assert inner[0] == pytest.approx(outer[0], rel=1e-8)
    assert np.abs(inner[1] - outer[1]).max() < 1e-8


def test_rotating_bar_energy_includes_the_bar():
    m = RotatingBar()
    assert m.structure == "integrable" and m.planar["omega"] == 0.054
    x0 = m.state_on_x_axis(0.5, -0.30, 0.1)
    assert m.energy(x0) == pytest.approx(-0.30, abs=1e-14)
    assert m.hamiltonian(x0) - m.potential(x0[:3]) == pytest.approx(0.5 * x0[3:] @ x0[3:]
                                                                   - 0.054 * 0.5 * x0[4])
    with pytest.raises(ValueError, match="no closed SymPy form"):
        m.symbolic()
    with pytest.raises(ValueError, match="a > b > c > 0"):
        RotatingBar(axes=(1.0, 2.0, 0.5))


@pytest.mark.parametrize("name", ["regular", "chaotic"])
def test_bar_energy_conserved_by_the_part_stepper(name):
    """ABA864 at τ = 0.05 keeps the Jacobi energy of both named orbits to
    1e-9 over 2000 time units (bounded, symplectic)."""
    model, x0 = bar_orbit(name)
    x, _ = parts_steps(model, x0, None, 0.05, 40000, "ABA864")
    assert abs(model.energy(x) - model.energy(x0)) < 1e-9 * abs(model.energy(x0))


# -- the magnetic bottle ---------------------------------------------------------------------
def test_bottle_field_and_state():
    m = MagneticBottle(b0=2.0, length=3.0)
    q = np.array([0.3, -0.2, 1.5])
    B = m.field_strength(q)
    # div B = ∂_xB_x + ∂_yB_y + ∂_zB_z = 0 (central differences).
    e = 1e-6
    div = sum((m.field_strength(q + e * u)[i] - m.field_strength(q - e * u)[i]) / (2 * e)
              for i, u in enumerate(np.eye(3)))
    assert abs(div) < 1e-9
    assert B[2] == pytest.approx(2.0 * (1 + 1.5 ** 2 / 9.0))
    x = m.state(q, [0.1, 0.2, 0.3])
    # The velocity is ẋ = ∂H/∂p = p − A.
    assert np.allclose(m.field(x)[:3], [0.1, 0.2, 0.3], atol=1e-15)


def test_bottle_conserves_angular_momentum_and_energy():
    """Gauss–Legendre (a symplectic RK method) conserves the quadratic
    invariant p_φ = x p_y − y p_x to round-off, and the energy to its error."""
    model, x0 = bottle_orbit("chaotic")
    x, _ = gauss_steps(model, x0, None, 0.02, 5000, "GL6")
    assert abs(model.angular_momentum(x) - model.angular_momentum(x0)) < 1e-14
    assert abs(model.energy(x) / model.energy(x0) - 1) < 1e-10


def test_registered_for_the_command_line():
    """The registry builds the three systems with their parameters; its
    default μ is the module's Sun–Jupiter value."""
    from varint.models.cr3bp import SUN_JUPITER_MU
    from varint.models.registry import MODELS

    assert MODELS["cr3bp"].defaults()["mu"] == SUN_JUPITER_MU
    assert MODELS["cr3bp"].build(mu=0.01).mu == 0.01
    assert MODELS["rotating-bar"].build(omega=0.05).planar["omega"] == pytest.approx(0.05)
    bottle = MODELS["magnetic-bottle"].build(b0=2.0)
    assert bottle.n_dof == 3


def _w_tables(W):
    """The symmetric W_i, W_ij, W_ijk tables of the 20 distinct index
    symbols ``W`` (:data:`W_ORDER`), and W."""
    tables = (np.empty(3), np.empty((3, 3)), np.empty((3, 3, 3)))
    for name, value in zip(W_ORDER[1:], W[1:], strict=True):
        for index in set(itertools.permutations(int(c) for c in name)):
            tables[len(name) - 1][index] = value
    return (W[0],) + tables


def _index_sums(X, q, W, K):
    """Φ, ∇Φ and D²Φ by the sums over i, j, k of the W tables as the module
    docstring writes them (Pfenniger 1984, eq. 3), in the arithmetic of X,
    q, W and K (floats or mpmath numbers)."""
    W0, W1, W2, W3 = W
    r = range(3)
    F = (W0 - 3 * sum(X[i] * W1[i] for i in r) + 3 * sum(X[i] * X[j] * W2[i][j] for i in r for j in r)
         - sum(X[i] * X[j] * X[k] * W3[i][j][k] for i in r for j in r for k in r))
    Fi = [-3 * W1[i] + 6 * sum(X[j] * W2[i][j] for j in r)
          - 3 * sum(X[j] * X[k] * W3[i][j][k] for j in r for k in r) for i in r]
    Fij = [[6 * W2[i][j] - 6 * sum(X[k] * W3[i][j][k] for k in r) for j in r] for i in r]
    return (-K * F, [-2 * K * q[i] * Fi[i] for i in r],
            [[-K * (4 * q[i] * q[j] * Fij[i][j] + (2 * Fi[i] if i == j else 0)) for j in r]
             for i in r])


def _index_loops(q, axes2, gm):
    """:func:`_index_sums` of the compiled λ and W, in NumPy: the formula the
    polynomials replace."""
    X = q * q
    W0, W1, W2, W3 = _w_tables(ferrers_w(ferrers_lambda(X, axes2), axes2))
    phi, g, D = _index_sums(X, q, (W0, W1, W2, W3), 35 / 32 * gm)
    return phi, np.array(g), np.array(D)


def test_polynomials_are_the_index_sums():
    """The polynomials in X (inside from the bar's table, outside from λ's
    W) give Φ, ∇Φ and D²Φ of the sums over the W tables to 1e-13 of each
    one's largest entry, at 400 points inside and outside the bar and for
    a second bar's axes and mass."""
    rng = np.random.default_rng(11)
    for axes2, gm in ((_AXES2, 0.1), (np.array([16.0, 4.0, 0.25]), 0.7)):
        table = inside_table(axes2, gm)
        points = rng.uniform(-1, 1, (400, 3)) * 1.3 * np.sqrt(axes2)
        inside = (points ** 2 / axes2).sum(1) < 1
        assert 60 < inside.sum() < 340
        for q in points:
            g, D = np.zeros(3), np.zeros((3, 3))
            phi = ferrers_grad_hess(q, axes2, gm, g, D, True, table)
            phi0, g0, D0 = _index_loops(q, axes2, gm)
            assert abs(phi - phi0) <= 1e-13 * abs(phi0)
            assert np.abs(g - g0).max() <= 1e-13 * np.abs(g0).max()
            assert np.abs(D - D0).max() <= 1e-13 * np.abs(D0).max()
            assert np.array_equal(D, D.T)


def _exact(q, axes2, gm):
    with mpmath.workdps(40):
        return _exact_here(q, axes2, gm)


def _exact_here(q, axes2, gm):
    """λ, the W and Φ, ∇Φ, D²Φ at 40 digits (mpmath): λ by a bracketing
    root finder on Σ X_i/(a_i² + λ) = 1, W and W_i from mpmath's Carlson
    integrals, the others from the module docstring's identities (exact
    relations: at 40 digits their cancellation far out leaves ~30)."""
    q = [mpmath.mpf(float(v)) for v in q]
    A = [mpmath.mpf(float(v)) for v in axes2]
    X = [v * v for v in q]
    lam = mpmath.mpf(0)
    if sum(X[i] / A[i] for i in range(3)) > 1:
        lam = mpmath.findroot(lambda u: sum(X[i] / (A[i] + u) for i in range(3)) - 1,
                              (mpmath.mpf(0), sum(X)), solver="anderson")
    al = [a + lam for a in A]
    delta = mpmath.sqrt(al[0] * al[1] * al[2])
    W1 = [2 * mpmath.elliprd(al[(i + 1) % 3], al[(i + 2) % 3], al[i]) / 3 for i in range(3)]
    W2 = [[(W1[i] - W1[j]) / (A[j] - A[i]) if i != j else None for j in range(3)]
          for i in range(3)]
    for i in range(3):
        W2[i][i] = (2 / (delta * al[i]) - sum(W2[i][j] for j in range(3) if j != i)) / 3
    W3 = [[[None] * 3 for _ in range(3)] for _ in range(3)]
    for i, j in itertools.permutations(range(3), 2):
        for k in set(itertools.permutations((i, i, j))):
            W3[k[0]][k[1]][k[2]] = (W2[i][i] - W2[i][j]) / (A[j] - A[i])
    for i, j, k in itertools.permutations(range(3)):
        W3[i][j][k] = (W2[0][1] - W2[0][2]) / (A[2] - A[1])
    for i in range(3):
        W3[i][i][i] = (2 / (delta * al[i] ** 2)
                       - sum(W3[i][i][j] for j in range(3) if j != i)) / 5
    W = (2 * mpmath.elliprf(*al), W1, W2, W3)
    return lam, W, _index_sums(X, q, W, mpmath.mpf(35) / 32 * mpmath.mpf(gm))


def _points(rng, axes2, count, scale):
    return rng.uniform(-1, 1, (count, 3)) * scale * np.sqrt(axes2)


@pytest.mark.parametrize("axes2, gm", [(_AXES2, 0.1), (np.array([16.0, 4.0, 0.25]), 0.7)])
def test_lambda_and_w_against_40_digits(axes2, gm):
    """λ (Newton's method on 1/S, stopped early: test_ferrers_lambda) to
    1e-8 of c² + λ, W and W_i to 2e-15 of
    their values, W_ij to 2e-13 and W_ijk to 2e-11 of the largest of each
    (measured 8e-14 and 9e-12; main's code 6e-14 and 4e-12: the partial
    fractions (W_i − W_j)/(a_j² − a_i²) cancel as λ grows past b² − c²) at
    150 points outside the bar to twice its axes and 30 just outside its
    surface (λ ~ 1e-6, where Newton's method on S − 1 ran to its cap of
    200 iterations), against 40-digit values."""
    rng = np.random.default_rng(17)
    points = _points(rng, axes2, 600, 2.0)
    points = points[(points ** 2 / axes2).sum(1) > 1][:150]
    surface = _points(rng, axes2, 30, 1.0)
    surface *= (1 + 1e-6) / np.sqrt((surface ** 2 / axes2).sum(1))[:, None]
    for q in np.concatenate([points, surface]):
        lam_exact, W_exact, _ = _exact(q, axes2, gm)
        lam = ferrers_lambda(q * q, axes2)
        assert lam > 0 and abs(lam - float(lam_exact)) <= 1e-8 * (axes2[2] + lam)
        # At the 40-digit λ: the W's own error, apart from λ's.
        got = _w_tables(ferrers_w(float(lam_exact), axes2))
        exact = [np.array(np.vectorize(float)(np.array(w, dtype=object)), dtype=float)
                 for w in W_exact]
        assert abs(got[0] - exact[0]) <= 2e-15 * exact[0]
        assert np.all(np.abs(got[1] - exact[1]) <= 2e-15 * exact[1])
        for k, bound in ((2, 2e-13), (3, 2e-11)):
            assert np.abs(got[k] - exact[k]).max() <= bound * np.abs(exact[k]).max()


@pytest.mark.parametrize("axes2, gm", [(_AXES2, 0.1), (np.array([16.0, 4.0, 0.25]), 0.7)])
def test_potential_derivatives_against_40_digits(axes2, gm):
    """Φ, ∇Φ and D²Φ at 300 points inside and outside the bar to 1.5 times
    its axes against the 40-digit formula: within 1e-13 of each one's
    largest entry; to 4 times the axes within 5e-12 (measured 1.2e-12 for
    D²Φ there, as main's code: the bracket's terms, ~λ^{3/2} W_ijk each,
    cancel to ~(1 − m²)³/λ^{3/2} and carry the W_ijk's rounding)."""
    rng = np.random.default_rng(23)
    table = inside_table(axes2, gm)
    for scale, count, bound in ((1.5, 300, 1e-13), (4.0, 60, 5e-12)):
        for q in _points(rng, axes2, count, scale):
            g, D = np.zeros(3), np.zeros((3, 3))
            phi = ferrers_grad_hess(q, axes2, gm, g, D, True, table)
            _, _, (phi0, g0, D0) = _exact(q, axes2, gm)
            g0 = np.array([float(v) for v in g0])
            D0 = np.array([[float(v) for v in row] for row in D0])
            assert abs(phi - float(phi0)) <= bound * abs(float(phi0))
            assert np.abs(g - g0).max() <= bound * np.abs(g0).max()
            assert np.abs(D - D0).max() <= bound * np.abs(D0).max()


def test_bar_energy_is_its_closed_part_plus_the_bar():
    """The Jacobi energy E_J and the potential of the bar model are the
    closed part's lambdified NumPy H and V (disc, bulge, rotating frame)
    plus Φ_B (ferrers_potential), bitwise, for one state and for many."""
    model, x0 = bar_orbit("chaotic")
    X = np.random.default_rng(2).uniform(-1, 1, (40, 6)) * np.array([8, 3, 1, 0.3, 0.3, 0.1])
    for x in (x0, X):
        cols = [x[..., i] for i in range(6)]
        phi = model.bar_potential(x[..., :3])
        closed_h = model._numpy_H(*cols) + np.zeros(x.shape[:-1])
        closed_v = model._numpy_V(*cols[:3]) + np.zeros(x.shape[:-1])
        assert np.array_equal(model.hamiltonian(x), closed_h + phi)
        assert np.array_equal(model.potential(x[..., :3]), closed_v + phi)

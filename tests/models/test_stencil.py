"""A new lattice is its stencil (varint.models.stencil, issue 26): a φ⁴
chain and lattice (site potential + linear coupling) and a Toda chain with
an on-site term (nonlinear bond, carried force) written in a few lines,
whose kernels, energy, densities and SymPy potential all follow — checked
against finite differences of their own energy and the energy law of a
fourth-order scheme. The built-in lattices' stencils are checked against
SymPy derivatives of their declared expressions."""

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
from numba import njit

from tests.models.test_lattices import hamiltonian_field, one_flow
from varint.models import FPUT, DisorderedKG, Potential, Stencil, StencilLattice
from varint.models import fput as fput_module
from varint.models import kg as kg_module
from varint.kernels.interval import Call
from varint.kernels.parts import PartsOrbit, PartsSetup, parts_batch
from varint.methods.parts import parts_steps
from varint.models.lattice import drift
from varint.models.stencil import A0, BOND_C, N_COEFFS, SITE_C

RNG = np.random.default_rng(20261127)


# -- φ⁴: u(q) = a q²/2 + λ q⁴/4 (c = (λ,)), bond κ r²/2 (c = (κ,)) ---------------
@njit
def phi4_force(q, a, c):
    return a * q + c[0] * q * q * q


@njit
def phi4_stiffness(q, a, c):
    return a + 3.0 * c[0] * q * q


@njit
def phi4_third(q, a, c):
    return 6.0 * c[0] * q


@njit
def spring_force(r, c):
    return c[0] * r


@njit
def spring_stiffness(r, c):
    return c[0]


@njit
def spring_third(r, c):
    return 0.0


PHI4 = Stencil(
    "phi4",
    site=Potential(phi4_force, phi4_stiffness, phi4_third,
                   terms=(lambda q, a, c: 0.5 * a * q * q + 0.25 * c[0] * q ** 4,),
                   expression=lambda q, a, c: a * q ** 2 / 2 + c[0] * q ** 4 / 4),
    bond=Potential(spring_force, spring_stiffness, spring_third,
                   terms=(lambda r, c: 0.5 * c[0] * r * r,),
                   expression=lambda r, c: c[0] * r ** 2 / 2, linear=True))


# -- Toda: φ(r) = (a/b²)(e^{br} − 1 − br) (c = (a, b)), on-site u = a q²/2 ----------
@njit
def toda_force(r, c):
    return c[0] / c[1] * (math.exp(c[1] * r) - 1.0)


@njit
def toda_stiffness(r, c):
    return c[0] * math.exp(c[1] * r)


@njit
def toda_third(r, c):
    return c[0] * c[1] * math.exp(c[1] * r)


@njit
def pin_force(q, a, c):
    return a * q


@njit
def pin_stiffness(q, a, c):
    return a


@njit
def pin_third(q, a, c):
    return 0.0


TODA = Stencil(
    "Toda",
    site=Potential(pin_force, pin_stiffness, pin_third, terms=(lambda q, a, c: 0.5 * a * q * q,),
                   expression=lambda q, a, c: a * q ** 2 / 2),
    bond=Potential(toda_force, toda_stiffness, toda_third,
                   terms=(lambda r, c: c[0] / c[1] ** 2 * (np.exp(c[1] * r) - 1.0 - c[1] * r),),
                   expression=lambda r, c: c[0] / c[1] ** 2 * (sp.exp(c[1] * r) - 1 - c[1] * r)))


def phi4(shape, boundary="fixed"):
    a = RNG.uniform(0.5, 1.5, int(np.prod(shape)))
    return StencilLattice(PHI4, shape, boundary, a=a, site_coeffs=(0.8,), bond_coeffs=(0.3,))


def toda(n, boundary="fixed"):
    return StencilLattice(TODA, n, boundary, a=0.2, bond_coeffs=(1.0, 0.7))


CASES = [("phi4 chain", lambda: phi4(7)), ("phi4 ring", lambda: phi4(7, "periodic")),
         ("phi4 2D", lambda: phi4((3, 4))), ("phi4 torus", lambda: phi4((3, 4), "periodic")),
         ("Toda chain", lambda: toda(6)), ("Toda ring", lambda: toda(6, "periodic"))]


@pytest.fixture(scope="module", params=CASES, ids=[c[0] for c in CASES])
def model(request):
    return request.param[1]()


def written_out(model, x):
    """H of the stencil written out site by site and bond by bond, from
    the geometry alone (not the package's NumPy forms)."""
    n = model.n_sites
    q, p = x[:n], x[n:]
    c = model.site_coeffs
    H = 0.5 * p @ p
    if model.stencil is PHI4:
        H += np.sum(0.5 * model.a * q * q + 0.25 * c[0] * q ** 4)
    else:
        H += np.sum(0.5 * model.a * q * q)
    nx, ny, per = model.nx, model.ny, model.boundary == "periodic"
    for i in range(nx):
        for j in range(ny):
            for di, dj in ((0, 1), (1, 0)) if model.lattice_dim == 2 else ((0, 1),):
                here = q[i * ny + j]
                ii, jj = i + di, j + dj
                if per:
                    there = q[(ii % nx) * ny + jj % ny]
                elif ii < nx and jj < ny:
                    there = q[ii * ny + jj]
                else:
                    there = 0.0
                H += bond_energy(model, there - here)
            # The wall bonds at the low edges of a fixed lattice.
            if not per and j == 0:
                H += bond_energy(model, q[i * ny] - 0.0)
            if not per and model.lattice_dim == 2 and i == 0:
                H += bond_energy(model, q[j] - 0.0)
    return H


def bond_energy(model, r):
    a, b = model.bond_coeffs[:2]
    if model.stencil is PHI4:
        return 0.5 * a * r * r
    return a / b ** 2 * (math.exp(b * r) - 1.0 - b * r)


def test_energy_is_the_stencil_written_out(model):
    x = RNG.uniform(-0.6, 0.6, model.dim)
    assert model.energy(x) == pytest.approx(written_out(model, x), rel=1e-13)
    assert np.sum(model.densities(x)) == pytest.approx(model.energy(x), rel=1e-13)


def test_kick_and_field_are_the_derivatives_of_the_energy(model):
    """The kick moves p by −h ∇V and its fused tangent map is its
    derivative; the field is J∇H: against central differences of H."""
    x = RNG.uniform(-0.6, 0.6, model.dim)
    n = model.n_sites
    field = hamiltonian_field(lambda y: written_out(model, y), x)
    h = 1e-3
    # Every flow carries one vector (the orbit does not depend on it): one
    # part stepper per stencil, k = 1, shared by its lattices.
    kicked, _ = one_flow(model, "V", h, x, np.zeros(model.dim))
    assert np.max(np.abs((kicked[n:] - x[n:]) / h - field[n:])) < 1e-7
    out = np.empty(model.dim)
    model.parts.field(x, model.params, out)
    assert np.max(np.abs(out - field)) < 1e-7
    for _ in range(2):
        v = RNG.standard_normal(model.dim)
        _, tv = one_flow(model, "V", 0.37, x, v)
        e = 1e-5
        xp, _ = one_flow(model, "V", 0.37, x + e * v, v)
        xm, _ = one_flow(model, "V", 0.37, x - e * v, v)
        fd = (xp - xm) / (2 * e)
        assert np.max(np.abs(tv - fd)) < 1e-8 * np.max(np.abs(fd))


def test_band_kernels_and_sympy_of_chains():
    """Fixed-end chains get band kernels (so every method runs them): the
    gradient and Hessian against differences of V, and the SymPy potential
    equal to V."""
    for m in (phi4(6), toda(6)):
        q = RNG.uniform(-0.5, 0.5, m.n_dof)
        e = 1e-6
        g = np.array([(m.potential(q + e * u) - m.potential(q - e * u)) / (2 * e)
                      for u in np.eye(m.n_dof)])
        assert np.max(np.abs(m.gradient(q) - g)) < 1e-8
        H = np.array([(m.gradient(q + e * u) - m.gradient(q - e * u)) / (2 * e)
                      for u in np.eye(m.n_dof)])
        assert np.max(np.abs(m.hessian(q) - H)) < 1e-7
        sym = m.symbolic()
        value = float(sym.V.subs(dict(zip(sym.q, q, strict=True))))
        assert value == pytest.approx(m.potential(q), rel=1e-12)


def test_a_stencil_runs_with_a_fourth_order_energy_law():
    """ABA864 on the stencil's kernels: the energy error falls as τ⁴ or
    faster (its order is 4; halving τ divides it by ≥ 2⁴ × 0.7): the
    largest relative error at t = 2, 4, …, 20. (The part stepper a
    lattice runs, with one vector, which the orbit does not read: the
    kernel :func:`one_flow` compiles for the Toda stencil, not one of its
    own.)"""
    m = toda(16)
    x0 = np.concatenate([RNG.uniform(-0.4, 0.4, 16), np.zeros(16)])
    e0 = m.energy(x0)
    errs = []
    for tau in (0.2, 0.1):
        x, w = x0, np.eye(m.dim)[:, :1]
        worst = 0.0
        for _ in range(10):
            x, w = parts_steps(m, x, w, tau, round(2.0 / tau), "ABA864")
            worst = max(worst, abs(m.energy(x) / e0 - 1))
        errs.append(worst)
    assert errs[0] / errs[1] > 16 * 0.7, errs


@pytest.mark.parametrize("stencil, coeffs", [(kg_module.STENCIL, ((), (4.0,))),
                                             (fput_module.STENCIL, ((), (0.25, 1.5))),
                                             (PHI4, ((0.8,), (0.3,))),
                                             (TODA, ((), (1.0, 0.7)))], ids=lambda s: getattr(
                                                 s, "name", ""))
def test_declared_derivatives_are_those_of_the_expression(stencil, coeffs):
    """Each potential's force, stiffness and third derivative (numba) are
    the SymPy derivatives of its expression, and its NumPy terms add up to
    the expression's value."""
    y, a = sp.symbols("y a")
    for pot, cs, is_site in ((stencil.site, coeffs[0], True), (stencil.bond, coeffs[1], False)):
        if pot is None:
            continue
        c = tuple(float(v) for v in cs) + (0.0,) * (N_COEFFS - len(cs))
        args = (a, tuple(sp.Float(v) for v in c)) if is_site else (tuple(sp.Float(v) for v in c),)
        u = pot.expression(y, *args)
        for yv, av in ((0.3, 1.1), (-0.7, 0.6)):
            at = {y: yv, a: av}
            num = (yv, av, c) if is_site else (yv, c)
            total = sum(t(*num) for t in pot.terms)
            assert total == pytest.approx(float(u.subs(at)), rel=1e-12, abs=1e-15)
            for order, kernel in ((1, pot.force), (2, pot.stiffness), (3, pot.third)):
                expected = float(sp.diff(u, y, order).subs(at))
                assert kernel(*num) == pytest.approx(expected, rel=1e-12, abs=1e-14), order


def test_bad_stencils_are_refused():
    with pytest.raises(ValueError, match="needs a site or a bond potential"):
        Stencil("nothing")
    with pytest.raises(ValueError, match="nonlinear bond, which runs on chains only"):
        StencilLattice(TODA, (3, 4))
    with pytest.raises(ValueError, match="at most 3 coefficients"):
        StencilLattice(PHI4, 5, site_coeffs=(1.0, 2.0, 3.0, 4.0))
    with pytest.raises(ValueError, match="must be a varint.models.stencil.Stencil"):
        StencilLattice("phi4", 5)


def test_built_in_lattices_are_their_stencils():
    """KG and FPUT are stencil lattices: their kernels are the stencil's."""
    assert DisorderedKG(8).stencil is kg_module.STENCIL
    assert FPUT(8).stencil is fput_module.STENCIL
    assert DisorderedKG(8).parts.apply is kg_module._apply


def _kick(model, h, x, W):
    """One kick of the model's part stepper on the orbit x and the columns
    of W (k vectors, a compile-time constant as in a run)."""
    parts, k = model.parts, W.shape[1]
    par, n_work = parts.params(max(parts.splits))
    x, W = x[None].copy(), W[None].copy()
    status, done = np.zeros(1, dtype=np.int64), np.zeros(1, dtype=np.int64)
    parts_batch(parts.apply, parts.field, k, False)(
        PartsOrbit(x, W, np.ones((1, k)), np.zeros((1, k), dtype=np.int64), np.empty((1, 0, 0)),
                   np.zeros((1, len(parts.names)), dtype=np.int64)),
        PartsSetup(np.array([parts.index("V")]), np.array([h]), par, n_work),
        Call(1, 0, 1.0, 0, np.inf), status, done)
    assert status[0] == 0
    return x[0], W[0]


def site_by_site_kick(model, h, x, W):
    """The chain's kick written site by site, each site's two bonds computed
    anew, in the order of the band kernels (grad, hess, band_kick_block):
    p_i −= h((u' + φ'_l) − φ'_r), δp_i = ((δp_i − c δq_i) − a_l δq_l) − a_r δq_r."""
    st, n = model.stencil, model.n_sites
    par = model.parts.params(max(model.parts.splits))[0]
    per = model.boundary == "periodic"
    cs, cb = tuple(par[SITE_C:SITE_C + 3]), tuple(par[BOND_C:BOND_C + 3])
    q, x, W = x[:n].copy(), x.copy(), W.copy()

    def bond(b):
        if per:
            return q[b % n] - q[(b - 1) % n]
        return (q[b] if b < n else 0.0) - (q[b - 1] if b >= 1 else 0.0)

    for i in range(n):
        a = par[A0 + i]
        u1 = st.site.force(q[i], a, cs) if st.site else 0.0
        u2 = st.site.stiffness(q[i], a, cs) if st.site else 0.0
        rl, rr = bond(i), bond(i + 1)
        x[n + i] -= h * ((u1 + st.bond.force(rl, cb)) - st.bond.force(rr, cb))
        kl, kr = st.bond.stiffness(rl, cb), st.bond.stiffness(rr, cb)
        c, al, ar = h * ((u2 + kl) + kr), h * (-kl), h * (-kr)
        for j in range(W.shape[1]):
            w = W[n + i, j] - c * W[i, j]
            if i >= 1 or per:
                w -= al * W[(i - 1) % n, j]
            if i < n - 1 or per:
                w -= ar * W[(i + 1) % n, j]
            W[n + i, j] = w
    return x, W


#: The chains of the bit-for-bit kick test: walls and rings, both regimes of
#: FPUT's bond (α = 0 or not), the smallest chains, a site potential.
KICK_CASES = {
    "FPU-beta": lambda: FPUT(9, 0.0, 1.5),
    "FPU-beta ring": lambda: FPUT(9, 0.0, 1.5, boundary="periodic"),
    "FPUT": lambda: FPUT(9, 0.25, 1.0), "FPUT ring": lambda: FPUT(9, 0.25, 1.0,
                                                                 boundary="periodic"),
    "FPU-beta n=2": lambda: FPUT(2, 0.0, 1.5),
    "FPUT ring n=3": lambda: FPUT(3, 0.25, 1.0, boundary="periodic"),
    "Toda chain": lambda: toda(6), "Toda ring": lambda: toda(6, "periodic")}


def kicks_differing():
    """The cases of :data:`KICK_CASES` whose kick differs from the
    site-by-site kick in any bit (two vectors: the loop over them a
    constant, as in a run)."""
    rng = np.random.default_rng(5)
    bad = []
    for name, make in KICK_CASES.items():
        model = make()
        x, W = rng.uniform(-0.6, 0.6, model.dim), rng.standard_normal((model.dim, 2))
        got, expected = _kick(model, 0.37, x, W), site_by_site_kick(model, 0.37, x, W)
        if not (np.array_equal(got[0], expected[0]) and np.array_equal(got[1], expected[1])):
            bad.append(name)
    return bad


def test_chain_kick_is_the_site_by_site_kick_bit_for_bit():
    """The kick carries each bond's φ', φ'' from one site to the next and
    takes both regimes of a branching bond (FPUT: α = 0 or not) in copies
    of its loop: the same operations on the same values as computing every
    site's bonds anew, so the same bits, walls and rings alike. Checked in
    a process of its own: in a process that first ran
    test_lattices.test_whole_steps_match_finite_differences (part steppers
    of KG and DDNLS), FPUT's kick gave other bits, on the code before this
    kick too (a state dependence of the part stepper, cause not found; the
    fingerprints of FPU-β and FPUT runs, fresh processes, are unchanged)."""
    code = "from tests.models.test_stencil import kicks_differing; print(kicks_differing())"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         cwd=Path(__file__).resolve().parents[2], timeout=900)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.strip().splitlines()[-1] == "[]"


@njit
def _drift(x, V, h, k):
    drift(x, V, h, k, x.shape[0] // 2)


@pytest.mark.parametrize("k", [1, 3])
def test_drift_is_q_plus_h_p_entry_by_entry(k):
    """The drift's loops (the orbit's row with the one vector's for k = 1,
    one loop per row otherwise) give every entry q + h·p, bit for bit."""
    n, h = 37, 0.3
    x, V = RNG.standard_normal(2 * n), RNG.standard_normal((k, 2 * n))
    got_x, got_V = x.copy(), V.copy()
    _drift(got_x, got_V, h, k)
    for row, got in ((x, got_x), *zip(V, got_V, strict=True)):
        expected = row.copy()
        expected[:n] = row[:n] + h * row[n:]
        assert np.array_equal(got, expected)

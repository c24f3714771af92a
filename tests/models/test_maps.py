"""Map models and the TM method for maps: tangent maps against finite
differences and symplecticity, the known laws of the indicators on the
standard map and on two coupled standard maps (Skokos, Bountis &
Antonopoulos 2007), chaos maps of a map's phase space, bitwise resume, and
clear refusals (OFLI, flow methods, schemes, fractional τ)."""

import numpy as np
import pytest
import sympy as sp

import varint
from varint.methods.map import MapPropagator
from varint.models import CoupledStandardMaps, StandardMap, from_map
from varint.models.maps import wrap
from tests.helpers import assert_bitwise_equal, fitted_slope

#: Two coupled standard maps with a regular orbit on a 2-torus and a chaotic
#: one (measured: X1 = 0.32 and 0.16 for the chaotic orbit, |X_i| < 2e-4 for
#: the regular one at t = 1e5).
COUPLED = (1.5, 1.5, 0.1)
REGULAR = (0.55, 0.1, 0.62, 0.2)
CHAOTIC = (0.55, 0.1, 0.005, 0.015)


def _fd_jacobian(model, x, h=1e-6):
    x = np.asarray(x, dtype=float)
    cols = []
    for e in np.eye(model.dim):
        # F without the reduction modulo the periods (central differences
        # must not straddle a cut).
        fp, fm = (np.empty(model.dim), np.empty(model.dim))
        model.iterate_kernel(x + h * e, model.params, fp)
        model.iterate_kernel(x - h * e, model.params, fm)
        cols.append((fp - fm) / (2 * h))
    return np.array(cols).T


def _omega(n, paper_order):
    """The symplectic form for (q, p) order, or (q1, p1, q2, p2, …)."""
    J = np.zeros((2 * n, 2 * n))
    for i in range(n):
        a, b = (2 * i, 2 * i + 1) if paper_order else (i, n + i)
        J[a, b], J[b, a] = 1.0, -1.0
    return J


@pytest.mark.parametrize("model,paper_order", [
    (StandardMap(1.3), False), (CoupledStandardMaps(*COUPLED), True),
    (CoupledStandardMaps(0.5, 0.05, 0.001), True)])
def test_tangent_maps_are_the_derivatives_and_symplectic(model, paper_order):
    rng = np.random.default_rng(3)
    om = _omega(model.n_dof, paper_order)
    for x in rng.uniform(-2, 2, (5, model.dim)):
        J = model.jacobian(x)
        assert np.abs(J - _fd_jacobian(model, x)).max() < 1e-8
        assert np.abs(J.T @ om @ J - om).max() < 1e-13


def test_standard_map_reduces_x_only():
    sm = StandardMap(2.0)
    x = sm.step([6.0, 10.0])
    p = 10.0 + 2.0 * np.sin(6.0)
    assert 0 <= x[0] < 2 * np.pi and np.isclose(x[0], (6.0 + p) % (2 * np.pi))
    assert x[1] == p  # the cylinder: p is not reduced
    assert np.allclose(wrap([[-0.5, 7.0]], [1.0, 0.0]), [[0.5, 7.0]])


def test_from_map_is_the_standard_map():
    x, p = sp.symbols("x p")
    p1 = p + 1.3 * sp.sin(x)
    m = from_map([x + p1, p1], [x, p], periods={x: 2 * sp.pi})
    sm = StandardMap(1.3)
    rng = np.random.default_rng(0)
    for z in rng.uniform(-3, 3, (5, 2)):
        assert np.allclose(m.step(z), sm.step(z), rtol=0, atol=1e-14)
        assert np.allclose(m.jacobian(z), sm.jacobian(z), rtol=0, atol=1e-14)
    a = varint.lyapunov_spectrum(m, [1.0, 0.5], 2000)
    b = varint.lyapunov_spectrum(sm, [1.0, 0.5], 2000)
    assert np.abs(a.exponents[-1] - b.exponents[-1]).max() < 1e-3  # chaotic: not bitwise


@pytest.mark.parametrize("exprs,coords,match", [
    ("x + p", "xp", "sequence"),
    ([sp.Symbol("x")], "x", "even number"),
    ([sp.Symbol("x") + sp.Symbol("K"), sp.Symbol("p")], "xp", "not coordinates"),
    ([sp.Abs(sp.Symbol("x")), sp.Symbol("p")], "xp", "differentiable"),
    ([sp.Symbol("x")], "xp", "image of each"),
])
def test_from_map_refuses_bad_input(exprs, coords, match):
    coords = [sp.Symbol(c) for c in coords]
    with pytest.raises(ValueError, match=match):
        from_map(exprs, coords)


def test_standard_map_x1_follows_chirikov_ln_k_over_2():
    """For K ≫ 1 the largest exponent is ln(K/2) (Chirikov 1979); measured
    here over 8 orbits of 2e5 iterations the deviation is 0.011 at K = 10
    and 0.0007 at K = 50, shrinking like 1/K² (the spread of one orbit's
    X1 at this length is ~0.002)."""
    rng = np.random.default_rng(1)
    x0 = np.column_stack([rng.uniform(0, 2 * np.pi, 8), rng.uniform(-np.pi, np.pi, 8)])
    dev = {}
    for K in (10.0, 50.0):
        r = varint.run(StandardMap(K), x0, "x1", 2e5, t_out=1)
        dev[K] = abs(r.exponents[:, -1, 0].mean() - np.log(K / 2))
    assert dev[10.0] < 0.02
    assert dev[50.0] < 0.003
    assert dev[50.0] < dev[10.0] / 4


def test_map_spectrum_pairs_and_energy_error_is_zero():
    r = varint.lyapunov_spectrum(CoupledStandardMaps(*COUPLED), CHAOTIC, 1e4)
    X = r.exponents[-1]
    assert X[0] > 0.25 and X[1] > 0.1
    # det DF = 1: the exponents sum to zero at every step; the symplectic
    # pairs X_i + X_{2N+1-i} vanish as t → ∞ (like 1/t).
    assert abs(X.sum()) < 1e-12
    assert abs(X[0] + X[3]) < 1e-3 and abs(X[1] + X[2]) < 1e-3
    assert np.array_equal(r.energy_error, np.zeros_like(r.energy_error))
    assert np.array_equal(r.t, np.round(r.t))  # t counts iterations


def test_gali_of_a_chaotic_orbit_decays_with_the_exponent_differences():
    """GALI_k ∝ exp(−[(X1−X2) + … + (X1−Xk)] t) (paper eq. 16): over each
    window before the round-off floor, the slope of ln GALI_k against the
    exponent differences of the spectrum measured over the same window (QR,
    the same orbit and initial vectors)."""
    m = CoupledStandardMaps(*COUPLED)
    T = np.arange(1, 301)
    g = varint.gali(m, CHAOTIC, 300, k=(2, 3, 4), t_out=T)
    lyap = varint.lyapunov_spectrum(m, CHAOTIC, 300, t_out=T)
    S = lyap.exponents * T[:, None]
    for k in (2, 3, 4):
        a, b = 10, int(T[np.argmax(g.gali[k] < 1e-12)])
        assert b - a >= 3
        slope = (np.log(g.gali[k][b - 1]) - np.log(g.gali[k][a - 1])) / (b - a)
        rates = (S[b - 1] - S[a - 1]) / (b - a)
        predicted = -sum(rates[0] - rates[j] for j in range(1, k))
        assert slope == pytest.approx(predicted, rel=0.02), k


def test_gali_and_sali_of_a_regular_orbit_on_a_2_torus():
    """A regular orbit of the 4D map lies on a 2-torus: GALI_2 stays
    constant, GALI_3 ∝ t⁻², GALI_4 ∝ t⁻⁴ (paper eq. 17 with s = 2); SALI
    stays away from 0 while a chaotic orbit's falls below 1e-8 at once;
    MEGNO → 2."""
    m = CoupledStandardMaps(*COUPLED)
    g = varint.gali(m, REGULAR, 1e5, k=(2, 3, 4))
    late = g.t >= 1e3
    assert abs(fitted_slope(g.t[late], g.gali[2][late])) < 0.05
    assert fitted_slope(g.t[late], g.gali[3][late]) == pytest.approx(-2, abs=0.1)
    assert fitted_slope(g.t[late], g.gali[4][late]) == pytest.approx(-4, abs=0.15)
    regular = varint.sali(m, REGULAR, 1e5)
    chaotic = varint.sali(m, CHAOTIC, 200)
    assert regular.sali[regular.t >= 100].min() > 0.1
    assert chaotic.sali[-1] < 1e-8
    assert varint.megno(m, REGULAR, 1e5).mean_megno[-1] == pytest.approx(2.0, abs=0.05)


def test_chaos_map_of_the_standard_map_separates_the_island(tmp_path):
    """K = 1.2: the fixed point (π, 0) is elliptic (|2 + K cos π| < 2), its
    island regular; (0, 0) is hyperbolic, in the chaotic sea. The map values
    do not depend on the chunking, and a checkpointed map resumes."""
    sm = StandardMap(1.2)
    grid = varint.phase_grid(sm, np.linspace(0, 2 * np.pi, 8, endpoint=False),
                             np.linspace(-np.pi, np.pi, 6, endpoint=False))
    a = varint.chaos_map(sm, grid, "sali", t_end=2000, chunk_size=7)
    b = varint.chaos_map(sm, grid, "sali", t_end=2000, chunk_size=48,
                         checkpoint=tmp_path / "m")
    assert np.array_equal(a.values, b.values, equal_nan=True)
    assert a.image().shape == (6, 8)
    x1 = varint.chaos_map(sm, np.array([[np.pi + 0.1, 0.0], [0.01, 0.0]]), "x1", t_end=2e4)
    assert x1.values[0] < 0.01 < 0.05 < x1.values[1]


def test_a_map_run_resumes_bitwise(tmp_path, monkeypatch):
    m = CoupledStandardMaps(*COUPLED)

    def run(**kw):
        return varint.run(m, CHAOTIC, "megno", 5000, **kw)

    reference = run()
    original = MapPropagator.advance
    calls = []

    def crashing(self, state, n):
        original(self, state, n)
        calls.append(n)
        if len(calls) == 3:
            raise KeyboardInterrupt

    path = tmp_path / "m.ckpt"
    with monkeypatch.context() as patch:
        patch.setattr(MapPropagator, "advance", crashing)
        with pytest.raises(KeyboardInterrupt):
            run(checkpoint=path, checkpoint_interval=0)
    assert_bitwise_equal(run(checkpoint=path, checkpoint_interval=0), reference)
    assert np.isnan(reference.ofli).all()  # a map has no flow


def test_maps_refuse_what_needs_a_flow():
    sm = StandardMap(1.0)
    with pytest.raises(ValueError, match="OFLI needs the flow"):
        varint.run(sm, [1.0, 0.0], "ofli", 100)
    with pytest.raises(ValueError, match="maps take: tm, two-particle"):
        varint.lyapunov_spectrum(sm, [1.0, 0.0], 100, method="dop853")
    with pytest.raises(ValueError, match="no splitting scheme"):
        varint.lyapunov_spectrum(sm, [1.0, 0.0], 100, scheme="SBAB2C")
    with pytest.raises(ValueError, match="whole iterations"):
        varint.lyapunov_spectrum(sm, [1.0, 0.0], 100, tau=0.5)


def test_tau_of_several_iterations_renormalises_less_often():
    m = CoupledStandardMaps(*COUPLED)
    one = varint.lyapunov_spectrum(m, CHAOTIC, 600, t_out=[600])
    three = varint.lyapunov_spectrum(m, CHAOTIC, 600, tau=3, t_out=[600])
    assert three.provenance.counts["steps"] == 200
    assert three.provenance.counts["map_evaluations"] == 600
    assert np.abs(one.exponents[-1] - three.exponents[-1]).max() < 1e-10

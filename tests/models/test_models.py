"""Model kernels against finite differences of the potential, against the
paper's explicit formulas, and the paper's orbits."""

import numpy as np
import pytest

import varint
from varint.models import FPUBeta, HenonHeiles, ThreeDof
from tests.naive import fd_gradient, fd_jacobian

MODELS = [HenonHeiles(), ThreeDof(), FPUBeta(6, 1.5)]
IDS = ["HenonHeiles", "ThreeDof", "FPU6"]


def _points(model, n=3, seed=1):
    return np.random.default_rng(seed).uniform(-0.4, 0.4, (n, model.n_dof))


@pytest.mark.parametrize("model", MODELS, ids=IDS)
def test_gradient_hessian_third_match_finite_differences(model):
    for q in _points(model):
        scale = 1 + np.abs(model.gradient(q)).max()
        assert np.allclose(model.gradient(q), fd_gradient(model.potential, q), atol=1e-8 * scale)
        H = model.hessian(q)
        assert np.allclose(H, H.T)
        assert np.allclose(H, fd_jacobian(model.gradient, q), atol=1e-8 * (1 + np.abs(H).max()))
        # Σ_k v_k D²(∂_k V) is the derivative of D²V along v.
        v = np.random.default_rng(2).standard_normal(model.n_dof)
        T = varint.kernels.banded.band_to_dense(model.third_band(q, v))
        fd = (model.hessian(q + 1e-5 * v) - model.hessian(q - 1e-5 * v)) / 2e-5
        assert np.allclose(T, fd, atol=1e-7 * (1 + np.abs(T).max()))


@pytest.mark.parametrize("model", MODELS, ids=IDS)
def test_corrector_terms_match_finite_differences(model):
    """∇C and D²C of C = ∇Vᵀ M⁻¹ ∇V (paper eq. 26, with the mass)."""
    for q in _points(model):
        gc = model.corrector_gradient(q)
        assert np.allclose(gc, fd_gradient(model.corrector, q), atol=1e-7 * (1 + np.abs(gc).max()))
        HC = model.corrector_hessian(q)
        fd = fd_jacobian(model.corrector_gradient, q)
        assert np.allclose(HC, fd, atol=1e-7 * (1 + np.abs(HC).max()))


def test_henon_heiles_corrector_equals_paper_appendix():
    """C, ∇C and D²C of Hénon–Heiles are the paper's eqs. (A.7), (A.8), (A.23)."""
    m = HenonHeiles()
    for x, y in _points(m):
        q = np.array([x, y])
        assert np.isclose(m.corrector(q), (x + 2 * x * y) ** 2 + (x * x - y * y + y) ** 2)
        assert np.allclose(m.corrector_gradient(q), [
            2 * x * (1 + 2 * x * x + 6 * y + 2 * y * y),
            2 * (y - 3 * y * y + 2 * y ** 3 + 3 * x * x + 2 * x * x * y)])
        assert np.allclose(m.corrector_hessian(q), 2 * np.array([
            [1 + 6 * x * x + 2 * y * y + 6 * y, 2 * x * (3 + 2 * y)],
            [2 * x * (3 + 2 * y), 1 + 2 * x * x + 6 * y * y - 6 * y]]))


def test_fpu_hessian_products_match_dense_finite_difference_hessian():
    m = FPUBeta(7, 1.5)
    q = _points(m, 1)[0]
    H_fd = np.empty((7, 7))
    for i in range(7):
        for j in range(7):
            ei, ej = np.eye(7)[i] * 1e-4, np.eye(7)[j] * 1e-4
            H_fd[i, j] = (m.potential(q + ei + ej) - m.potential(q + ei - ej)
                          - m.potential(q - ei + ej) + m.potential(q - ei - ej)) / 4e-8
    W = np.random.default_rng(3).standard_normal((7, 3))
    assert np.allclose(m.hvp(q, W), H_fd @ W, atol=1e-6)
    assert m.hessian_band(q).shape == (2, 7)  # tridiagonal: never an n×n matrix


def test_fpu_is_matrix_free_at_n_4096():
    m = FPUBeta(4096, 1.5)
    rng = np.random.default_rng(4)
    q, w = rng.uniform(-0.1, 0.1, 4096), rng.standard_normal(4096)
    fd = (m.gradient(q + 1e-6 * w) - m.gradient(q - 1e-6 * w)) / 2e-6
    assert np.allclose(m.hvp(q, w), fd, atol=1e-6)
    r = varint.lyapunov_spectrum(m, np.concatenate([q, np.zeros(4096)]), 1.0, tau=0.05,
                                 n_exponents=2, t_out=1)
    assert np.isfinite(r.exponents).all()


def test_three_dof_uses_the_paper_inverse_mass():
    m = ThreeDof()
    assert np.allclose(m.inverse_mass, [1, np.sqrt(2), np.sqrt(3)])
    x = np.array([0.1, -0.2, 0.05, 0.3, 0.1, -0.2])
    q, p = x[:3], x[3:]
    H3 = (0.5 * (q[0] ** 2 + p[0] ** 2) + np.sqrt(2) / 2 * (q[1] ** 2 + p[1] ** 2)
          + np.sqrt(3) / 2 * (q[2] ** 2 + p[2] ** 2) + q[0] ** 2 * q[1] + q[0] ** 2 * q[2])
    assert np.isclose(m.energy(x), H3)  # paper eq. (55)


@pytest.mark.parametrize("name,px", [("R1", 0.2334), ("C1", 0.4208), ("C2", 0.11879)])
def test_paper_orbits_solve_px_from_the_energy(name, px):
    model, x0 = varint.paper_orbit(name)
    assert np.isclose(model.energy(x0), 0.125, rtol=1e-14)
    assert round(x0[2], len(str(px)) - 2) == px


def test_paper_orbits_r2_r3():
    model, x0 = varint.paper_orbit("r2")
    assert isinstance(model, ThreeDof) and np.allclose(x0, [0, 0, 0, 0.1, 0.347, 0])
    model, x0 = varint.paper_orbit("R3")
    assert isinstance(model, FPUBeta) and model.n_dof == 8 and model.beta == 1.5
    assert np.allclose(x0[:8], 0.1) and np.allclose(x0[8:], 0)


def test_no_real_momentum_is_an_error():
    with pytest.raises(ValueError, match="no real momentum p\\[0\\] gives energy 0.01"):
        varint.solve_momentum(HenonHeiles(), [0.0, 0.558], [0.0, 0.0], 0.01)
    with pytest.raises(ValueError, match="unknown paper orbit 'R9'.*R1, C1, C2, R2, R3"):
        varint.paper_orbit("R9")


@pytest.mark.parametrize("minv,match", [([1.0, -1.0], "positive"), ([1.0], "shape"),
                                        ([np.nan, 1.0], "positive and finite")])
def test_bad_inverse_mass(minv, match):
    m = HenonHeiles()
    with pytest.raises(ValueError, match=match):
        varint.models.Model(2, m.potential, m.grad_kernel, m.hess_kernel, m.third_kernel, 1,
                            inverse_mass=minv)


def test_henon_heiles_compiled_v_is_its_numpy_v_bit_for_bit():
    # potential_rows (a prepared run's short call measures V with it) must
    # round as the NumPy V of every other path: over wide scales, through
    # overflow, and at signed zeros, infinities and NaN.
    model = HenonHeiles()
    if model.potential_rows is None:
        pytest.skip("NumPy's power is SVML's on this CPU (AVX-512): no compiled V")
    rng = np.random.default_rng(5)
    states = np.concatenate([rng.standard_normal((20_000, 4)) * scale
                             for scale in (1e-8, 1e-3, 0.3, 1.0, 1e3, 1e100, 1e160)])
    special = np.array([0.0, -0.0, np.inf, -np.inf, np.nan, 1e308, -1e-310, 1.0])
    pairs = np.array(np.meshgrid(special, special)).reshape(2, -1).T
    states = np.concatenate([states, np.hstack([pairs, pairs])])
    with np.errstate(all="ignore"):
        expected = model.potential(states[:, :2])
    got = model.potential_rows(states)
    assert got.dtype == np.float64 and got.shape == expected.shape
    # Bit for bit, NaNs included.
    np.testing.assert_array_equal(got.view(np.int64), expected.view(np.int64))

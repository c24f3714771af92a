"""The compiled right-hand side of orbit + deviation vectors against the
equations written out with the model's dense gradient and Hessian."""

import numpy as np
import pytest

from varint.baselines.rhs import pack, tangent_jacobian, tangent_rhs, unpack
from varint.models import FPUBeta, HenonHeiles, ThreeDof


@pytest.mark.parametrize("model", [HenonHeiles(), ThreeDof(), FPUBeta(6, 1.5)],
                         ids=["HenonHeiles", "ThreeDof", "FPU6"])
@pytest.mark.parametrize("k", [0, 1, 3])
def test_rhs_is_hamiltons_equations_and_their_linearisation(model, k):
    """q̇ = M⁻¹p, ṗ = −∇V, δq̇ = M⁻¹δp, δṗ = −D²V δq (paper eqs. 6, 7)."""
    rhs, fun = tangent_rhs(model)
    n, d = model.n_dof, model.dim
    rng = np.random.default_rng(k)
    x = rng.uniform(-0.5, 0.5, d)
    W = rng.standard_normal((d, k))
    y = pack(x, W)
    y.flags.writeable = False  # as SUNDIALS passes it
    yp = np.empty_like(y)
    rhs(0.0, y, yp)
    q, p = x[:n], x[n:]
    H = model.hessian(q)
    minv = model.inverse_mass
    expected_x = np.concatenate([minv * p, -model.gradient(q)])
    expected_W = np.concatenate([minv[:, None] * W[n:], -H @ W[:n]])
    xdot, Wdot = unpack(yp, d)
    assert np.allclose(xdot, expected_x, rtol=1e-14, atol=1e-15)
    assert np.allclose(Wdot, expected_W, rtol=1e-13, atol=1e-14)
    assert np.array_equal(fun(0.0, y), yp)


def test_rhs_is_shared_by_models_with_the_same_kernels():
    assert tangent_rhs(HenonHeiles())[0] is tangent_rhs(HenonHeiles())[0]
    assert tangent_rhs(FPUBeta(6, 1.5))[0] is not tangent_rhs(FPUBeta(6, 1.0))[0]


@pytest.mark.parametrize("model", [HenonHeiles(), ThreeDof(), FPUBeta(6, 1.5)],
                         ids=["HenonHeiles", "ThreeDof", "FPU6"])
@pytest.mark.parametrize("k", [0, 1, 3])
def test_the_jacobian_is_the_derivative_of_the_right_hand_side(model, k):
    """J = ∂ẏ/∂y against central differences of the same right-hand side
    (error O(h²) ≈ 1e-10 relative at h = 1e-5), and J·v without J equal to
    the dense product."""
    _, fun = tangent_rhs(model)
    jac, jac_times = tangent_jacobian(model)
    rng = np.random.default_rng(10 + k)
    y = pack(rng.uniform(-0.5, 0.5, model.dim), rng.standard_normal((model.dim, k)))
    y.flags.writeable = False
    size = y.size
    J = np.empty((size, size))
    jac(0.0, y, fun(0.0, y), J)
    h = 1e-5
    J_fd = np.empty((size, size))
    for c in range(size):
        e = np.zeros(size)
        e[c] = h
        J_fd[:, c] = (fun(0.0, y + e) - fun(0.0, y - e)) / (2 * h)
    assert np.abs(J - J_fd).max() <= 1e-8 * np.abs(J_fd).max()
    v = rng.standard_normal(size)
    Jv = np.empty(size)
    jac_times(0.0, y, fun(0.0, y), v, Jv)
    assert np.allclose(Jv, J @ v, rtol=1e-13, atol=1e-13 * np.abs(J).max())


def test_no_exact_jacobian_for_a_time_dependent_model():
    import sympy as sp

    from varint.models import from_potential

    q, t = sp.symbols("q t")
    with pytest.raises(ValueError, match="time-dependent model"):
        tangent_jacobian(from_potential(-sp.cos(q) * (1 + sp.cos(t) / 10), [q], time=t))


@pytest.mark.parametrize("model", [HenonHeiles(), ThreeDof(), FPUBeta(6, 1.5)],
                         ids=["HenonHeiles", "ThreeDof", "FPU6"])
def test_the_generated_rhs_is_the_kernels_rhs_to_rounding(model):
    """The right-hand side generated from the SymPy potential and the one
    built on the model's kernels are two implementations of eqs. 6–7: they
    agree to a few units of rounding for any k, and tangent_rhs uses the
    generated one."""
    from varint.baselines.rhs import generated_rhs, kernel_rhs

    gen, kern = generated_rhs(model), kernel_rhs(model)
    assert tangent_rhs(model) is gen
    rng = np.random.default_rng(3)
    for k in (0, 1, 3):
        y = pack(rng.uniform(-0.5, 0.5, model.dim), rng.standard_normal((model.dim, k)))
        a, b = gen[1](0.0, y), kern[1](0.0, y)
        assert np.allclose(a, b, rtol=1e-15, atol=1e-15 * np.abs(b).max())


def test_large_and_time_dependent_models_keep_the_kernel_rhs():
    import sympy as sp

    from varint.baselines.rhs import GENERATED_MAX_N, generated_rhs
    from varint.models import from_potential

    q, t = sp.symbols("q t")
    assert generated_rhs(from_potential(-sp.cos(q) * (1 + sp.cos(t) / 10), [q], time=t)) is None
    assert generated_rhs(FPUBeta(GENERATED_MAX_N + 1, 1.5)) is None


def test_a_later_process_loads_the_rhs_and_jacobian_without_compiling_or_sympy():
    """A built-in model's generated right-hand side is a signed module of
    the cache directory and its Jacobian a closure cached on disk: a new
    process (same cache) loads both, to the bit, without importing SymPy,
    deriving V again or compiling (numba's cache hits, no misses)."""
    import json
    import os
    import subprocess
    import sys
    from pathlib import Path

    from varint.baselines.rhs import generated_rhs

    model = HenonHeiles()
    rhs, fun = generated_rhs(model)
    jac = tangent_jacobian(model)[0]
    y = pack(np.array([0.1, -0.2, 0.3, 0.05]), np.eye(4)[:, :2])
    J, yp = np.empty((y.size, y.size)), np.empty_like(y)
    rhs(0.0, y, yp)
    jac(0.0, y, yp, J)
    here = [yp.view(np.int64).tolist(), fun(0.0, y).view(np.int64).tolist(),
            J.view(np.int64).ravel().tolist()]
    code = ("import json, sys, numpy as np; from varint.baselines.rhs import generated_rhs, "
            "tangent_jacobian; from varint.models import HenonHeiles; m = HenonHeiles(); "
            "rhs, fun = generated_rhs(m); jac = tangent_jacobian(m)[0]; "
            f"y = np.array({y.tolist()!r}); J = np.empty((y.size, y.size)); out = fun(0.0, y); "
            "yp = np.empty_like(y); rhs(0.0, y, yp); jac(0.0, y, out, J); "
            "print(json.dumps(['sympy' in sys.modules, rhs.py_func.__module__, "
            "[yp.view(np.int64).tolist(), out.view(np.int64).tolist(), "
            "J.view(np.int64).ravel().tolist()], "
            "[len(f.stats.cache_misses) for f in (rhs, fun, jac)], "
            "[len(f.stats.cache_hits) for f in (rhs, fun, jac)]]))")
    root = Path(__file__).resolve().parents[2]
    done = subprocess.run([sys.executable, "-c", code], env=dict(os.environ, PYTHONPATH=str(root)),
                          check=True, capture_output=True, text=True)
    sympy_loaded, module, bits, misses, hits = json.loads(done.stdout.strip().splitlines()[-1])
    assert not sympy_loaded
    assert module == rhs.py_func.__module__ and module.startswith("varint_rhs_")
    assert bits == here
    assert misses == [0, 0, 0] and all(hits)

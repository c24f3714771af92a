"""V compiled over rows, emitted from the NumPy V's expression
(:mod:`varint.models.potential_rows`): bitwise the NumPy V where it is
made, not made where NumPy could round otherwise."""

import numpy as np
import pytest
import sympy as sp

import varint
from varint.models import from_potential
from varint.models import potential_rows as rows_module
from varint.models.potential_rows import NUMPY_POWER_IS_LIBM, rows_source

x, y, z = sp.symbols("x y z")

#: Potentials whose NumPy V (SymPy's lambdify) holds only products,
#: quotients, squares, reciprocals and square roots: compiled on every CPU.
EVERY_CPU = [
    (x**2 + y**2) / 2 + x**2 * y**2,
    x**2 / 2 + sp.sqrt(2) / 2 * y**2 + sp.sqrt(3) / 2 * z**2 + x**2 * y + x**2 * z,
    1 / (1 + x**2 + y**2) + sp.sqrt(1 + (x - y)**2) + sp.Rational(1, 7) * x * y,
    sp.Integer(5) + 0 * x,
]
#: Potentials with other powers (a cube, a fourth power, r^(3/2), x^-2):
#: NumPy's power, so compiled only where it is libm's.
LIBM_ONLY = [
    (x**2 + y**2) / 2 + x**2 * y - y**3 / 3,
    x**4 / 4 + y**4 / 4 - x**2 * y**2 + (1 + x**2)**sp.Rational(3, 2),
    y**2 + x**-2,
]


def _states(n, seed):
    """Rows over wide scales, with zeros of both signs, infinities and NaN."""
    rng = np.random.default_rng(seed)
    rows = np.concatenate([rng.standard_normal((4000, 2 * n)) * scale
                           for scale in (1e-8, 1e-2, 0.7, 1.0, 1e3, 1e100, 1e160)])
    special = np.array([0.0, -0.0, np.inf, -np.inf, np.nan, 1e308, -1e-310, 1.0])
    grid = np.array(np.meshgrid(*[special] * n)).reshape(n, -1).T
    return np.ascontiguousarray(np.concatenate([rows, np.hstack([grid, grid])]))


def _assert_bitwise(model):
    """The compiled V of ``model`` is its NumPy V bit for bit (signed
    zeros too), NaN where it is NaN (a NaN's sign and payload are no value:
    an invalid operation's NaN may come out with either sign, and the short
    call leaves a non-finite V to the general path)."""
    states = _states(model.n_dof, seed=model.n_dof)
    with np.errstate(all="ignore"):
        expected = model.potential(states[:, :model.n_dof])
    got = model.potential_rows(states)
    assert got.dtype == np.float64 and got.shape == expected.shape
    nan = np.isnan(expected)
    np.testing.assert_array_equal(np.isnan(got), nan)
    np.testing.assert_array_equal(got[~nan].view(np.int64), expected[~nan].view(np.int64))


@pytest.mark.parametrize("V", EVERY_CPU, ids=str)
def test_a_generated_models_compiled_v_is_its_numpy_v_on_every_cpu(V):
    model = from_potential(V, sorted(V.free_symbols, key=str) or [x])
    assert model.potential_rows is not None
    _assert_bitwise(model)


@pytest.mark.parametrize("V", LIBM_ONLY, ids=str)
def test_other_powers_are_compiled_only_where_numpys_power_is_libms(V):
    model = from_potential(V, sorted(V.free_symbols, key=str))
    assert (model.potential_rows is not None) == NUMPY_POWER_IS_LIBM
    if model.potential_rows is None:
        pytest.skip("NumPy's power is SVML's on this CPU (AVX-512): no compiled V")
    _assert_bitwise(model)


def test_no_compiled_v_where_numpy_could_round_otherwise():
    # NumPy's sin is its own SIMD code or SVML's on some CPUs; V(q, t) is
    # not a function of the coordinates alone.
    assert from_potential(y**2 + sp.sin(x), [x, y]).potential_rows is None
    t = sp.Symbol("t")
    assert from_potential(x**2 * (1 + sp.cos(t)), [x], time=t).potential_rows is None


def test_the_compiled_copy_writes_squares_as_products_and_other_powers_as_pow(monkeypatch):
    names = ("q_0", "q_1")
    source = rows_source("q_0**2*q_1 - 1/3*q_1**3 + (q_0 - q_1)**(-1.0)", names)
    # NumPy's square and reciprocal; libm's pow with a float exponent
    # (numba's q_1 ** 3 would be products).
    if NUMPY_POWER_IS_LIBM:
        assert "q_0 * q_0 * q_1 - 1 / 3 * q_1 ** 3.0 + 1.0 / (q_0 - q_1)" in source
    # As on a CPU with AVX-512: a cube is SVML's there, a square is not.
    monkeypatch.setattr(rows_module, "NUMPY_POWER_IS_LIBM", False)
    assert rows_source("q_0**2*q_1 - 1/3*q_1**3", names) is None
    assert "(q_0 - q_1) * (q_0 - q_1)" in rows_source("(q_0 - q_1)**2 + sqrt(q_1)", names)
    # Names that are not coordinates, other functions, comparisons, huge
    # integers: refused.
    for text in ("q_0 + pi", "exp(q_0)", "q_0 < q_1", "q_0 * 2**60", "q_0**q_1", "2**q_0",
                 "q_0**0.0"):
        assert rows_source(text, names) is None, text


def test_a_generated_models_short_call_takes_its_compiled_v_bitwise():
    model = from_potential((x**2 + y**2) / 2 + x**2 * y**2, [x, y])
    x0 = np.array([0.3, 0.2, 0.1, -0.2])
    run = varint.prepare(model, "integrate", 0.2, tau=0.05)
    run(x0)
    assert run._again.short is not None and run._again.short.potential_kernel is not None
    for x1 in (x0, x0 + [1e-3, 0.0, -2e-3, 0.0]):
        got, want = run(x1), varint.integrate(model, x1, 0.2, tau=0.05)
        for key in ("state", "states", "energy_error", "t"):
            np.testing.assert_array_equal(getattr(got, key), getattr(want, key))
        assert got.accuracy.energy_error == want.accuracy.energy_error

"""V over rows, a program of the shared interpreter made from the NumPy V's
expression (:mod:`varint.models.potential_rows`): bitwise the NumPy V where
it is made, not made where NumPy could round otherwise."""

import math

import numpy as np
import pytest
import sympy as sp

import varint
from varint.models import from_potential
from varint.models import potential_rows as rows_module
from varint.models.henon_heiles import _V, HenonHeiles
from varint.models.potential_rows import NUMPY_POWER_IS_LIBM, rows_program

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
def test_other_powers_are_compiled_wholly_only_where_numpys_power_is_libms(V):
    model = from_potential(V, sorted(V.free_symbols, key=str))
    # Elsewhere compiled but for its powers (NumPyPowers, tested below).
    assert isinstance(model.potential_rows, rows_module.NumPyPowers) != NUMPY_POWER_IS_LIBM
    _assert_bitwise(model)


def test_no_compiled_v_where_numpy_could_round_otherwise():
    # NumPy's sin is its own SIMD code or SVML's on some CPUs; V(q, t) is
    # not a function of the coordinates alone.
    assert from_potential(y**2 + sp.sin(x), [x, y]).potential_rows is None
    t = sp.Symbol("t")
    assert from_potential(x**2 * (1 + sp.cos(t)), [x], time=t).potential_rows is None


def _text(expression, names, **options):
    """What the program of ``expression`` computes, as text; None where no
    program is made."""
    program = rows_program(expression, names, **options)
    return None if program is None else program.expression


def test_the_program_writes_squares_as_products_and_other_powers_as_pow(monkeypatch):
    names = ("q_0", "q_1")
    source = _text("q_0**2*q_1 - 1/3*q_1**3 + (q_0 - q_1)**(-1.0)", names)
    # NumPy's square and reciprocal; libm's pow with a float exponent
    # (numba's q_1 ** 3 would be products).
    if NUMPY_POWER_IS_LIBM:
        assert source == "q_0 * q_0 * q_1 - 1 / 3 * q_1 ** 3.0 + 1.0 / (q_0 - q_1)"
    # As on a CPU with AVX-512: a cube is SVML's there, left to NumPy; a
    # square is not.
    monkeypatch.setattr(rows_module, "NUMPY_POWER_IS_LIBM", False)
    assert _text("q_0**2*q_1 - 1/3*q_1**3", names) == "q_0 * q_0 * q_1 - 1 / 3 * _pw0"
    assert _text("(q_0 - q_1)**2 + sqrt(q_1)", names) == "(q_0 - q_1) * (q_0 - q_1) + _sqrt(q_1)"
    # Names that are not coordinates, other functions, comparisons, huge
    # integers: refused.
    for text in ("q_0 + pi", "exp(q_0)", "q_0 < q_1", "q_0 * 2**60", "q_0**q_1", "2**q_0",
                 "q_0**0.0"):
        assert rows_program(text, names) is None, text


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


def _assert_rows_bitwise(rows, numpy_v, n, seed=0):
    """``rows`` (a compiled V over rows) is ``numpy_v`` of the coordinates
    (:func:`_assert_bitwise`'s comparison) over wide scales and special
    values, and warns about nothing."""
    states = _states(n, seed=seed)
    with np.errstate(all="ignore"):
        expected = numpy_v(states[:, :n])
    with np.errstate(all="raise"):
        got = rows(states)
    assert got.dtype == np.float64 and got.shape == expected.shape
    nan = np.isnan(expected)
    np.testing.assert_array_equal(np.isnan(got), nan)
    np.testing.assert_array_equal(got[~nan].view(np.int64), expected[~nan].view(np.int64))


@pytest.mark.parametrize("V", LIBM_ONLY, ids=str)
def test_other_powers_left_to_numpy_give_the_numpy_v_bitwise(V):
    # What a CPU with AVX-512 runs (numpy_powers): the rest compiled, the
    # powers NumPy's own. Here NumPy's power is that CPU's or libm's: the
    # same ufunc the NumPy V calls, on the same doubles.
    model = from_potential(V, sorted(V.free_symbols, key=str))
    rows = rows_module.rows_from(model._numpy_V, model.n_dof, plus_zero=True,
                                 numpy_powers=True)
    assert isinstance(rows, rows_module.NumPyPowers)
    _assert_rows_bitwise(rows, model.potential, model.n_dof, seed=3)
    _assert_rows_bitwise(rows.resolved(), model.potential, model.n_dof, seed=3)
    # Where NumPy's power is libm's, the model's own compiled V is whole.
    assert isinstance(model.potential_rows, rows_module.NumPyPowers) != NUMPY_POWER_IS_LIBM


def test_henon_heiles_v_with_its_cube_left_to_numpy_is_its_numpy_v():
    rows = rows_module.rows_from(_V, 2, numpy_powers=True)
    assert rows.exponents == (3.0,)
    _assert_rows_bitwise(rows, HenonHeiles().potential, 2, seed=5)


def test_the_powers_are_numpys_whatever_it_computes(monkeypatch):
    # As on a CPU where NumPy's power is not libm's (SVML's on AVX-512): a
    # stand-in power one ulp above libm's. The compiled V must take its
    # values, not compute its own: V is then the NumPy expression over the
    # stand-in's powers.
    def power(b, e):
        return np.nextafter(np.power(b, e), np.inf)

    monkeypatch.setattr(rows_module, "_power", power)
    program = rows_program("0.5 * (x * x + y * y) + x * x * y - y ** 3 / 3.0 + (x - y) ** 4",
                           ("x", "y"), numpy_powers=True)
    assert program.exponents == (3.0, 4.0) and program.expression.endswith("_pw0 / 3.0 + _pw1")

    def expected(q):
        x, y = q[:, 0], q[:, 1]
        return 0.5 * (x * x + y * y) + x * x * y - power(y, 3) / 3.0 + power(x - y, 4)

    def v(x, y):
        return 0.5 * (x * x + y * y) + x * x * y - y ** 3 / 3.0 + (x - y) ** 4

    rows = rows_module.rows_from(v, 2, numpy_powers=True)
    _assert_rows_bitwise(rows, expected, 2, seed=7)
    # (Not libm's: the stand-in moved some finite values.)
    states = _states(2, seed=7)
    with np.errstate(all="ignore"):
        got, libm = rows(states), v(states[:, 0], states[:, 1])
    finite = np.isfinite(libm)
    assert np.any(got[finite] != libm[finite])


def test_numpy_powers_are_refused_inside_a_powers_base_and_for_names_of_powers():
    names = ("q_0", "q_1")
    assert rows_program("(1 + q_0**3)**1.5", names, numpy_powers=True) is None
    # (With libm's pow interpreted, the same expression is made.)
    assert rows_program("(1 + q_0**3)**1.5", names, numpy_powers=False) is not None
    # A square of a NumPy power is a product of it; a sqrt of one its sqrt.
    assert _text("(q_0**3)**2 + sqrt(q_1**5)", names,
                 numpy_powers=True) == "_pw0 * _pw0 + _sqrt(_pw1)"
    # An argument named as the powers.
    assert rows_program("q_0 * _pw0", ("q_0", "_pw0")) is None


class _HenonHeilesAVX512(HenonHeiles):
    """Hénon–Heiles with its V compiled as on a CPU with AVX-512."""

    @property
    def potential_rows(self):
        return rows_module.rows_from(_V, 2, numpy_powers=True)


def test_a_short_call_with_powers_left_to_numpy_is_the_one_shot_call_bitwise():
    model = _HenonHeilesAVX512()
    _, x0 = varint.paper_orbit("R1")
    run = varint.prepare(model, "integrate", 0.2, tau=0.05)
    run(x0)
    assert isinstance(run._again.short.potential_kernel, rows_module.NumPyPowers)
    for x1 in (x0, x0 + [1e-3, 0.0, -2e-3, 0.0]):
        got, want = run(x1), varint.integrate(model, x1, 0.2, tau=0.05)
        for key in ("state", "states", "energy_error", "t"):
            np.testing.assert_array_equal(getattr(got, key), getattr(want, key))
        assert got.accuracy.energy_error == want.accuracy.energy_error


def test_powers_interpreted_are_libms_pow():
    # Where NumPy's power is libm's, the program calls libm's pow (Python's
    # math.pow calls it too), whatever this CPU's NumPy does.
    rows = rows_program("q_0 ** 3 - q_1 ** (3/2) + (q_0 * q_1) ** -2.5", ("q_0", "q_1"),
                        numpy_powers=False)
    assert isinstance(rows, rows_module.Rows)
    states = _states(2, seed=11)[::7].copy()
    with np.errstate(all="raise"):
        got = rows(states)
    expected = []
    for a, b in states[:, :2].tolist():
        terms = []
        for base, e in ((a, 3.0), (b, 1.5), (a * b, -2.5)):
            try:
                terms.append(math.pow(base, e))
            except (ValueError, OverflowError, ZeroDivisionError):
                with np.errstate(all="ignore"):
                    terms.append(float(np.power(base, e)))   # (the special cases)
        expected.append(terms[0] - terms[1] + terms[2])
    expected = np.array(expected)
    nan = np.isnan(expected)
    np.testing.assert_array_equal(np.isnan(got), nan)
    np.testing.assert_array_equal(got[~nan].view(np.int64), expected[~nan].view(np.int64))


def test_arithmetic_on_constants_is_pythons_as_in_the_numpy_v():
    # Constants alone are folded by Python's rules before the program
    # runs (an exact integer product, a correctly rounded quotient, NumPy's
    # sqrt, −0.0), then meet the coordinates' doubles in the NumPy V's order.
    text = "1/3*q_0 + 2*3*q_1 - -0.0*q_0 + sqrt(2)/2*q_1 - q_0/7 + -(5/3)"
    states = _states(2, seed=13)
    with np.errstate(all="ignore"):
        expected = eval(text, {"sqrt": np.sqrt, "q_0": states[:, 0], "q_1": states[:, 1]})
        got = rows_program(text, ("q_0", "q_1"))(states)
    nan = np.isnan(expected)
    np.testing.assert_array_equal(np.isnan(got), nan)
    np.testing.assert_array_equal(got[~nan].view(np.int64), expected[~nan].view(np.int64))
    assert rows_program("q_0 * (1/0)", ("q_0",)) is None       # (the NumPy V raises)
    assert rows_program("q_0 * (99999999 * 99999999)", ("q_0",)) is None   # beyond 2^53

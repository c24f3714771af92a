"""from_potential: kernels generated from SymPy against finite differences,
the hand-written built-in kernels against their symbolic twins, bandwidth
detection, and the errors for bad input."""

import numpy as np
import pytest
import sympy as sp

import varint
from varint.cachedir import CacheDirWarning
from varint.kernels.banded import band_to_dense
from varint.models import FPUBeta, HenonHeiles, ThreeDof, from_potential
from varint.models.symbolic import SymbolicModel
from tests.naive import fd_gradient, fd_jacobian

BUILT_IN = [HenonHeiles(), ThreeDof(), FPUBeta(8, 1.5), FPUBeta(5, 0.3)]
BUILT_IN_IDS = ["HenonHeiles", "ThreeDof", "FPU8", "FPU5-beta0.3"]


def twin(model):
    s = model.symbolic()
    return from_potential(s.V, s.q, s.inverse_mass)


@pytest.mark.parametrize("model", BUILT_IN, ids=BUILT_IN_IDS)
def test_hand_written_kernels_equal_their_symbolic_twins(model):
    """Each built-in model's kernels, potential, bandwidth and masses equal
    those generated from its own symbolic() at random points."""
    sym = twin(model)
    assert sym.bandwidth == model.bandwidth
    assert np.array_equal(sym.inverse_mass, model.inverse_mass)
    rng = np.random.default_rng(3)
    for q in rng.uniform(-0.6, 0.6, (5, model.n_dof)):
        v = rng.standard_normal(model.n_dof)
        scale = 1 + np.abs(model.hessian_band(q)).max()
        assert np.allclose(sym.gradient(q), model.gradient(q), rtol=1e-14, atol=1e-15 * scale)
        assert np.allclose(sym.hessian_band(q), model.hessian_band(q), rtol=1e-14,
                           atol=1e-15 * scale)
        assert np.allclose(sym.third_band(q, v), model.third_band(q, v), rtol=1e-14,
                           atol=1e-14 * scale * np.abs(v).max())
        assert np.isclose(sym.potential(q), model.potential(q), rtol=1e-14, atol=1e-16)
    Q = rng.uniform(-0.6, 0.6, (2, 3, model.n_dof))
    assert np.allclose(sym.potential(Q), model.potential(Q), rtol=1e-14, atol=1e-16)


x, y, z = sp.symbols("x y z")
#: A dense 3-dof potential with transcendental functions and rational
#: coefficients: every kind of term the code generator has to print.
DENSE_V = sp.exp(-x) * sp.sin(y) + sp.cos(x * z) / 3 + z**4 / 4 + sp.Rational(1, 7) * x * y * z \
    + sp.sqrt(2) * y**2 + sp.log(2 + x**2)


def test_generated_kernels_match_finite_differences_of_the_potential():
    m = from_potential(DENSE_V, [x, y, z], inverse_mass=[1, 2, sp.Rational(1, 2)])
    assert m.bandwidth == 2
    f = sp.lambdify((x, y, z), DENSE_V)
    rng = np.random.default_rng(7)
    for q in rng.uniform(-1, 1, (4, 3)):
        assert np.isclose(m.potential(q), f(*q), rtol=1e-14)
        assert np.allclose(m.gradient(q), fd_gradient(m.potential, q), atol=1e-8)
        H = m.hessian(q)
        assert np.allclose(H, fd_jacobian(m.gradient, q), atol=1e-8)
        v = rng.standard_normal(3)
        T = band_to_dense(m.third_band(q, v))
        fd = (m.hessian(q + 1e-5 * v) - m.hessian(q - 1e-5 * v)) / 2e-5
        assert np.allclose(T, fd, atol=1e-7)
        # The corrector assembled by the base class from these kernels.
        assert np.allclose(m.corrector_gradient(q), fd_gradient(m.corrector, q), atol=1e-7)


@pytest.mark.parametrize("V, q, bandwidth", [
    (x**2 + y**2 + z**2, [x, y, z], 0),
    ((y - x)**2 + (z - y)**4, [x, y, z], 1),
    ((z - x)**2, [x, y, z], 2),
    (x**2 * y + y**3, [x, y], 1),
    (x**3, [x], 0),
], ids=["decoupled", "chain", "next-nearest", "HH-like", "one-dof"])
def test_bandwidth_is_read_from_the_hessian_sparsity(V, q, bandwidth):
    assert from_potential(V, q).bandwidth == bandwidth


def test_a_chain_gets_a_matrix_free_band_hessian():
    """A 12-particle chain with next-nearest-neighbour springs: bandwidth 2,
    not 11, and the band Hessian equals the dense one."""
    qs = sp.symbols("u0:12")
    V = sum((qs[i + 1] - qs[i])**4 / 4 for i in range(11)) + \
        sum((qs[i + 2] - qs[i])**2 / 2 for i in range(10))
    m = from_potential(V, qs)
    assert m.bandwidth == 2
    q = np.random.default_rng(1).uniform(-1, 1, 12)
    assert np.allclose(m.hessian(q), fd_jacobian(m.gradient, q), atol=1e-7)


def test_symbolic_model_runs_every_method_like_the_built_in(r1):
    """The generated kernels plug into the TM stepper and the baselines: on
    R1 they reproduce the hand-written model to round-off."""
    model, x0 = r1
    sym = twin(model)
    for method in ("tm", "taylor", "cvode", "dop853"):
        a = varint.lyapunov_spectrum(model, x0, 5.0, method=method, t_out=1)
        b = varint.lyapunov_spectrum(sym, x0, 5.0, method=method, t_out=1)
        assert np.allclose(a.exponents, b.exponents, rtol=1e-10, atol=1e-13)


def test_symbolic_returns_the_definition_and_describe_records_it():
    m = from_potential(x**2 * y + y**4, [x, y], inverse_mass=[1, sp.sqrt(3)], name="mine")
    s = m.symbolic()
    assert x**2 * y + y**4 == s.V and s.q == (x, y) and s.inverse_mass[1] == sp.sqrt(3)
    assert m.inverse_mass[1] == pytest.approx(np.sqrt(3), rel=1e-16)
    d = m.describe()
    assert d["name"] == "mine" and d["q"] == ["x", "y"]
    assert sp.sympify(d["potential"]) == s.V
    assert isinstance(m, SymbolicModel)


def test_generated_code_goes_to_the_cache_directory(tmp_path, monkeypatch):
    monkeypatch.setenv("VARINT_CACHE_DIR", str(tmp_path))
    m = from_potential(x**4 + x * y**2 + sp.Rational(3, 11) * y**6, [x, y])
    assert m.gradient([1.0, 1.0]).tolist() == pytest.approx([5.0, 2 + 18 / 11])
    files = list((tmp_path / "models").glob("varint_potential_*.py"))
    assert len(files) == 1 and "def third(" in files[0].read_text()


def test_an_unwritable_cache_directory_falls_back_to_a_temporary_one(tmp_path, monkeypatch):
    blocker = tmp_path / "file"
    blocker.write_text("not a directory")
    monkeypatch.setenv("VARINT_CACHE_DIR", str(blocker))
    with pytest.warns(CacheDirWarning, match="it is not a directory"):
        m = from_potential(x**4 / 4 + x**2 * y**4 + sp.Rational(2, 13) * y**2, [x, y])
    assert m.gradient([1.0, 1.0]).tolist() == pytest.approx([3.0, 4 + 4 / 13])


def test_equal_potentials_share_their_compiled_kernels():
    a = from_potential(x**2 * y**2 + x**4, [x, y])
    b = from_potential(x**2 * y**2 + x**4, [x, y], name="again")
    assert a.grad_kernel is b.grad_kernel and a.third_kernel is b.third_kernel


a, b = sp.symbols("a b")


@pytest.mark.parametrize("V, q, kwargs, message", [
    (a * x**2 + b * y, [x, y], {}, "not coordinates: a, b"),
    (sp.Abs(x) ** 3, [x], {}, "three times differentiable"),
    (sp.Piecewise((x**2, x > 0), (0, True)), [x], {}, "three times differentiable"),
    (sp.Max(x, y) ** 2, [x, y], {}, "three times differentiable"),
    (x**2 + sp.zoo, [x], {}, "non-finite"),
    (x**2 * sp.oo, [x], {}, "non-finite"),
    (sp.I * x**2, [x], {}, "real"),
    (sp.besselj(0, x), [x], {}, "cannot evaluate"),
    ("x**2", [x], {}, "SymPy expression"),
    (x**2, [x, x], {}, "twice"),
    (x**2, [], {}, "at least one"),
    (x**2, ["x"], {}, "SymPy symbols"),
    (x**2, 3, {}, "sequence of SymPy symbols"),
    (x**2 + y**2, [x, y], {"inverse_mass": [1, 0]}, r"inverse_mass\[1\] must be positive"),
    (x**2 + y**2, [x, y], {"inverse_mass": [1, -2.0]}, r"inverse_mass\[1\] must be positive"),
    (x**2 + y**2, [x, y], {"inverse_mass": [1, float("nan")]}, "positive and finite"),
    (x**2 + y**2, [x, y], {"inverse_mass": [1, 2, 3]}, "2 entries"),
    (x**2 + y**2, [x, y], {"inverse_mass": [1, a]}, r"inverse_mass\[1\] must be a number"),
], ids=["extra-symbols", "abs", "piecewise", "max", "zoo", "oo", "imaginary", "bessel",
        "string", "duplicate-q", "empty-q", "q-strings", "q-int", "zero-mass", "negative-mass",
        "nan-mass", "mass-length", "symbolic-mass"])
def test_bad_potentials_are_refused_with_a_message_naming_the_problem(V, q, kwargs, message):
    with pytest.raises(ValueError, match=message):
        from_potential(V, q, **kwargs)


# -- potentials typed as text (varint run --potential): read, never evaluated ------------
@pytest.mark.parametrize("text", [
    "(x**2+y**2)/2 + x**2*y - y**3/3", "x^2/2 + y^3", "-x**2 + +y", "1/3*x - 2/7", "x/y/2",
    "0.1*x**4 - 1.5e-3*y", "x**-2 + x**(1/3) + 2**(x+y)", "sqrt(x**2 + y**2) + exp(-x) * pi",
    "log(1 + x**2) + atan2(y, x) + E**y", "sinh(x) + cosh(y)**2 - tanh(x*y)",
    "sin(x)*cos(y) + tan(x) + asin(x/2) + acos(y/2) + atan(x)", "x - y - (x - y) - 1 + 2",
])
def test_formulas_read_as_sympy_reads_trusted_text(text):
    from varint.formula import parse_formula

    expected = sp.sympify(text, locals={"x": x, "y": y})  # trusted text, in a test only
    got = parse_formula(text, ["x", "y"])
    assert sp.simplify(got - expected) == 0
    assert got.free_symbols <= {x, y}


def test_formula_numbers_stay_exact():
    from varint.formula import parse_formula

    V = parse_formula("x**2/3 + 1/10", ["x"])
    assert x**2 / 3 + sp.Rational(1, 10) == V


def test_every_formula_function_compiles_into_the_kernels():
    """One potential using every allowed function: the generated kernels'
    gradient equals SymPy's derivative at a point."""
    from varint.formula import FUNCTIONS, parse_formula

    args = {"acosh": "(2 + x**2)", "atan2": "(y + 3, 2 + x)"}
    text = " + ".join(f"{f}{args.get(f, '(0.3 + x/10 + y/20)')}" for f in FUNCTIONS) + " + x**2"
    V = parse_formula(text, ["x", "y"])
    model = from_potential(V, [x, y])
    q = np.array([0.1, -0.2])
    grad = [float(sp.diff(V, s).subs({x: q[0], y: q[1]})) for s in (x, y)]
    assert np.allclose(model.gradient(q), grad, rtol=1e-13)


def test_formula_coordinates_may_be_unicode_names():
    from varint.formula import parse_formula

    theta = sp.Symbol("θ")
    assert parse_formula("θ**2/2 + cos(θ)", ["θ"]) == theta**2 / 2 + sp.cos(theta)
    # Python reads identifiers in NFKC form: a fullwidth ｘ is x.
    assert parse_formula("ｘ**2", ["x"]) == x**2

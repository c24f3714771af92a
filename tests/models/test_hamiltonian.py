"""from_hamiltonian: structure recognition, clear errors, the generated
kernels against SymPy and finite differences, momenta solved from the
energy, pickling."""

import pickle

import numpy as np
import pytest
import sympy as sp
from numba.core import event

from tests.flows.steppers import (bottle, coupled_general, cr3bp, larmor, relativistic,
                                  tao_example)
from varint import codecache
from varint.kernels import row_program
from varint.models import from_hamiltonian
from varint.models.bar import bar_orbit
from varint.models.hamiltonian import (GeneralHamiltonian, IntegrableHamiltonian,
                                       SeparableHamiltonian, TermwiseHamiltonian)
from varint.models.symbolic import SymbolicModel

x, y, z, px, py, pz, t = sp.symbols("x y z p_x p_y p_z t")


def test_recognised_structures():
    assert isinstance(cr3bp(), IntegrableHamiltonian)
    assert cr3bp().planar == {"plane": (0, 1), "a": 1.0, "b": 0.0, "omega": 1.0, "others": {}}
    # Uniform field B = 2, symmetric gauge: Larmor rotation Ω = 1 with the
    # oscillator b = 1 moved into A, z free … plus its own z⁴/4 in V.
    assert larmor().planar == {"plane": (0, 1), "a": 1.0, "b": 1.0, "omega": 1.0,
                               "others": {2: (1.0, 0.0)}}
    assert isinstance(relativistic(), SeparableHamiltonian)
    # ½|p − A|² with A_x free of x, A_y free of y: a potential and the parts
    # of p_x, p_y, p_z.
    assert isinstance(bottle(), TermwiseHamiltonian)
    assert bottle().part_names == ("V", "p_x", "p_y", "p_z")
    assert isinstance(coupled_general(), GeneralHamiltonian)
    assert isinstance(tao_example(), GeneralHamiltonian)
    m = from_hamiltonian((px ** 2 + 2 * py ** 2) / 2 + x ** 4 + y ** 2 * x, [x, y], [px, py])
    assert isinstance(m, SymbolicModel)
    assert m.inverse_mass.tolist() == [1.0, 2.0]
    # Landau gauge: a uniform field, not in the rotating form, but termwise.
    landau = from_hamiltonian(((px + y) ** 2 + py ** 2) / 2 + x ** 4, [x, y], [px, py])
    assert isinstance(landau, TermwiseHamiltonian)
    # A time-dependent T(p) + V(q, t) with a non-quadratic T: the general form.
    m = from_hamiltonian(sp.sqrt(1 + px ** 2) + x ** 2 * (1 + sp.cos(t)) / 2, [x], [px], time=t)
    assert isinstance(m, GeneralHamiltonian) and m.time_dependent


def test_forced_structures():
    H = (px ** 2 + py ** 2) / 2 + y * px - x * py - 1 / sp.sqrt(x ** 2 + y ** 2 + 1)
    assert isinstance(from_hamiltonian(H, [x, y], [px, py], structure="general"),
                      GeneralHamiltonian)
    sep = from_hamiltonian(px ** 2 / 2 + x ** 4, [x], [px], structure="separable")
    assert isinstance(sep, SeparableHamiltonian)
    with pytest.raises(ValueError, match="structure='separable' does not fit"):
        from_hamiltonian(H, [x, y], [px, py], structure="separable")
    with pytest.raises(ValueError, match="structure='integrable' does not fit"):
        from_hamiltonian(px ** 2 * x ** 2 + x ** 2, [x], [px], structure="integrable")
    with pytest.raises(ValueError, match="structure='terms' does not fit"):
        from_hamiltonian(px ** 2 * x ** 2 + x ** 2, [x], [px], structure="terms")
    terms = from_hamiltonian(H, [x, y], [px, py], structure="terms")
    assert isinstance(terms, TermwiseHamiltonian) and terms.part_names == ("V", "p_x", "p_y")
    with pytest.raises(ValueError, match="structure must be 'auto' or one of"):
        from_hamiltonian(H, [x, y], [px, py], structure="rotating")


@pytest.mark.parametrize("H, q, p, kwargs, message", [
    (x ** 2 + px ** 2 + sp.Symbol("k") * x, [x], [px], {}, "neither coordinates nor momenta: k"),
    (x ** 2 + px ** 2 * t, [x], [px], {}, "time=<its symbol>"),
    (x ** 2 + px ** 2, [x, y], [px], {}, "one momentum per coordinate"),
    (x ** 2 + px ** 2, [x], [x], {}, "both a coordinate and a momentum"),
    (x ** 2 + 1, [x], [y], {}, "does not depend on the momenta"),
    (sp.Abs(x) + px ** 2 * x, [x], [px], {}, "twice differentiable"),
    (sp.I * x + px ** 2 * x, [x], [px], {}, "must be real"),
    (sp.oo * x + px ** 2, [x], [px], {}, "non-finite"),
    ("x + p", [x], [px], {}, "must be a SymPy expression"),
    (x ** 2 + px ** 2, [x], [px], {"escape_radius": -1.0}, "escape_radius must be positive"),
    (x ** 2 + px ** 2, [x], [px], {"time": x}, "also a coordinate"),
])
def test_bad_input_is_refused_with_a_clear_message(H, q, p, kwargs, message):
    with pytest.raises(ValueError, match=message):
        from_hamiltonian(H, q, p, **kwargs)


@pytest.mark.parametrize("build", [cr3bp, relativistic, larmor, bottle, coupled_general])
def test_kernels_against_sympy_and_finite_differences(build):
    """∇H from the compiled kernel equals SymPy's derivatives at a random
    state, and D²H equals central differences of ∇H."""
    model = build()
    s = model.symbolic()
    xs = (*s.q, *s.p)
    rng = np.random.default_rng(4)
    state = 0.3 + 0.4 * rng.random(model.dim)
    subs = dict(zip(xs, state, strict=True))
    exact = np.array([float(sp.diff(s.H, v).evalf(subs=subs)) for v in xs])
    assert np.abs(model.gradient_h(state) - exact).max() < 1e-13 * max(1, np.abs(exact).max())
    eps = 1e-6
    fd = np.array([(model.gradient_h(state + eps * e) - model.gradient_h(state - eps * e))
                   / (2 * eps) for e in np.eye(model.dim)])
    D = model.hessian_h(state)
    assert np.abs(D - D.T).max() == 0
    assert np.abs(D - fd).max() < 1e-7 * max(1, np.abs(D).max())
    assert model.energy(state) == pytest.approx(float(s.H.evalf(subs=subs)), rel=1e-14)


def test_momentum_from_energy_on_a_section():
    """p_y solved on y = 0 from H = E has H = E to round-off and q̇_y ≥ 0;
    the forbidden region gives NaN."""
    model = cr3bp()
    X = np.zeros((5, 4))
    X[:, 0] = [-0.5, 0.2, 0.5, 0.8, 3.0]
    E = -1.6
    X[:, 3] = model.momentum_from_energy(X, E, 1)
    ok = np.isfinite(X[:, 3])
    assert ok.any() and not ok.all()
    assert np.abs(model.energy(X[ok]) - E).max() < 1e-14
    assert (model.field(X[ok][0])[1] >= 0)
    with pytest.raises(ValueError, match="not a polynomial of degree 1 or 2"):
        relativistic().momentum_from_energy(np.zeros(4), 1.5, 0)


def test_models_pickle():
    for build in (cr3bp, relativistic, bottle):
        model = build()
        copy = pickle.loads(pickle.dumps(model))
        state = np.array([0.3, 0.2, 0.1, 0.5, 0.4, 0.3][:model.dim])
        assert copy.energy(state) == model.energy(state)
        assert np.array_equal(copy.gradient_h(state), model.gradient_h(state))


def test_describe_names_the_hamiltonian():
    d = cr3bp().describe()
    assert d["structure"] == "integrable" and d["q"] == ["x", "y"] and d["p"] == ["p_x", "p_y"]
    assert sp.sympify(d["hamiltonian"]) == cr3bp().symbolic().H


def _numpy_h(model, X, t=None):
    """The lambdified NumPy H of the model's own expression (what its
    energies were before they were compiled), on the columns of X."""
    args = [X[..., i] for i in range(model.dim)] + ([t] if t is not None else [])
    return model._numpy_H(*args) + np.zeros(X.shape[:-1])


@pytest.mark.parametrize("build", [cr3bp, relativistic, larmor, bottle, coupled_general])
def test_compiled_energies_are_the_numpy_h_bitwise(build):
    """H, V and the energy scale of the compiled copies (potential_rows)
    are the lambdified NumPy H's and V's bit for bit, on states of several
    shapes, a single state a NumPy scalar."""
    model = build()
    rng = np.random.default_rng(8)
    X = rng.uniform(-0.6, 0.6, (7, 3, model.dim))
    assert np.array_equal(model.hamiltonian(X).view(np.int64), _numpy_h(model, X).view(np.int64))
    # The program on the shared interpreter (what a short call's repeated
    # calls take) as well as NumPy's (a first call's, until it is ready).
    for repeated in (False, True):
        got = model._values(model._numpy_H, X, 0.0, model.dim, repeated)
        assert np.array_equal(got.view(np.int64), _numpy_h(model, X).view(np.int64))
    x0, later = X[0], X[1:].reshape(-1, model.dim)
    h0, scale, h = model.start_and_later_energies(x0, later)
    assert np.array_equal(h0, model.hamiltonian(x0)) and np.array_equal(h, model.hamiltonian(later))
    assert np.array_equal(scale, model.energy_scale(x0))
    one = model.hamiltonian(X[0, 0])
    assert type(one) is np.float64 and one == _numpy_h(model, X[0, 0])
    q = X[..., :model.n_dof]
    if model._numpy_V is not None:
        expected = model._numpy_V(*(q[..., i] for i in range(model.n_dof))) + np.zeros(q.shape[:-1])
    else:       # a general H: H at rest
        expected = _numpy_h(model, np.concatenate([q, np.zeros_like(q)], axis=-1))
    assert np.array_equal(model.potential(q), expected)


def test_compiled_time_dependent_energy_is_h_of_each_time():
    """A time-dependent H (polynomial: compiled, the time a column) and one
    with a cosine (NumPy's, not compiled: its bits could differ) give
    H(x, t) of each row's own time, equal to the exact H and to the
    lambdified one bitwise."""
    q, p, s = sp.symbols("q p s")
    X = np.array([[0.3, 0.4], [0.1, -0.2], [-0.7, 0.25]])
    T = np.array([0.5, 1.0, 2.5])
    for H in (p ** 2 / 2 + q ** 2 * p + q ** 4 / 4 + q * s, p ** 2 / 2 + q * p * sp.cos(s)):
        model = from_hamiltonian(H, [q], [p], time=s)
        got = model.hamiltonian(X, T)
        assert np.array_equal(model._values(model._numpy_H, X, T, model.dim, True), got)
        exact = [float(H.subs({q: a, p: b, s: c})) for (a, b), c in zip(X, T, strict=True)]
        assert got == pytest.approx(exact, rel=1e-15, abs=1e-16)
        assert np.array_equal(got, _numpy_h(model, X, T))
        assert model.hamiltonian(X, 1.5) == pytest.approx(
            [float(H.subs({q: a, p: b, s: 1.5})) for a, b in X], rel=1e-15, abs=1e-16)


class _Compiles(event.Listener):
    """The functions numba compiles while installed."""

    def __init__(self):
        self.names = []

    def on_start(self, ev):
        self.names.append(ev.data["dispatcher"].py_func.__qualname__)

    def on_end(self, ev):
        pass


def _first_energies(build, X):
    """The functions numba compiles while ``build()`` makes a model and
    its first H, V and energy scale at the states ``X``; and those values."""
    listener = _Compiles()
    with event.install_listener("numba:compile", listener):
        model = build()
        values = (model.hamiltonian(X), model.potential(X[:, :model.n_dof]),
                  model.energy_scale(X))
    return listener.names, model, values


def test_a_new_models_first_energies_compile_nothing():
    """A model's first energies compile nothing: NumPy's until calls
    repeat, then one interpreter shared by every model
    (varint.kernels.row_program), never a kernel per expression (one was
    compiled for each before)."""
    X = np.array([[0.3, 0.1, -0.2, 0.4], [0.5, -0.3, 0.2, 0.1]])
    names, model, (h, v, _) = _first_energies(lambda: from_hamiltonian(
        (px - y) ** 2 / 2 + (py + x) ** 2 / 2 + x ** 4 / 7 + x * y ** 2 / 3, [x, y], [px, py]), X)
    assert names == []
    assert np.array_equal(h, _numpy_h(model, X))
    assert np.array_equal(v, model._numpy_V(X[:, 0], X[:, 1]))
    # Repeated calls (a short call's verdict) take the interpreter,
    # compiled at most once; then a new model's first energies take it too,
    # compiling nothing.
    model.start_and_later_energies(X[:1], X[1:])
    assert row_program.ready()
    names, model, (h, v, scale) = _first_energies(lambda: from_hamiltonian(
        (px - y) ** 2 / 2 + (py + x) ** 2 / 2 + x ** 4 / 9 + x * y ** 2 / 5, [x, y], [px, py]), X)
    assert names == []
    assert np.array_equal(h, _numpy_h(model, X))
    assert np.array_equal(v, model._numpy_V(X[:, 0], X[:, 1]))
    assert codecache.in_disk_cache(row_program.run_program)


def test_the_bars_energies_are_the_numpy_h_and_its_bar_bitwise():
    """The rotating bar's H (its closed part interpreted, the Ferrers bar
    added) is the lambdified H's closed part plus the same bar term."""
    model, x0 = bar_orbit("regular")
    rng = np.random.default_rng(4)
    X = x0 + rng.uniform(-0.3, 0.3, (9, model.dim))
    expected = _numpy_h(model, X)
    model._energy_term(np.ascontiguousarray(X), expected)
    for repeated in (False, True):
        got = model._values(model._numpy_H, X, 0.0, model.dim, repeated)
        assert np.array_equal(got.view(np.int64), expected.view(np.int64))
    assert model.hamiltonian(X[0]) == expected[0]
    h0, scale, h = model.start_and_later_energies(X[:2], X[2:])
    assert np.array_equal(np.concatenate([h0, h]), expected)
    assert np.array_equal(scale, model.energy_scale(X[:2]))

"""Planetary systems (varint.models.Planetary, varint.kernels.nbody,
varint.correctors): coordinates and elements, the compiled derivatives
against finite differences of the NumPy Hamiltonian, the flows' tangent
maps against finite differences of the flows, REBOUND's conversions, and
the measured error laws of the Wisdom–Holman map and its correctors."""

import math

import numpy as np
import pytest

import varint
from varint.correctors import WHT_ORDERS, corrector_word
from varint.kernels import nbody
from varint.kernels.banded import band_to_dense
from varint.models import Planetary
from varint.schemes import get_scheme, part_stages

from tests.helpers import fitted_slope

MASSES = [1.0, 1e-3, 3e-4, 5e-4]
ELEMENTS = [dict(a=1.0, e=0.05, M=0.4), dict(a=1.6, e=0.1, inc=0.1, Omega=0.3, omega=1.0, M=2.0),
            dict(a=2.5, e=0.2, inc=0.05, Omega=4.0, omega=2.5, M=4.0)]


@pytest.fixture(scope="module", params=["jacobi", "democratic"])
def system(request):
    model = Planetary(MASSES, G=1.3, coordinates=request.param)
    return model, model.from_elements(ELEMENTS)


def _fd(f, x, d=1e-5):
    """Fourth-order central differences of f at x, column by column."""
    cols = []
    for i in range(len(x)):
        e = np.zeros(len(x))
        e[i] = d * max(1.0, abs(x[i]))
        cols.append((8 * (f(x + e) - f(x - e)) - (f(x + 2 * e) - f(x - 2 * e))) / (12 * e[i]))
    return np.array(cols).T


# -- coordinates and elements ----------------------------------------------------------
def test_elements_round_trip_in_both_frames(system):
    model, _ = system
    for frame in ("jacobi", "heliocentric"):
        x = model.from_elements(ELEMENTS, frame)
        el = model.to_elements(x, frame)
        want = np.array([[e.get(k, 0.0) for k in ("a", "e", "inc", "Omega", "omega", "M")]
                         for e in ELEMENTS])
        assert np.allclose(el, want, rtol=0, atol=1e-12)


def test_hyperbolic_and_true_anomaly_elements():
    model = Planetary([1.0, 1e-3])
    x = model.from_elements([dict(a=-2.0, e=1.7, f=0.5, inc=0.3)])
    a, e, inc, *_ = model.to_elements(x)[0]
    assert (a, e, inc) == pytest.approx((-2.0, 1.7, 0.3), abs=1e-12)
    assert model.periods(x)[0] == np.inf


def test_cartesian_round_trip_and_invariants_agree_between_coordinates():
    """The same bodies in Jacobi and democratic heliocentric coordinates:
    one energy, one angular momentum, and both equal to the bodies' own
    ½Σ m v² + U and Σ m X × V."""
    jac = Planetary(MASSES, G=1.3)
    dem = Planetary(MASSES, G=1.3, coordinates="democratic")
    xj = jac.from_elements(ELEMENTS)
    X, V = jac.to_cartesian(xj)
    xd = dem.from_cartesian(X, V)
    assert np.allclose(dem.to_cartesian(xd)[0], X, rtol=0, atol=1e-15)
    assert np.allclose(jac.from_cartesian(X + 5.0, V - 0.2), xj, rtol=0, atol=1e-14)
    m = np.array(MASSES)
    assert np.allclose(m @ X, 0, atol=1e-17) and np.allclose(m @ V, 0, atol=1e-17)
    kinetic = 0.5 * np.sum(m * np.sum(V * V, axis=1))
    U = -sum(1.3 * m[a] * m[b] / np.linalg.norm(X[a] - X[b])
             for a in range(4) for b in range(a + 1, 4))
    L = np.sum(m[:, None] * np.cross(X, V), axis=0)
    for model, x in ((jac, xj), (dem, xd)):
        assert model.energy(x) == pytest.approx(kinetic + U, rel=1e-14)
        assert np.allclose(model.angular_momentum(x), L, rtol=1e-14, atol=1e-20)
        assert model.conserved(x)["angular_momentum"] == pytest.approx(np.linalg.norm(L))


@pytest.mark.parametrize("bad, match", [
    (dict(masses=[1.0]), "at least two"), (dict(masses=[1.0, -1e-3]), "positive and finite"),
    (dict(masses="sun"), "sequence"), (dict(masses=[1.0, 1e-3], G=0), "G must be"),
    (dict(masses=[1.0, 1e-3], coordinates="helio"), "coordinates must be one of")])
def test_bad_models_are_refused(bad, match):
    with pytest.raises(ValueError, match=match):
        Planetary(**bad)


@pytest.mark.parametrize("els, match", [
    ([dict(e=0.1)], "planet 1: the element 'a' is missing"),
    ([dict(a=1.0, e=1.0)], "not exactly 1"), ([dict(a=1.0, e=1.2)], "a must be positive"),
    ([dict(a=1.0, ecc=0.1)], "unknown element 'ecc'"), ([dict(a=1.0, M=1, f=1)], "not both"),
    ([dict(a=-1.0, e=2.0, f=3.0)], "never reaches"), ([dict(a=float("nan"))], "finite"),
    (dict(a=1.0), "sequence of 1 mappings")])
def test_bad_elements_are_refused(els, match):
    with pytest.raises(ValueError, match=match):
        Planetary([1.0, 1e-3]).from_elements(els)


def test_element_grid_replaces_one_planets_elements():
    model = Planetary(MASSES[:3])
    grid = varint.element_grid(model, ELEMENTS[:2], 2, [1.5, 1.7, 1.9], [0.0, 0.2],
                               axes=("a", "e"))
    assert grid.states.shape == (6, 12) and grid.axes == ("a", "e")
    el = np.array([model.to_elements(x)[1] for x in grid.states])
    assert np.allclose(el[:, 0], np.tile([1.5, 1.7, 1.9], 2)) and np.allclose(
        el[:, 1], np.repeat([0.0, 0.2], 3), atol=1e-14)
    assert np.allclose(el[:, 2], 0.1)                      # the other elements kept
    with pytest.raises(ValueError, match="planet must be an integer in 1..2"):
        varint.element_grid(model, ELEMENTS[:2], 3, [1.5], [0.0])
    with pytest.raises(ValueError, match="axes must be two different elements"):
        varint.element_grid(model, ELEMENTS[:2], 1, [1.5], [0.0], axes=("a", "q"))
    with pytest.raises(ValueError, match="planet 2: a must be positive"):
        varint.element_grid(model, ELEMENTS[:2], 2, [1.5], [1.5])


# -- derivatives and flows ------------------------------------------------------------
def test_potential_kernels_are_the_derivatives_of_U():
    """∇U, D²U and Σ v_k D²∂_kU (the band kernels of every other method)
    against finite differences of the NumPy potential and of each other."""
    model = Planetary(MASSES, G=1.3)
    q = model.from_elements(ELEMENTS)[:9]
    g = model.gradient(q)
    assert np.allclose(g, _fd(lambda y: np.atleast_1d(model.potential(y)), q)[0], rtol=0,
                       atol=1e-9 * np.max(np.abs(g)))
    H = model.hessian(q)
    assert np.allclose(H, _fd(model.gradient, q), rtol=0, atol=1e-9 * np.max(np.abs(H)))
    v = np.linspace(-1, 1, 9)
    T = band_to_dense(model.third_band(q, v))
    Tfd = np.zeros((9, 9))
    for k in range(9):
        e = np.zeros(9)
        e[k] = 1e-5
        Tfd += v[k] * (8 * (model.hessian(q + e) - model.hessian(q - e))
                       - (model.hessian(q + 2 * e) - model.hessian(q - 2 * e))) / 12e-5
    assert np.allclose(T, Tfd, rtol=0, atol=1e-8 * np.max(np.abs(T)))


def test_interaction_plus_kepler_potentials_is_U():
    """∇B = ∇U − ∇V_Kepler exactly as the split says (Jacobi: V_Kepler =
    −Σ G m_i M_{i−1}/|q_i|; democratic: H_I is the planet pairs alone)."""
    jac = Planetary(MASSES, G=1.3)
    q = jac.from_elements(ELEMENTS)[:9]
    Q = q.reshape(3, 3)
    m, M = np.array(MASSES), np.cumsum(MASSES)
    gk = np.concatenate([1.3 * m[i + 1] * M[i] * Q[i] / np.linalg.norm(Q[i]) ** 3
                         for i in range(3)])
    assert np.allclose(jac.interaction_gradient(q), jac.gradient(q) - gk, rtol=0, atol=1e-17)
    dem = Planetary(MASSES, G=1.3, coordinates="democratic")
    qd = dem.from_cartesian(*jac.to_cartesian(jac.from_elements(ELEMENTS)))[:9]
    gi = _fd(lambda y: np.atleast_1d(dem.interaction(y)), qd)[0]
    assert np.allclose(dem.interaction_gradient(qd), gi, rtol=0, atol=1e-12)


def test_jacobi_transforms_are_transposes():
    model = Planetary(MASSES)
    rng = np.random.default_rng(3)
    q, g = rng.normal(size=9), rng.normal(size=9)
    u, lt = np.empty(9), np.empty(9)
    nbody.jacobi_to_helio(q, model.params, u)
    nbody.jacobi_transpose(g, model.params, lt)
    assert u @ g == pytest.approx(q @ lt, rel=1e-14)
    assert np.allclose(u.reshape(3, 3), model.helio_positions(q), rtol=1e-15)


def _flow(model, part, h, x, W=None):
    x = np.array(x, dtype=float)
    V = np.zeros((0, model.dim)) if W is None else np.array(W, dtype=float)
    status = nbody.apply_flow(part, h, x, V, V.shape[0], model.params,
                              np.empty(model.parts.n_work))
    assert status == 0
    return x, V


@pytest.mark.parametrize("part", ["Kepler", "Interaction", "Jump"])
def test_each_flows_tangent_is_its_derivative_and_symplectic(system, part):
    model, x0 = system
    if part not in model.parts.names:
        pytest.skip("Jacobi coordinates have no jump")
    idx = model.parts.index(part)
    h = 0.3
    _, V = _flow(model, idx, h, x0, np.eye(model.dim))
    J = V.T
    Jfd = _fd(lambda y: _flow(model, idx, h, y)[0], x0, 1e-6)
    assert np.max(np.abs(J - Jfd)) <= 1e-8 * np.max(np.abs(J))
    n = model.n_dof
    S = np.block([[np.zeros((n, n)), np.eye(n)], [-np.eye(n), np.zeros((n, n))]])
    assert np.max(np.abs(J.T @ S @ J - S)) <= 1e-14 * np.max(np.abs(J)) ** 2


def test_vector_field_is_hamiltons(system):
    """ẋ = J∇H: the compiled field against finite differences of the NumPy
    energy."""
    model, x0 = system
    grad = _fd(lambda y: np.atleast_1d(model.energy(y)), x0, 1e-6)[0]
    n = model.n_dof
    want = np.concatenate([grad[n:], -grad[:n]])
    assert np.allclose(model.vector_field(x0), want, rtol=0, atol=1e-8 * np.max(np.abs(want)))


# -- schemes: the measured error laws -------------------------------------------------
def _word(model, scheme, tau):
    s = get_scheme(scheme)
    n_parts = s.n_parts if hasattr(s, "n_parts") else 2
    return part_stages(s, tau, model.parts.slots(n_parts))


def _run(model, x, parts, h, n, W=None):
    x = np.array(x, dtype=float)
    V = np.zeros((0, model.dim)) if W is None else np.array(W, dtype=float)
    work = np.empty(model.parts.n_work)
    for _ in range(n):
        assert nbody.apply_word(parts, h, x, V, V.shape[0], model.params, work) == 0
    return x, V


def _corrector(model, order, tau, inverse):
    word = corrector_word(order, inverse)
    return (np.array([s for s, _ in word], dtype=np.int64),
            np.array([c * tau for _, c in word]))


def _max_energy_error(model, x0, scheme, tau, orbits=8, corrector=None):
    """Largest relative energy error at the ends of 8 blocks over ``orbits``
    inner periods (2π), with the WHT corrector of that order applied to
    the outputs (the map runs on C⁻¹(x₀))."""
    parts, h = _word(model, scheme, tau)
    n = int(round(orbits * 2 * math.pi / tau))
    E0 = model.energy(x0)
    y = x0 if corrector is None else _run(model, x0, *_corrector(model, corrector, tau, True), 1)[0]
    worst = 0.0
    for _ in range(8):
        y, _ = _run(model, y, parts, h, n // 8)
        x = y if corrector is None else _run(model, y, *_corrector(model, corrector, tau, False),
                                             1)[0]
        worst = max(worst, abs(model.energy(x) - E0) / abs(E0))
    return worst


def _two_planets(eps):
    model = Planetary([1.0, eps, 0.3 * eps])
    return model, model.from_elements([dict(a=1.0, e=0.05), dict(a=1.6, e=0.02, M=2.0,
                                                                 inc=0.1)])


TAUS = (2 * math.pi / 16, 2 * math.pi / 32, 2 * math.pi / 64)


def test_wisdom_holman_energy_error_is_eps_tau_squared():
    """WH (SABA1): slope 2 in τ (measured 2.00), and linear in ε (the
    errors at ε = 1e-3 and 1e-4 differ tenfold, measured 10.0)."""
    errs = {eps: [_max_energy_error(*_two_planets(eps), "SABA1", tau) for tau in TAUS]
            for eps in (1e-3, 1e-4)}
    for eps, e in errs.items():
        assert abs(fitted_slope(TAUS, e) - 2.0) < 0.1, (eps, e)
    ratio = np.array(errs[1e-3]) / np.array(errs[1e-4])
    assert np.all(np.abs(ratio - 10.0) < 1.0), ratio


def test_corrector_leaves_eps_tau4_plus_eps2_tau2():
    """With the third-order corrector: at ε = 1e-5 the ετ⁴ term rules
    (slope 4, measured 4.0), at ε = 1e-2 the ε²τ² term (slope 2,
    measured 2.09, and ∝ ε²: exponent 2.24 from ε = 5e-3 to 1e-2);
    uncorrected errors are hundreds of times larger."""
    # From τ = T/24 on (at T/12–T/16 higher terms still show).
    fine = (2 * math.pi / 24, 2 * math.pi / 32, 2 * math.pi / 48)
    small = [_max_energy_error(*_two_planets(1e-5), "SABA1", tau, corrector=3) for tau in fine]
    assert abs(fitted_slope(fine, small) - 4.0) < 0.3, small
    plain = _max_energy_error(*_two_planets(1e-5), "SABA1", fine[0])
    assert plain > 100 * small[0]
    coarse = (2 * math.pi / 32, 2 * math.pi / 48, 2 * math.pi / 64)
    big = [_max_energy_error(*_two_planets(1e-2), "SABA1", tau, corrector=3) for tau in coarse]
    assert abs(fitted_slope(coarse, big) - 2.0) < 0.15, big
    half = _max_energy_error(*_two_planets(5e-3), "SABA1", coarse[1], corrector=3)
    assert abs(math.log2(big[1] / half) - 2.0) < 0.3, (big, half)


@pytest.mark.parametrize("order", WHT_ORDERS)
def test_corrector_inverse_and_higher_orders(order):
    """C⁻¹ then C returns the state to round-off; every order at least
    matches the third-order one's error (at ε = 1e-5, τ = T/32)."""
    model, x0 = _two_planets(1e-5)
    tau = TAUS[1]
    y, _ = _run(model, x0, *_corrector(model, order, tau, True), 1)
    back, _ = _run(model, y, *_corrector(model, order, tau, False), 1)
    assert np.max(np.abs(back - x0)) <= 1e-14 * np.max(np.abs(x0))
    assert _max_energy_error(model, x0, "SABA1", tau, corrector=order) <= 1.5 * \
        _max_energy_error(model, x0, "SABA1", tau, corrector=3)


def test_higher_order_schemes_for_a_small_perturbation():
    """SABA2 (ετ⁴ + ε²τ²) at ε = 1e-5: slope 4 (measured 4.1); ABA1064
    (ετ¹⁰ + ε²τ⁶ + ε³τ⁴) is at the round-off floor from τ = T/16 (measured
    8e-15), where WH's error is 5e-9."""
    model, x0 = _two_planets(1e-5)
    fine = (2 * math.pi / 24, 2 * math.pi / 32, 2 * math.pi / 48)
    saba2 = [_max_energy_error(model, x0, "SABA2", tau) for tau in fine]
    assert abs(fitted_slope(fine, saba2) - 4.0) < 0.3, saba2
    assert _max_energy_error(model, x0, "ABA1064", TAUS[0]) < 1e-13


def test_democratic_heliocentric_map_is_second_order():
    """The map of Duncan, Levison & Lee (ABC2 on H_I, H_J, H_K): energy
    error slope 2 in τ (measured 2.0)."""
    model = Planetary([1.0, 1e-3, 3e-4], coordinates="democratic")
    x0 = model.from_elements([dict(a=1.0, e=0.05), dict(a=1.6, e=0.02, M=2.0, inc=0.1)])
    errs = [_max_energy_error(model, x0, "ABC2", tau) for tau in TAUS]
    assert abs(fitted_slope(TAUS, errs) - 2.0) < 0.15, errs


def test_wh_step_tangent_is_its_derivative_and_reversible(system):
    model, x0 = system
    scheme = "SABA1" if model.coordinates == "jacobi" else "ABC2"
    parts, h = _word(model, scheme, 0.2)
    _, V = _run(model, x0, parts, h, 20, np.eye(model.dim))
    J = V.T
    Jfd = _fd(lambda y: _run(model, y, parts, h, 20)[0], x0, 1e-6)
    assert np.max(np.abs(J - Jfd)) <= 1e-7 * np.max(np.abs(J))
    y, Vy = _run(model, x0, parts, h, 50, np.eye(model.dim))
    back, Vb = _run(model, y, *_word(model, scheme, -0.2), 50, Vy)
    assert np.max(np.abs(back - x0)) <= 1e-13 * np.max(np.abs(x0))
    # p = m′v makes ∂q/∂p ~ τ/m′ ~ 1e3: round-off relative to ‖J‖².
    assert np.max(np.abs(Vb - np.eye(model.dim))) <= 1e-14 * np.max(np.abs(Vy)) ** 2


# -- REBOUND ------------------------------------------------------------------------
def test_rebound_conversions():
    """A REBOUND simulation built by sim.add(a=..., e=...) (elements
    relative to the interior centre of mass) is the state from_elements
    gives; from_rebound takes its energy; to_rebound gives it back."""
    rebound = pytest.importorskip("rebound")
    sim = rebound.Simulation()
    sim.G = 1.3
    sim.add(m=MASSES[0])
    for m, el in zip(MASSES[1:], ELEMENTS, strict=True):
        sim.add(m=m, **el)
    sim.move_to_com()
    model, x = Planetary.from_rebound(sim)
    assert np.allclose(x, model.from_elements(ELEMENTS), rtol=0, atol=1e-14)
    assert model.energy(x) == pytest.approx(sim.energy(), rel=1e-13)
    back = model.to_rebound(x)
    assert back.energy() == pytest.approx(sim.energy(), rel=1e-13)
    assert np.allclose(Planetary.from_rebound(back)[1], x, rtol=0, atol=1e-15)
    dem, xd = Planetary.from_rebound(sim, coordinates="democratic")
    assert dem.energy(xd) == pytest.approx(sim.energy(), rel=1e-13)


@pytest.mark.parametrize("n, coords, parts", [
    (1, "jacobi", "both"), (2, "jacobi", "both"), (3, "jacobi", "kick"),
    (1, "democratic", "both"), (3, "democratic", "kick"),
    # The drift of n planets is n copies of one planet's lines, side by
    # side, at offsets of one formula in n and the planet
    # (nbody_unrolled._drift_source): one and two planets hold them to the
    # generic loop; three compile a drift for this alone (13 CPU s cold).
    pytest.param(3, "jacobi", "drift", marks=pytest.mark.slow)])
def test_unrolled_flows_are_the_generic_ones_bit_for_bit(n, coords, parts):
    """The straight-line drift and kick of varint.kernels.nbody_unrolled
    (what runs) against the generic loops of varint.kernels.nbody (what
    the tests above hold to the physics)."""
    from varint.kernels.nbody_unrolled import drift_kernel, kick_kernel

    model = Planetary(MASSES[:n + 1], G=1.3, coordinates=coords)
    x0 = model.from_elements(ELEMENTS[:n])
    V0 = np.random.default_rng(1).normal(size=(3, model.dim))
    work = np.empty(model.parts.n_work)
    flows = {"drift": (nbody.KEPLER, lambda: drift_kernel(n)),
             "kick": (nbody.INTERACTION, lambda: kick_kernel(n, coords == "jacobi"))}
    for part, make in (flows.values() if parts == "both" else [flows[parts]]):
        kernel = make()
        for h in (0.3, 0.0, -7.0):
            x1, V1 = x0.copy(), V0.copy()
            x2, V2 = x0.copy(), V0.copy()
            out = kernel(x1, V1, 3, h, model.params)
            assert nbody.apply_flow(part, h, x2, V2, 3, model.params, work) == (out or 0)
            assert x1.tobytes() == x2.tobytes() and V1.tobytes() == V2.tobytes()


def test_a_failing_drift_moves_no_planet():
    """One planet at the centre: the drift reports it degenerate and no
    planet moves (the generic loop would have moved the planets before)."""
    from varint.kernels.kepler import KEPLER_DEGENERATE
    from varint.kernels.nbody_unrolled import drift_kernel

    model = Planetary(MASSES[:3])
    x = model.from_elements(ELEMENTS[:2])
    x[3:6] = 0.0
    before = x.copy()
    assert drift_kernel(2)(x, np.eye(12)[:1].copy(), 1, 0.3, model.params) == KEPLER_DEGENERATE
    assert np.array_equal(x, before)


def test_close_encounter_is_detected_by_both_kicks():
    """Two planets at (1, 0, 0) and (1, s, 0) from the star, against f = 2
    mutual Hill radii ((m₁ + m₂)/3m₀)^{1/3} √((r₁² + r₂²)/2): the generic
    and the generated kick flag the same states, exactly those closer than
    that, on both sides of it."""
    from varint.kernels.nbody_unrolled import kick_kernel

    m = [1.0, 1e-3, 3e-4]
    rhill = np.cbrt(1.3e-3 / 3)
    flags = set()
    for coords in ("jacobi", "democratic"):
        model = Planetary(m, coordinates=coords, close_encounter=2.0)
        for s in (0.8, 0.99, 1.01, 1.2):
            sep = s * 2.0 * rhill           # about s times the bound
            X = np.array([[0.0, 0, 0], [1.0, 0, 0], [1.0, sep, 0]])
            x = model.from_cartesian(X, [[0.0, 0, 0], [0, 1, 0], [0, 1.1, 0]])
            x1, x2 = x.copy(), x.copy()
            V = np.zeros((0, model.dim))
            generated = kick_kernel(2, coords == "jacobi")(x1, V, 0, 1e-9, model.params)
            generic = nbody.apply_flow(nbody.INTERACTION, 1e-9, x2, V, 0, model.params,
                                       np.empty(model.parts.n_work))
            U = model.helio_positions(x1[:6])
            bound = 2.0 * rhill * np.sqrt((U[0] @ U[0] + U[1] @ U[1]) / 2)
            want = nbody.ENCOUNTER if np.linalg.norm(U[0] - U[1]) < bound else 0
            assert generated == generic == want, (coords, s)
            flags.add(want)
    assert flags == {0, nbody.ENCOUNTER}
    assert Planetary(m).describe().get("close_encounter") is None
    with pytest.raises(ValueError, match="close_encounter must be a positive"):
        Planetary(m, close_encounter=0)


def test_models_pickle_for_dask_workers():
    """A map on a Dask cluster sends the model to the workers: it pickles
    with its generated flows, and the copy describes the same system."""
    import pickle

    model = Planetary(MASSES, G=1.3, close_encounter=2.0)
    copy = pickle.loads(pickle.dumps(model))
    assert copy.describe() == model.describe()
    assert np.array_equal(copy.params, model.params)
    x0 = model.from_elements(ELEMENTS)
    assert copy.energy(x0) == model.energy(x0)

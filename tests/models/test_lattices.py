"""The lattice models (Klein–Gordon, FPUT, DDNLS in 1D and 2D): every part's
flow is the exact flow of the Hamiltonian part written out independently
here, its fused tangent map is the derivative of the flow, the parts add up
to the model's H, and the site distributions add up to the conserved
quantity."""

import numpy as np
import pytest

import varint
from varint.kernels.interval import Call
from varint.kernels.parts import PartsOrbit, PartsSetup, parts_batch
from varint.methods.parts import parts_steps
from varint.methods.tm import tangent_map_steps
from varint.models import DDNLS, FPUT, DisorderedKG, FPUBeta

RNG = np.random.default_rng(20240601)


def one_flow(model, part, h, x, v=None):
    """The exact flow of one part for time h (and its tangent map on v).
    Without v the flow still carries one (zero) vector: the orbit does not
    depend on the vectors, and one kernel per lattice (k = 1) serves every
    test here."""
    parts = model.parts
    par, n_work = parts.params(2 if part == "L" else max(parts.splits))
    x = np.array(x, dtype=float)[None].copy()
    k = 1
    W = np.zeros((1, model.dim, 1)) if v is None else np.array(v, dtype=float).reshape(1, -1, 1)
    W = np.ascontiguousarray(W)
    status, done = np.zeros(1, dtype=np.int64), np.zeros(1, dtype=np.int64)
    parts_batch(parts.apply, parts.field, k, False)(
        PartsOrbit(x, W, np.ones((1, k)), np.zeros((1, k), dtype=np.int64), np.empty((1, 0, 0)),
                   np.zeros((1, len(parts.names)), dtype=np.int64)),
        PartsSetup(np.array([parts.index(part)]), np.array([float(h)]), par, n_work),
        Call(1, 0, 1.0, 0, np.inf), status, done)
    assert status[0] == 0
    return x[0], None if v is None else W[0, :, 0]


# -- the Hamiltonians, written out independently of the package ---------------
def neighbours(model, a):
    """Σ over nearest neighbours, by explicit index loops."""
    nx, ny = model.nx, model.ny
    out = np.zeros_like(a)
    per = model.boundary == "periodic"
    for i in range(nx):
        for j in range(ny):
            s = i * ny + j
            moves = [(0, -1), (0, 1)] + ([(-1, 0), (1, 0)] if model.lattice_dim == 2 else [])
            for di, dj in moves:
                ii, jj = i + di, j + dj
                if per:
                    ii, jj = ii % nx, jj % ny
                elif not (0 <= ii < nx and 0 <= jj < ny):
                    continue
                out[s] += a[ii * ny + jj]
    return out


def kg_parts(model):
    n, W, eps = model.n_sites, model.W, model.epsilon
    z = 2 * model.lattice_dim

    def T(x):
        return 0.5 * np.sum(x[n:] ** 2)

    def V(x):
        q = x[:n]
        # Σ_bonds (q_m − q_l)² = z Σq² − qᵀKq, walls included with fixed ends.
        bonds = z * np.sum(q * q) - q @ neighbours(model, q)
        return np.sum(0.5 * eps * q * q + 0.25 * q ** 4) + bonds / (2 * W)
    return {"T": T, "V": V}


def fput_parts(model):
    n, a, b = model.n_sites, model.alpha, model.beta

    def T(x):
        return 0.5 * np.sum(x[n:] ** 2)

    def V(x):
        q = x[:n]
        if model.boundary == "periodic":
            r = np.roll(q, -1) - q
        else:
            r = np.diff(np.concatenate([[0.0], q, [0.0]]))
        return np.sum(r * r / 2 + a * r ** 3 / 3 + b * r ** 4 / 4)
    return {"T": T, "V": V}


def ddnls_parts(model):
    n, eps, beta = model.n_sites, model.epsilon, model.beta

    def A(x):
        r = x[:n] ** 2 + x[n:] ** 2
        return np.sum(eps / 2 * r + beta / 8 * r * r)

    def B(x):
        p = x[n:]
        return -0.5 * p @ neighbours(model, p)

    def C(x):
        q = x[:n]
        return -0.5 * q @ neighbours(model, q)
    return {"A": A, "B": B, "C": C, "L": lambda x: B(x) + C(x)}


def hamiltonian_field(H, x, h=1e-6):
    """J∇H by central differences."""
    g = np.empty_like(x)
    for i in range(x.size):
        e = np.zeros_like(x)
        e[i] = h
        g[i] = (H(x + e) - H(x - e)) / (2 * h)
    n = x.size // 2
    return np.concatenate([g[n:], -g[:n]])


CASES = [
    ("KG 1D fixed", lambda: DisorderedKG(7, 4.0, 1), kg_parts),
    ("KG 1D ring", lambda: DisorderedKG(7, 3.0, 2, boundary="periodic"), kg_parts),
    ("KG 2D fixed", lambda: DisorderedKG((3, 4), 10.0, 3), kg_parts),
    ("KG 2D torus", lambda: DisorderedKG((3, 4), 10.0, 4, boundary="periodic"), kg_parts),
    ("FPUT fixed", lambda: FPUT(6, 0.25, 1.0), fput_parts),
    ("FPUT ring", lambda: FPUT(6, 0.25, 1.0, boundary="periodic"), fput_parts),
    ("DDNLS 1D fixed", lambda: DDNLS(7, 4.0, 1.0, 5), ddnls_parts),
    ("DDNLS 1D ring", lambda: DDNLS(8, 4.0, 0.7, 6, boundary="periodic"), ddnls_parts),
    ("DDNLS 2D fixed", lambda: DDNLS((3, 4), 10.0, 1.0, 7), ddnls_parts),
    ("DDNLS 2D torus", lambda: DDNLS((3, 4), 10.0, 1.0, 8, boundary="periodic"), ddnls_parts),
]
IDS = [c[0] for c in CASES]


@pytest.fixture(scope="module", params=CASES, ids=IDS)
def case(request):
    _, build, parts = request.param
    model = build()
    return model, parts(model)


def state(model, scale=0.6):
    return RNG.uniform(-scale, scale, model.dim)


def test_each_flow_is_the_flow_of_its_part(case):
    """(φ_h(x) − φ_{−h}(x)) / 2h → J∇P(x), P the part written out above:
    the flow integrates that part and no other."""
    model, parts = case
    x = state(model)
    for name, P in parts.items():
        h = 1e-4
        xp, _ = one_flow(model, name, h, x)
        xm, _ = one_flow(model, name, -h, x)
        field = hamiltonian_field(P, x)
        err = np.max(np.abs((xp - xm) / (2 * h) - field)) / max(1.0, np.max(np.abs(field)))
        assert err < 1e-6, (name, err)


def test_flows_are_exact(case):
    """φ_{h1} ∘ φ_{h2} = φ_{h1+h2} to round-off: each flow is the exact flow
    of its part (an approximate one would differ at O(h²))."""
    model, parts = case
    x = state(model)
    for name in parts:
        a, _ = one_flow(model, name, 0.3, x)
        a, _ = one_flow(model, name, 0.45, a)
        b, _ = one_flow(model, name, 0.75, x)
        assert np.max(np.abs(a - b)) < 1e-13 * max(1.0, np.max(np.abs(b))), name


def test_tangent_flows_match_finite_differences(case):
    """Each part's fused tangent map is the derivative of its flow: against
    central differences (h = 1e-5, error O(h²) ~ 1e-10) in three random
    directions, to 1e-8 relative."""
    model, parts = case
    x = state(model)
    for name in parts:
        for _ in range(3):
            v = RNG.standard_normal(model.dim)
            _, tv = one_flow(model, name, 0.37, x, v)
            h = 1e-5
            xp, _ = one_flow(model, name, 0.37, x + h * v)
            xm, _ = one_flow(model, name, 0.37, x - h * v)
            fd = (xp - xm) / (2 * h)
            assert np.max(np.abs(tv - fd)) < 1e-8 * np.max(np.abs(fd)), name


def test_the_parts_add_up_to_the_model(case):
    """The model's energy is the sum of the parts written out above, and its
    vector field (used by accumulators that need the flow) is J∇H."""
    model, parts = case
    x = state(model)
    split = model.parts.splits[max(model.parts.splits)]
    assert model.energy(x) == pytest.approx(sum(parts[p](x) for p in split), rel=1e-13)
    out = np.empty(model.dim)
    model.parts.field(x, model.params, out)
    field = hamiltonian_field(model.energy, x)
    assert np.max(np.abs(out - field)) < 1e-7 * max(1.0, np.max(np.abs(field)))


def test_densities_add_up_to_the_conserved_quantity(case):
    model, _ = case
    x = state(model)
    total = np.sum(model.densities(x))
    if model.density_of == "norm":
        assert total == pytest.approx(model.norm(x), rel=1e-14)
    else:
        assert total == pytest.approx(model.energy(x), rel=1e-13)
    assert model.densities(x).shape == (model.n_sites,)


def test_whole_steps_match_finite_differences():
    """A whole step of the highest-order schemes, with its tangent map, on a
    2D lattice: against central differences to 1e-8. The displaced orbits
    carry the vector too (their orbits do not depend on it): one kernel, k = 1."""
    for model, scheme in ((DDNLS((3, 4), 10.0, 1.0, 2), "s17ABC8"),
                          (DisorderedKG((3, 4), 10.0, 2), "ABA864"),
                          (DDNLS(8, 4.0, 1.0, 3), "s11odr6")):
        x = state(model)
        v = RNG.standard_normal(model.dim)
        _, tv = parts_steps(model, x, v[:, None], 0.1, 3, scheme)
        h = 1e-5
        xp, _ = parts_steps(model, x + h * v, v[:, None], 0.1, 3, scheme)
        xm, _ = parts_steps(model, x - h * v, v[:, None], 0.1, 3, scheme)
        fd = (xp - xm) / (2 * h)
        assert np.max(np.abs(tv[:, 0] - fd)) < 1e-8 * np.max(np.abs(fd)), scheme


def test_fused_fput_is_bitwise_the_generic_stepper(monkeypatch):
    """For a chain with fixed ends the fused kick runs the operations of the
    band kernels in the same order: both steppers give the same bits (so
    FPUBeta's results did not change when it became FPUT with α = 0). The
    generic stepper, not the one generated for small symbolic models. (One
    vector: the order of operations is per vector, and the part stepper of
    k = 1 is the one :func:`one_flow` compiles for FPUT, not one of its own.)"""
    from varint.methods import parts, tm

    for module in (tm, parts):
        monkeypatch.setattr(module, "symbolic_fits", lambda model, k: False)
    for model in (FPUBeta(9, 1.5), FPUT(9, 0.3, 1.0)):
        x0 = state(model, 0.3)
        W0 = RNG.standard_normal((model.dim, 1))
        W0 /= np.linalg.norm(W0)
        for scheme in ("ABA864", "SABA3", "SBAB2", "s11odr6"):
            xa, Wa = parts_steps(model, x0, W0, 0.05, 100, scheme)
            xb, Wb = tangent_map_steps(model, x0, W0, 0.05, 100, scheme)
            assert np.array_equal(xa, xb) and np.array_equal(Wa, Wb), scheme


def test_fused_kg_agrees_with_the_generic_stepper():
    """The fused Klein–Gordon part stepper and the generic tangent-map
    stepper are the same map to round-off. (One vector on 16 sites: the
    part stepper of k = 1 is :func:`one_flow`'s for the Klein–Gordon
    lattices, and the generic stepper the one
    :func:`test_the_default_is_bitwise_the_named_scheme` runs; a smaller
    chain with one vector would run a stepper generated for it.)"""
    model = DisorderedKG(16, 4.0, 3)
    x0 = state(model, 0.5)
    xa, Wa = parts_steps(model, x0, np.eye(model.dim)[:, :1], 0.05, 100, "ABA864")
    xb, Wb = tangent_map_steps(model, x0, np.eye(model.dim)[:, :1], 0.05, 100, "ABA864")
    assert np.max(np.abs(xa - xb)) < 1e-13
    assert np.max(np.abs(Wa - Wb)) < 1e-12 * np.max(np.abs(Wa))


def test_band_kernels_of_the_chains_match_their_energies():
    """The band kernels (which the other methods use) are the derivatives of
    V: gradient and Hessian against differences of the potential."""
    for model in (DisorderedKG(6, 4.0, 1), FPUT(6, 0.25, 1.0)):
        q = RNG.uniform(-0.5, 0.5, model.n_dof)
        h = 1e-6
        g = np.array([(model.potential(q + h * e) - model.potential(q - h * e)) / (2 * h)
                      for e in np.eye(model.n_dof)])
        assert np.max(np.abs(model.gradient(q) - g)) < 1e-8
        H = np.array([(model.gradient(q + h * e) - model.gradient(q - h * e)) / (2 * h)
                      for e in np.eye(model.n_dof)])
        assert np.max(np.abs(model.hessian(q) - H)) < 1e-7


def test_ddnls_hopping_sign_is_a_gauge():
    """(q, p)_l → (−1)^l (q, p)_l flips the sign of the hopping: the model at
    x and the flipped-hopping model (β, ε the same) at Gx have the same
    energy; |ψ_l|² evolve identically (checked through the B and C flows,
    which flip sign with the hopping)."""
    model = DDNLS(8, 4.0, 1.0, 1, boundary="periodic")
    x = state(model)
    g = np.tile((-1.0) ** np.arange(8), 2)
    n = model.n_sites
    onsite = ddnls_parts(model)["A"]
    hop = ddnls_parts(model)["L"]
    assert model.energy(x) == pytest.approx(onsite(g * x) - hop(g * x), rel=1e-13)
    y, _ = one_flow(model, "L", 0.3, x)
    yg, _ = one_flow(model, "L", -0.3, g * x)
    assert np.allclose(y[:n] ** 2 + y[n:] ** 2, yg[:n] ** 2 + yg[n:] ** 2, atol=1e-14)


def test_disorder_and_geometry():
    kg = DisorderedKG((4, 5), 10.0, 7)
    assert kg.shape == (4, 5) and kg.n_sites == 20 and kg.dim == 40
    assert np.array_equal(kg.epsilon, np.random.default_rng(7).uniform(0.5, 1.5, 20))
    assert not kg.band_kernels and DisorderedKG(5, 4.0).band_kernels
    dd = DDNLS(30, 6.0, 1.0, 3)
    assert np.array_equal(dd.epsilon, np.random.default_rng(3).uniform(-3.0, 3.0, 30))
    assert DDNLS(30, 6.0, 1.0, 3).describe() == dd.describe()
    assert DDNLS(30, 6.0, 1.0, 4).describe() != dd.describe()
    assert kg.positions()[7].tolist() == [1.0, 2.0]


def test_initial_blocks():
    kg = DisorderedKG(21, 4.0, 0)
    x = kg.initial_block(5, 0.1, seed=3)
    h = kg.densities(x)
    assert np.allclose(h[8:13], 0.1) and np.all(h[:8] == 0) and np.all(h[13:] == 0)
    dd = DDNLS((9, 9), 10.0, 1.0, 0)
    x = dd.initial_block(3, 1.0, seed=1)
    assert dd.norm(x) == pytest.approx(9.0)
    z = dd.densities(x).reshape(9, 9)
    assert np.allclose(z[3:6, 3:6], 1.0) and z.sum() == pytest.approx(9.0)


@pytest.mark.parametrize("build, match", [
    (lambda: DisorderedKG(1), "at least 2 sites"),
    (lambda: DisorderedKG((2, 2), boundary="periodic"), "at least 3 sites"),
    (lambda: DisorderedKG((3, 3, 3)), "shape must be"),
    (lambda: DisorderedKG(8, W=0.0), "W must be a positive"),
    (lambda: DisorderedKG(8, seed=-1), "seed must be a non-negative integer"),
    (lambda: DisorderedKG(8, boundary="open"), "boundary must be one of fixed, periodic"),
    (lambda: DDNLS(8, beta=-1.0), "beta must be >= 0"),
    (lambda: DDNLS(8, W=-1.0), "W must be >= 0"),
    (lambda: FPUT(1), "n must be an integer >= 2"),
    (lambda: FPUT(8, alpha=float("nan")), "alpha must be a finite real number"),
    (lambda: DisorderedKG(10 ** 12), "needs about"),
])
def test_bad_lattices_are_refused(build, match):
    with pytest.raises(ValueError, match=match):
        build()


def test_methods_and_schemes_that_do_not_fit_are_refused():
    dd = DDNLS(8, 4.0, 1.0, 0)
    x0 = dd.initial_block(1)
    with pytest.raises(ValueError, match="method 'dop853' needs the band-Hessian kernels"):
        varint.run(dd, x0, "x1", 1.0, method="dop853")
    with pytest.raises(ValueError, match="needs the corrector flow"):
        varint.run(dd, x0, "x1", 1.0, scheme="SABA2C")
    kg2 = DisorderedKG((4, 4), 10.0)
    with pytest.raises(ValueError, match="splits into 2 parts .* a scheme over 3 parts"):
        varint.run(kg2, kg2.initial_block(1), "x1", 1.0, scheme="s9ABC6")
    with pytest.raises(ValueError, match="no band-stored Hessian"):
        kg2.hessian_band(np.zeros(16))


def test_a_lattice_runs_its_own_scheme_by_default():
    """The lattices declare their best scheme (Danieli et al. 2019: ABA864
    for the KG and FPUT chains, s11ABC6 for the DDNLS); method "tm" runs it
    when none is given — on the part stepper, or on the stepper generated
    for a small chain — and its pilot tries the same scheme. The other
    methods keep varint's DEFAULT_SCHEME."""
    from varint import stepsize
    from varint.methods import make_propagator
    from varint.methods.parts import PartsPropagator
    from varint.methods.tm import TangentMapPropagator
    from varint.schemes import DEFAULT_SCHEME, default_for

    for model, own, stepper in ((DisorderedKG(40, 4.0, 1), "ABA864", PartsPropagator),
                                (DisorderedKG((4, 4), 4.0, 1), "ABA864", PartsPropagator),
                                (FPUT(40, 0.25, 1.0), "ABA864", PartsPropagator),
                                (FPUBeta(8, 1.5), "ABA864", TangentMapPropagator),
                                (DDNLS(12, 4.0, 1.0, 1), "S11ABC6", PartsPropagator)):
        assert default_for(model).upper() == own
        prop = make_propagator("tm", model, 0.1, "qr")
        assert type(prop) is stepper and prop.scheme.name.upper() == own, model.name
        assert stepsize.default_scheme(model, None, "tm") is prop.scheme
        assert default_for(model, "tdhcc") == DEFAULT_SCHEME
    chain = FPUBeta(8, 1.5)
    assert make_propagator("tdhcc", chain, 0.1, "qr").scheme.name == DEFAULT_SCHEME
    assert stepsize.default_scheme(chain, None, "tdhcc").name == DEFAULT_SCHEME
    # A given scheme is run as given.
    assert make_propagator("tm", chain, 0.1, "qr", scheme="SABA2C").scheme.name == "SABA2C"


def test_the_default_is_bitwise_the_named_scheme():
    """A lattice's run without a scheme is its own scheme's run, bit for
    bit. (The orbit and one vector: the generic stepper of
    test_fused_kg_agrees_with_the_generic_stepper, not one for an
    indicator's accumulator; which scheme runs shows in every bit of the
    orbit and the vector alike.)"""
    model = DisorderedKG(16, 4.0, 2)
    x0 = model.initial_block(3, 0.3)
    w0 = np.eye(model.dim)[:, :1]
    a = varint.integrate(model, x0, 2.0, tau=0.1, deviations=w0)
    b = varint.integrate(model, x0, 2.0, tau=0.1, deviations=w0, scheme="ABA864")
    for name in ("state", "deviations", "energy_error"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name

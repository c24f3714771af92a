"""No option returns a wrong result under an "accurate" verdict: every option
that could spoil a result is bounded, refused with its valid range, or
warned about."""

import warnings

import numpy as np
import pytest
import sympy as sp

import varint
from varint.methods import two_particle as TP
from varint.models import DDNLS, FPUT, DisorderedKG, from_map, from_potential
from varint.models.symbolic import NonSymplecticWarning


@pytest.fixture(scope="module")
def c1_every_step():
    model, x0 = varint.paper_orbit("C1")
    return varint.lyapunov_spectrum(model, x0, 2000.0, tau=0.05, seed=1, renormalize_every=1,
                                    t_out=[2000.0])


@pytest.mark.parametrize("every", [10 ** 6, 5000, 200, 100.0])
def test_a_long_renormalisation_interval_is_capped_by_the_adaptive_rule(every, c1_every_step):
    """renormalize_every=1e6 let C1's vectors align: X2..X4 came out
    +0.039, +0.041, +0.039 instead of 0.0019, −0.0025, −0.0575. The given
    interval is a maximum under the adaptive rule's bounds, so the spectrum
    is every-step QR's to round-off (and sums to zero, as a Hamiltonian
    spectrum must)."""
    model, x0 = varint.paper_orbit("C1")
    r = varint.lyapunov_spectrum(model, x0, 2000.0, tau=0.05, seed=1, renormalize_every=every,
                                 t_out=[2000.0])
    X = r.exponents[-1]
    assert np.abs(X - c1_every_step.exponents[-1]).max() < 1e-9
    assert X[1] == pytest.approx(0.0019, abs=3e-4) and X[3] == pytest.approx(-0.0575, abs=1e-3)
    assert abs(X.sum()) < 1e-9 and r.accuracy.accurate


def test_a_short_given_interval_still_renormalises_that_often(c1_every_step):
    """A short interval the bounds allow is used (at most that many steps):
    the spectrum is every-step QR's to round-off."""
    model, x0 = varint.paper_orbit("C1")
    a = varint.lyapunov_spectrum(model, x0, 2000.0, tau=0.05, seed=1, renormalize_every=2,
                                 t_out=[2000.0])
    assert np.abs(a.exponents - c1_every_step.exponents).max() < 1e-10


@pytest.mark.parametrize("d0", [1e10, 1.0, 1e-2, 1e-13, 1e-300])
def test_a_two_particle_separation_outside_the_linear_range_is_refused(d0):
    """d0 = 1e10 gave exponents near 1200, "accurate": a separation must be
    within the linear dynamics and above round-off, [1e4 ε s, 1e-3 s] for
    states of scale s; the message gives the range, before any work."""
    model, x0 = varint.paper_orbit("R1")
    lo, hi = TP.d0_range(np.asarray(x0)[None])
    assert lo == pytest.approx(1e4 * np.finfo(float).eps * 0.558) and hi == pytest.approx(5.58e-4)
    with pytest.raises(ValueError, match=r"d0 = .* is outside \[1\.24e-12, 0\.000558\]"):
        varint.run(model, x0, "x1", 10.0, method="two-particle", d0=d0)


def test_separations_inside_the_range_agree_with_the_tangent_map():
    """Inside the range the two-particle X1 is the TM method's to its own
    error (studies/two_particle.py), at both ends of it."""
    model, x0 = varint.paper_orbit("R1")
    tm = varint.run(model, x0, "x1", 200.0, t_out=[200.0]).exponents[-1, 0]
    for d0 in (1e-8, 5e-4, 1.5e-12):
        r = varint.run(model, x0, "x1", 200.0, method="two-particle", d0=d0, t_out=[200.0])
        assert abs(r.exponents[-1, 0] - tm) < 0.05 * abs(tm), d0


def test_the_range_follows_the_scale_of_the_states():
    """A map's states of scale 1 (and the zero state, which has none) take
    d0 up to 1e-3; states of scale 1e3, d0 down to 2.2e-9."""
    assert TP.d0_range(np.zeros((1, 2)))[1] == pytest.approx(1e-3)
    assert TP.d0_range(np.full((1, 2), 1e3))[0] == pytest.approx(1e7 * np.finfo(float).eps)
    sm = varint.models.StandardMap(1.2)
    with pytest.raises(ValueError, match="d0 = 0.5 is outside"):
        varint.run(sm, [1.0, 0.5], "x1", 100, method="two-particle", d0=0.5)


def test_a_map_that_is_not_symplectic_is_warned_about():
    """x' = 2x, p' = p (det DF = 2) gave X1 + X2 = ln 2 without a word: a
    map failing DFᵀ J DF = J on sample points is warned about; its spectrum
    is what it is (the warning says the pair law does not hold)."""
    x, p = sp.symbols("x p")
    with pytest.warns(NonSymplecticWarning, match=r"not symplectic: max \|DFᵀ J DF − J\| = 1"):
        m = from_map([2 * x, p], [x, p])
    r = varint.lyapunov_spectrum(m, [0.1, 0.2], 50)
    assert r.exponents[-1].sum() == pytest.approx(np.log(2), rel=1e-12)
    with pytest.warns(NonSymplecticWarning):
        from_map([x + p, p + 0.5 * sp.sin(x) + 0.01 * p], [x, p])   # dissipative


def test_symplectic_maps_are_accepted_quietly():
    x, p = sp.symbols("x p")
    q1, q2, p1, p2 = sp.symbols("q1 q2 p1 p2")
    k1 = p1 + 0.9 * sp.sin(q1) + 0.1 * sp.sin(q1 - q2)
    k2 = p2 + 0.9 * sp.sin(q2) - 0.1 * sp.sin(q1 - q2)
    with warnings.catch_warnings():
        warnings.simplefilter("error", NonSymplecticWarning)
        from_map([x + p + 1.2 * sp.sin(x), p + 1.2 * sp.sin(x)], [x, p],
                 periods={x: 2 * sp.pi})
        from_map([q1 + k1, q2 + k2, k1, k2], [q1, q2, p1, p2])
        from_map([x + p ** 3, p], [x, p])            # a shear: exact, large derivatives


@pytest.mark.parametrize("model", [DisorderedKG(16, W=4.0, seed=1), FPUT(16),
                                   DDNLS(16, W=4.0, beta=1.0, seed=1)], ids=lambda m: m.name)
@pytest.mark.parametrize("indicator", ["dvd", "spreading"])
def test_lattice_observables_are_refused_at_zero_energy(model, indicator):
    """A lattice at rest returned 24 of 32 NaN observables, "accurate": the
    distribution over sites is 0/0 there, so the state is refused up front
    (in runs, maps and ensembles alike)."""
    zero = np.zeros(model.dim)
    quantity = "norm" if isinstance(model, DDNLS) else "energy"
    with pytest.raises(ValueError, match=f"total {quantity} .* is 0.0.*undefined"):
        varint.run(model, zero, indicator, 1.0, 0.1)
    X = np.vstack([model.initial_block(2, 0.4), zero])
    with pytest.raises(ValueError, match="of orbit 1"):
        varint.chaos_map(model, X, indicator, t_end=1.0, tau=0.1, progress=False)


def test_zero_energy_is_refused_in_an_ensemble_too():
    with pytest.raises(ValueError, match="total energy"):
        varint.ensemble(DisorderedKG, [1], lambda m, s: np.zeros(m.dim), "dvd", 1.0, 0.1,
                        params={"shape": 16}, progress=False)


def test_other_indicators_still_run_from_rest():
    """X1 of a lattice at rest is defined (its deviation vector still grows):
    only the distributions over sites are refused."""
    kg = DisorderedKG(16, W=4.0, seed=1)
    r = varint.run(kg, np.zeros(kg.dim), "x1", 1.0, 0.1)
    assert np.isfinite(r.exponents).all()


def test_huge_parameters_give_a_clear_error_not_a_type_error():
    """FPUT(alpha=1e300, beta=1e300) failed with 'must be numba functions':
    its coefficients are exact integers of 301 digits to SymPy, beyond what
    numba compiles. They are now written as doubles; beyond a double's range
    the model is refused saying so, and a run that overflows fails as such."""
    small = FPUT(4, alpha=1e300, beta=1e300)
    with pytest.raises(varint.IntegrationError, match="non-finite"):
        # SABA1: the fewest stages, the smallest kernel to compile them into.
        varint.run(small, small.initial_block(2, 0.4), "x1", 3.0, 0.1, scheme="SABA1")
    # The corrector's coefficient of SBAB2C (an FPUT chain's own default,
    # ABA864, has no corrector).
    with pytest.raises(ValueError, match=r"about 10\^401, beyond the range of a double"):
        varint.run(FPUT(4, alpha=1e200, beta=0.0), FPUT(4).initial_block(2, 0.4), "x1", 3.0,
                   0.1, scheme="SBAB2C")
    q = sp.symbols("q")
    with pytest.raises(ValueError, match="beyond the range of a double"):
        from_potential(sp.Integer(10) ** 400 * q ** 2, [q])
    # A large but representable coefficient compiles and is exact to a double.
    m = from_potential(sp.Integer(3) ** 60 * q ** 2 / 2, [q])
    assert m.gradient([1.0])[0] == float(sp.Integer(3) ** 60)

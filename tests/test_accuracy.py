"""The accuracy verdict every result carries (varint.accuracy): its energy
error against a scale that stays meaningful when H = 0, the conserved
quantities a model declares, and the AccuracyWarning when the error passes
the tolerance at which indicators stop being trustworthy — on the cases of
the issues: a coarse run, a stiff potential where τ = 0.05 makes
a regular orbit look chaotic, and potentials singular on the orbit."""

import warnings

import numpy as np
import pytest
import sympy as sp

import varint
from varint.accuracy import DEFAULT_ENERGY_TOL, Accuracy, AccuracyWarning
from varint.models import from_potential
from varint.schemes import get_scheme, stage_arrays

x, y = sp.symbols("x y")


@pytest.fixture(scope="module")
def stiff_quartic():
    """A smooth 2-dof potential no default was tuned on: a box orbit of the
    stiff quartic V = 68 (x⁴ + y⁴ + x²y²). SBAB2C at τ = 0.05 makes it
    chaotic (X1 ≈ 0.2, SALI = 0, mean MEGNO ≈ 740 at t = 1e4); at τ ≤ 0.02
    and with ABA864 at τ = 0.001 it is regular (X1 ≈ 1e-3, MEGNO → 2)."""
    model = from_potential(68 * (x**4 + y**4 + x**2 * y**2), [x, y], name="stiff quartic")
    return model, np.array([1.0, 0.5, 0.0, 0.0])


# -- every result carries a verdict ------------------------------------------------
def test_an_accurate_run_says_so_and_carries_its_largest_error():
    model, x0 = varint.paper_orbit("R1")
    with warnings.catch_warnings():
        warnings.simplefilter("error", AccuracyWarning)
        r = varint.lyapunov_spectrum(model, x0, 1000.0, tau=0.05)
    acc = r.accuracy
    assert varint.Accuracy is Accuracy and varint.AccuracyWarning is AccuracyWarning
    assert isinstance(acc, Accuracy) and acc.energy_tol == DEFAULT_ENERGY_TOL
    assert acc.energy_error == np.max(r.energy_error) and 1e-9 < acc.energy_error < 1e-6
    assert acc.conserved == {"energy": acc.energy_error}
    assert bool(acc.accurate) and acc.fraction_over == 0.0
    assert acc.verdict.startswith("accurate")
    assert acc.t_worst in r.t


def test_the_verdict_survives_save_and_load(tmp_path):
    model, x0 = varint.paper_orbit("C1")
    r = varint.lyapunov_spectrum(model, np.stack([x0, x0]), 100.0, tau=0.05)
    r.save(tmp_path / "r.npz")
    back = varint.load_result(tmp_path / "r.npz").accuracy
    assert np.array_equal(back.energy_error, r.accuracy.energy_error)
    assert np.array_equal(back.accurate, r.accuracy.accurate)
    assert back.energy_tol == r.accuracy.energy_tol and back.tau == 0.05


def test_energy_errors_are_relative_to_kinetic_plus_potential_when_h_is_zero():
    """H = 0 exactly: |ΔH|/|H| would be infinite, an absolute error
    meaningless. The scale is |T| + |V| at t = 0 (= 4 here)."""
    model = from_potential((x**2 + y**2) / 2 - 2, [x, y], name="shifted oscillator")
    x0 = np.array([0.0, 0.0, 2.0, 0.0])
    assert model.energy(x0) == 0.0 and model.energy_scale(x0) == 4.0
    r = varint.integrate(model, x0, 50.0, tau=0.1, scheme="SBAB2", t_out=50)
    expected = np.abs(model.energy(r.states)) / 4.0
    assert np.allclose(r.energy_error, expected, rtol=1e-12, atol=0)
    assert np.isfinite(r.energy_error).all() and r.energy_error.max() > 1e-6
    # A negative energy is not inflated either: H = −1.5, |T| + |V| = 2.5.
    x1 = np.array([1.0, 0.0, 0.0, 0.0])
    assert model.energy(x1) == -1.5 and model.energy_scale(x1) == 1.5


def test_sections_use_the_same_scale():
    model = from_potential((x**2 + y**2) / 2 - 2, [x, y], name="shifted oscillator")
    x0 = np.array([0.0, 0.3, 2.0, 0.0])
    s = varint.surface_of_section(model, x0, 60.0, tau=0.05)
    expected = np.abs(model.energy(s.points) - model.energy(x0)) / model.energy_scale(x0)
    ok = ~np.isnan(s.times)
    assert ok.sum() > 5
    assert np.allclose(s.energy_error[ok], expected[ok], rtol=1e-12, atol=0)
    assert bool(s.accuracy.accurate)


# -- the warning --------------------------------------------------------------------
def test_a_bounded_but_wrong_run_warns_with_the_figure_and_the_remedy():
    """The default scheme (SBAB2C) at τ = 1 on R1: a 3.9 % energy error, X1
    9 % above the accurate value at t = 1e3 (τ = 0.05, from the same seeded
    vectors), and nothing else looks wrong. Every R1 run of this file is a
    Lyapunov spectrum with the default scheme: one kernel, the first
    test's (a scheme of its own here, s11odr6 at τ = 1.5, cost ~35 CPU s
    cold for the same law)."""
    model, x0 = varint.paper_orbit("R1")
    with pytest.warns(AccuracyWarning) as record:
        r = varint.lyapunov_spectrum(model, x0, 1000.0, tau=1.0)
    msg = str(record[0].message)
    assert "relative energy error 0.0393" in msg
    assert "above energy_tol = 0.001" in msg
    assert "(step " in msg and "of tau = 1)" in msg
    assert "smaller tau" in msg and "select_scheme" in msg
    assert not r.accuracy.accurate and r.accuracy.energy_error == pytest.approx(0.0393, rel=0.01)
    good = varint.lyapunov_spectrum(model, x0, 1000.0, tau=0.05)
    assert r.exponents[-1, 0] / good.exponents[-1, 0] - 1 == pytest.approx(0.086, abs=0.02)


def test_energy_tol_sets_the_threshold():
    # The verdict is the orbit's, whatever the indicator: the R1 runs of
    # this file are all Lyapunov spectra with the default scheme, one kernel.
    model, x0 = varint.paper_orbit("R1")
    with pytest.warns(AccuracyWarning, match="above energy_tol = 1e-08"):
        r = varint.lyapunov_spectrum(model, x0, 200.0, tau=0.05, energy_tol=1e-8)
    assert r.accuracy.energy_tol == 1e-8 and not r.accuracy.accurate
    with warnings.catch_warnings():
        warnings.simplefilter("error", AccuracyWarning)
        r = varint.lyapunov_spectrum(model, x0, 200.0, tau=1.0, energy_tol=np.inf)
    assert r.accuracy.energy_error > 0.01 and bool(r.accuracy.accurate)


@pytest.mark.parametrize("bad", [0.0, -1e-3, np.nan, "1e-3", True])
def test_energy_tol_must_be_a_positive_number(bad):
    model, x0 = varint.paper_orbit("R1")
    with pytest.raises(ValueError, match="energy_tol must be a positive number"):
        varint.sali(model, x0, 10.0, tau=0.05, energy_tol=bad)


def test_a_batch_warns_with_how_many_orbits_and_the_worst():
    model, x0 = varint.paper_orbit("R1")
    _, c1 = varint.paper_orbit("C1")
    # τ = 1: R1's error 0.039 is the larger (C1's 0.033).
    with pytest.warns(AccuracyWarning, match=r"2 of 2 orbits \(100.0%\); worst: orbit 0"):
        r = varint.lyapunov_spectrum(model, np.stack([x0, c1]), 1000.0, tau=1.0)
    assert r.accuracy.energy_error.shape == (2,) and r.accuracy.fraction_over == 1.0


def test_the_stiff_case_warns_at_tau_005_and_is_regular_by_default(stiff_quartic):
    """τ = 0.05 turns the regular box orbit chaotic; the verdict says so.
    Without τ the automatic step keeps the energy error small and every
    indicator calls it regular."""
    model, x0 = stiff_quartic
    with pytest.warns(AccuracyWarning, match="regular orbits may look chaotic"):
        bad = varint.sali(model, x0, 2000.0, tau=0.05)
    assert bad.sali[-1] < 1e-8  # the wrong verdict the warning is about
    with warnings.catch_warnings():
        warnings.simplefilter("error", AccuracyWarning)
        s = varint.sali(model, x0, 2000.0)
        m = varint.megno(model, x0, 2000.0)
        lce = varint.lyapunov_spectrum(model, x0, 2000.0, n_exponents=1)
    tau = s.provenance.tau
    assert tau < 0.02 and s.provenance.tau_choice["rule"] == "pilot"
    assert s.sali[-1] > 1e-3
    assert m.mean_megno[-1] == pytest.approx(2.0, abs=0.2)
    # The converged reference: the default scheme at τ = 0.002, on the
    # kernel of lce and bad_x1 (ABA864 at the same τ, a kernel of its own,
    # ~15 CPU s cold, measured X1 within 3e-4 of it: 0.0050727 against
    # 0.0050739).
    tight = varint.lyapunov_spectrum(model, x0, 2000.0, tau=0.002, n_exponents=1)
    assert lce.exponents[-1, 0] == pytest.approx(tight.exponents[-1, 0], rel=0.1)
    assert lce.exponents[-1, 0] < 0.1 * bad_x1(model, x0)
    assert s.accuracy.energy_error < 1e-4


def bad_x1(model, x0):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AccuracyWarning)
        return varint.lyapunov_spectrum(model, x0, 2000.0, tau=0.05, n_exponents=1).exponents[
            -1, 0]


# -- potentials singular on the orbit ------------------------------------------------
@pytest.fixture(scope="module")
def inverse_x():
    return from_potential(1 / x + y**2 / 2, [x, y], name="1/x")


def test_an_orbit_that_jumps_over_a_singularity_is_caught_by_the_verdict(inverse_x):
    """Started at x = −1 the orbit falls onto x = 0, where the force 1/x²
    is huge but finite: it jumps across, and its energy error (≈ 60) is the
    only sign. (One exponent: the orbit, hence the verdict, is that of the
    whole spectrum, whose kernel is larger to compile.)"""
    with pytest.warns(AccuracyWarning, match=r"relative energy error [1-9]\d\.\d+ at t = "):
        r = varint.lyapunov_spectrum(inverse_x, [-1.0, 0.1, 0.0, 0.0], 100.0, tau=0.05,
                                     n_exponents=1)
    assert r.accuracy.energy_error > 10 and not r.accuracy.accurate


def test_an_orbit_landing_on_the_singularity_ends_in_an_integration_error(inverse_x):
    """Started so that the first drift of SABA2 lands exactly on x = 0: the
    gradient is infinite there and the run stops, naming it."""
    kinds, h, _ = stage_arrays(get_scheme("SABA2"), 0.05)
    assert kinds[0] == 0  # the step starts with a drift h[0]·p
    p = 1.0
    x_start = -(h[0] * p)
    with pytest.raises(varint.IntegrationError, match="gradient of the potential is not "
                                                      "finite") as info:
        varint.integrate(inverse_x, [x_start, 0.1, p, 0.0], 10.0, tau=0.05, scheme="SABA2")
    assert info.value.step == 1


def test_a_potential_not_real_at_the_start_is_refused():
    model = from_potential(sp.log(x) + y**2 / 2, [x, y], name="log x")
    with pytest.raises(ValueError, match=r"potential of log x is not finite at the initial "
                                         r"state, q = \[-1.0, 0.1\] \(energy = nan\)"):
        varint.lyapunov_spectrum(model, [-1.0, 0.1, 0.0, 0.0], 100.0, tau=0.05)


def test_an_orbit_entering_where_the_potential_is_not_real_fails_without_nan():
    """log x from x = 2 moving left: its gradient 1/x stays finite for
    x < 0, where V is not real; the energy there is NaN. The run ends with
    an IntegrationError at the output time where that is found (t = 3), and
    no NaN is handed out as an exponent. (One exponent: where the orbit
    fails does not depend on the vectors carried, and its kernel is smaller
    to compile than the whole spectrum's.)"""
    model = from_potential(sp.log(x) + y**2 / 2, [x, y], name="log x")
    x0 = [2.0, 0.1, -0.3, 0.0]
    with pytest.raises(varint.IntegrationError, match="the potential is not finite") as info:
        varint.lyapunov_spectrum(model, x0, 50.0, tau=0.05, t_out=50, n_exponents=1)
    assert info.value.reason.startswith("the potential is not finite")
    assert info.value.t == 3.0 and info.value.step == 60
    partial = info.value.partial
    assert len(partial.t) == 2
    assert np.isfinite(partial.exponents).all() and np.isfinite(partial.energy_error).all()
    # Flagged, it warns twice: the failure, and the energy error (NaN past
    # x = 0, so the verdict is "not accurate", checked below).
    with pytest.warns(RuntimeWarning, match="1 of 1 orbits failed"), \
            pytest.warns(AccuracyWarning, match="relative energy error"):
        r = varint.lyapunov_spectrum(model, x0, 50.0, tau=0.05, t_out=50, errors="flag",
                                     n_exponents=1)
    assert r.status == varint.Status.POTENTIAL_NONFINITE
    assert np.isfinite(r.accuracy.energy_error) and not r.accuracy.accurate


# -- conserved quantities a model declares ---------------------------------------------
class CentralPotential(varint.models.base.Model):
    """V = r²/2 + r⁴/4 in the plane, which conserves the angular momentum
    L = x p_y − y p_x besides H; ``fake`` adds x as if it were conserved."""

    def __init__(self, fake=False):
        inner = from_potential((x**2 + y**2) / 2 + (x**2 + y**2) ** 2 / 4, [x, y])
        super().__init__(2, inner.potential, inner.grad_kernel, inner.hess_kernel,
                         inner.third_kernel, inner.bandwidth, name="central")
        self.fake = fake

    def conserved(self, X):
        X = np.asarray(X, dtype=float)
        out = {"energy": self.energy(X),
               "angular momentum": X[..., 0] * X[..., 3] - X[..., 1] * X[..., 2]}
        if self.fake:
            out["x"] = X[..., 0] + 1.0
        return out


def test_declared_conserved_quantities_are_checked():
    x0 = [0.5, 0.0, 0.0, 0.7]
    r = varint.integrate(CentralPotential(), x0, 100.0, tau=0.05, t_out=20)
    acc = r.accuracy
    assert set(acc.conserved) == {"energy", "angular momentum"}
    assert acc.conserved["angular momentum"] < 1e-12  # splitting schemes keep L exactly
    assert bool(acc.accurate)
    with pytest.warns(AccuracyWarning, match="relative x error"):
        r = varint.integrate(CentralPotential(fake=True), x0, 100.0, tau=0.05, t_out=20)
    assert not r.accuracy.accurate and r.accuracy.conserved["x"] > 0.1


# -- maps ----------------------------------------------------------------------------
def test_a_map_reports_the_fraction_of_orbits_over_the_tolerance():
    model = varint.models.HenonHeiles()
    grid = varint.section_grid(model, 0.125, np.linspace(-0.4, 0.6, 6), np.linspace(-0.4, 0.4, 6))
    with pytest.warns(AccuracyWarning, match=r"the chaos map is not accurate enough .*\(\d+ of "
                                             rf"{len(grid)} orbits \("):
        r = varint.chaos_map(model, grid, "sali", t_end=200.0, tau=1.2, scheme="SBAB2C",
                             progress=False)
    acc = r.accuracy
    assert acc.energy_error.shape == (len(grid),)
    assert 0 < acc.fraction_over <= 1
    assert acc.fraction_over == np.mean(acc.energy_error > acc.energy_tol)
    with warnings.catch_warnings():
        warnings.simplefilter("error", AccuracyWarning)
        fine = varint.chaos_map(model, grid, "sali", t_end=200.0, tau=0.05, progress=False)
    assert fine.accuracy.fraction_over == 0.0


def test_the_reference_of_a_plain_model_is_its_energy_and_scale_bit_for_bit():
    # Reference and its errors evaluate T and V once for a model whose
    # energy is the base model's; they must equal Model.energy and
    # Model.energy_scale to the last bit (a model with its own conserved
    # quantities takes the general path, checked by the test above).
    from varint.accuracy import Reference, plain_energy

    model, x0 = varint.paper_orbit("R1")
    X = np.random.default_rng(3).normal(scale=0.3, size=(7, 4))
    assert plain_energy(model)
    ref = Reference(model, X)
    assert ref.values["energy"].tobytes() == model.energy(X).tobytes()
    assert ref.scales["energy"].tobytes() == model.energy_scale(X).tobytes()
    Y = X[::-1] * 1.01
    err = ref.errors(Y)["energy_error"]
    want = np.abs(model.energy(Y) - model.energy(X)) / model.energy_scale(X)
    assert err.tobytes() == want.tobytes()


def test_assess_keeps_the_worst_time_across_quantities_and_failures():
    # Two quantities, NaN after a failure, an orbit with no finite value:
    # the largest of each, the time of the larger one, NaN where none.
    from varint.accuracy import assess

    t = np.array([1.0, 2.0, 3.0])
    energy = np.array([[1e-9, 3e-9, 2e-9], [1e-9, np.nan, np.nan], [np.nan] * 3])
    other = np.array([[5e-9, 1e-9, 1e-9], [1e-10, 1e-10, np.nan], [np.nan] * 3])
    acc = assess(t, {"energy_error": energy, "conserved_error:norm": other},
                 np.array([0, 2, 2]), 4e-9, 0.1, False)
    np.testing.assert_array_equal(acc.conserved["energy"], [3e-9, 1e-9, np.nan])
    np.testing.assert_array_equal(acc.conserved["norm"], [5e-9, 1e-10, np.nan])
    np.testing.assert_array_equal(acc.t_worst, [1.0, 1.0, np.nan])
    np.testing.assert_array_equal(acc.accurate, [False, False, False])
    acc = assess(t, {"energy_error": energy[:1]}, np.array([0]), 4e-9, 0.1, True)
    assert acc.t_worst == 2.0 and acc.energy_error == 3e-9 and bool(acc.accurate)


# -- a chaos map's chunks take their rows of the map's reference ------------------
@pytest.mark.parametrize("make", [
    lambda: varint.models.HenonHeiles(),
    lambda: from_potential(sp.exp(x - y) + sp.cos(x) * y**2 + sp.log(2 + sp.sin(y)), [x, y],
                           name="transcendental"),
    lambda: varint.models.CR3BP(0.01),
])
def test_a_reference_of_some_rows_is_bitwise_the_reference_of_those_states(make):
    # The map computes the reference once and hands each chunk its rows:
    # the same bits as the chunk's states would give alone, for a plain
    # energy, transcendental V (NumPy's vector loops on other lengths) and
    # a model with its own conserved quantity (the Jacobi constant).
    model = make()
    X = 0.1 * np.random.default_rng(3).standard_normal((1037, model.dim))
    if isinstance(model, varint.models.CR3BP):
        X[:, 0] += 0.5
    whole = varint.accuracy.Reference(model, X)
    idx = np.random.default_rng(4).permutation(len(X))[:517]
    part, alone = whole.rows(idx), varint.accuracy.Reference(model, X[idx])
    assert part.values.keys() == alone.values.keys()
    for name in alone.values:
        assert part.values[name].tobytes() == alone.values[name].tobytes()
        assert part.scales[name].tobytes() == alone.scales[name].tobytes()
    errors = part.errors(X[idx] * 1.001)
    assert {k: v.tobytes() for k, v in errors.items()} == \
        {k: v.tobytes() for k, v in alone.errors(X[idx] * 1.001).items()}

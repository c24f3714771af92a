"""Every registered splitting scheme: coefficients, layout, measured order,
reversibility, symplecticity of its tangent map, and the tangent map being
the exact derivative of the numerical map."""

import math

import numpy as np
import pytest

import varint
from varint.schemes import (DEFAULT_SCHEME, DRIFT, KICK, CompositionScheme, ProcessedScheme,
                            SplittingScheme, register_scheme, registered, scheme_word,
                            stage_arrays)

from tests.helpers import fitted_slope, generic_tangent_map_steps

NAMES = [s.name for s in registered(2)]


def test_registry_has_the_literature_schemes():
    expected = {f"{f}{n}{c}" for f in ("SABA", "SBAB") for n in range(1, 5) for c in ("", "C")}
    expected |= {"ABA864", "ABAH864", "FR4", "s9odr6", "s11odr6", "SRKN14a"}
    expected |= {"s15odr8", "s17odr8", "s35odr10"}
    assert expected <= set(NAMES)


@pytest.mark.parametrize("name", ["FR4", "s9odr6", "s11odr6", "s15odr8", "s17odr8", "s35odr10"])
def test_compositions_meet_their_odd_power_conditions(name):
    """A symmetric composition Π S2(γ_i τ) of order p needs Σγ_i = 1 and
    Σγ_i^k = 0 for every odd k < p (Hairer, Lubich & Wanner, Geometric
    Numerical Integration, Sect. V.3.2: the trees with one vertex); the next
    odd power sum does not vanish. A single wrong digit of a published γ
    breaks these sums far above round-off."""
    s = varint.get_scheme(name)
    half = list(s.kicks)  # the kicks of a leapfrog composition are its γ
    full = half + half[-2::-1]
    assert math.fsum(full) == pytest.approx(1.0, abs=1e-15)
    for k in range(3, s.order, 2):
        assert abs(math.fsum(g ** k for g in full)) < 1e-15, k
    assert abs(math.fsum(g ** (s.order + 1) for g in full)) > 1e-6


def test_lookup_is_case_insensitive_and_errors_list_names():
    assert varint.get_scheme("sbab2c") is varint.get_scheme("SBAB2C")
    with pytest.raises(ValueError, match="unknown scheme 'RK4'.*SABA1.*SRKN14a.*s21ABC8"):
        varint.get_scheme("RK4")


def test_one_registry_resolves_two_and_k_part_schemes():
    """One registry and one resolver for every scheme: a composition over
    three parts resolves like a two-part scheme, and is refused (naming the
    models it runs on) where the drift and kick of H = T + V are needed."""
    abc2 = varint.get_scheme("abc2")
    assert isinstance(abc2, CompositionScheme) and abc2 is varint.SCHEMES["ABC2"]
    assert varint.get_scheme(abc2) is abc2
    assert varint.get_scheme("SBAB2C", n_parts=2).n_parts == 2
    with pytest.raises(ValueError, match="'ABC2' composes the flows of 3 parts.*DDNLS"):
        varint.get_scheme("ABC2", n_parts=2)
    processed = {s for s in registered() if isinstance(s, ProcessedScheme)}
    assert set(registered()) == set(registered(2)) | set(registered(3)) | processed
    assert not set(registered(2)) & set(registered(3))
    assert DEFAULT_SCHEME in varint.SCHEMES and varint.get_scheme(DEFAULT_SCHEME).name == "SBAB2C"
    with pytest.raises(ValueError, match="already registered"):
        register_scheme(CompositionScheme("abc2", 3, (1.0,), 2))


@pytest.mark.parametrize("name", NAMES)
def test_coefficients_sum_to_one_and_layout_is_palindromic(name):
    s = varint.get_scheme(name)
    stages = s.stages()
    assert math.isclose(math.fsum(c for k, c in stages if k == DRIFT), 1.0, abs_tol=1e-15)
    assert math.isclose(math.fsum(c for k, c in stages if k == KICK), 1.0, abs_tol=1e-15)
    assert list(stages) == list(stages)[::-1]
    kinds = [k for k, _ in stages]
    assert all(a != b for a, b in zip(kinds[:-1], kinds[1:], strict=True)), "drifts and kicks alternate"
    assert kinds[0] == (DRIFT if s.drift_first else KICK)


def test_paper_scheme_is_sbab2c_as_published():
    s = varint.get_scheme("SBAB2C")
    assert s.stages() == ((KICK, 1 / 6), (DRIFT, 0.5), (KICK, 2 / 3), (DRIFT, 0.5), (KICK, 1 / 6))
    assert s.corrector == 1 / 72 and s.order == 4
    kinds, h, hc = stage_arrays(s, 0.1)
    # Corrector fused into the outer kicks with length −gτ³/2 (paper eq. 22).
    assert hc[0] == hc[-1] == pytest.approx(-(1 / 72) * 0.1 ** 3 / 2)
    assert s.force_evaluations == 2  # first and last kick share q across steps


def test_invalid_schemes_are_refused():
    with pytest.raises(ValueError, match="sum to"):
        SplittingScheme("bad", True, (0.5,), (0.9,), order=2)
    with pytest.raises(ValueError, match="palindromic"):
        SplittingScheme("bad", True, (0.5,), (0.5, 0.2, 0.3), order=2)


def _energy_errors(model, x0, tau, scheme, t_end=20.0, every=1):
    """|ΔH| / (|T| + |V|) after every ``every`` steps up to ``t_end``, on
    the generic stepper (one compilation for all schemes; see
    :func:`tests.helpers.generic_tangent_map_steps`). The test measures the
    energy error itself, at steps chosen large enough to be above
    round-off. With four deviation vectors (the orbit does not depend on
    them), as the tests below: the generic stepper is compiled per number
    of vectors."""
    n = int(round(t_end / tau))
    xs, _, _ = generic_tangent_map_steps(model, x0, np.eye(4), tau=tau, n_steps=n,
                                         scheme=scheme, every=every)
    return (model.energy(xs) - model.energy(x0)) / model.energy_scale(x0)


@pytest.mark.parametrize("name", NAMES)
def test_measured_order_of_energy_error(name, c1):
    """Slope of max |ΔH/H| over t ≤ 20 against τ on Hénon–Heiles (C1,
    H = 1/8) equals the documented order ± 0.3."""
    model, x0 = c1
    s = varint.get_scheme(name)
    if s.order >= 10:
        # The order-10 s35odr10 goes from pre-asymptotic (slope 13 at
        # τ ≥ 0.6) to round-off (1e-14 at τ = 0.2) within a factor 3 of τ,
        # where a max over a window of an oscillating error scatters (this
        # ladder's max gives 10.4 to 10.6 depending on the rungs): the RMS
        # of the error at the times common to every τ (every 2 up to 20)
        # scales exactly as τ^10, measured 10.13.
        taus = (0.5, 0.4, 1 / 3, 0.25)
        errs = [np.sqrt(np.mean(_energy_errors(model, x0, tau, name,
                                               every=round(2.0 / tau)) ** 2))
                for tau in taus]
    else:
        # Sixth-order schemes reach round-off at τ = 0.05; measure them earlier.
        taus = (0.4, 0.2, 0.1) if s.order >= 6 else (0.2, 0.1, 0.05)
        errs = [np.max(np.abs(_energy_errors(model, x0, tau, name))) for tau in taus]
    assert abs(fitted_slope(taus, errs) - s.order) < 0.3, errs


@pytest.mark.parametrize("name", NAMES)
def test_reversibility(name, c1):
    """S(−τ)ⁿ S(τ)ⁿ returns the start (orbit and tangent map) to round-off."""
    model, x0 = c1
    W0 = np.eye(4)
    x, W = generic_tangent_map_steps(model, x0, W0, tau=0.1, n_steps=200, scheme=name)
    xb, Wb = generic_tangent_map_steps(model, x, W, tau=-0.1, n_steps=200, scheme=name)
    assert np.max(np.abs(xb - x0)) < 1e-12
    assert np.max(np.abs(Wb - W0)) < 1e-10


def test_momentum_flip_reversibility(c1):
    """Flipping p after n steps and stepping n more returns the flipped start."""
    model, x0 = c1
    flip = np.array([1.0, 1.0, -1.0, -1.0])
    W = np.eye(4)    # unused: the stepper of the other tests
    x, _ = generic_tangent_map_steps(model, x0, W, tau=0.1, n_steps=300, scheme="SABA3C")
    xb, _ = generic_tangent_map_steps(model, x * flip, W, tau=0.1, n_steps=300, scheme="SABA3C")
    assert np.max(np.abs(xb * flip - x0)) < 1e-12


J4 = np.block([[np.zeros((2, 2)), np.eye(2)], [-np.eye(2), np.zeros((2, 2))]])


def _J(n):
    return np.block([[np.zeros((n, n)), np.eye(n)], [-np.eye(n), np.zeros((n, n))]])


@pytest.mark.parametrize("name", NAMES)
def test_tangent_map_is_symplectic(name, c1):
    model, x0 = c1
    _, M = generic_tangent_map_steps(model, x0, np.eye(4), tau=0.1, n_steps=50, scheme=name)
    assert np.max(np.abs(M.T @ J4 @ M - J4)) < 1e-13


@pytest.mark.parametrize("model", [varint.models.ThreeDof(), varint.models.FPUBeta(5, 1.5)],
                         ids=["ThreeDof", "FPU5"])
@pytest.mark.parametrize("name", ["SBAB2C", "SABA3C", "ABA864"])
def test_tangent_map_is_symplectic_with_masses_and_bands(model, name):
    n = model.n_dof
    x0 = np.linspace(-0.2, 0.3, 2 * n)
    _, M = generic_tangent_map_steps(model, x0, np.eye(2 * n), tau=0.05, n_steps=50,
                                     scheme=name)
    J = _J(n)
    assert np.max(np.abs(M.T @ J @ M - J)) < 1e-13


@pytest.mark.parametrize("name", NAMES)
def test_tangent_map_is_the_derivative_of_the_map(name, c1):
    """TS equals the central finite difference of Sⁿ, with error ∝ h²."""
    model, x0 = c1
    n = 40
    _, M = generic_tangent_map_steps(model, x0, np.eye(4), tau=0.1, n_steps=n, scheme=name)
    hs = (4e-3, 2e-3, 1e-3)
    errs = []
    for h in hs:
        fd = np.empty((4, 4))
        for i in range(4):
            e = np.zeros(4)
            e[i] = h
            xp, _ = generic_tangent_map_steps(model, x0 + e, np.eye(4), tau=0.1, n_steps=n,
                                              scheme=name)
            xm, _ = generic_tangent_map_steps(model, x0 - e, np.eye(4), tau=0.1, n_steps=n,
                                              scheme=name)
            fd[:, i] = (xp - xm) / (2 * h)
        errs.append(np.max(np.abs(fd - M)) / np.max(np.abs(M)))
    assert errs[-1] < 1e-4
    assert abs(fitted_slope(hs, errs) - 2.0) < 0.3, errs


def test_scheme_fields_are_normalised_and_checked():
    s = SplittingScheme("LF-array", True, np.array([0.5]), [1.0], order=np.int64(2),
                        corrector=np.float32(0.5))
    assert s.drifts == (0.5,) and s.kicks == (1.0,) and type(s.order) is int
    assert type(s.corrector) is float and hash(s)
    for bad, match in [(dict(order=2.5), "order must be a positive integer, got 2.5"),
                       (dict(order=float("nan")), "order must be a positive integer"),
                       (dict(corrector="abc"), "corrector must be a finite number"),
                       (dict(drifts=(float("nan"),)), r"drifts\[0\] must be a finite real"),
                       (dict(kicks=(float("inf"),)), r"kicks\[0\] must be a finite real"),
                       (dict(kicks=("1",)), r"kicks\[0\] must be a finite real number, got '1'")]:
        args = dict(name="LF", drift_first=True, drifts=(0.5,), kicks=(1.0,), order=2)
        args.update(bad)
        with pytest.raises(ValueError, match="scheme 'LF': " + match):
            SplittingScheme(**args)


def test_register_scheme_refuses_what_is_not_a_scheme():
    before = dict(varint.SCHEMES)
    with pytest.raises(ValueError, match="register_scheme needs a SplittingScheme or "
                                         "CompositionScheme, got str"):
        varint.register_scheme("SBAB9")
    assert before == varint.SCHEMES


# -- schemes over k parts (the lattices) ---------------------------------------
PART_NAMES = [s.name for s in registered(3)]


def test_part_registry_holds_the_verified_compositions():
    expected = {"ABC2", "ABC4_Y", "ABC4_S", "ABC6_Y", "ABC6_YA", "s9ABC6", "s11ABC6", "s13ABC6",
                "s15ABC8", "s17ABC8", "s21ABC8"}
    assert expected == set(PART_NAMES)
    # Danieli et al. 2019 name s19ABC8, but its 19-stage table was not found:
    # it is not registered, and no other table stands in for it.
    assert "S19ABC8" not in varint.SCHEMES
    with pytest.raises(ValueError, match="composes the flows of 3 parts"):
        varint.get_scheme("s9ABC6", n_parts=2)


@pytest.mark.parametrize("name", PART_NAMES)
def test_compositions_are_palindromic_and_consistent(name):
    s = varint.get_scheme(name)
    word = s.word()
    assert word == word[::-1]
    for part in range(3):
        assert math.isclose(math.fsum(c for p, c in word if p == part), 1.0, abs_tol=1e-14)
    assert all(a[0] != b[0] for a, b in zip(word[:-1], word[1:], strict=True)), "adjacent flows merged"
    # A's merge across stages: s + 1 A flows, 2s B flows, s C flows.
    assert s.flows_per_step() == (s.stages + 1, 2 * s.stages, s.stages)


def test_invalid_compositions_are_refused():
    with pytest.raises(ValueError, match="sum to"):
        CompositionScheme("bad", 3, (0.4,), order=2)
    with pytest.raises(ValueError, match="n_parts must be an integer >= 2"):
        CompositionScheme("bad", 1, (1.0,), order=2)


def test_corrector_schemes_become_words_with_correctors_outside():
    word = scheme_word(varint.get_scheme("SABA2C"))
    assert word[0][0] == word[-1][0] == varint.schemes.CORRECTOR
    assert word[0][2] == 3 and word[0][1] == pytest.approx(-varint.get_scheme("SABA2C")
                                                           .corrector / 2)


def _rms_energy_error(model, x0, tau, scheme, t_end=8.0, every=0.4):
    """RMS of ΔH/H at the times every 0.4 up to 8: common to all step sizes
    τ = 0.4/m, so the error at each time scales exactly as τ^order (a max
    over a window of an oscillating error, as above, scatters by ±0.3 for
    the 6th- and 8th-order compositions)."""
    t_out = np.arange(1, int(round(t_end / every)) + 1) * every
    # Large steps on purpose (an order is measured above round-off).
    r = varint.integrate(model, x0, t_end, tau=tau, scheme=scheme, t_out=t_out, energy_tol=1.0)
    e = model.energy(r.states)
    h0 = model.energy(x0)
    return float(np.sqrt(np.mean(((e - h0) / h0) ** 2)))


LADDER = tuple(0.4 / m for m in (3, 4, 5, 6, 8))   # τ = 0.133 … 0.05


@pytest.fixture(scope="module")
def ddnls_cases():
    rng = np.random.default_rng(1)
    out = []
    for shape in (16, (4, 4)):
        model = varint.models.DDNLS(shape, 4.0, 1.0, 1)
        out.append((model, rng.uniform(-1, 1, model.dim)))
    return out


@pytest.mark.parametrize("name", PART_NAMES)
def test_measured_order_of_three_part_schemes(name, ddnls_cases):
    """Energy-error slope against τ on the DDNLS (1D, 16 sites, and 2D,
    4 × 4; W = 4, β = 1, random q, p in [−1, 1]) within 0.2 of the order."""
    s = varint.get_scheme(name)
    for model, x0 in ddnls_cases:
        errs = [_rms_energy_error(model, x0, tau, name) for tau in LADDER]
        assert abs(fitted_slope(LADDER, errs) - s.order) < 0.2, (model.name, errs)


@pytest.mark.parametrize("model, scheme", [
    (varint.models.DisorderedKG(16, 4.0, 1), "ABA864"),
    (varint.models.DisorderedKG((4, 4), 10.0, 1), "ABA864"),
    (varint.models.FPUT(16, 0.25, 1.0, boundary="periodic"), "ABA864"),
    (varint.models.FPUT(16, 0.25, 1.0, boundary="periodic"), "s11odr6"),
    (varint.models.DisorderedKG(16, 4.0, 2, boundary="periodic"), "SABA2"),
    (varint.models.DDNLS(16, 4.0, 1.0, 1), "ABA864"),
    (varint.models.DDNLS((4, 4), 4.0, 1.0, 1), "s11odr6"),
    (varint.models.FPUT(16, 0.25, 1.0), "SABA2C"),
], ids=["KG1D-ABA864", "KG2D-ABA864", "FPUTring-ABA864", "FPUTring-s11odr6", "KGring-SABA2",
        "DDNLS2part-ABA864", "DDNLS2D2part-s11odr6", "FPUT-SABA2C"])
def test_measured_order_of_two_part_schemes_on_lattices(model, scheme):
    """The two-part schemes through the lattices' fused flows keep their
    order (ABA864's (8,6,4) is 4 when neither part is small). A fixed-end
    chain runs the stepper generated for its scheme (KG1D, FPUT with
    SABA2C), a ring or 2D lattice the part stepper of its model, which
    takes every scheme as data (FPUT's ring runs ABA864 and s11odr6 on
    one kernel)."""
    rng = np.random.default_rng(3)
    x0 = rng.uniform(-0.5, 0.5, model.dim)
    errs = [_rms_energy_error(model, x0, tau, scheme) for tau in LADDER]
    order = varint.get_scheme(scheme).order
    assert abs(fitted_slope(LADDER, errs) - order) < 0.2, errs


def test_ddnls_norm_is_the_second_integral(ddnls_cases):
    """The two-part split (every flow a rotation) conserves the norm to
    round-off; the three-part split does not (B and C each change it), its
    norm error falls with the scheme's order."""
    model, x0 = ddnls_cases[0]
    s0 = model.norm(x0)

    def worst(scheme, tau):
        # The coarse three-part runs are meant to err: the accuracy verdict
        # (its warning) is not what this test checks.
        r = varint.integrate(model, x0, 20.0, tau=tau, scheme=scheme, t_out=50, energy_tol=1.0)
        return np.max(np.abs(model.norm(r.states) / s0 - 1))
    # Round-off of 200 steps of the eigenvector transforms: ~3e-13.
    assert worst("ABA864", 0.1) < 2e-12
    assert worst("s11odr6", 0.1) < 2e-12
    errs = [worst("ABC4_Y", tau) for tau in (0.1, 0.05, 0.025)]
    assert errs[-1] > 1e-11 and abs(fitted_slope((0.1, 0.05, 0.025), errs) - 4) < 0.3
    assert worst("s17ABC8", 0.1) < 1e-3 * worst("ABC2", 0.1)


def test_two_and_three_part_splits_converge_to_the_same_orbit(ddnls_cases):
    model, x0 = ddnls_cases[1]
    a = varint.integrate(model, x0, 2.0, tau=0.01, scheme="s17ABC8").state
    b = varint.integrate(model, x0, 2.0, tau=0.01, scheme="s11odr6").state
    assert np.max(np.abs(a - b)) < 1e-10


def test_the_default_scheme_is_named_in_one_place():
    # Every module reads DEFAULT_SCHEME; the name itself appears as code
    # only where it is registered and among the candidates the scheme
    # selection tries (not as anyone's default).
    import ast
    from pathlib import Path

    package = Path(varint.__file__).parent
    named = sorted(str(path.relative_to(package)) for path in package.rglob("*.py")
                   if any(isinstance(node, ast.Constant) and node.value == DEFAULT_SCHEME
                          for node in ast.walk(ast.parse(path.read_text(encoding="utf-8")))))
    assert named == ["schemes.py", "selection.py"]

"""The two-particle method: it follows the TM method's tangent dynamics to
the size its theory allows (an error ∝ d0 from the curvature of the flow,
one growing as d0 → 0 from rounding the separation), for flows and maps
(separations across a periodic cut included), for every indicator, with
both renormalisation rules, and resumes bitwise."""

import numpy as np
import pytest

import varint
from varint.models import StandardMap
from tests.helpers import assert_bitwise_equal, fitted_slope, hook_advance


def test_spectrum_agrees_with_the_tm_method_at_the_best_separation(r1, c1):
    for model, x0 in (r1, c1):
        tm = varint.lyapunov_spectrum(model, x0, 200.0, t_out=[200.0])
        tp = varint.lyapunov_spectrum(model, x0, 200.0, method="two-particle", d0=1e-8,
                                      t_out=[200.0])
        assert np.abs(tp.exponents - tm.exponents).max() < 1e-7
        # The reference orbit is the TM method's scheme and step; the TM
        # method's generated stepper evaluates the derivatives in another
        # order, so they agree to round-off grown by the chaotic divergence
        # (e^{χ1 t} ≈ 1e4 on C1 at t = 200).
        np.testing.assert_allclose(tp.state, tm.state, rtol=0, atol=1e-10)


def test_error_grows_as_d0_and_as_d0_goes_to_zero(r1):
    """Against the TM method on the same orbit: ∝ d0 for 1e-6 ≤ d0 ≤ 1e-4
    (measured slope 1.00), growing again below 1e-10 (rounding), down to the
    smallest d0 the method accepts (1e4 ε times the orbit's scale)."""
    model, x0 = r1
    tm = varint.run(model, x0, "x1", 200.0, t_out=[200.0]).exponents[-1, 0]

    def error(d0):
        r = varint.run(model, x0, "x1", 200.0, method="two-particle", d0=d0, t_out=[200.0])
        return abs(r.exponents[-1, 0] - tm)

    large = [1e-6, 1e-5, 1e-4]
    assert fitted_slope(large, [error(d) for d in large]) == pytest.approx(1.0, abs=0.1)
    small = [1.5e-12, 4e-12, 1e-11]
    errs = [error(d) for d in small]
    assert fitted_slope(small, errs) < -0.7
    assert min(errs) > 10 * error(1e-8)


def test_raw_vectors_approximate_the_tangent_map(r1):
    """Without renormalisation the separations, scaled back by the
    rescalings, follow the tangent map of the whole run."""
    model, x0 = r1
    W0 = np.eye(4)[:, :2]
    tm = varint.integrate(model, x0, 20.0, deviations=W0)
    tp = varint.integrate(model, x0, 20.0, deviations=W0, method="two-particle", d0=1e-7)
    rel = np.abs(tp.deviations - tm.deviations).max() / np.abs(tm.deviations).max()
    assert 1e-12 < rel < 1e-5


def test_maps_and_separations_across_the_periodic_cut():
    sm = StandardMap(10.0)
    for x0 in ([1.0, 0.5], [2 * np.pi - 1e-12, 0.3], [0.0, 0.3]):
        tm = varint.run(sm, x0, "x1", 1e4, t_out=[1e4]).exponents[-1, 0]
        tp = varint.run(sm, x0, "x1", 1e4, method="two-particle", t_out=[1e4])
        assert abs(tp.exponents[-1, 0] - tm) < 1e-6
    cm = varint.models.CoupledStandardMaps(1.5, 1.5, 0.1)
    g = varint.gali(cm, (0.55, 0.1, 0.62, 0.2), 1e3, k=(2, 3), method="two-particle")
    ref = varint.gali(cm, (0.55, 0.1, 0.62, 0.2), 1e3, k=(2, 3))
    assert g.gali[2][-1] == pytest.approx(ref.gali[2][-1], rel=1e-4)


def test_threshold_rule_keeps_the_indicators(c1):
    """With d_max the neighbours drift out to d_max before they are put
    back; the normalised vectors are the same to the curvature error."""
    model, x0 = c1
    ref = varint.gali(model, x0, 100.0, k=(2, 3))
    g = varint.gali(model, x0, 100.0, k=(2, 3), method="two-particle", d0=1e-9, d_max=1e-6)
    for k in (2, 3):  # 1 % while GALI_3 falls over 5 decades
        assert np.allclose(np.log(g.gali[k]), np.log(ref.gali[k]), atol=1e-2)
    m = varint.megno(model, x0, 100.0, method="two-particle", d_max=1e-6)
    assert m.mean_megno[-1] == pytest.approx(varint.megno(model, x0, 100.0).mean_megno[-1],
                                             rel=1e-4)


@pytest.mark.parametrize("options", [{}, {"d_max": 1e-6}])
def test_resumes_bitwise(c1, tmp_path, monkeypatch, options):
    model, x0 = c1

    def run(**kw):
        return varint.sali(model, x0, 200.0, method="two-particle", **options, **kw)

    reference = run()

    class Crash(Exception):
        pass

    def crash():
        raise Crash

    path = tmp_path / "tp.ckpt"
    with monkeypatch.context() as patch:
        hook_advance(patch, "two-particle", 4, crash)
        with pytest.raises(Crash):
            run(checkpoint=path, checkpoint_interval=0)
    assert_bitwise_equal(run(checkpoint=path, checkpoint_interval=0), reference)


def test_bad_options_are_refused(c1):
    model, x0 = c1
    with pytest.raises(ValueError, match="d0 must be a positive"):
        varint.sali(model, x0, 10.0, method="two-particle", d0=0.0)
    with pytest.raises(ValueError, match="d_max must exceed"):
        varint.sali(model, x0, 10.0, method="two-particle", d0=1e-8, d_max=1e-9)
    with pytest.raises(ValueError, match="orthogonal"):
        varint.lyapunov_spectrum(model, x0, 10.0, method="two-particle", d_max=1e-6)
    with pytest.raises(TypeError, match="unknown option 'd1'"):
        varint.sali(model, x0, 10.0, method="two-particle", d1=1e-8)
    with pytest.raises(ValueError, match="no splitting scheme"):
        varint.sali(StandardMap(1.0), [1.0, 0.0], 10, method="two-particle", scheme="SBAB2")

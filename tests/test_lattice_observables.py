"""The lattice observables ("spreading", "dvd") against laws from theory
and an independent integrator: the exact Bessel solution of the clean
linear DDNLS, m₂ = 2t² per dimension, and the mLCE of DOP853's variational
equations."""

import numpy as np
import pytest
from scipy.special import jv

import varint
from varint.indicators.lattice import moments
from varint.models import DDNLS, DisorderedKG


def test_moments_of_known_distributions():
    """A single site: m₂ = 0, P = 1; N equal sites on a line: m₂ =
    (N² − 1)/12, P = N; on an nx × ny rectangle the variances add."""
    line = np.arange(9.0)[:, None]
    z = np.zeros(9)
    z[4] = 3.0
    centre, m2, part = moments(z, line)
    assert centre[0] == 4.0 and m2 == 0.0 and part == 1.0
    _, m2, part = moments(np.ones(9), line)
    assert m2 == pytest.approx(80 / 12, rel=1e-14) and part == pytest.approx(9, rel=1e-14)
    kg = DisorderedKG((5, 8), 10.0, 0)
    _, m2, part = moments(np.ones(40), kg.positions())
    assert m2 == pytest.approx(24 / 12 + 63 / 12, rel=1e-14) and part == pytest.approx(40)
    # A narrow packet far from the origin keeps its digits.
    far = np.arange(10 ** 7, 10 ** 7 + 3, dtype=float)[:, None]
    _, m2, _ = moments(np.array([1.0, 0.0, 1.0]), far)
    assert m2 == pytest.approx(1.0, rel=1e-12)


def test_spreading_on_the_clean_linear_chain_is_the_bessel_solution():
    """W = 0, β = 0, one site excited: |ψ_l(t)|² = J_l(2t)² exactly, so
    m₂ = Σ l² J_l(2t)² = 2t² (ballistic), while the packet is far from the
    ends. Integrated with the three-part s11ABC6 (τ = 0.02)."""
    model = DDNLS(61, 0.0, 0.0, 0)
    x0 = model.initial_block(1, 1.0)
    r = varint.run(model, x0, "spreading", 8.0, 0.02, scheme="s11ABC6", t_out=[2.0, 4.0, 8.0],
                   profiles=True)
    assert np.allclose(r["m2"], 2 * r.t ** 2, rtol=1e-10, atol=0)
    sites = np.arange(61) - 30
    for profile, t in zip(r["profile"], r.t, strict=True):
        assert np.max(np.abs(profile - jv(sites, 2 * t) ** 2)) < 1e-11
    assert np.allclose(r["total"], 1.0, rtol=1e-10)


def test_spreading_on_the_clean_square_lattice_adds_both_directions():
    """In 2D the x and y hopping commute: m₂ = 2t² + 2t² = 4t²."""
    model = DDNLS((31, 31), 0.0, 0.0, 0)
    r = varint.run(model, model.initial_block(1, 1.0), "spreading", 4.0, 0.02,
                   scheme="s9ABC6", t_out=[2.0, 4.0])
    assert np.allclose(r["m2"], 4 * r.t ** 2, rtol=1e-7, atol=0)
    assert np.allclose(r["total"], 1.0, rtol=1e-9)


@pytest.mark.slow
def test_dvd_mlce_matches_dop853_variational_equations():
    """Λ(t) of the "dvd" indicator (TM, ABA864 through the fused KG
    kicks) against DOP853 on the variational equations (band Hessian),
    same seeded deviation vector; the DVD and the packet are distributions
    over the 16 sites."""
    kg = DisorderedKG(16, 4.0, 1)
    x0 = kg.initial_block(1, 0.4, seed=1)
    t_out = [50.0, 100.0, 200.0]
    a = varint.run(kg, x0, "dvd", 200.0, 0.05, scheme="ABA864", t_out=t_out, seed=3,
                   profiles=True)
    b = varint.run(kg, x0, "x1", 200.0, 0.05, method="dop853", t_out=t_out, seed=3)
    assert np.allclose(a["x1"], b.exponents[:, 0], rtol=1e-5, atol=0), (a["x1"], b.exponents)
    assert np.allclose(a["dvd"].sum(axis=-1), 1.0, rtol=1e-12)
    assert np.all((a["dvd_participation"] >= 1) & (a["dvd_participation"] <= 16))
    # The packet's energy is conserved by ABA864 at τ = 0.05 to ~1e-6.
    assert np.allclose(a["total"], kg.energy(x0), rtol=1e-4)


def test_observables_need_a_lattice():
    hh = varint.models.HenonHeiles()
    with pytest.raises(ValueError, match="lattice observables need a lattice model"):
        varint.run(hh, [0.0, 0.1, 0.3, 0.0], "spreading", 1.0)
    kg = DisorderedKG(8, 4.0, 0)
    with pytest.raises(ValueError, match="follows one deviation vector, got 2"):
        varint.run(kg, kg.initial_block(1), "dvd", 1.0, deviations=np.eye(kg.dim)[:, :2])

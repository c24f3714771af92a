"""MEGNO, FLI and OFLI against their known laws (Cincotta & Simó 2000;
Froeschlé et al. 1997; Fouchard et al. 2002)."""

import numpy as np
import pytest

import varint
from varint.models import FPUBeta


def test_mean_megno_tends_to_two_on_a_torus(r1):
    r = varint.megno(*r1, 1e5, t_out=[1e3, 1e4, 1e5])
    assert abs(r.mean_megno[-1] - 2.0) < 0.1  # measured 1.985 (seed 0), 1.995 (seed 3)
    assert abs(r.mean_megno[-1] - 2.0) < abs(r.mean_megno[0] - 2.0)


def test_mean_megno_grows_like_half_the_lyapunov_exponent_times_t(c1):
    """Ȳ ≈ χ₁ t/2 on chaotic orbits: between t = 5e3 and 1e4 Ȳ grows at half
    the rate at which the same vector's log-stretching grows."""
    model, x0 = c1
    times = [5e3, 1e4]
    r = varint.megno(model, x0, 1e4, t_out=times)
    lce = varint.lyapunov_spectrum(model, x0, 1e4, t_out=times, n_exponents=1)
    S = lce.exponents[:, 0] * lce.t  # ln‖w(t)‖ of the same initial vector
    rate = (S[1] - S[0]) / (times[1] - times[0])
    slope = (r.mean_megno[1] - r.mean_megno[0]) / (times[1] - times[0])
    assert slope == pytest.approx(rate / 2, rel=0.15)


def test_megno_tends_to_zero_for_an_isochronous_linear_chain():
    """β = 0: the FPU chain is a set of harmonic oscillators, every
    deviation stays bounded and Ȳ → 0 (stable periodic motion)."""
    x0 = np.concatenate([np.full(8, 0.1), np.zeros(8)])
    r = varint.megno(FPUBeta(8, 0.0), x0, 1e3, t_out=[1e2, 1e3])
    assert abs(r.mean_megno[-1]) < 0.02 and abs(r.mean_megno[-1]) < abs(r.mean_megno[0])


def test_fli_is_the_running_maximum_of_the_log_stretching(c1):
    """FLI(t) = sup_{s≤t} ln‖w(s)‖ ≥ ln‖w(t)‖ = t·X1(t) of the same vector,
    and OFLI ≤ FLI since the orthogonal part is never longer."""
    model, x0 = c1
    times = np.linspace(50, 2000, 40)
    r = varint.megno(model, x0, 2000.0, t_out=times)
    lce = varint.lyapunov_spectrum(model, x0, 2000.0, t_out=times, n_exponents=1)
    S = lce.exponents[:, 0] * lce.t
    assert np.all(r.fli >= S - 1e-9)
    assert np.all(np.diff(r.fli) >= 0)
    assert np.all(r.ofli <= r.fli + 1e-9)
    assert np.isclose(r.fli[-1], np.maximum.accumulate(S)[-1], rtol=0.05)


def test_fli_separates_regular_from_chaotic(r1, c1):
    reg = varint.megno(*r1, 1e3, t_out=[1e3])
    cha = varint.megno(*c1, 1e3, t_out=[1e3])
    assert reg.fli[-1] < 10 < 30 < cha.fli[-1]  # ln t vs χ₁ t


def test_megno_is_tm_only(c1):
    with pytest.raises(ValueError, match="method='tm' only"):
        varint.megno(*c1, 10.0, method="dop853")


def test_megno_resumes_bitwise_from_a_checkpoint(tmp_path, c1):
    """The accumulators live in the run state, so a resumed run is the
    uninterrupted one, bit for bit."""
    model, x0 = c1
    full = varint.megno(model, x0, 200.0, t_out=4)
    path = tmp_path / "m.ckpt"
    part = varint.megno(model, x0, 200.0, t_out=4, checkpoint=path, checkpoint_interval=0.0)
    again = varint.megno(model, x0, 200.0, t_out=4, checkpoint=path)
    for name in ("megno", "mean_megno", "fli", "ofli"):
        assert np.array_equal(getattr(full, name), getattr(part, name))
        assert np.array_equal(getattr(full, name), getattr(again, name))

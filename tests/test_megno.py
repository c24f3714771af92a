"""MEGNO, FLI and OFLI against their known laws (Cincotta & Simó 2000;
Froeschlé et al. 1997; Fouchard et al. 2002)."""

import numpy as np
import pytest

import varint
from varint import checkpoint as ckpt
from varint.models import FPUBeta
from tests.helpers import assert_bitwise_equal, hook_advance


class Crash(Exception):
    """Stands for anything that ends a process between two checkpoints."""


def crash():
    raise Crash


def test_mean_megno_tends_to_two_on_a_torus(r1):
    r = varint.megno(*r1, 1e5, t_out=[1e3, 1e4, 1e5])
    assert abs(r.mean_megno[-1] - 2.0) < 0.1  # measured 1.985 (seed 0), 1.995 (seed 3)
    assert abs(r.mean_megno[-1] - 2.0) < abs(r.mean_megno[0] - 2.0)


def test_mean_megno_grows_like_half_the_lyapunov_exponent_times_t(c1):
    """Ȳ ≈ χ₁ t/2 on chaotic orbits: between t = 5e3 and 1e4 Ȳ grows at half
    the rate at which the same vector's log-stretching grows."""
    model, x0 = c1
    times = [5e3, 1e4]
    # τ as measured: on a chaotic orbit another step is another trajectory,
    # whose finite-time rates fluctuate by more than the tolerance allows.
    r = varint.megno(model, x0, 1e4, tau=0.05, t_out=times)
    lce = varint.lyapunov_spectrum(model, x0, 1e4, tau=0.05, t_out=times, n_exponents=1)
    S = lce.exponents[:, 0] * lce.t  # ln‖w(t)‖ of the same initial vector
    rate = (S[1] - S[0]) / (times[1] - times[0])
    slope = (r.mean_megno[1] - r.mean_megno[0]) / (times[1] - times[0])
    assert slope == pytest.approx(rate / 2, rel=0.15)


def test_megno_tends_to_zero_for_an_isochronous_linear_chain():
    """β = 0: the FPU chain is a set of harmonic oscillators, every
    deviation stays bounded and Ȳ → 0 (stable periodic motion; measured
    Ȳ = 5.6e-4 at t = 1e3). Four particles: the law holds for any length,
    and the generated stepper's straight-line derivatives grow with it."""
    x0 = np.concatenate([np.full(4, 0.1), np.zeros(4)])
    r = varint.megno(FPUBeta(4, 0.0), x0, 1e3, t_out=[1e2, 1e3])
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


def test_taylor_and_tm_give_the_same_megno(r1, c1):
    """The accumulator is the same compiled code in every method: on R1 the
    Taylor reference and the TM method agree to the accuracy of their
    tangent dynamics (Ȳ → 2), on C1 both grow at χ₁/2 (χ₁ ≈ 0.045, paper
    Sect. VI) although their trajectories have parted by round-off."""
    times = [5e3, 1e4]
    tm = varint.megno(*r1, 1e4, t_out=times, tau=0.05)
    taylor = varint.megno(*r1, 1e4, t_out=times, method="taylor", tau=0.05)
    assert abs(taylor.mean_megno[-1] - tm.mean_megno[-1]) < 1e-3  # measured 9e-6
    assert 1.8 < tm.mean_megno[-1] < 2.2
    for method in ("tm", "taylor"):
        r = varint.megno(*c1, 1e4, t_out=times, method=method, tau=0.05)
        slope = (r.mean_megno[1] - r.mean_megno[0]) / (times[1] - times[0])
        assert slope == pytest.approx(0.045 / 2, rel=0.2)  # measured 0.0248 and 0.0252


@pytest.mark.parametrize("method", sorted(varint.METHODS))
def test_megno_resumes_bitwise_after_a_crash(tmp_path, c1, monkeypatch, method):
    """The accumulators live in the run state, so a run that crashed
    part-way and resumed from its checkpoint is the uninterrupted one, bit
    for bit."""
    model, x0 = c1

    def run(**kw):
        return varint.megno(model, x0, 100.0, t_out=4, method=method, **kw)

    full = run()
    path = tmp_path / "m.ckpt"
    with monkeypatch.context() as patch:
        hook_advance(patch, method, 2, crash)
        with pytest.raises(Crash):
            run(checkpoint=path, checkpoint_interval=0.0)
    assert 0 < ckpt.read(path).state.step < round(100.0 / 0.05)  # it really stopped part-way
    assert_bitwise_equal(run(checkpoint=path), full)

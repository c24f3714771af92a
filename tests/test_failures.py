"""Every check of the hot loop, reached through the public API: a
non-finite orbit, an escape (the model's radius or one given per call), a
degenerate deviation vector and overflowing unrenormalised vectors each stop
the run with an IntegrationError giving the time and the step, or, with
errors="flag", freeze the orbit and mark it — never a NaN passed on as an
exponent. Model kernels that do not fit the protocol are refused in Python,
before numba sees them."""

import re

import numpy as np
import pytest
from numba import njit

import varint
from varint.models import HenonHeiles, Model, solve_momentum
from varint.models.henon_heiles import _grad, _hess, _potential, _third


# Runs pass τ = 0.05: the failures are located in its steps (the automatic
# step's fallback for escaping orbits is tested in test_stepsize).


@pytest.fixture(scope="module")
def escaping():
    """Hénon–Heiles at H = 0.25 > 1/6, heading for the saddle: it leaves the
    well near t ≈ 16 and reaches infinity in finite time."""
    model = HenonHeiles()
    return model, solve_momentum(model, [0.0, 0.0], [0.0, 0.2], 0.25)


def assert_time_and_step(err, tau):
    """The message gives t and the step, and they agree with the attributes."""
    msg = str(err)
    match = re.search(r"at t = ([0-9.e+-]+) \(step (\d+) of tau = ", msg)
    assert match, msg
    assert int(match.group(2)) == err.step and float(match.group(1)) == pytest.approx(err.t)
    assert err.t == pytest.approx(err.step * tau)


def test_hh_above_escape_energy_raises_non_finite_with_time_and_step(escaping):
    with pytest.raises(varint.IntegrationError, match="non-finite") as info:
        varint.lyapunov_spectrum(*escaping, 100.0, tau=0.05)
    err = info.value
    assert_time_and_step(err, 0.05)
    assert 10 < err.t < 30
    assert "above the escape energy 0.166667" in str(err)
    # The partial result holds only finite exponents, up to the failure.
    assert np.isfinite(err.partial.exponents).all() and err.partial.t[-1] < err.t


@pytest.mark.parametrize("where", ["model", "call"])
def test_escape_radius_stops_the_orbit_as_escaped(where, escaping):
    model, x0 = escaping
    kw = {"escape_radius": 5.0}
    if where == "model":
        model, kw = HenonHeiles(escape_radius=5.0), {}
    with pytest.raises(varint.IntegrationError, match="escaped") as info:
        varint.gali(model, x0, 100.0, tau=0.05, **kw)
    assert_time_and_step(info.value, 0.05)
    assert escaping[0].escape_radius is None  # the per-call radius left the model alone
    # It is stopped where |q| first exceeds 5, before it overflows.
    # Near escape the energy error passes 1e-3; the verdict is not the subject.
    crossed = varint.integrate(escaping[0], x0, info.value.t - 0.05, tau=0.05,
                               energy_tol=1.0).state
    assert np.hypot(*crossed[:2]) <= 5.0
    with pytest.raises(varint.IntegrationError, match="non-finite") as overflow:
        varint.gali(*escaping, 100.0, tau=0.05)
    assert overflow.value.t > info.value.t


def test_flagged_orbits_are_frozen_and_marked_the_others_run_on(escaping, c1):
    x0 = np.stack([c1[1], escaping[1]])
    with pytest.warns(RuntimeWarning, match=r"1 of 2 orbits failed .* orbit 1 failed at t = "):
        r = varint.lyapunov_spectrum(escaping[0], x0, 100.0, tau=0.05, errors="flag")
    assert r.status[0] == 0 and r.status[1] == varint.Status.ORBIT_NONFINITE
    alone = varint.lyapunov_spectrum(*c1, 100.0, tau=0.05)
    assert r.exponents[0].tobytes() == alone.exponents.tobytes()
    # Orbit 1: finite exponents before its failure, NaN (not garbage) after.
    failed_at = np.isnan(r.exponents[1, :, 0]).argmax()
    assert failed_at > 0
    assert np.isfinite(r.exponents[1, :failed_at]).all()
    assert np.isnan(r.exponents[1, failed_at:]).all()
    assert np.isnan(r.energy_error[1, failed_at:]).all()


def test_overflowing_raw_deviation_vectors_raise_with_time_and_step(c1):
    """integrate() never renormalises: on the chaotic orbit C1 the vectors
    grow like e^{0.045 t} and pass 1e300 near t ≈ 1.5e4. The check runs
    every 16 steps, so the step reported is at most 16 past the crossing."""
    W0 = np.eye(4)[:, :1]
    with pytest.raises(varint.IntegrationError, match="exceeded 1e\\+300") as info:
        varint.integrate(*c1, 3e4, tau=0.05, deviations=W0)
    err = info.value
    assert_time_and_step(err, 0.05)
    before = varint.integrate(*c1, (err.step - 16) * 0.05, tau=0.05, deviations=W0)
    assert np.abs(before.deviations).max() < 1e300
    assert np.isfinite(err.partial.state).all()  # the orbit itself is fine


@njit(cache=True)
def _hess_singular(q, par, B):
    # Hénon–Heiles' Hessian, but undefined (NaN) for x > 0.3: a user kernel
    # with a singularity the orbit runs into while staying finite itself.
    _hess(q, par, B)
    if q[0] > 0.3:
        B[0, 0] = np.nan


def test_a_non_finite_hessian_stops_the_run_naming_it(c1):
    """Without a corrector (SBAB2) the orbit needs no Hessian and stays
    finite; the Hessian kernel's NaN is caught where it is produced, before
    it reaches the deviation vectors, and named."""
    model = Model(2, _potential, _grad, _hess_singular, _third, bandwidth=1,
                  name="singular HH")
    with pytest.raises(varint.IntegrationError,
                       match="the Hessian of the potential is not finite") as info:
        varint.lyapunov_spectrum(model, c1[1], 1000.0, tau=0.05, scheme="SBAB2")
    assert_time_and_step(info.value, 0.05)
    assert np.isfinite(info.value.partial.exponents).all()


def test_kernels_that_are_not_compiled_are_refused_by_the_model():
    def grad(q, par, g):
        g[:] = q

    with pytest.raises(ValueError, match="grad kernel must be a numba-compiled function"):
        Model(2, _potential, grad, _hess, _third, bandwidth=1)


@njit
def _grad_wrong_signature(q, g):
    g[0] = q[0]


def test_kernels_with_a_wrong_signature_give_a_clear_error_not_numba_internals(c1):
    model = Model(2, _potential, _grad_wrong_signature, _hess, _third, bandwidth=1,
                  name="wrong")
    with pytest.raises(TypeError, match="kernels of model 'wrong' could not be compiled"):
        varint.lyapunov_spectrum(model, c1[1], 10.0, tau=0.05)


@pytest.mark.parametrize("method", sorted(varint.METHODS))
def test_every_method_stops_an_escaping_orbit_with_an_error_or_a_flag(method, escaping):
    """Hénon–Heiles above 1/6: a clear error with time and step, or with
    errors="flag" a marked orbit — never NaN exponents handed out as
    results. (Batches under errors="flag" are tried above with "tm".)"""
    with pytest.raises(varint.IntegrationError) as info:
        varint.lyapunov_spectrum(*escaping, 100.0, tau=0.05, method=method)
    assert_time_and_step(info.value, 0.05)
    assert "above the escape energy" in str(info.value)
    assert np.isfinite(info.value.partial.exponents).all()
    with pytest.warns(RuntimeWarning, match="1 of 1 orbits failed"):
        r = varint.lyapunov_spectrum(*escaping, 100.0, tau=0.05, method=method, errors="flag")
    assert r.status != 0
    ok = r.t < info.value.t
    assert np.isfinite(r.exponents[ok]).all() and np.isnan(r.exponents[~ok]).all()

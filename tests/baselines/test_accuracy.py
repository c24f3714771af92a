"""The baselines against the extended-precision Taylor reference, and the
Lyapunov spectra of the chaotic orbit C1 from all four methods."""

import numpy as np
import pytest

import varint
from varint.cache import reference
from varint.state import initial_deviations
from tests.helpers import fitted_slope

T_END = 100.0


@pytest.fixture(scope="module", params=["R1", "C1"])
def orbit(request):
    model, x0 = varint.paper_orbit(request.param)
    ref = reference(model, x0, T_END, tau=0.1, deviations=np.eye(4))
    return request.param, model, x0, ref


def errors(r, ref):
    """Max orbit error and relative max error of the raw tangent map."""
    return (float(np.abs(r.state - ref.state).max()),
            float(np.abs(r.deviations - ref.deviations).max() / np.abs(ref.deviations).max()))


def run(model, x0, method, tau=0.05, **options):
    return varint.integrate(model, x0, T_END, tau=tau, method=method, deviations=np.eye(4),
                            **options)


def test_double_precision_taylor_is_at_round_off(orbit):
    """Measured 1e-15 (R1) and 1.3e-13 (C1, chaos amplifies round-off)."""
    name, model, x0, ref = orbit
    bound = {"R1": 1e-13, "C1": 1e-11}[name]
    for block in (None, 1):  # natural steps through blocks, and a restart every τ
        e_orbit, e_tangent = errors(run(model, x0, "taylor", block=block), ref)
        assert e_orbit < bound and e_tangent < 10 * bound


def test_cvode_error_follows_its_tolerance(orbit):
    """The global error at t = 100 is within 1e4 (R1; 1e5 on the chaotic C1)
    times the tolerance and falls by at least 1e3 from rtol = atol = 1e-8 to
    1e-12 (measured: 490–1750 and 1500–8400 times the tolerance)."""
    name, model, x0, ref = orbit
    factor = {"R1": 1e4, "C1": 1e5}[name]
    tols = (1e-8, 1e-10, 1e-12)
    errs = []
    for tol in tols:
        e_orbit, e_tangent = errors(run(model, x0, "cvode", rtol=tol, atol=tol), ref)
        assert e_orbit < factor * tol and e_tangent < 10 * factor * tol, (tol, e_orbit, e_tangent)
        errs.append(e_orbit)
    assert errs[0] > 1e3 * errs[-1]


def test_dop853_error_follows_delta_when_it_takes_natural_steps(orbit):
    """With τ = 2 DOP853 takes several steps per interval and its error is
    proportional to δ (measured 20–300 δ, slope 0.94–0.99)."""
    name, model, x0, ref = orbit
    deltas = (1e-6, 1e-8, 1e-10)
    errs = [errors(run(model, x0, "dop853", tau=2.0, delta=d), ref)[0] for d in deltas]
    assert all(e < 1e3 * d for e, d in zip(errs, deltas, strict=True)), errs
    assert 0.8 < fitted_slope(deltas, errs) < 1.2


def test_dop853_restarted_every_small_tau_is_a_fixed_step_eighth_order_method(orbit):
    """At τ = 0.05 every interval is one DOP853 step truncated to τ, so δ
    hardly matters and the error is near round-off (the paper's setting)."""
    name, model, x0, ref = orbit
    for delta in (1e-5, 1e-10):
        r = run(model, x0, "dop853", delta=delta)
        # One step per interval, after SciPy's guess of a first step.
        assert r.provenance.counts["dop853_steps"] <= 2000 + 2
        assert errors(r, ref)[0] < 1e-12


def test_virtual_renormalisation_equals_restarting_every_tau(c1):
    """Blocks of natural Taylor steps renormalised virtually give the same
    spectrum, GALIs and SALI as restarting from the renormalised state every
    τ (the paper's procedure), to round-off."""
    model, x0 = c1
    for run_, field in ((varint.lyapunov_spectrum, "exponents"), (varint.gali, "gali"),
                        (varint.sali, "sali")):
        blocks = run_(model, x0, T_END, method="taylor", t_out=4)
        restarts = run_(model, x0, T_END, method="taylor", block=1, t_out=4)
        a, b = getattr(blocks, field), getattr(restarts, field)
        if field == "gali":
            a, b = np.array(list(a.values())), np.array(list(b.values()))
        assert np.allclose(a, b, rtol=1e-10, atol=1e-13)


@pytest.fixture(scope="module")
def c1_chaotic_spread():
    """Mean and standard deviation of X_i(1000) over 64 copies of C1 moved
    by 1e-12 along y (on the same energy surface, same initial vectors): the
    spread chaos alone produces, since the trajectories of different codes
    separate after t ≈ 500. Measured: X1 0.054 ± 0.009, X2 0.0045 ± 0.0008."""
    model, x0 = varint.paper_orbit("C1")
    rng = np.random.default_rng(5)
    X = np.array([varint.solve_momentum(model, [0.0, x0[1] + 1e-12 * rng.standard_normal()],
                                        [0.0, 0.0], 0.125) for _ in range(64)])
    W0 = initial_deviations(4, 4, 1, seed=0)[0]
    r = varint.lyapunov_spectrum(model, X, 1000.0, tau=0.05, scheme="ABA864", deviations=W0,
                                 t_out=1)
    E = r.exponents[:, -1]
    return E.mean(axis=0), E.std(axis=0)


def test_lyapunov_spectra_of_c1_from_all_four_methods_agree(c1, c1_chaotic_spread):
    """At t = 100, before the trajectories separate, all methods agree to
    better than 1e-5 (TM with SBAB2C, τ = 0.05, differs by 1.5e-6, CVODE by
    1e-7, DOP853 and Taylor by 1e-14). At t = 1000 each lies within 5
    standard deviations of the chaotic spread, and the pair sums
    |X1 + X4|, |X2 + X3| are below 2e-3 (paper Fig. 5: ≈ 4e-4 and 1e-4)."""
    model, x0 = c1
    mean, std = c1_chaotic_spread
    ref = reference(model, x0, 1000.0, 0.05, kind="lyapunov_spectrum", t_out=[100, 1000])
    results = {"taylor (extended)": ref}
    for method in ("tm", "taylor", "cvode", "dop853"):
        results[method] = varint.lyapunov_spectrum(model, x0, 1000.0, tau=0.05, method=method,
                                                   t_out=[100, 1000])
    for method, r in results.items():
        assert np.abs(r.exponents[0] - ref.exponents[0]).max() < 1e-5, method
        assert (np.abs(r.exponents[1] - mean) < 5 * std).all(), (method, r.exponents[1], mean, std)
        assert (r.pair_sums()[1] < 2e-3).all(), method

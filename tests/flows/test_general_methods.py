"""A general H(q, p) through varint's runs: method="tm" runs its
Gauss–Legendre steps on the part stepper (every indicator, checkpoints),
the reference methods integrate Hamilton's equations of the same
expression, and what cannot run is refused with one clear line."""

import math

import numpy as np
import pytest
import sympy as sp

import varint
from tests.flows.steppers import coupled_general, gauss_steps, taylor_reference
from tests.helpers import fitted_slope
from varint.flows.general import GENERAL_SCHEMES
from varint.methods.parts import parts_steps
from varint.models import from_hamiltonian

X0 = np.array([0.1, 0.05, 0.2, 0.25])


@pytest.mark.parametrize("name", sorted(GENERAL_SCHEMES))
def test_part_stepper_runs_the_same_step(name):
    """One step through the part stepper is the Gauss–Legendre step of
    varint.flows.gauss from the explicit guess, bit for bit, orbit and
    tangent map."""
    model = coupled_general()
    x, W = parts_steps(model, X0, np.eye(4), 0.1, 1, name)
    x_ref, W_ref = gauss_steps(model, X0, np.eye(4), 0.1, 1, name)
    assert np.array_equal(x, x_ref)
    assert np.array_equal(W, W_ref)


@pytest.mark.parametrize("name, steps", [("GL4", (20, 40, 80)), ("GL6", (10, 20, 40))])
def test_measured_order_through_a_run(name, steps):
    """lyapunov_spectrum's orbit at t = 4 against heyoka's Taylor method
    falls as τ^(2s)."""
    model = coupled_general()
    ref = taylor_reference(model, X0, 4.0)
    taus = [4.0 / n for n in steps]
    errors = []
    for tau in taus:
        r = varint.lyapunov_spectrum(model, X0, 4.0, tau=tau, scheme=name, t_out=[4.0],
                                     energy_tol=math.inf, progress=False)
        errors.append(np.abs(r.state - ref).max())
    assert fitted_slope(taus, errors) == pytest.approx(GENERAL_SCHEMES[name].order, abs=0.3)


def test_reference_methods_agree_on_a_general_hamiltonian():
    """Taylor, DOP853 and CVODE from the same expression give the orbit
    and the largest exponent's log-stretching that GL8 gives, to their
    tolerances (DOP853's default rtol 1e-6 is the loosest: 1.4e-5 in the
    log-stretching over t = 10)."""
    model = coupled_general()
    w = np.eye(4)[:, :1]
    runs = {m: varint.lyapunov_spectrum(model, X0, 10.0, tau=0.5 if m == "tm" else 1.0,
                                        method=m, deviations=w, t_out=[10.0],
                                        energy_tol=math.inf, progress=False)
            for m in ("tm", "taylor", "dop853", "cvode")}
    ref = runs["taylor"]
    for m, r in runs.items():
        assert np.abs(r.state - ref.state).max() < 1e-5, m
        assert abs(r.exponents[-1, 0] - ref.exponents[-1, 0]) * 10.0 < 1e-4, m


def test_every_indicator_and_bitwise_resume(tmp_path):
    """SALI, GALI, MEGNO and FLI run; a run cut into chunks by output
    times gives the same bits as one in a single chunk (each step is a
    function of the state alone)."""
    model = coupled_general()
    for ind in ("sali", "gali", "megno", "fli"):
        r = varint.run(model, X0, ind, 5.0, tau=0.25, progress=False)
        assert r.accuracy.accurate, ind
    one = varint.lyapunov_spectrum(model, X0, 20.0, tau=0.25, t_out=[20.0], progress=False)
    many = varint.lyapunov_spectrum(model, X0, 20.0, tau=0.25, t_out=np.arange(1.0, 21.0),
                                    progress=False)
    assert np.array_equal(one.state, many.state)
    assert np.array_equal(one.exponents[-1], many.exponents[-1])


def test_refusals():
    model = coupled_general()
    with pytest.raises(ValueError, match="own schemes .*GL4, GL6, GL8.*'SBAB2'"):
        varint.lyapunov_spectrum(model, X0, 1.0, tau=0.1, scheme="SBAB2", progress=False)
    q, p, t = sp.symbols("q p t")
    timed = from_hamiltonian((q ** 2 + 1) * (p ** 2 + 1) / 2 * (1 + sp.cos(t) / 10), [q], [p],
                             time=t)
    with pytest.raises(ValueError, match="depends on time .*method='taylor'"):
        varint.lyapunov_spectrum(timed, np.array([0.5, 0.1]), 1.0, tau=0.1, progress=False)

"""A general H(q, p) through varint's runs: method="tm" runs its
Gauss–Legendre steps on the part stepper (every indicator, checkpoints),
the reference methods integrate Hamilton's equations of the same
expression, and what cannot run is refused with one clear line."""

import dataclasses
import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numba
import numpy as np
import pytest
import sympy as sp
from scipy.integrate import solve_ivp

import varint
from tests.flows.steppers import coupled_general, taylor_reference
from tests.helpers import fitted_slope
from varint.flows import general as GEN
from varint.flows.general import GENERAL_SCHEMES, TAO_SCHEMES
from varint.flows.tao import tao_stepper, tao_work
from varint.kernels.closures import closure_key
from varint.kernels.parts import parts_batch
from varint.models import from_hamiltonian
from varint.schemes import part_stages

ROOT = Path(__file__).resolve().parents[2]
X0 = np.array([0.1, 0.05, 0.2, 0.25])
# Two vectors in every run of this model without an accumulator: SALI needs
# exactly two, and the part stepper is compiled per number of vectors (not
# per renormalisation), so the Lyapunov runs, GALI_2 and SALI share one
# kernel (SALI's own, beside one for k = 2N, was ~20 CPU s cold).
K = 2


def _order_through_a_run(name, steps):
    """The fitted slope of lyapunov_spectrum's orbit error at t = 4 against
    heyoka's Taylor method, over τ = 4 / steps."""
    model = coupled_general()
    ref = taylor_reference(model, X0, 4.0)
    taus = [4.0 / n for n in steps]
    errors = []
    for tau in taus:
        r = varint.lyapunov_spectrum(model, X0, 4.0, tau=tau, scheme=name, t_out=[4.0],
                                     n_exponents=K, energy_tol=math.inf, progress=False)
        errors.append(np.abs(r.state - ref).max())
    return fitted_slope(taus, errors)


@pytest.mark.parametrize("name, steps", [("GL4", (20, 40, 80)), ("GL6", (10, 20, 40))])
def test_measured_order_through_a_run(name, steps):
    """lyapunov_spectrum's orbit at t = 4 against heyoka's Taylor method
    falls as τ^(2s)."""
    assert _order_through_a_run(name, steps) == pytest.approx(GENERAL_SCHEMES[name].order,
                                                              abs=0.3)


def test_reference_methods_agree_on_a_general_hamiltonian():
    """Taylor, DOP853 and CVODE from the same expression give the orbit
    and the largest exponent's log-stretching that GL8 gives, to their
    tolerances (DOP853's default rtol 1e-6 is the loosest: 1.4e-5 in the
    log-stretching over t = 10)."""
    model = coupled_general()
    # Two exponents from the unit vectors e_1, e_2: X1 is the log-stretching
    # of e_1 (QR leaves the first column's direction alone), and method="tm"
    # runs the kernel of the other tests (k = K).
    runs = {m: varint.lyapunov_spectrum(model, X0, 10.0, tau=0.5 if m == "tm" else 1.0,
                                        method=m, deviations=np.eye(4)[:, :K], t_out=[10.0],
                                        energy_tol=math.inf, progress=False)
            for m in ("tm", "taylor", "dop853", "cvode")}
    ref = runs["taylor"]
    for m, r in runs.items():
        assert np.abs(r.state - ref.state).max() < 1e-5, m
        assert abs(r.exponents[-1, 0] - ref.exponents[-1, 0]) * 10.0 < 1e-4, m


def test_every_indicator_and_bitwise_resume(tmp_path):
    """SALI, GALI (GALI_2: the two vectors of SALI), MEGNO and FLI run; a
    run cut into chunks by output times gives the same bits as one in a
    single chunk (each step is a function of the state alone)."""
    model = coupled_general()
    for ind, options in (("sali", {}), ("gali", {"k": K}), ("megno", {}), ("fli", {})):
        r = varint.run(model, X0, ind, 5.0, tau=0.25, progress=False, **options)
        assert r.accuracy.accurate, ind
    one = varint.lyapunov_spectrum(model, X0, 20.0, tau=0.25, t_out=[20.0], n_exponents=K,
                                   progress=False)
    many = varint.lyapunov_spectrum(model, X0, 20.0, tau=0.25, t_out=np.arange(1.0, 21.0),
                                    n_exponents=K, progress=False)
    assert np.array_equal(one.state, many.state)
    assert np.array_equal(one.exponents[-1], many.exponents[-1])
    # MEGNO and FLI step one vector, SALI two: the Gauss–Legendre step
    # behind the part stepper's flows is compiled for a run-time k only
    # (none at all where the kernels came from the disk cache).
    apply = model.parts.apply.py_func
    cells = dict(zip(apply.__code__.co_freevars, apply.__closure__, strict=True))
    for name in ("step4", "step6", "step8"):
        step = cells[name].cell_contents
        assert {sig[3] for sig in step.signatures} <= {numba.types.int64}, name


SECOND_PROCESS = """
import json, sys
import numpy as np
import varint
from varint import compiling
from tests.flows.steppers import coupled_general
x0, t_end, options = json.loads(sys.argv[1])
if "deviations" in options:
    options["deviations"] = np.array(options["deviations"])
r = varint.lyapunov_spectrum(coupled_general(), np.array(x0), t_end, progress=False, **options)
print(json.dumps([compiling.compile_seconds(), r.exponents.tobytes().hex()]))
"""


def _second_process(t_end, **options):
    """(compile seconds, the exponents' bytes in hex) of
    ``lyapunov_spectrum(coupled_general(), X0, t_end, **options)`` in a new
    process on this one's caches (options as JSON: arrays as lists)."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    done = subprocess.run([sys.executable, "-c", SECOND_PROCESS,
                           json.dumps([X0.tolist(), t_end, options])],
                          env=env, check=True, capture_output=True, text=True, cwd=ROOT)
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_a_second_process_runs_a_general_model_without_compiling():
    """The part stepper of a general H, compiled (or loaded) here, is read
    by a new process from the disk cache: it compiles nothing and gives the
    same bits (it closes over the model's kernels and the Gauss–Legendre
    tables, both named by what they are: varint.kernels.closures)."""
    here = varint.lyapunov_spectrum(coupled_general(), X0, 2.0, tau=0.25, n_exponents=K,
                                    progress=False)
    compiled, there = _second_process(2.0, tau=0.25, n_exponents=K)
    assert compiled == 0.0
    assert there == here.exponents.tobytes().hex()


def test_the_part_steppers_key_names_the_model_and_the_tables(monkeypatch):
    """The disk cache's key of a general H's part stepper is the same for
    the same model and tables made anew, and another for another model or
    for Gauss–Legendre tables one ulp apart: no kernel serves code it was
    not compiled from."""
    def key(model):
        parts = model.parts
        apply = GEN.general_apply.__wrapped__(model.grad_h, model.grad_hess_h, model.n_dof,
                                              parts.par.shape[0], None, frozenset({2}))
        return closure_key(parts_batch(apply, parts.field, K, False))

    model = coupled_general()
    same = key(model)
    assert key(model) == same
    assert key(from_hamiltonian(*_other_general())) != same
    gl8 = GEN.GAUSS["GL8"]
    a = [list(row) for row in gl8.a]
    a[0][0] = float(np.nextafter(a[0][0], 1.0))
    monkeypatch.setitem(GEN.GAUSS, "GL8", dataclasses.replace(gl8, a=tuple(map(tuple, a))))
    assert key(model) != same


def _other_general():
    """coupled_general with another coupling constant."""
    x, y, px, py = sp.symbols("x y p_x p_y")
    H = ((px ** 2 + py ** 2) / 2 + (x ** 2 + y ** 2) / 2 + x ** 2 * y - y ** 3 / 3
         + (x * py) ** 2 / 8 + x * y * px / 5)
    return H, [x, y], [px, py]


def test_refusals():
    model = coupled_general()
    with pytest.raises(ValueError, match="own schemes .*GL4, GL6, GL8.*'SBAB2'"):
        varint.lyapunov_spectrum(model, X0, 1.0, tau=0.1, scheme="SBAB2", progress=False)


def _timed_general():
    """Tao's (q² + 1)(p² + 1)/2 with a periodic modulation (1 + cos t / 10):
    a general H(q, p, t), and its Hamilton's equations from SymPy."""
    q, p, t = sp.symbols("q p t")
    H = (q ** 2 + 1) * (p ** 2 + 1) / 2 * (1 + sp.cos(t) / 10)
    rhs = sp.lambdify((t, q, p), [sp.diff(H, p), -sp.diff(H, q)])
    return from_hamiltonian(H, [q], [p], time=t), rhs


@pytest.mark.parametrize("name, steps", [("GL4", (20, 40, 80)), ("GL6", (10, 20, 40))])
def test_time_dependent_measured_order(name, steps):
    """A time-dependent general H under method="tm" (the Gauss–Legendre
    step of K = H + p_t in the extended phase space): the orbit at t = 4
    against SciPy's DOP853 at rtol 1e-13 on Hamilton's equations from SymPy
    (independent of varint's kernels) falls as τ^(2s), and K's error falls
    with τ (p_t is advanced by the step's own quadrature)."""
    model, rhs = _timed_general()
    x0 = np.array([0.5, 0.1])
    ref = solve_ivp(lambda t, y: rhs(t, *y), (0.0, 4.0), x0, method="DOP853", rtol=1e-13,
                    atol=1e-15).y[:, -1]
    taus = [4.0 / n for n in steps]
    errors, k_errors = [], []
    for tau in taus:
        r = varint.lyapunov_spectrum(model, x0, 4.0, tau=tau, scheme=name, t_out=[4.0],
                                     energy_tol=math.inf, progress=False)
        errors.append(np.abs(r.state - ref).max())
        k_errors.append(r.accuracy.energy_error)
    assert fitted_slope(taus, errors) == pytest.approx(GENERAL_SCHEMES[name].order, abs=0.3)
    assert k_errors[2] < k_errors[0] / 2 ** (GENERAL_SCHEMES[name].order - 1)


def test_time_dependent_tangent_is_the_derivative_of_the_map():
    """The tangent map of a time-dependent general H (GL6, 8 steps from
    t = 0) equals central finite differences of the same map."""
    model, _ = _timed_general()
    x0 = np.array([0.5, 0.1])

    def run(x):
        # Through a run (integrate: the vectors never renormalised), on the
        # kernel of the measured order's runs (k = 2N; the renormalisation
        # is not compiled in), where the part stepper's own loop
        # (parts_steps) compiled one more (10 CPU s cold). The shifted
        # orbits carry the vectors too (the orbit does not depend on them).
        r = varint.integrate(model, x, 0.8, tau=0.1, scheme="GL6", deviations=np.eye(2),
                             energy_tol=math.inf, progress=False)
        assert r.provenance.counts["steps"] == 8
        return r.state, r.deviations

    _, W = run(x0)
    eps = 1e-6
    fd = np.column_stack([(run(x0 + eps * e)[0] - run(x0 - eps * e)[0]) / (2 * eps)
                          for e in np.eye(2)])
    assert np.abs(W - fd).max() < 1e-8


@pytest.mark.parametrize("name, steps", [("TAO4", (160, 320, 640)), ("TAO6", (320, 640, 1280))])
def test_tao_measured_order_through_a_run(name, steps):
    """Tao's method as schemes of method="tm" (its own step body on the
    stepping skeleton, the second copy kept in the run's state): the orbit
    at t = 4 against heyoka's Taylor method falls as τ^order (in the
    asymptotic range: the binding ω = 20 makes the error's constant large
    until ωτ ≪ 1: TAO6's local slopes over 160 → 320 → 640 steps were 5.5,
    5.9)."""
    assert _order_through_a_run(name, steps) == pytest.approx(TAO_SCHEMES[name].order, abs=0.3)


def test_tao_runs_its_step_and_resumes_bit_for_bit():
    """Through the skeleton, Tao's method gives the orbit of tao_step
    applied step after step (no reset of the second copy), bit for bit, and
    the log-stretching of its tangent to round-off; a run cut into 20 calls
    by output times gives the same bits as one call (the second copy and G
    travel in the run's state)."""
    model = coupled_general()
    scheme, tau, n = TAO_SCHEMES["TAO4"], 0.05, 200
    parts, h = part_stages(scheme, tau, {0: 0, 1: 1, 2: 2})
    x, x2, G = X0.copy(), X0.copy(), np.eye(4)
    V = np.eye(4)[:1].copy()
    work = np.empty(tao_work(model.n_dof, 1))
    par = model.parameters_at(None)
    log_growth = 0.0
    tao_step = tao_stepper(model.grad_hess_h)
    for _ in range(n):
        assert tao_step(parts, h, scheme.omega, x, x2, V, 1, G, par, work) == 0
        norm = np.linalg.norm(V[0])
        log_growth += math.log(norm)
        V[0] /= norm
    w0 = np.eye(4)[:, :1]
    one = varint.lyapunov_spectrum(model, X0, n * tau, tau=tau, scheme="TAO4", deviations=w0,
                                   t_out=[n * tau], energy_tol=math.inf, progress=False)
    many = varint.lyapunov_spectrum(model, X0, n * tau, tau=tau, scheme="TAO4", deviations=w0,
                                    t_out=np.linspace(0.5, n * tau, 20), energy_tol=math.inf,
                                    progress=False)
    assert np.array_equal(one.state, x)
    assert one.exponents[-1, 0] * n * tau == pytest.approx(log_growth, rel=1e-12)
    assert np.array_equal(one.state, many.state)
    assert np.array_equal(one.exponents[-1], many.exponents[-1])
    # Its stepper closes over the model's kernel, so a new process loads it
    # from the disk cache (varint.flows.tao.tao_stepper says why).
    compiled, there = _second_process(n * tau, tau=tau, scheme="TAO4",
                                      deviations=w0.tolist(), t_out=[n * tau],
                                      energy_tol=math.inf)
    assert compiled == 0.0
    assert there == one.exponents.tobytes().hex()
    timed, _ = _timed_general()
    with pytest.raises(ValueError, match="Tao's method takes no time-dependent H"):
        varint.lyapunov_spectrum(timed, np.array([0.5, 0.1]), 1.0, tau=0.1, scheme="TAO4",
                                 progress=False)

"""Generated steppers for a rotating frame's H = A + V(q) (issue 29): the
drift is A's exact linear flow emitted as straight-line code
(varint.codegen.tm), so the restricted three-body problem and a charged
particle in a uniform magnetic field run on the generated one-orbit and
SIMD-lane kernels.

What is checked: the same map as the part flows (varint.flows.split) to
round-off — not bitwise, since the generated kick adds by fused
multiply–adds and evaluates ∇V, D²V from its own common subexpressions —;
each scheme's order measured against heyoka's Taylor reference, for the
orbit and the tangent map; the tangent map equal to finite differences of
the same map and symplectic; SIMD lanes bitwise the one-orbit stepper; the
Jacobi constant conserved with an error that does not grow and scales as
the scheme's order.
"""

import numpy as np
import pytest

from tests.flows.steppers import (cr3bp, finite_difference, larmor, symplectic_form,
                                  taylor_reference)
from tests.helpers import fitted_slope
from varint.methods import make_propagator
from varint.methods.parts import generated_rotating, parts_steps
from varint.methods.tm import TangentMapPropagator, tangent_map_steps
from varint.models import CR3BP
from varint.models.cr3bp import cr3bp_orbit
from varint.protocol import Renorm
from varint.state import RunState

_CASES = {
    "cr3bp": (cr3bp, np.array([0.5, 0.0, 0.0, 0.9])),
    "spatial": (lambda: CR3BP(0.01215, spatial=True),
                np.array([0.5, 0.05, 0.1, -0.05, 0.9, 0.02])),
    "larmor": (larmor, np.array([0.5, 0.1, 0.2, 0.1, 0.6, 0.3])),
}


def _generated_map(model, x0, tau, n, scheme):
    """``n`` steps of the generated stepper from ``x0``: the orbit and the
    full tangent map (2N, 2N), a column per run of one vector. The map is
    linear and the orbit reads no vector, so the columns are those of one
    run with 2N vectors; one vector's stepper compiles in ~2/5 of the
    time of four's (its straight-line code grows with the vectors: 5 and
    13 CPU s cold for ABA864 on Hénon–Heiles), and is the one stepper per
    (model, scheme) of every test below, finite differences included."""
    runs = [tangent_map_steps(model, x0, np.eye(model.dim)[:, j:j + 1], tau, n, scheme)
            for j in range(model.dim)]
    assert all(np.array_equal(x, runs[0][0]) for x, _ in runs)
    return runs[0][0], np.hstack([W for _, W in runs])


@pytest.mark.parametrize("case", sorted(_CASES))
def test_tm_runs_the_generated_stepper(case):
    """method="tm" picks the generated stepper for every two-part scheme,
    correctors included, and every k up to 2N."""
    model = _CASES[case][0]()
    assert generated_rotating(model)
    for scheme in ("SRKN14a", "SBAB2C"):
        P = make_propagator("tm", model, 0.01, "qr", scheme=scheme)
        assert isinstance(P, TangentMapPropagator)
        assert all(P._stepper(k) is not None for k in (0, 1, model.dim))


@pytest.mark.parametrize("scheme, case", [
    ("SBAB2", "cr3bp"), ("SBAB2", "spatial"), ("SRKN14a", "cr3bp"), ("SBAB2", "larmor"),
    # Every case and every scheme is above; each pair compiles a stepper
    # of its own (6-19 CPU s cold with one vector). Larmor runs SBAB2 by
    # default: its 6-dimensional SRKN14a stepper (14 stages) was the file's
    # costliest kernel (54 CPU s cold with six vectors); SBAB2's serves the
    # larmor tests below too.
    pytest.param("SRKN14a", "larmor", marks=pytest.mark.slow),
    pytest.param("SRKN14a", "spatial", marks=pytest.mark.slow)])
def test_generated_is_the_part_flows_map_to_round_off(case, scheme):
    """200 steps of the generated stepper and of the part flows, orbit and
    full tangent map: the same map, up to round-off (a few ulps per stage
    and step; SBAB2's truncation error at this τ is ~1e-5, a wrong drift's
    far larger). The drift of each frame (case) and the stage sequence of
    each scheme are independent parts of the generated code: every case
    and every scheme is checked by default, the remaining pairs with
    ``-m slow``. (The part flows carry the 2N vectors in one run: the
    part stepper tests/flows/test_split.py compiles.)"""
    build, x0 = _CASES[case]
    model = build()
    d = model.dim
    xg, Wg = _generated_map(model, x0, 0.01, 200, scheme)
    xp, Wp = parts_steps(model, x0, np.eye(d), 0.01, 200, scheme)
    assert np.abs(xg - xp).max() < 2e-12 * max(1.0, np.abs(xp).max())
    assert np.abs(Wg - Wp).max() < 2e-11 * max(1.0, np.abs(Wp).max())


# SABA2C reaches its asymptote late (errors 2.3e-5, 1.0e-5, 7.3e-7, 4.7e-8
# at 80 … 640 steps, against SABA2's 7e-2 … 1.1e-3).
_ORDERS = [("SBAB2", (2, 4), (80, 160, 320)), ("ABA864", (4, 8), (40, 80, 160)),
           ("SRKN14a", (6, 6), (160, 320, 640)), ("SABA2C", (4, 4), (320, 640, 1280))]


@pytest.mark.parametrize("case, scheme, order, steps",
                         [("cr3bp", *row) for row in _ORDERS]
                         + [("larmor", "SBAB2", (2, 4), (80, 160, 320)),
                            # SRKN14a's order 6 is measured on cr3bp above;
                            # on larmor it needs a stepper of its own.
                            pytest.param("larmor", "SRKN14a", (6, 6), (4, 8, 16),
                                         marks=pytest.mark.slow)])
def test_generated_measured_order(case, scheme, order, steps):
    """Orbit and tangent map at t = 2 converge to the Taylor reference at
    the scheme's order. With ε = 1 SBAB2 and ABA864 have orders 2 and 4 (up
    to their higher nominal orders, whose terms may still lead; SBAB2 on
    larmor measured 2.00); SRKN14a keeps order 6 (A quadratic in p, V of q
    alone); the corrector of SABA2C (C = {V,{V,A}} = ∇Vᵀ diag(a) ∇V, the
    rotation being linear in p), which the part flows do not run, raises
    SABA2 to order 4."""
    build, x0 = _CASES[case]
    model = build()
    ref, M_ref = taylor_reference(model, x0, 2.0, tangent=True)
    errs, terrs = [], []
    for n in steps:
        x, W = _generated_map(model, x0, 2.0 / n, n, scheme)
        errs.append(np.abs(x - ref).max())
        terrs.append(np.abs(W - M_ref).max())
    taus = [2.0 / n for n in steps]
    low, high = order
    for e in (errs, terrs):
        assert low - 0.3 < fitted_slope(taus, e) < high + 0.5


@pytest.mark.parametrize("case, scheme", [("cr3bp", "SRKN14a"), ("larmor", "SBAB2")])
def test_generated_tangent_is_the_derivative_and_symplectic(case, scheme):
    """100 steps: the tangent map equals central differences of the
    same generated map, and MᵀJM = J to round-off. The differences are of
    the orbit of the same compiled stepper (with one vector, which the
    orbit does not read: the stepper test_generated_is_the_part_flows_map_to_round_off
    compiles for the case, not one without vectors of its own; the law
    holds for any scheme)."""
    build, x0 = _CASES[case]
    model = build()
    d = model.dim
    _, M = _generated_map(model, x0, 0.02, 100, scheme)
    D = finite_difference(lambda z: tangent_map_steps(model, z, np.eye(d)[:, :1], 0.02, 100,
                                                      scheme)[0], x0)
    assert np.abs(D - M).max() < 1e-8 * max(1.0, np.abs(M).max())
    J = symplectic_form(d // 2)
    assert np.abs(M.T @ J @ M - J).max() < 1e-12 * max(1.0, np.abs(M).max() ** 2)


def _run(model, X, tau, n, scheme, k=1):
    W = np.tile(np.eye(model.dim)[:, :k], (len(X), 1, 1))
    state = RunState.start(np.array(X, dtype=float), W)
    TangentMapPropagator(model, tau, Renorm.NONE, scheme=scheme, parallel=False).advance(
        state, n)
    assert (state.status == 0).all()
    return state.x, state.W


#: The scheme of the run-level tests below: what they check (lanes, the
#: invariant's law, the compensated drift) holds for any scheme, and
#: SBAB2's three stages compile in a third of SRKN14a's fourteen (7-11 CPU
#: s cold against 20-26 for each of these steppers); SRKN14a's generated
#: stages are held to the part flows, its order and the finite
#: differences above.
_RUN_SCHEME = "SBAB2"


def test_lanes_are_bitwise_the_one_orbit_stepper():
    """Nine orbits run as SIMD lanes; each alone runs the one-orbit
    stepper: the same bits."""
    model, x0 = cr3bp_orbit("sun-jupiter-chaotic")
    X = x0 + 1e-4 * np.arange(9)[:, None] * np.array([1.0, 0.0, 0.0, 0.0])
    xl, Wl = _run(model, X, 0.05, 300, _RUN_SCHEME)
    for m in (0, 4, 8):
        x1, W1 = _run(model, X[m:m + 1], 0.05, 300, _RUN_SCHEME)
        assert np.array_equal(xl[m], x1[0]) and np.array_equal(Wl[m], W1[0])


def test_jacobi_constant_conserved_at_the_scheme_order():
    """The Jacobi constant of a regular Sun–Jupiter orbit over 20 000 steps
    of SBAB2: its error stays bounded (the late half no larger than 3×
    the early half: no drift; measured 1.02e-2 and 1.02e-2 at τ = 0.1) and
    falls as τ² when τ halves (measured 1.99). (With one vector, which the
    orbit does not read: the one-orbit stepper of the test above, not one
    without vectors of its own.)"""
    model, x0 = cr3bp_orbit("sun-jupiter-regular")
    C0 = model.jacobi(x0)
    worst = []
    for tau, chunks in ((0.1, 40), (0.05, 80)):
        x, errors = x0.copy(), []
        for _ in range(chunks):
            x = _run(model, x[None], tau, 250, _RUN_SCHEME)[0][0]
            errors.append(abs(model.jacobi(x) - C0))
        errors = np.array(errors)
        half = len(errors) // 2
        assert errors[half:].max() < 3.0 * errors[:half].max()
        worst.append(errors.max())
    assert fitted_slope([0.1, 0.05], worst) == pytest.approx(2.0, abs=0.3)


def test_more_vectors_than_fit_are_refused():
    """k = 12 vectors (2N(1 + k) > 48) have no generated stepper; the
    generic one's drift is not a rotating frame's, so the run is refused in
    one line."""
    model, x0 = cr3bp_orbit("sun-jupiter-regular")
    state = RunState.start(x0[None], np.tile(np.eye(4), (1, 1, 3)))
    P = TangentMapPropagator(model, 0.05, Renorm.NONE, scheme="SRKN14a")
    with pytest.raises(ValueError, match="at most 4 vectors"):
        P.advance(state, 1)


_SIM_SCRIPT = r'''
import json, numpy as np, varint
from varint.models import CR3BP
model = CR3BP(0.000954)
X = model.section_grid(3.05, [0.4, 0.55, 0.6], [0.0]).states
kw = dict(t_end=2, tau=0.05, threshold=None, progress=False, scheme="SBAB2")
cpu = varint.chaos_map(model, X, "fli", **kw)
gpu = varint.chaos_map(model, X, "fli", backend="cuda", **kw)
print(json.dumps([bool(np.array_equal(cpu.values, gpu.values)),
                  bool(np.array_equal(cpu.state, gpu.state))]))
'''


def test_cuda_kernel_on_the_simulator_is_bitwise_the_cpu():
    """The CUDA emitter writes the same rotating-frame drift (numba's CUDA
    simulator, in a subprocess: set before numba.cuda is imported): an FLI
    map's values and final states are the CPU's bits."""
    import json
    import os
    import subprocess
    import sys

    pytest.importorskip("numba.cuda")
    env = dict(os.environ, NUMBA_ENABLE_CUDASIM="1")
    run = subprocess.run([sys.executable, "-c", _SIM_SCRIPT], env=env, capture_output=True,
                         text=True, timeout=900)
    assert run.returncode == 0, run.stderr[-3000:]
    assert json.loads(run.stdout.strip().splitlines()[-1]) == [True, True]


def test_compensated_drift_is_the_same_map():
    """compensated=True adds the rotating frame's drift (written as
    increments) by Kahan's summation: 2000 SBAB2 steps agree with the
    plain stepper to round-off (measured 1.1e-12), and differ from it (the
    compensation acts). (With one vector: the plain stepper is then the
    one-orbit stepper the tests above compile.)"""
    model, x0 = cr3bp_orbit("sun-jupiter-regular")
    runs = []
    for compensated in (False, True):
        state = RunState.start(x0[None], np.eye(4)[None, :, :1].copy())
        TangentMapPropagator(model, 0.1, Renorm.NONE, scheme=_RUN_SCHEME,
                             compensated=compensated).advance(state, 2000)
        assert state.status[0] == 0
        runs.append(state.x[0])
    assert np.abs(runs[0] - runs[1]).max() < 1e-10
    assert not np.array_equal(runs[0], runs[1])

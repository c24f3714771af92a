"""The logarithmic-Hamiltonian time transformation (varint.time_transform):
the tangent map is the derivative of the same map, the schemes keep their
order in physical time, a near-collision orbit keeps its energy where
constant steps lose it, and a resumed run repeats the bits."""

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

from varint import codecache
from varint.models import from_potential
from varint.models.cr3bp import CR3BP, SUN_JUPITER_MU
from varint.flows.split import planar_flow
from varint.time_transform import LogHamiltonian, _symbolic_parts, describe

EPS = 1e-3   # Plummer softening: a near-singular centre


@pytest.fixture(scope="module")
def plummer():
    x, y = sp.symbols("x y")
    return from_potential(-1 / sp.sqrt(x**2 + y**2 + sp.Float(EPS)**2), [x, y])


#: An eccentric orbit of the softened point mass: pericentre ≈ 0.02.
X0 = np.array([1.0, 0.0, 0.0, 0.2])


def _grad_h(lh, x, d=1e-6):
    """∇H by central differences of the energy (for the vectors' δp_t)."""
    return np.array([(lh.energy(x + e)[0] - lh.energy(x - e)[0]) / (2 * d)
                     for e in np.eye(4) * d])


def _step(lh, x0, h, k, C=0.0):
    """One LH step of ``x0`` on its energy shell (p_t = −H(x0)) with k unit
    vectors, δp_t = −∇H·δx: (x, V rows, δt, t)."""
    x = x0.copy()
    V = np.eye(4)[:k].copy()
    dt = np.zeros(k)
    dpt = -V @ _grad_h(lh, x0) if k else np.zeros(0)
    clock = np.array([0.0, -lh.energy(x0)[0] + C])
    status = lh.step_kernel(x, V, dt, dpt, clock, lh.kinds, lh.coef, h, lh.par, True, C,
                            np.zeros(3, np.int64), np.empty(4), np.empty(2), np.empty((2, 2)),
                            np.empty(k))
    assert status == 0
    return x, V, dt, clock[0]


@pytest.mark.parametrize("which", ["plummer", "cr3bp"])
def test_tangent_is_the_derivative_of_the_same_map(which, plummer):
    """(δx, δt) of one LH step against central differences of the step of
    the perturbed state on its own energy shell (p_t = −H): the difference
    falls as d² (slope 2) down to the δp_t's own differences."""
    if which == "plummer":
        lh, x0, h = LogHamiltonian(plummer, "ABA864"), np.array([0.3, 0.1, 0.2, 1.5]), 0.1
    else:
        # ABA864, as the maps' test below: one emitted CR3BP stepper.
        lh, x0, h = (LogHamiltonian(CR3BP(SUN_JUPITER_MU), "ABA864"),
                     np.array([0.6, 0.05, 0.1, 0.7]), 0.1)
    C = 0.0
    _, V, dt, _ = _step(lh, x0, h, 4, C)
    errors = []
    for d in (1e-3, 1e-4):
        J, Jt = np.empty((4, 4)), np.empty(4)
        for j in range(4):
            e = np.zeros(4)
            e[j] = d
            a, _, _, ta = _step(lh, x0 + e, h, 0, C)
            b, _, _, tb = _step(lh, x0 - e, h, 0, C)
            J[:, j], Jt[j] = (a - b) / (2 * d), (ta - tb) / (2 * d)
        errors.append(max(np.abs(J - V.T).max(), np.abs(Jt - dt).max()))
    slope = math.log10(errors[0] / errors[1])
    assert 1.8 < slope < 2.2, (errors, slope)


def _specified_step(lh, x, V, dt, dpt, wc, h, C):
    """One LH step as the kernel module's docstring specifies it, in plain
    NumPy, with A, ∇A, V, ∇V and D²V lambdified from the model's SymPy
    form and A's flow from :mod:`varint.flows.split` (free motion, or
    ``planar_flow``): independent of the emitted code, its printer and
    its CSE."""
    A, Vq, q, p, flow, par = _symbolic_parts(lh.model)
    n = len(q)
    xs = (*q, *p)
    fA = sp.lambdify([xs], [A, *(sp.diff(A, s) for s in xs)], "math")
    fV = sp.lambdify([q], [Vq, *(sp.diff(Vq, s) for s in q)], "math")
    fH = sp.lambdify([q], sp.hessian(Vq, q), "numpy")
    for kind, c in zip(lh.kinds, lh.coef, strict=True):
        hs = c * h
        if kind == 0:
            a, *gA = fA(x)
            W = a + wc
            tau = hs / W
            dtau = -(tau / W) * (dpt + V @ np.array(gA))
            if flow.kind == "free":
                x[:n] += tau * par * x[n:]
                V[:, :n] += tau * par * V[:, n:]
            else:
                planar_flow(tau, x, V, len(V), par)
            _, *gA = fA(x)
            V[:, :n] += np.outer(dtau, gA[n:])
            V[:, n:] -= np.outer(dtau, gA[:n])
            dt += dtau
        else:
            v, *gV = fV(x[:n])
            gV, HV = np.array(gV), np.array(fH(x[:n]), dtype=float)
            w = hs / (C - v)
            r = w / (C - v)
            x[n:] -= w * gV
            V[:, n:] -= w * V[:, :n] @ HV.T + r * np.outer(V[:, :n] @ gV, gV)
    return x, V, dt


@pytest.mark.parametrize("which", ["plummer", "cr3bp"])
def test_the_emitted_step_is_the_specified_step_to_round_off(which, plummer):
    """The emitted, unrolled step (straight-line derivatives, half-integer
    powers by square roots) against the specification in plain NumPy, one
    LH step with three vectors off the energy shell's δp_t = 0: equal to
    round-off (measured ≤ 3e-16 relative on both)."""
    if which == "plummer":
        lh, x0, h = LogHamiltonian(plummer, "ABA864"), np.array([0.3, 0.1, 0.2, 1.5]), 0.1
    else:
        # ABA864, as the maps' test below: one emitted CR3BP stepper.
        lh, x0, h = (LogHamiltonian(CR3BP(SUN_JUPITER_MU), "ABA864"),
                     np.array([0.6, 0.05, 0.1, 0.7]), 0.1)
    rng = np.random.default_rng(7)
    V0, dpt = rng.standard_normal((3, 4)), rng.standard_normal(3)
    wc = -lh.energy(x0)[0]
    x, V, dt = x0.copy(), V0.copy(), np.zeros(3)
    status = lh.step_kernel(x, V, dt, dpt, np.array([0.0, wc]), lh.kinds, lh.coef, h, lh.par,
                            True, 0.0, np.zeros(3, np.int64), np.empty(4), np.empty(2),
                            np.empty((2, 2)), np.empty(3))
    assert status == 0
    xs, Vs, dts = _specified_step(lh, x0.copy(), V0.copy(), np.zeros(3), dpt, wc, h, 0.0)
    for got, want in ((x, xs), (V, Vs), (dt, dts)):
        assert np.abs(got - want).max() < 1e-13 * np.abs(want).max(), (got, want)


def _heyoka_plummer(x0, t):
    hy = pytest.importorskip("heyoka")
    q = hy.make_vars("x", "y")
    v = hy.make_vars("vx", "vy")
    r3 = (q[0] * q[0] + q[1] * q[1] + EPS**2) ** 1.5
    sys = [(q[0], v[0]), (q[1], v[1]), (v[0], -q[0] / r3), (v[1], -q[1] / r3)]
    ta = hy.taylor_adaptive(sys, x0.astype(np.longdouble), fp_type=np.longdouble,
                            tol=np.longdouble(1e-18))
    ta.propagate_until(np.longdouble(t))
    return np.asarray(ta.state, dtype=float)


@pytest.mark.parametrize("scheme,order", [("SBAB2", 2), ("ABA864", 4)])
def test_order_in_physical_time_against_heyoka(scheme, order, plummer):
    """The global error at physical time t = 3 (through the pericentre
    passage) falls as h^order."""
    lh = LogHamiltonian(plummer, scheme)
    ref = _heyoka_plummer(X0, 3.0)
    hs = (0.02, 0.01) if order == 2 else (0.04, 0.02)
    err = []
    for h in hs:
        r = lh.advance(X0, np.zeros((4, 0)), 3.0, h)
        assert r.status[0] == 0 and r.t[0] == 3.0
        err.append(np.abs(r.x[0] - ref).max())
    slope = math.log2(err[0] / err[1])
    assert order - 0.3 < slope < order + 0.5, (err, slope)


def test_near_collision_energy_bounded_where_constant_steps_fail(plummer):
    """Ten pericentre passages at 0.02 of a softened point mass: the LH
    steps keep the energy to 1e-5, constant steps of the same count (the
    same scheme in physical time) lose it by more than 1 %."""
    lh = LogHamiltonian(plummer, "ABA864")
    t_end, E0 = 20.0, lh.energy(X0)[0]
    r = lh.advance(X0, np.zeros((4, 0)), t_end, 0.05)
    assert r.status[0] == 0
    assert abs(lh.energy(r.x)[0] - E0) < 1e-5 * abs(E0)
    n = int(r.steps[0] + r.tail_steps[0])
    x, V, dt, clock = X0.copy(), np.zeros((0, 4)), np.zeros(0), np.array([0.0, 0.0])
    scratch = (np.empty(4), np.empty(2), np.empty((2, 2)), np.empty(0))
    for _ in range(n):
        if lh.step_kernel(x, V, dt, np.zeros(0), clock, lh.kinds, lh.coef, t_end / n, lh.par,
                          False, 0.0, np.zeros(3, np.int64), *scratch) != 0:
            break
    assert not abs(lh.energy(x)[0] - E0) < 1e-2 * abs(E0)


def test_vectors_are_physical_time_deviations(plummer):
    """The vectors at an output are H's tangent flow at equal physical
    time: against finite differences of the state at that time."""
    lh = LogHamiltonian(plummer, "ABA864")
    r = lh.advance(X0, np.eye(4), 1.0, 0.005)
    C = r.C[0]
    d = 1e-6
    J = np.empty((4, 4))
    for j in range(4):
        e = np.zeros(4)
        e[j] = d
        # Each perturbed state on its own energy shell (p_t = −H): H's
        # flow to t = 1, whatever the transformation does.
        a = lh.advance(X0 + e, np.zeros((4, 0)), 1.0, 0.005, C=C).x[0]
        b = lh.advance(X0 - e, np.zeros((4, 0)), 1.0, 0.005, C=C).x[0]
        J[:, j] = (a - b) / (2 * d)
    # Each perturbed orbit lands through its own tail: the maps differ at
    # the integration error, not round-off. Without the projection δx −
    # f_H δt the difference would be of the order of f_H δt.
    assert np.abs(J - r.W[0]).max() < 1e-7 * np.abs(r.W[0]).max()   # measured 1e-9


def test_resume_from_an_output_repeats_the_bits(plummer, tmp_path):
    """0 → 2 → 4 in one process against 0 → 2, saved to disk and loaded,
    then 2 → 4 with the saved C and p_t."""
    lh = LogHamiltonian(plummer, "ABA864")
    W0 = np.eye(4)[:, :2].copy()
    a = lh.advance(X0, W0, 2.0, 0.05)
    b = lh.advance(a.x, a.W, 4.0, 0.05, t0=2.0, C=a.C, pt=a.pt)
    np.savez(tmp_path / "s.npz", x=a.x, W=a.W, C=a.C, pt=a.pt)
    s = np.load(tmp_path / "s.npz")
    c = lh.advance(s["x"], s["W"], 4.0, 0.05, t0=2.0, C=s["C"], pt=s["pt"])
    assert np.array_equal(b.x, c.x) and np.array_equal(b.W, c.W) and np.array_equal(b.t, c.t)


def test_refusals(plummer):
    with pytest.raises(ValueError, match="offset must be a finite number > 0, got -1"):
        LogHamiltonian(plummer, offset=-1.0)
    with pytest.raises(ValueError, match="two-part scheme without a corrector"):
        LogHamiltonian(plummer, "SBAB2C")
    with pytest.raises(ValueError, match="h must be a finite number > 0, got 0"):
        LogHamiltonian(plummer).advance(X0, np.zeros((4, 0)), 1.0, 0)


def test_u_not_positive_stops_with_a_reason(plummer):
    """C below V on the orbit (U ≤ 0) is reported by name."""
    lh = LogHamiltonian(plummer, "ABA864")
    r = lh.advance(X0, np.zeros((4, 0)), 1.0, 0.05, C=-5.0)
    assert r.status[0] == -1 and r.t[0] == 0.0
    values, _, status = lh.fli(X0[None], np.eye(4)[:1], 1.0, 0.05, C=-5.0)
    assert np.isnan(values[0]) and status[0] == -1
    assert "U = C − V" in describe(status[0])


# -- maps: varint.chaos_map(..., time_transform="log") ----------------------------------

def _cr3bp_orbits():
    """Twelve Sun–Jupiter orbits; with δ = 0.5 orbit 9 meets U ≤ 0 (δ = 1: none)."""
    rng = np.random.default_rng(1)
    return np.column_stack([rng.uniform(0.3, 0.9, 12), rng.uniform(-0.1, 0.1, 12),
                            rng.uniform(-0.2, 0.2, 12), rng.uniform(0.3, 1.0, 12)])


def test_chaos_map_log_is_the_fli_of_the_same_orbits_in_any_chunks():
    """The map's values are LogHamiltonian.fli's bits on the same orbits
    and vectors (default_rng([seed, m])), for chunks of 5 and of all 12;
    an orbit the LH stops (U ≤ 0) is NaN with a failure status, and its
    reason is counted in the provenance."""
    from varint import chaos_map
    from varint.protocol import Status
    from varint.state import initial_deviations

    model, X = CR3BP(SUN_JUPITER_MU), _cr3bp_orbits()
    lh = LogHamiltonian(model, "ABA864", offset=0.5)
    W0 = initial_deviations(4, 1, len(X), 3, np.arange(len(X)))[:, :, 0]
    values, _, status = lh.fli(X, W0, 20.0, 0.2, every=5.0)
    assert status[9] == -1 and (np.delete(status, 9) == 0).all()   # the case is exercised
    maps = []
    for size in (5, None):
        with pytest.warns(RuntimeWarning, match="1 of 12 orbits were stopped by the "
                          "logarithmic Hamiltonian .*U = C − V"):
            maps.append(chaos_map(model, X, "fli", t_end=20.0, tau=0.2, time_transform="log",
                                  seed=3, scheme="ABA864", offset=0.5, every=5.0,
                                  chunk_size=size, progress=False, energy_tol=math.inf))
    for r in maps:
        assert np.array_equal(r.values, values, equal_nan=True)
        assert np.array_equal(r.status, np.where(status < 0, int(Status.INTEGRATOR_FAILED),
                                                 status))
        assert np.isnan(r.values[9]) and 0.0 <= r.t_stop[9] < 20.0   # where it stopped
        assert (np.delete(r.t_stop, 9) == 20.0).all()
        prov = r.provenance
        assert prov.method == "tm+log" and prov.tau == 0.2 and prov.seed == 3
        assert prov.method_options["scheme"]["name"] == "ABA864" and prov.method_options["h"] == 0.2
        assert prov.method_options["offset"] == 0.5 and prov.method_options["every"] == 5.0
        assert prov.options["lh_failures"] == {describe(-1): 1}
    assert maps[0].provenance.options["chunks"] == 3 and maps[1].provenance.options["chunks"] == 1


@pytest.mark.parametrize("kwargs,message", [
    ({"indicator": "sali"}, "FLI maps only, got indicator 'sali'"),
    ({"tau": -0.1}, r"tau \(the fictitious step h\) must be a positive finite number, got -0.1"),
    ({"backend": "cuda"}, "CPU only, got backend 'cuda'"),
    ({"scheme": "SBAB2C"}, "two-part scheme without a corrector or processor, got 'SBAB2C'"),
    ({"threshold": 3.0}, "does not take threshold=3.0"),
    ({"checkpoint": "somewhere"}, "does not take checkpoint='somewhere'"),
    ({"k": 2}, "takes the options .* got 'k'"),
    ({"time_transform": "sundman"}, "time_transform must be None or one of .* got 'sundman'"),
    ({"model": "standard"}, "needs an autonomous H"),
])
def test_chaos_map_log_refusals_name_the_value(kwargs, message, plummer):
    """Each refused before any kernel compiles."""
    from varint import chaos_map
    from varint.models import StandardMap

    args = {"model": plummer, "indicator": "fli", "tau": 0.05, "time_transform": "log"}
    args.update(kwargs)
    if args["model"] == "standard":
        args["model"] = StandardMap(1.0)
    model, indicator = args.pop("model"), args.pop("indicator")
    with pytest.raises(ValueError, match=message):
        chaos_map(model, X0[None], indicator, t_end=1.0, **args)


# -- the generated stepper: signed, cached, loaded without compiling -----------------------

#: An LH FLI run of a softened 1-dof point mass in a new interpreter: prints
#: the seconds compiled, the values' bytes and the warnings' text.
_FRESH = """
import json, warnings
import numpy as np, sympy as sp
from varint import compiling
from varint.models import from_potential
from varint.time_transform import LogHamiltonian
x = sp.Symbol("x")
model = from_potential(-1 / sp.sqrt(x**2 + sp.Float(1e-2)), [x])
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    lh = LogHamiltonian(model, "SBAB2")
    values, counts, status = lh.fli(np.array([[1.0, 0.1], [0.5, 0.0]]), np.eye(2), 5.0, 0.05)
print(json.dumps([compiling.compile_seconds(), values.tobytes().hex(), status.tolist(),
                  [str(w.message) for w in caught]]))
"""


def _fresh(cache_dir):
    """:data:`_FRESH` in a new interpreter on this tree with ``cache_dir``."""
    root = Path(__file__).resolve().parent.parent
    env = dict(os.environ, PYTHONPATH=str(root), VARINT_CACHE_DIR=str(cache_dir))
    done = subprocess.run([sys.executable, "-c", _FRESH], env=env, check=True,
                          capture_output=True, text=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_a_second_process_compiles_nothing_and_an_edited_stepper_never_runs(tmp_path):
    """The LH stepper is generated source in the cache directory, signed
    (varint.codecache): a second process loads it and numba's signed
    files, compiles nothing and gets the same bits; a payload appended to
    the cached source (it would create a marker file) fails the signature,
    is discarded with a warning and the stepper rebuilt, with the same
    bits."""
    cache_dir, marker = tmp_path / "cache", tmp_path / "MARKER"
    compiled, cold, status, _ = _fresh(cache_dir)
    assert compiled > 0.0 and status == [0, 0]
    (path,) = (cache_dir / "kernels").glob("varint_lh_*.py")
    assert path.read_bytes().startswith(codecache.HEADER)
    numba_files = list((cache_dir / "kernels" / "__pycache__").glob("varint_lh_*.nb[ic]"))
    assert numba_files and all(f.read_bytes().startswith(codecache.HEADER) for f in numba_files)

    compiled, warm, _, caught = _fresh(cache_dir)
    assert compiled == 0.0 and warm == cold
    assert not any("is not used" in w for w in caught)

    path.write_text(path.read_text() + f"\nopen({str(marker)!r}, 'w').write('pwned')\n")
    _, again, _, caught = _fresh(cache_dir)
    assert any("generated kernel file" in w and "is not used" in w for w in caught)
    assert again == cold and not marker.exists()

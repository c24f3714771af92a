"""Time-periodic Hamiltonians H = p²/2 + V(q, t), integrated in the extended
phase space: the generated kernels against SymPy, the known behaviour of a
parametrically driven pendulum (a chaotic layer at the separatrix, a
resonance island), the order of accuracy of the extended energy K = H + p_t
and of the tangent map against the Taylor reference, every method on the
same definition, force reuse, and bitwise resume."""

import numpy as np
import pytest
import sympy as sp

import varint
from varint.cache import reference
from varint.models import from_potential
from varint.schemes import get_scheme, stage_arrays, stage_times
from tests.helpers import assert_bitwise_equal, fitted_slope, hook_advance

q, t = sp.symbols("q t")
#: The parametrically driven pendulum V = −cos q (1 + ε cos Ωt), ε = 0.2,
#: Ω = 1.5: its separatrix (H = 1, p = 2 at q = 0) is broken into a chaotic
#: layer; p = 2.3 at q = 0 starts in a resonance island inside that layer,
#: p = 0.5 in the libration region (both regular).
V = -sp.cos(q) * (1 + sp.Rational(1, 5) * sp.cos(sp.Rational(3, 2) * t))
LAYER, ISLAND, LIBRATION = [0.0, 2.0], [0.0, 2.3], [0.0, 0.5]


@pytest.fixture(scope="module")
def pendulum():
    return from_potential(V, [q], time=t)


def test_kernels_match_sympy_at_every_time():
    x, y = sp.symbols("x y")
    W = (x**2 + y**2) / 2 + sp.sin(t) * x**2 * y - sp.cos(2 * t) * y**3 / 3
    m = from_potential(W, [x, y], time=t)
    rng = np.random.default_rng(2)
    for qv, tv in zip(rng.uniform(-0.5, 0.5, (4, 2)), rng.uniform(-3, 3, 4), strict=True):
        at = {x: qv[0], y: qv[1], t: tv}
        grad = [float(sp.diff(W, s).subs(at)) for s in (x, y)]
        hess = [[float(sp.diff(W, a, b).subs(at)) for b in (x, y)] for a in (x, y)]
        dv, gt = m.time_derivatives(qv, tv)
        assert np.allclose(m.gradient(qv, tv), grad, atol=1e-14)
        assert np.allclose(m.hessian(qv, tv), hess, atol=1e-14)
        assert dv == pytest.approx(float(sp.diff(W, t).subs(at)), abs=1e-14)
        assert np.allclose(gt, [float(sp.diff(W, t, s).subs(at)) for s in (x, y)], atol=1e-14)
        v = np.array([0.3, -0.7])
        third = sum(v[k] * np.array([[float(sp.diff(W, a, b, s).subs(at)) for b in (x, y)]
                                     for a in (x, y)]) for k, s in enumerate((x, y)))
        B = m.third_band(qv, v, tv)
        assert np.allclose([B[0, 0], B[0, 1], B[1, 0]], [third[0, 0], third[1, 1], third[0, 1]],
                           atol=1e-14)
        assert m.potential(qv, tv) == pytest.approx(float(W.subs(at)), abs=1e-15)


def test_from_potential_time_input_is_checked():
    with pytest.raises(ValueError, match="time=<its symbol>"):
        from_potential(V, [q])
    with pytest.raises(ValueError, match="SymPy symbol"):
        from_potential(V, [q], time="t")
    with pytest.raises(ValueError, match="also a coordinate"):
        from_potential(V, [q, t], time=t)


def test_stage_times_put_kicks_where_the_drifts_left_time():
    """Every kick acts at the time the drifts before it reached, in units
    of τ; the last kick of a BAB step is exactly at 1, the next step's
    first, so the force can be reused between them."""
    for name in ("SBAB2C", "SABA2C", "ABA864", "SBAB3"):
        scheme = get_scheme(name)
        kinds, h, _ = stage_arrays(scheme, 0.1)
        c = stage_times(scheme)
        reached = np.concatenate([[0.0], np.cumsum(np.where(kinds == 0, h, 0.0))[:-1]]) / 0.1
        assert np.allclose(c, reached, atol=1e-14)
        assert c[0] == 0.0
        if not scheme.drift_first:  # a BAB step ends with a kick
            assert c[-1] == 1.0


def test_driven_pendulum_chaotic_layer_and_resonance_island(pendulum):
    """X1 > 0 and SALI → 0 exponentially in the layer; in the island and the
    libration region X1 falls like ln t / t and SALI like a power law (a
    1½-degree-of-freedom system: its regular orbits are 2-tori of the
    extended phase space, on which two physical vectors align slowly)."""
    x0 = np.array([LAYER, ISLAND, LIBRATION])
    r = varint.run(pendulum, x0, "x1", 2e4, tau=0.05, t_out=[2e3, 2e4])
    s = varint.run(pendulum, x0, "sali", 2e3, tau=0.05, t_out=[2e2, 2e3])
    X1 = r.exponents[:, :, 0]
    assert X1[0, -1] > 0.1
    assert s.sali[0, -1] < 1e-14
    for i in (1, 2):
        assert X1[i, -1] < 1e-3 and X1[i, -1] < X1[i, 0] / 3
        assert s.sali[i, -1] > 1e-6
    assert (r.energy_error < 1e-6).all()  # K = H + p_t, conserved


@pytest.mark.parametrize("scheme", ["SBAB2C", "SBAB2", "SABA2C", "SBAB1"])
def test_order_of_the_extended_energy_and_tangent_errors(pendulum, scheme):
    """Against the extended-precision Taylor reference at t = 12.8, the
    error of K = H + p_t and of the tangent map fall as τ^p with p the
    scheme's order (measured: 4.00, 2.00, 4.00, 2.00 for both)."""
    x0, T = np.array([0.0, 1.0]), 12.8
    ref = reference(pendulum, x0, T, tau=0.1, deviations=np.eye(2))
    taus = 0.1 * 2.0 ** -np.arange(4)
    k_err, w_err = [], []
    for tau in taus:
        r = varint.integrate(pendulum, x0, T, tau=tau, scheme=scheme, deviations=np.eye(2))
        k_err.append(r.energy_error[-1])
        w_err.append(np.abs(r.deviations - ref.deviations).max())
    p = get_scheme(scheme).order
    assert fitted_slope(taus, k_err) == pytest.approx(p, abs=0.15)
    assert fitted_slope(taus, w_err) == pytest.approx(p, abs=0.15)


@pytest.mark.slow  # compiles the time-dependent variant of every method (~2 min)
def test_every_method_integrates_the_same_definition(pendulum):
    """X1 and K of the layer orbit over t = 30 (a few Lyapunov times) from
    every method against the Taylor reference."""
    x0, T = np.array(LAYER), 30.0
    ref = varint.lyapunov_spectrum(pendulum, x0, T, tau=0.05, method="taylor",
                                   precision="extended", t_out=[T])
    cases = [("tm", {"scheme": "ABA864"}, 1e-9), ("taylor", {}, 1e-12),
             ("dop853", {"delta": 1e-13}, 1e-10), ("cvode", {"rtol": 1e-12, "atol": 1e-12}, 1e-7),
             ("tdheps", {}, 1e-6), ("tdhcc", {}, 1e-2), ("tdhes", {}, 1e-2),
             ("two-particle", {"scheme": "ABA864"}, 1e-6)]
    for method, opts, tol in cases:
        r = varint.lyapunov_spectrum(pendulum, x0, T, tau=0.05, method=method, t_out=[T], **opts)
        assert np.abs(r.exponents[-1] - ref.exponents[-1]).max() < tol, method
        assert r.energy_error[-1] < max(tol, 1e-9), method


def test_forces_are_reused_between_steps(pendulum):
    """The last kick of an SBAB2C step and the first of the next are at the
    same (q, t), bit for bit: 2 gradients per step, as for an autonomous V."""
    r = varint.lyapunov_spectrum(pendulum, LAYER, 100.0, tau=0.05)
    steps = r.provenance.counts["steps"]
    assert r.provenance.counts["gradient"] <= 2 * steps + 100


@pytest.mark.parametrize("method", ["tm", "dop853",
                                    pytest.param("tdheps", marks=pytest.mark.slow),
                                    pytest.param("two-particle", marks=pytest.mark.slow)])
def test_a_time_dependent_run_resumes_bitwise(pendulum, tmp_path, monkeypatch, method):
    # "x1", the indicator the chaotic-layer test already compiles for "tm":
    # resuming is the same law whatever the accumulator, so no kernel of its own.
    def run(**kw):
        return varint.run(pendulum, LAYER, "x1", 40.0, tau=0.05, method=method, **kw)

    reference_run = run()

    class Crash(Exception):
        pass

    def crash():
        raise Crash

    path = tmp_path / "c.ckpt"
    with monkeypatch.context() as patch:
        hook_advance(patch, method, 3, crash)
        with pytest.raises(Crash):
            run(checkpoint=path, checkpoint_interval=0)
    resumed = run(checkpoint=path, checkpoint_interval=0)
    assert_bitwise_equal(resumed, reference_run)
    assert resumed.energy_error[-1] > 0  # p_t was restored, K is not H


def test_sections_refuse_time_dependent_models(pendulum):
    with pytest.raises(ValueError, match="phase_grid"):
        varint.section_grid(pendulum, 0.5, [0.1], [0.1])
    with pytest.raises(ValueError, match="phase_grid"):
        varint.surface_of_section(pendulum, LAYER, 10.0)

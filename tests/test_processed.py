"""Processed schemes (Blanes, Casas & Murua 2006): the processor and its
inverse, the measured effective order of orbit and tangent vector, the
tangent map as the derivative of the processed map, bitwise chunking and
resume, and the refusals where the processor would not be applied."""

import copy
import math

import numpy as np
import pytest

import varint
from varint.cache import reference
from varint.methods.tm import TangentMapPropagator
from varint.protocol import Renorm
from varint.schemes import ProcessedScheme, get_scheme, registered
from varint.state import RunState, initial_deviations

from tests.helpers import fitted_slope

PROCESSED = ("P11odr6", "P13odr8", "P23odr10")


def _same(a, b):
    """The same bits."""
    assert a.shape == b.shape and a.tobytes() == b.tobytes()


def _run(model, x0, W0, tau, n, scheme, chunks=None, generic=False):
    """``n`` steps of ``scheme`` by the TM propagator in the given chunks;
    ``generic``: on the generic stepper (kernels/tm.py, the kernel's stages
    as data: one compilation serves every scheme) instead of the one
    generated for the kernel's stages."""
    state = RunState.start(np.asarray(x0, float)[None], np.asarray(W0, float)[None])
    prop = TangentMapPropagator(model, tau, Renorm.NONE, scheme=scheme, parallel=False)
    if generic:
        prop._generated[state.k] = None
    for c in chunks or (n,):
        prop.advance(state, c)
    return state


def _error(model, x0, w0, t_end, tau, scheme, ref):
    """Relative error of orbit and vectors at ``t_end`` against ``ref``, on
    the generic stepper: the effective order is the composition P⁻¹ K P's,
    whichever stepper runs K (P and P⁻¹ are applied outside it, the same
    code for both; test_generated_stepper checks that the two steppers are
    the same map to round-off)."""
    r = _run(model, x0, w0, tau, round(t_end / tau), scheme, generic=True)
    return max(np.linalg.norm(r.x[0] - ref.state) / np.linalg.norm(ref.state),
               np.linalg.norm(r.W[0] - ref.deviations) / np.linalg.norm(ref.deviations))


@pytest.mark.parametrize("name", PROCESSED)
def test_coefficients_meet_the_sum_rules(name):
    """The kernel is a composition Π S2(a_i τ) with Σa = 1 whose odd power
    sums Σa³, Σa⁵ vanish (no processor can remove the τ³ and τ⁵ error
    terms of S2, which are not commutators with H; Blanes, Casas & Murua
    2006, Sect. 3); the processor's coefficients sum to 0, so P is near the
    identity. A wrong digit breaks these far above the published 15 digits."""
    s = get_scheme(name, processed=True)
    full = list(s.kernel) + list(s.kernel[-2::-1])
    assert math.fsum(full) == pytest.approx(1.0, abs=1e-15)
    for k in (3, 5):
        assert abs(math.fsum(a ** k for a in full)) < 1e-14, k
    assert abs(math.fsum(s.processor)) < 1e-15
    assert s.force_evaluations == len(full)


@pytest.mark.parametrize("name", PROCESSED)
def test_processor_inverse_undoes_it_with_its_tangent(name, c1):
    """P⁻¹(P(x)) = x and DP⁻¹ DP = I to round-off: the two stage tables
    are one map and its inverse, tangent maps included."""
    model, x0 = c1
    s = get_scheme(name, processed=True)
    prop = TangentMapPropagator(model, 0.3, Renorm.NONE, scheme=s, parallel=False)
    x, W = np.array(x0, float)[None], np.eye(4)[None].copy()
    rows = np.array([True])
    prop._apply(x, W, rows, s.processor_stages(0.3))
    moved = np.max(np.abs(x[0] - x0))
    assert moved > 1e-9   # P is not the identity at this τ (far above round-off)
    prop._apply(x, W, rows, s.processor_stages(0.3, inverse=True))
    assert np.max(np.abs(x[0] - x0)) < 1e-15
    assert np.max(np.abs(W[0] - np.eye(4))) < 1e-14


@pytest.mark.parametrize("name, taus", [("P11odr6", (0.5, 0.25, 0.125)),
                                        ("P13odr8", (0.5, 0.25, 0.125)),
                                        ("P23odr10", (1.0, 0.5, 0.25))])
def test_measured_effective_order_of_orbit_and_tangent(name, taus, r1):
    """The global error of the orbit and of one tangent vector at t = 20,
    against the extended-precision Taylor reference, falls as τ^order (the
    effective order); the kernel alone (no processor) is far less
    accurate at the same step. The three schemes and the kernels alone
    share one compilation, the generic stepper's (a stepper generated per
    kernel would be three, ~45 CPU s cold)."""
    model, x0 = r1
    w0 = np.eye(4)[:, :1]
    ref = reference(model, x0, 20.0, tau=0.1, deviations=w0)
    s = get_scheme(name, processed=True)
    errs = [_error(model, x0, w0, 20.0, tau, name, ref) for tau in taus]
    assert abs(fitted_slope(taus, errs) - s.order) < 0.6, errs
    alone = _error(model, x0, w0, 20.0, taus[-1], s.kernel_scheme, ref)
    assert alone > 30 * errs[-1], (alone, errs[-1])


def test_tangent_is_the_derivative_of_the_processed_map(c1):
    """A deviation vector of a processed run equals the central finite
    differences of its final state along the vector's initial direction
    (error ∝ h²): P⁻¹'s, the kernel's and P's tangent maps enter exactly.
    The direction is a seeded generic one, so every column of the tangent
    map enters; the stepper generated for P13odr8's kernel with one vector,
    which the other tests of a state on that stepper share."""
    model, x0 = c1
    tau, n = 0.2, 20
    w = np.random.default_rng(0).standard_normal(4)
    w /= np.linalg.norm(w)
    Mw = _run(model, x0, w[:, None], tau, n, "P13odr8").W[0, :, 0]
    hs = (4e-3, 2e-3, 1e-3)
    errs = []
    for h in hs:
        xp = _run(model, x0 + h * w, w[:, None], tau, n, "P13odr8").x[0]
        xm = _run(model, x0 - h * w, w[:, None], tau, n, "P13odr8").x[0]
        errs.append(np.max(np.abs((xp - xm) / (2 * h) - Mw)) / np.max(np.abs(Mw)))
    assert errs[-1] < 1e-4
    assert abs(fitted_slope(hs, errs) - 2.0) < 0.3, errs


def test_chunking_and_resume_are_bitwise(c1):
    """The kernel's state lives in the run state, so chunks (and outputs,
    each read through P) never change a bit, and a copy of the state
    resumed by a new propagator continues bitwise."""
    model, x0 = c1
    # One vector and P13odr8: the generated kernel of
    # test_tangent_is_the_derivative_of_the_processed_map (the law holds for
    # any scheme and number of vectors).
    w0 = np.eye(4)[:, :1]
    whole = _run(model, x0, w0, 0.2, 30, "P13odr8")
    parts = _run(model, x0, w0, 0.2, 30, "P13odr8", chunks=(7, 1, 22))
    _same(whole.x, parts.x)
    _same(whole.W, parts.W)
    half = _run(model, x0, w0, 0.2, 12, "P13odr8")
    resumed = copy.deepcopy(half)
    TangentMapPropagator(model, 0.2, Renorm.NONE, scheme="P13odr8",
                         parallel=False).advance(resumed, 18)
    _same(whole.x, resumed.x)
    _same(whole.W, resumed.W)
    many = varint.integrate(model, x0, 6.0, tau=0.2, scheme="P13odr8", deviations=w0,
                            t_out=np.linspace(0.2, 6.0, 30))
    one = varint.integrate(model, x0, 6.0, tau=0.2, scheme="P13odr8", deviations=w0)
    _same(many.state, one.state)
    _same(many.deviations, one.deviations)


def test_compensated_kernel_is_bitwise_across_outputs_and_agrees(r1):
    """With ``compensated=True`` the kernel's Kahan terms are part of the
    run state like the kernel's own: outputs (each read through P) change
    no bit, and the result agrees with the plain run to round-off."""
    model, x0 = r1
    w0 = np.eye(4)[:, :1]
    kw = dict(tau=0.25, scheme="P13odr8", deviations=w0, compensated=True)
    one = varint.integrate(model, x0, 20.0, **kw)
    many = varint.integrate(model, x0, 20.0, t_out=np.linspace(1.0, 20.0, 20), **kw)
    _same(one.state, many.state)
    _same(one.deviations, many.deviations)
    plain = varint.integrate(model, x0, 20.0, tau=0.25, scheme="P13odr8", deviations=w0)
    assert np.max(np.abs(plain.state - one.state)) < 1e-12


def test_a_state_set_from_outside_is_processed_again(c1):
    """An orbit whose state is not what the last call wrote starts from
    P⁻¹ of its new state (the kernel's kept state would be stale)."""
    model, x0 = c1
    w0 = np.eye(4)[:, :1]   # one vector: the kernel the other P13odr8 tests compile
    state = _run(model, x0, w0, 0.2, 5, "P13odr8")
    other = np.array(x0, float) * 0.9
    state.x[0] = other
    state.W[0] = w0
    TangentMapPropagator(model, 0.2, Renorm.NONE, scheme="P13odr8",
                         parallel=False).advance(state, 5)
    fresh = _run(model, other, w0, 0.2, 5, "P13odr8")
    _same(state.x, fresh.x)
    _same(state.W, fresh.W)


def test_lyapunov_exponent_agrees_with_an_unprocessed_scheme(c1):
    """Indicators take a processed scheme unchanged: the largest
    exponent of C1 agrees with SRKN14a's (vectors renormalised in the
    kernel's coordinates differ by the near-identity DP, a bounded
    difference in the sum of logarithms)."""
    model, x0 = c1
    a = varint.lyapunov_spectrum(model, x0, 200.0, tau=0.2, scheme="P13odr8", n_exponents=1)
    b = varint.lyapunov_spectrum(model, x0, 200.0, tau=0.1, scheme="SRKN14a", n_exponents=1)
    assert abs(a.exponents[-1, 0] - b.exponents[-1, 0]) < 0.01 * abs(b.exponents[-1, 0])
    # Renormalised runs stay bitwise whatever the outputs (each a stop);
    # one exponent, the kernel of the run above.
    few = varint.lyapunov_spectrum(model, x0, 40.0, tau=0.2, scheme="P13odr8", t_out=2,
                                   n_exponents=1)
    many = varint.lyapunov_spectrum(model, x0, 40.0, tau=0.2, scheme="P13odr8",
                                    t_out=np.linspace(0.2, 40.0, 200), n_exponents=1)
    _same(few.exponents[-1], many.exponents[-1])
    # The automatic step takes a processed scheme by its effective order.
    auto = varint.lyapunov_spectrum(model, x0, 20.0, scheme="P13odr8", n_exponents=1)
    assert np.isfinite(auto.exponents).all()


def test_processed_schemes_are_refused_where_no_processor_is_applied(c1):
    model, x0 = c1
    assert {s.name for s in registered() if isinstance(s, ProcessedScheme)} == set(PROCESSED)
    with pytest.raises(ValueError, match="'P13odr8' is processed.*method='tm'"):
        get_scheme("P13odr8", n_parts=2)
    for method in ("tdhes", "two-particle"):
        with pytest.raises(ValueError, match="'P13odr8' is processed.*method='tm'"):
            varint.lyapunov_spectrum(model, x0, 1.0, tau=0.1, method=method, scheme="P13odr8",
                                     n_exponents=1)
    with pytest.raises(ValueError, match="processor coefficients sum to"):
        ProcessedScheme("bad", kernel=(0.5,), processor=(0.1, 0.2), order=2)
    with pytest.raises(ValueError, match="kernel must be a non-empty"):
        ProcessedScheme("bad", kernel=(), processor=(0.1, -0.1), order=2)


def test_chaos_map_takes_a_processed_scheme(c1):
    """A map of 12 orbits (SIMD lanes) runs a processed scheme unchanged:
    its X1 is, orbit by orbit, bit for bit the exponent of
    ``lyapunov_spectrum`` on the same orbits and seeded vectors, whose
    processed runs are checked above (P, P⁻¹ are applied outside the
    stepper; lanes are bitwise the one-orbit stepper:
    test_generated_stepper, test_rotating_generated). All 12 orbits in one
    call run the map's lane kernel: one orbit at a time would compile the
    one-orbit stepper too (~21 CPU s cold). (MEGNO against s17odr8's map
    instead: two lane kernels, ~38 CPU s cold.)"""
    model, x0 = c1
    X = np.array([x0 * (1 + 0.01 * i) for i in range(12)])
    X[:, 2] = x0[2]
    a = varint.chaos_map(model, X, "x1", t_end=100.0, tau=0.2, scheme="P13odr8",
                         progress=False)
    # Orbit m of the map starts from the vector of default_rng([seed, m]).
    W0 = initial_deviations(model.dim, 1, len(X), 0)
    one = varint.lyapunov_spectrum(model, X, 100.0, tau=0.2, scheme="P13odr8", deviations=W0,
                                   t_out=1)
    np.testing.assert_array_equal(np.asarray(a.values), one.exponents[:, -1, 0], strict=True)

"""The compiled tangent-map stepper: against the paper's explicit maps, and
the properties the rest of varint relies on (no tangent work for k = 0,
chunk invariance, batches, specialised vs run-time sizes, counting)."""

import numpy as np
import pytest

import varint
from varint.kernels import tm as K
from varint.kernels.checks import renormalize_block
from varint.kernels.interval import Call
from varint.protocol import Renorm, Status
from varint.methods import make_propagator
from varint.state import RunState
from varint.methods.tm import tangent_map_steps
from tests.naive import hh_tm_sbab2c_step, qr_positive


def test_sbab2c_equals_the_papers_explicit_maps(c1):
    """The generic stepper reproduces Appendix A's SBAB2C TM map (A.21–A.23)."""
    model, x0 = c1
    x, W = x0.copy(), np.eye(4)
    for _ in range(100):
        x, W = hh_tm_sbab2c_step(x, W, 0.05)
    xk, Wk = tangent_map_steps(model, x0, np.eye(4), tau=0.05, n_steps=100, scheme="SBAB2C")
    assert np.max(np.abs(xk - x)) < 1e-13
    assert np.max(np.abs(Wk - W)) < 1e-11 * np.max(np.abs(W))


def test_renormalize_qr_matches_lapack():
    rng = np.random.default_rng(0)
    W = rng.standard_normal((6, 4))
    Q, R = qr_positive(W)
    acc_m, acc_e = np.ones(4), np.zeros(4, dtype=np.int64)
    V = W.copy()
    r = np.empty(4)
    assert renormalize_block(V, Renorm.QR, acc_m, acc_e, r) == Status.OK
    assert np.allclose(V, Q, atol=1e-14)
    assert np.allclose(np.log(acc_m) + acc_e * np.log(2), np.log(np.diag(R)), atol=1e-14)
    assert np.allclose(r, np.diag(R), rtol=1e-14)  # the stretching the accumulators see


def test_log_accumulator_is_exact_over_huge_growth():
    """Mantissa/exponent accumulation keeps Σ log r exact where a plain
    product would overflow after a few hundred factors."""
    acc_m, acc_e = np.ones(1), np.zeros(1, dtype=np.int64)
    total = 0.0
    for r in np.geomspace(1e5, 1e10, 400):
        W = np.array([[r], [0.0]])
        renormalize_block(W, Renorm.NORMALIZE, acc_m, acc_e, np.empty(0))
        total += np.log(r)
    assert np.isclose(np.log(acc_m[0]) + acc_e[0] * np.log(2), total, rtol=1e-14)


def _vectors(scheme):
    """The deviation vectors the layout tests carry: the default scheme's
    four (its kernel of k = 4 is the one test_sbab2c_equals_the_papers_explicit_maps
    and every spectrum of Hénon–Heiles run), one for the other schemes (a
    kernel of k = 1 compiles in about half the time of k = 4, the tangent
    products being unrolled per vector; carrying vectors or not is the law,
    not how many)."""
    return np.eye(4) if scheme == "SBAB2C" else np.eye(4)[:, :1]


# One scheme of each layout (kick or drift first, with or without corrector).
# The Lyapunov spectrum (its accumulation) on the default scheme, whose
# kernel is the four vectors' above.
@pytest.mark.parametrize("scheme", ["SBAB2C", "SABA2C", "SABA2", "SBAB3"])
def test_orbit_without_vectors_is_bitwise_the_orbit_with_vectors(c1, scheme):
    model, x0 = c1
    plain = varint.integrate(model, x0, 50.0, tau=0.05, scheme=scheme)
    carried = varint.integrate(model, x0, 50.0, tau=0.05, scheme=scheme,
                               deviations=_vectors(scheme))
    assert np.array_equal(plain.state, carried.state)
    if scheme == "SBAB2C":
        lce = varint.lyapunov_spectrum(model, x0, 50.0, tau=0.05, scheme=scheme, t_out=1)
        assert np.array_equal(plain.state, lce.state)


def test_no_tangent_work_without_vectors(c1):
    model, x0 = c1
    counts = varint.integrate(model, x0, 10.0, scheme="SBAB2").provenance.counts
    assert counts["hessian"] == counts["third"] == counts["tangent_products"] == 0
    # With a corrector the orbit needs D²V for ∇C = 2 D²V M⁻¹∇V, but still no
    # third derivatives and no products with deviation vectors.
    counts = varint.integrate(model, x0, 10.0, scheme="SBAB2C").provenance.counts
    assert counts["third"] == counts["tangent_products"] == 0


@pytest.mark.parametrize("scheme", ["SBAB2C", "SABA2C", "SABA2", "SBAB3", "FR4"])
def test_force_evaluations_per_step_are_counted(c1, scheme):
    model, x0 = c1
    s = varint.get_scheme(scheme)
    prop = make_propagator("tm", model, 0.05, "qr", scheme=scheme)
    # The kernels of the test above (the count is the orbit's).
    state = RunState.start(x0[None], _vectors(scheme)[None].copy())
    prop.advance(state, 1000)
    # One extra evaluation at most: the very first kick of a run has no reuse.
    assert 1000 * s.force_evaluations <= state.counts["gradient"] <= 1000 * s.force_evaluations + 1
    assert state.counts["steps"] == 1000


@pytest.mark.parametrize("renorm", ["qr", "normalize", "none"])
def test_advance_is_chunk_invariant(c1, renorm):
    model, x0 = c1
    prop = make_propagator("tm", model, 0.05, renorm, scheme="SBAB2C")
    a = RunState.start(x0[None], np.eye(4)[None])
    b = RunState.start(x0[None], np.eye(4)[None])
    prop.advance(a, 777)
    for n in (1, 5, 100, 671):
        prop.advance(b, n)
    for field in ("x", "W", "acc_m", "acc_e"):
        assert np.array_equal(getattr(a, field), getattr(b, field)), field


def test_batch_equals_single_orbits_bitwise_serial_and_parallel():
    model = varint.models.HenonHeiles()
    X = np.array([varint.paper_orbit(n)[1] for n in ("R1", "C1", "C2")])
    many = varint.lyapunov_spectrum(model, X, 200.0, seed=3)
    serial = varint.lyapunov_spectrum(model, X, 200.0, seed=3, parallel=False)
    assert np.array_equal(many.exponents, serial.exponents)
    # Orbit m of a batch draws its vectors from default_rng([seed, m]).
    W0 = varint.state.initial_deviations(4, 4, 3, 3)
    for m in range(3):
        one = varint.lyapunov_spectrum(model, X[m], 200.0, deviations=W0[m])
        assert np.array_equal(one.exponents, many.exponents[m])


def test_specialised_and_run_time_sized_kernels_agree_bitwise(c1):
    model, x0 = c1
    from varint.schemes import stage_arrays

    kinds, h, hc = stage_arrays(varint.get_scheme("SABA3C"), 0.05)
    results = []
    kernels = K.model_kernels(model)
    # Two vectors: sizes fixed at compile time against read at run time is
    # the law; two vectors exercise the k-loop and its QR (k = 4 would add
    # compile time, the products being per vector, for nothing more).
    for kernel in (K.tm_batch(2, 2, 1, False, kernels), K.tm_batch(-1, -1, -1, False, kernels)):
        X, W = x0[None].copy(), np.eye(4)[None, :, :2].copy()
        acc_m, acc_e = np.ones((1, 2)), np.zeros((1, 2), dtype=np.int64)
        kernel(K.TMOrbit(X, W, acc_m, acc_e, np.empty((1, 0, 0)), np.zeros((1, 4), dtype=np.int64),
                         np.empty((1, 0)), np.empty((1, 0, 0))),
               K.TMSetup(kinds, h, hc, model.inverse_mass, model.params, model.bandwidth,
                         np.empty(0)),
               Call(500, 0, 0.05, int(Renorm.QR), np.inf), np.zeros(1, dtype=np.int64),
               np.zeros(1, dtype=np.int64))
        results.append((X, W, acc_m))
    for a, b in zip(*results, strict=True):
        assert np.array_equal(a, b)

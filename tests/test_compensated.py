"""Compensated summation in the generated TM stepper (``compensated=True``;
Kahan 1965, Hairer, McLachlan & Razakarivony 2008): the same map as the
plain stepper, a lower round-off that grows more slowly, and a state that
resumes bitwise."""

import numpy as np
import pytest
import sympy as sp

import varint
from varint.methods.tm import TangentMapPropagator
from varint.models import HenonHeiles
from varint.protocol import Renorm, Status
from varint.state import RunState
from tests.helpers import assert_bitwise_equal
from tests.test_checkpoint import crash_then_resume

HH = HenonHeiles()


def _start(x0, W0):
    return RunState.start(np.array(x0, dtype=float).copy(), np.array(W0, dtype=float).copy())


def _relative(a, b):
    return float(np.linalg.norm(np.ravel(a) - np.ravel(b)) / np.linalg.norm(b))


def _r1():
    model, x0 = varint.paper_orbit("R1")
    w0 = np.random.default_rng(0).standard_normal(model.dim)
    return model, np.asarray(x0, dtype=float), w0 / np.linalg.norm(w0)


def _energy(x):
    return 0.5 * (x[:, 2]**2 + x[:, 3]**2) + 0.5 * (x[:, 0]**2 + x[:, 1]**2) \
        + x[:, 0]**2 * x[:, 1] - x[:, 1]**3 / 3


def test_compensated_energy_round_off():
    """Hairer, McLachlan & Razakarivony's (2008) measure: the energy error
    of a long run of a high-order scheme at a step where its truncation
    error is negligible (SRKN14a, τ = 1/32) is round-off. Over 16
    Hénon–Heiles orbits at E = 0.1, after 2^10 and 2^14 steps, the RMS
    energy error of compensated runs is below 10 ulps of E (1.4e-16) and a
    twentieth of the plain one (measured on 32 orbits: 1.7e-17 against
    7.4e-16 and 2.2e-17 against 2.6e-15), and from 2^10 to 2^14 steps it
    grows no faster than a random walk's (4x; measured on these 16 orbits:
    1.9x, plain 4.5x). So at the step level (``compensated="step"``: the
    orbit's displacement over each step added compensated; measured 2.1e-17
    and 4.3e-17, 2.1x)."""
    m = 16
    y = np.linspace(-0.2, 0.3, m)
    x0 = np.column_stack([np.zeros(m), y, np.sqrt(2 * (0.1 - 0.5 * y**2 + y**3 / 3)),
                          np.zeros(m)])
    e0 = _energy(x0)
    rms = {}
    for comp in (False, True, "step"):
        state = _start(x0, np.zeros((m, 4, 0)))
        p = TangentMapPropagator(HH, 1 / 32, Renorm.NONE, scheme="SRKN14a", parallel=False,
                                 compensated=comp)
        rms[comp] = []
        for n in (2**10, 2**14 - 2**10):
            p.advance(state, n)
            rms[comp].append(float(np.sqrt(np.mean((_energy(state.x) - e0) ** 2))))
    for level in (True, "step"):
        for plain, comp in zip(rms[False], rms[level], strict=True):
            assert comp < 1.4e-16 and comp < plain / 20, (level, rms)
        assert rms[level][1] < 4 * rms[level][0], (level, rms)


def test_compensated_error_against_the_reference():
    """R1 with one tangent vector to t = 400, SRKN14a at τ = 1/32 (its
    truncation error is below round-off): against the extended-precision
    Taylor reference the compensated error is below 1e-13 and a tenth of
    the plain one (measured: 5.2e-14 and 1.8e-12)."""
    from varint.cache import reference

    model, x0, w0 = _r1()
    ref = reference(model, x0, 400.0, tau=0.1, deviations=w0[:, None])
    err = {}
    for comp in (False, True):
        r = varint.integrate(model, x0, 400.0, tau=1 / 32, scheme="SRKN14a",
                             deviations=w0[:, None], compensated=comp)
        err[comp] = max(_relative(r.state, ref.state),
                        _relative(r.deviations, ref.deviations[:, 0]))
    assert err[True] < 1e-13 and err[True] < err[False] / 10, err


def test_compensated_is_the_same_map():
    """Compensation changes only round-off: 400 steps of chaotic
    Hénon–Heiles orbits with a corrector scheme and QR renormalisation agree
    with the plain stepper to < 1e-11 relative (round-off amplified by the
    orbits' divergence; measured 1.6e-14, as with two vectors). Four
    vectors and the default scheme (SBAB2C): the two steppers the spectra
    of test_compensated_run_resumes_from_its_checkpoint_bitwise and
    test_compensated_through_an_indicator run, compiled once for the file."""
    x0 = np.array([[0.0, -0.25, 0.42, 0.0], [0.0, 0.1, 0.45, 0.02]])
    W0 = np.random.default_rng(3).standard_normal((2, 4, 4))
    out = {}
    for comp in (False, True):
        state = _start(x0, W0)
        TangentMapPropagator(HH, 0.05, Renorm.QR, scheme="SBAB2C", parallel=False,
                             compensated=comp).advance(state, 400)
        assert (state.status == Status.OK).all()
        out[comp] = state
    assert np.abs(out[True].x - out[False].x).max() < 1e-11
    assert np.abs(out[True].W - out[False].W).max() < 1e-11
    assert not np.array_equal(out[True].x, out[False].x)   # compensation did act


def test_compensated_resumes_bitwise_and_its_compensations_are_state():
    """1000 steps in one call and as 400 + 600 (sparse QR renormalisation,
    four vectors): the same bits, the compensations included; restarting the
    second chunk from zero compensations instead gives other bits, so the
    compensations must be (and are) carried in the state. The stepper of
    test_compensated_is_the_same_map (SBAB2C, four vectors, QR): one kernel
    for both."""
    x0 = np.array([[0.0, -0.25, 0.42, 0.0], [0.0, 0.1, 0.45, 0.02]])
    W0 = np.random.default_rng(4).standard_normal((2, 4, 4))

    def run(chunks, drop=False):
        p = TangentMapPropagator(HH, 0.05, Renorm.QR, scheme="SBAB2C", parallel=False,
                                 compensated=True)
        state = _start(x0, W0)
        for i, n in enumerate(chunks):
            if drop and i:
                state.extra["tm_compensation"][:] = 0.0
            p.advance(state, n)
        return state

    one, two, dropped = run([1000]), run([400, 600]), run([400, 600], drop=True)
    assert one.extra["tm_compensation"].shape == (2, 4, 5)   # the orbit's and each vector's
    assert np.abs(one.extra["tm_compensation"]).max() > 0.0
    for name in ("x", "W", "acc_m", "acc_e"):
        assert np.array_equal(getattr(one, name), getattr(two, name)), name
    for key in one.extra:
        assert np.array_equal(one.extra[key], two.extra[key]), key
    assert not np.array_equal(one.x, dropped.x)


def test_compensated_run_resumes_from_its_checkpoint_bitwise(c1, tmp_path, monkeypatch):
    """A compensated spectrum stopped after two chunks and resumed from its
    checkpoint is bitwise the run that never stopped: the compensations
    travel in the checkpoint with the rest of the state."""
    def run(**kw):
        return varint.lyapunov_spectrum(*c1, 100.0, tau=0.05, compensated=True, **kw)

    reference = run()
    resumed, step = crash_then_resume(monkeypatch, tmp_path / "c.ckpt", run)
    assert 0 < step < 2000
    assert_bitwise_equal(resumed, reference)


def test_the_automatic_step_pilots_compensated_runs_compensated():
    """Without τ, a compensated run's pilot is compensated too: with
    energy_tol = 1e-13 (pilot tolerance 1e-15) on R1 to t = 100 SRKN14a's
    plain pilots stay at the plain round-off (≥ 6e-15 at every step tried)
    and the run falls back with a warning, while the compensated pilots
    meet it (measured 3e-16 to 7e-16) and choose a step."""
    from varint.accuracy import AccuracyWarning

    model, x0 = varint.paper_orbit("R1")
    with pytest.warns(AccuracyWarning, match="no step of SRKN14a"):
        plain = varint.integrate(model, x0, 100.0, scheme="SRKN14a", energy_tol=1e-13)
    comp = varint.integrate(model, x0, 100.0, scheme="SRKN14a", energy_tol=1e-13,
                            compensated=True)
    assert plain.provenance.tau_choice["rule"] == "fallback"
    assert comp.provenance.tau_choice["rule"] == "pilot"
    assert max(e for _, e in comp.provenance.tau_choice["tried"]) > 1e-15   # it searched
    assert np.max(np.abs(comp.energy_error)) < 1e-13


def test_compensated_through_an_indicator():
    """The option reaches the TM method through an indicator's call: the
    spectrum of C2 with compensation is the plain one to 1e-12 and sums to
    zero (the tangent map preserves volume)."""
    model, x0 = varint.paper_orbit("C2")
    plain = np.asarray(varint.lyapunov_spectrum(model, x0, t_end=100.0, tau=0.05).exponents)
    comp = varint.lyapunov_spectrum(model, x0, t_end=100.0, tau=0.05, compensated=True)
    x = np.asarray(comp.exponents)
    assert np.abs(x - plain).max() < 1e-12 and abs(x[-1].sum()) < 1e-12
    assert comp.provenance.method_options["compensated"] is True


@pytest.mark.parametrize("options, match", [
    ({"compensated": "yes"}, "compensated must be True, False, 'orbit' or 'step', got 'yes'"),
    ({"compensated": True, "backend": "cuda"}, "compensated=True runs on the CPU only"),
    ({"compensated": "orbit", "backend": "cuda"}, "compensated='orbit' runs on the CPU only"),
    ({"compensated": "vectors"}, "compensated must be True, False, 'orbit' or 'step', got 'vectors'"),
])
def test_compensated_bad_options(options, match):
    with pytest.raises(ValueError, match=match):
        TangentMapPropagator(HH, 0.05, Renorm.QR, **options)


def test_compensated_needs_a_generated_stepper():
    """FPU n = 8 with 16 vectors has no generated stepper: refused in one
    line before any step, not run plain."""
    model, x0 = varint.paper_orbit("R3")
    state = _start(np.asarray(x0)[None], np.eye(model.dim)[None])
    p = TangentMapPropagator(model, 0.05, Renorm.QR, compensated=True)
    with pytest.raises(ValueError, match="compensated=True runs generated steppers"):
        p.advance(state, 10)
    assert state.step == 0


def test_a_bad_compensated_is_refused_before_the_pilot():
    """Without τ the pilot is given the option as the run was: a bad value
    is refused in one line when the first pilot's propagator is built,
    not taken for True by the pilot and refused only after it."""
    model, x0 = varint.paper_orbit("R1")
    with pytest.raises(ValueError, match="compensated must be True, False, 'orbit' or 'step', got 'yes'"):
        varint.integrate(model, x0, 100.0, compensated="yes")


# -- compensated="orbit": the orbit's drifts and kicks, plain vectors ------------------

def _c2_compensations(scheme, tau):
    """C2 with one tangent vector to t = 400 with each ``compensated``:
    the runs and their errors against the extended-precision Taylor
    reference."""
    from varint.cache import reference

    model, x0 = varint.paper_orbit("C2")
    w0 = np.random.default_rng(0).standard_normal(model.dim)
    w0 /= np.linalg.norm(w0)
    ref = reference(model, x0, 400.0, tau=0.1, deviations=w0[:, None])
    err, runs = {}, {}
    for comp in (False, "orbit", True):
        r = runs[comp] = varint.integrate(model, x0, 400.0, tau=tau, scheme=scheme,
                                          deviations=w0[:, None], compensated=comp)
        err[comp] = max(_relative(r.state, ref.state),
                        _relative(r.deviations, ref.deviations[:, 0]))
    assert np.array_equal(runs["orbit"].state, runs[True].state)
    assert not np.array_equal(runs["orbit"].deviations, runs[True].deviations)
    assert runs["orbit"].provenance.method_options["compensated"] == "orbit"
    return err


def test_orbit_compensation_is_full_compensation_s_orbit():
    """C2 (chaotic: the orbit's round-off, amplified, dominates the
    vector's) with one tangent vector to t = 400, SRKN14a at τ = 1/32 (its
    truncation error is below round-off, as in
    test_compensated_error_against_the_reference, whose plain and
    compensated Hénon–Heiles kernels it reuses): with
    ``compensated="orbit"`` the orbit is bitwise full compensation's (the
    orbit never reads the vectors) and the vector is not (its updates are
    plain); against the extended-precision Taylor reference the error is a
    tenth of plain summation's (measured: 2.7e-13 against 6.2e-12; full
    compensation 4.0e-14). Within a factor 3 of full compensation's it is
    with s35odr10 at τ = 0.1 (fewer steps, so less plain round-off in the
    vector): test_orbit_compensation_is_within_3_of_full_s35odr10, slow."""
    err = _c2_compensations("SRKN14a", 1 / 32)
    assert err["orbit"] < err[False] / 10, err


@pytest.mark.slow
def test_orbit_compensation_is_within_3_of_full_s35odr10():
    """As test_orbit_compensation_is_full_compensation_s_orbit with
    s35odr10 at τ = 0.1 (its truncation error is below round-off): the
    vector's error stays within a factor 3 of full compensation's and a
    tenth of plain summation's (measured: 1.7e-13 with True and 2.9e-12
    plain). Slow: its three 35-stage kernels, which no other test runs,
    take 80 CPU s to compile cold (154 s in the suite's cold run). With
    SRKN14a at τ = 1/32 the ratio to full compensation is 4–8 (t = 400 to
    1600: more steps, more plain round-off in the vector), so the quick
    test checks the tenth of plain summation only."""
    err = _c2_compensations("s35odr10", 0.1)
    assert err["orbit"] < 3 * err[True] and err["orbit"] < err[False] / 10, err


@pytest.mark.parametrize("level", ["orbit", "step"])
def test_partial_compensation_resumes_bitwise_and_its_compensations_are_state(level):
    """1000 steps in one call and as 400 + 600 (sparse QR renormalisation
    of one vector) give the same bits; only the orbit's compensations are
    non-zero (the vector's stay zero; with "step", those of each step's
    addition), and they are state: restarting the second chunk from zero
    compensations gives other bits. SRKN14a with one vector: the steppers
    of test_orbit_compensation_is_full_compensation_s_orbit and
    test_step_compensation_against_the_reference (resuming does not depend
    on the scheme or on the number of vectors)."""
    x0 = np.array([[0.0, -0.25, 0.42, 0.0], [0.0, 0.1, 0.45, 0.02]])
    W0 = np.random.default_rng(4).standard_normal((2, 4, 1))

    def run(chunks, drop=False):
        p = TangentMapPropagator(HH, 0.05, Renorm.QR, scheme="SRKN14a", parallel=False,
                                 compensated=level)
        state = _start(x0, W0)
        for i, n in enumerate(chunks):
            if drop and i:
                state.extra["tm_compensation"][:] = 0.0
            p.advance(state, n)
        assert (state.status == Status.OK).all()
        return state

    one, two, dropped = run([1000]), run([400, 600]), run([400, 600], drop=True)
    c = one.extra["tm_compensation"]
    assert np.abs(c[:, :, 0]).max() > 0.0 and not c[:, :, 1:].any()
    for name in ("x", "W", "acc_m", "acc_e"):
        assert np.array_equal(getattr(one, name), getattr(two, name)), name
    for key in one.extra:
        assert np.array_equal(one.extra[key], two.extra[key]), key
    assert not np.array_equal(one.x, dropped.x)


# -- compensated="step": the orbit's displacement over each step -----------------------

def test_step_compensation_against_the_reference():
    """R1 (regular) and C2 (chaotic) with one tangent vector to t = 400,
    SRKN14a at τ = 1/32 (its truncation error is below round-off, as in
    test_compensated_error_against_the_reference, whose plain kernel it
    reuses): with ``compensated="step"`` (the stages add plainly to the
    orbit's displacement since the step began, the displacement is added
    to the state by Kahan's summation once per step, the vectors plain)
    the error against the extended-precision Taylor reference is a tenth
    of plain summation's (measured: R1 3.6e-14 against 1.8e-12, C2 3.1e-13
    against 6.2e-12; "orbit" 7.2e-13 and 2.7e-13), and below 1e-13 on R1;
    the orbit differs from plain summation's and from "orbit"'s (other
    roundings), and the provenance names the level."""
    from varint.cache import reference

    for name, bound in (("R1", 1e-13), ("C2", 1e-12)):
        model, x0 = varint.paper_orbit(name)
        w0 = np.random.default_rng(0).standard_normal(model.dim)
        w0 /= np.linalg.norm(w0)
        ref = reference(model, x0, 400.0, tau=0.1, deviations=w0[:, None])
        err, runs = {}, {}
        for comp in (False, "step"):
            r = runs[comp] = varint.integrate(model, x0, 400.0, tau=1 / 32, scheme="SRKN14a",
                                              deviations=w0[:, None], compensated=comp)
            err[comp] = max(_relative(r.state, ref.state),
                            _relative(r.deviations, ref.deviations[:, 0]))
        assert err["step"] < bound and err["step"] < err[False] / 10, (name, err)
        assert not np.array_equal(runs["step"].state, runs[False].state)
        assert runs["step"].provenance.method_options["compensated"] == "step"


def test_step_compensation_fails_mid_step_where_the_plain_step_fails():
    # V = −√x has no force for x < 0: the orbit heads there and a kick's
    # forces turn non-finite in the middle of a step. With
    # compensated="step" a kick's p is kept as the step's start plus its
    # displacement and written back only on a failure's way out, so the
    # run must end as the plain one does (the same status, step and force
    # evaluations, mid-step) and leave the plain run's state, p included,
    # within round-off (a p left at the step's start would be off by the
    # step's kicks).
    x, y = sp.symbols("x y")
    model = varint.models.from_potential(-sp.sqrt(x) + y**2 / 2, [x, y])
    x0 = np.array([0.5, 0.0, -2.0, 0.1])
    runs = {}
    for level in (False, "step"):
        with pytest.warns(RuntimeWarning, match="failed"):
            runs[level] = varint.integrate(model, x0, 5.0, tau=0.01, scheme="SRKN14a",
                                           compensated=level, errors="flag")
    plain, step = runs[False], runs["step"]
    assert int(plain.status) == int(step.status) != int(Status.OK)
    assert plain.provenance.counts == step.provenance.counts
    assert plain.provenance.counts["gradient"] % 14 != 0      # it failed mid-step
    assert _relative(step.state, plain.state) < 1e-13

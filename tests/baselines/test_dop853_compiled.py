"""The compiled DOP853 engine is SciPy's DOP853 solver: replayed from the
states SciPy's own solver reached on the paper's orbits, every step is
accepted or rejected alike after as many trials, ends at the same time, and
lands on the same state and proposes the same next step to round-off; every
interval costs the same evaluations, steps and rejections.

Tolerances. The kernel repeats SciPy's arithmetic operation by operation;
what is left free is the order in which BLAS adds the ≤ 13 terms of each
stage combination, solution update and error estimate (NumPy's OpenBLAS
for SciPy's solver, SciPy's OpenBLAS through numba for the kernel). Two
orders of a sum of n terms differ by at most 2γ_n Σ|terms|,
γ_n = nu/(1 − nu), u = 2⁻⁵³ (Higham, *Accuracy and Stability of Numerical
Algorithms*, 2nd ed., Sect. 4.2).

* States: through twelve stages with |a_sj| up to 43 that worst case
  compounds into a useless bound, so the tolerance is measured instead: a
  kernel adding in plain loops (another order) differs from SciPy by at
  most 3e-15 relative per step and 2e-15 per interval on these runs.
  :data:`RTOL_STEP` = 1e-13 leaves a factor 30; it is still far below the
  local error the method makes and controls (δ per step).
* Step sizes: a step's first trial has the size given, exactly the same;
  a later trial has the size proposed by the rejected one before it. A
  proposal is h 0.9 err^(−1/8) with err ∝ ‖e₅‖²/√(‖e₅‖² + 0.01 ‖e₃‖²), so
  two proposals from the same trial differ by (3/8) of the relative
  difference of the error estimates e = Σ E_j k_j / sc: at most 2γ₁₃·κ
  from their own sums, κ their condition number, and up to three times as
  much again, by measurement, from the stages k_j, whose sums were ordered
  differently too — (3/8)·8γ₁₃·κ in all (:func:`proposal_tolerance`).
  After the short truncated last step of an interval κ reaches 1e16: that
  estimate is rounding noise, in SciPy as much as here. The loop kernel
  uses at most 42 % of this tolerance.
* End states of an interval: the sizes of its steps after the first trial
  may differ as above, which moves the local errors (≈ h^{p+1}, p = 8) by
  (p + 1) times their relative difference; each is at most the error
  allowed, rtol·|y| + atol (:func:`interval_tolerance`).

Where numba's BLAS adds like NumPy's, as on the machine measured, the
engines agree bit for bit, which
``test_engines_are_bitwise_identical_and_share_their_continuation_state``
checks.
"""

import copy
from dataclasses import dataclass

import numpy as np
import pytest
from numba import njit

import varint.baselines.dop853 as dop853_module
import varint
from varint.baselines import dop853_kernel as DK
from varint.baselines.rhs import tangent_rhs
from varint.protocol import Status
from varint.methods import make_propagator
from varint.models import HenonHeiles
from varint.state import RunState, initial_deviations

#: Relative agreement required per step and per interval (module notes).
RTOL_STEP = 1e-13
#: Steps replayed per configuration: SciPy's first 10⁴ in the slow run, its
#: first 2000 in the default suite (the same configurations and checks, a
#: fifth of the time, which is the Python replay's, not compiling).
N_STEPS = 10_000
N_STEPS_QUICK = 2_000
NFEV, STEPS, REJECTED = (DK.COUNTS.index(c) for c in
                         ("rhs_evaluations", "dop853_steps", "dop853_rejected"))


@dataclass
class Step:
    """One call of SciPy's ``DOP853.step``: the state before and after, and
    the stages and error scale of each trial (the last one accepted, unless
    the step failed)."""
    t: float
    y: np.ndarray
    f: np.ndarray
    h_abs: float
    t_new: float
    y_new: np.ndarray
    h_new: float
    nfev: int
    accepted: bool
    trials: list


class RecordingDOP853(dop853_module.DOP853):
    """SciPy's solver, logging every interval it integrates, every step and
    every trial step."""

    intervals = []

    def __init__(self, fun, t0, y0, t_bound, first_step=None, **options):
        super().__init__(fun, t0, y0, t_bound, first_step=first_step, **options)
        self.y0 = np.array(y0)
        self.first_step = np.nan if first_step is None else first_step
        self.init_nfev = self.nfev
        self.steps = []
        self.trials = []
        self.intervals.append(self)

    def _estimate_error_norm(self, K, h, scale):
        self.trials.append((K.copy(), scale.copy()))
        return super()._estimate_error_norm(K, h, scale)

    def step(self):
        t, y, f, h_abs, nfev = self.t, self.y.copy(), self.f.copy(), self.h_abs, self.nfev
        message = super().step()
        self.steps.append(Step(t, y, f, h_abs, self.t, self.y.copy(), self.h_abs,
                               self.nfev - nfev, self.status != "failed", self.trials))
        self.trials = []
        return message


def start(orbit, k=4):
    model, x0 = varint.paper_orbit(orbit)
    return model, RunState.start(x0[None], initial_deviations(4, k, 1, seed=0))


def record(monkeypatch, run, n_steps):
    """The intervals SciPy's solver integrates while ``run()`` is repeated
    (with a propagator of ``engine="scipy"``) until ``n_steps`` steps were
    taken."""
    monkeypatch.setattr(RecordingDOP853, "intervals", [])
    monkeypatch.setattr(dop853_module, "DOP853", RecordingDOP853)
    while sum(len(i.steps) for i in RecordingDOP853.intervals) < n_steps:
        run()
    return RecordingDOP853.intervals


def rel(a, b):
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


def proposal_tolerance(Ks, scale):
    """Largest relative difference of a proposed step size that two
    summation orders make (module notes): (3/8)·8γ₁₃·κ + 8u, κ the larger
    condition number of the two error estimates (2-norm)."""
    u = np.finfo(float).eps / 2
    kappa = 0.0
    for E in (DK.E5, DK.E3):
        e = np.linalg.norm((E @ Ks) / scale)
        kappa = max(kappa, np.linalg.norm((np.abs(E) @ np.abs(Ks)) / scale) / e)
    gamma = 13 * u / (1 - 13 * u)
    return 3 / 8 * 8 * gamma * kappa + 8 * u


def interval_tolerance(solver, rtol, atol):
    """Largest relative difference of the end states of an interval
    (module notes): RTOL_STEP, plus (p + 1)·(rtol + atol/‖y‖∞) times the
    possible relative differences of the sizes of its trials after the
    first (those proposed by the trials before them)."""
    trials = [trial for s in solver.steps for trial in s.trials][:-1]
    sizes = sum(proposal_tolerance(*trial) for trial in trials)
    return RTOL_STEP + 9 * (rtol + atol / np.abs(solver.y).max()) * sizes


def replay_steps(rhs, intervals, tau, rtol, atol, n_steps=None):
    """Every recorded step (the first ``n_steps``) redone by
    the engine's ``try_step`` from SciPy's state: the same decisions after as many
    trials, and the largest relative differences of the step sizes, the new
    states and the proposed steps (also as a fraction of their tolerance)."""
    worst = {"size": 0.0, "state": 0.0, "h_next": 0.0, "h_next_of_tolerance": 0.0, "steps": 0}
    for solver in intervals:
        size = solver.y0.size
        Ks, y_new, work = np.empty((DK.N_STAGES + 1, size)), np.empty(size), np.empty((5, size))
        for s in solver.steps:
            counts = np.zeros(len(DK.COUNTS), dtype=np.int64)
            Ks[0] = s.f
            ok, t_new, h_new = DK.dop853_engine(rhs).try_step(
                s.t, s.y, s.h_abs, tau, rtol, atol, DK.POWERS, Ks, y_new, work, counts)
            assert ok == s.accepted
            assert counts[NFEV] == s.nfev
            assert counts[REJECTED] == len(s.trials) - s.accepted
            worst["steps"] += 1
            if ok:
                # The first trial has the step size given; a later one, the
                # size proposed by a rejected trial.
                h = s.t_new - s.t
                size_tol = sum(proposal_tolerance(*trial) for trial in s.trials[:-1])
                dh = abs((t_new - s.t) - h) / h
                assert dh <= size_tol, (dh, size_tol)
                worst["size"] = max(worst["size"], dh)
                dy = rel(y_new, s.y_new)
                assert dy <= RTOL_STEP + dh * h * np.abs(Ks).max() / np.abs(s.y_new).max()
                worst["state"] = max(worst["state"], dy)
                dh_next = abs(h_new - s.h_new) / s.h_new
                worst["h_next"] = max(worst["h_next"], dh_next)
                worst["h_next_of_tolerance"] = max(
                    worst["h_next_of_tolerance"],
                    dh_next / (size_tol + proposal_tolerance(*s.trials[-1])))
            else:
                assert t_new == s.t_new
            if worst["steps"] == n_steps:
                return worst
    return worst


def replay_intervals(rhs, intervals, tau, rtol, atol):
    """Every recorded interval redone whole by the engine's ``integrate_interval``
    from SciPy's start state and first step (NaN: SciPy chose it): the same
    status and counts, and the largest relative difference of the end state
    (the last accepted one if it failed), also as a fraction of
    :func:`interval_tolerance`. The step proposed at the end is checked
    step by step instead (:func:`replay_steps`): from a state that differs
    by round-off it may legitimately differ by much more (module notes)."""
    worst = {"state": 0.0, "state_of_tolerance": 0.0}
    for solver in intervals:
        size = solver.y0.size
        counts = np.zeros(len(DK.COUNTS), dtype=np.int64)
        y = solver.y0.copy()
        status, _ = DK.dop853_engine(rhs).integrate_interval(
            y, solver.first_step, tau, rtol, atol, DK.POWERS,
            np.empty((DK.N_STAGES + 1, size)), np.empty(size), np.empty((5, size)), counts)
        assert status == {"finished": Status.OK, "failed": Status.INTEGRATOR_FAILED}[solver.status]
        assert counts[NFEV] == solver.nfev
        assert counts[STEPS] == len(solver.steps)
        trials = (solver.nfev - solver.init_nfev) // DK.N_STAGES
        assert counts[REJECTED] == trials - sum(s.accepted for s in solver.steps)
        dy = rel(y, solver.y)
        worst["state"] = max(worst["state"], dy)
        worst["state_of_tolerance"] = max(worst["state_of_tolerance"],
                                          dy / interval_tolerance(solver, rtol, atol))
    return worst


@pytest.mark.parametrize("n_steps", [N_STEPS_QUICK,
                                     pytest.param(N_STEPS, marks=pytest.mark.slow)])
@pytest.mark.parametrize("delta", [1e-5, 1e-10])
@pytest.mark.parametrize("tau", [0.05, 0.5])
@pytest.mark.parametrize("orbit", ["R1", "C1"])
def test_compiled_steps_are_scipys_steps(orbit, tau, delta, n_steps, monkeypatch):
    """Over SciPy's first 2000 steps (10⁴ in the slow run) on R1 and C1
    (full spectrum): each step replayed from SciPy's state makes the same
    decisions and agrees to round-off; each interval replayed whole costs
    the same and ends at the same state to round-off (tolerances: module
    notes)."""
    model, state = start(orbit)
    prop = make_propagator("dop853", model, tau, "qr", delta=delta, engine="scipy")
    intervals = record(monkeypatch, lambda: prop.advance(state, 100), n_steps)
    rhs, _ = tangent_rhs(model)
    by_step = replay_steps(rhs, intervals, tau, delta, delta, n_steps)
    assert by_step["steps"] == n_steps
    assert by_step["h_next_of_tolerance"] <= 1, by_step
    by_interval = replay_intervals(rhs, intervals, tau, delta, delta)
    assert by_interval["state_of_tolerance"] <= 1, by_interval


def test_initial_steps_rejections_and_failures_are_scipys(monkeypatch):
    """The rarer paths. SciPy's initial-step selection (no first step given)
    and rejected trials: C1 with τ = 7, rtol = 1e-3. Giving up when the step
    size collapses: an orbit above the escape energy reaching infinity."""
    model, state = start("C1")
    prop = make_propagator("dop853", model, 7.0, "qr", rtol=1e-3, atol=1e-9, engine="scipy")

    def fresh_interval():
        state.extra.pop("dop853_h", None)  # forget the step proposed last
        prop.advance(state, 1)

    intervals = record(monkeypatch, fresh_interval, 500)
    rhs, _ = tangent_rhs(model)
    assert sum(len(s.trials) - 1 for i in intervals for s in i.steps) > 20
    assert all(np.isnan(i.first_step) for i in intervals)
    by_step = replay_steps(rhs, intervals, 7.0, 1e-3, 1e-9)
    by_interval = replay_intervals(rhs, intervals, 7.0, 1e-3, 1e-9)
    assert by_step["h_next_of_tolerance"] <= 1, by_step
    assert by_interval["state_of_tolerance"] <= 1, by_interval

    x0 = varint.solve_momentum(HenonHeiles(), [0.0, 0.0], [0.0, 0.2], 0.25)
    state = RunState.start(x0[None], initial_deviations(4, 2, 1, seed=0))
    prop = make_propagator("dop853", HenonHeiles(), 0.05, "qr", engine="scipy")
    intervals = record(monkeypatch, lambda: prop.advance(state, 1000), 1)
    assert state.status[0] == Status.INTEGRATOR_FAILED and intervals[-1].status == "failed"
    rhs, _ = tangent_rhs(HenonHeiles())
    by_step = replay_steps(rhs, intervals, 0.05, 1e-5, 1e-5)
    by_interval = replay_intervals(rhs, intervals, 0.05, 1e-5, 1e-5)
    assert by_step["h_next_of_tolerance"] <= 1, by_step
    assert by_interval["state_of_tolerance"] <= 1, by_interval


@pytest.mark.parametrize("orbit", ["R1", "C1"])
def test_engines_count_the_same_work(orbit):
    """Whole runs through the propagator: the same counts, states equal to
    round-off (200 intervals: too short for C1's chaos to amplify it)."""
    model, _ = start(orbit)
    for tau, delta in [(0.05, 1e-5), (0.5, 1e-10)]:
        runs = {}
        for engine in dop853_module.ENGINES:
            _, state = start(orbit)
            make_propagator("dop853", model, tau, "qr", delta=delta, engine=engine).advance(
                state, 200)
            runs[engine] = state
        a, b = runs["compiled"], runs["scipy"]
        assert a.counts == b.counts
        assert a.counts["dop853_steps"] >= 200 and a.counts["blocks"] == 200
        assert rel(a.x, b.x) <= 1e-11 and rel(a.W, b.W) <= 1e-11
        assert np.allclose(np.log(a.acc_m) + a.acc_e * np.log(2),
                           np.log(b.acc_m) + b.acc_e * np.log(2), rtol=0, atol=1e-11)


@njit
def _numba_dot(Kt, a, x):
    return np.dot(Kt, a), np.dot(x, x)


def blas_rounds_like_numpy():
    """Whether numba's BLAS (SciPy's) gives NumPy's bits for the products
    the kernel forms: a column-major matrix times a vector, and x·x."""
    rng = np.random.default_rng(1)
    for s in range(1, DK.N_STAGES + 2):
        Ks = rng.standard_normal((s, 20))
        a, x = rng.standard_normal(s), rng.standard_normal(20)
        mv, xx = _numba_dot(Ks.T, a, x)
        if not (np.array_equal(mv, np.dot(Ks.T, a)) and xx == x.dot(x)):
            return False
    return True


def test_engines_are_bitwise_identical_and_share_their_continuation_state(c1, r1):
    """Where numba's BLAS rounds like NumPy's the engines give the same bits
    — so a run may switch engine at any checkpoint: both keep only the next
    step size (``dop853_h``) between intervals."""
    if not blas_rounds_like_numpy():
        pytest.skip("numba's BLAS adds in another order than NumPy's on this machine")
    model = c1[0]
    X = np.stack([c1[1], r1[1]])

    def state():
        return RunState.start(X, initial_deviations(4, 3, 2, seed=0))

    whole = state()
    make_propagator("dop853", model, 0.5, "qr", delta=1e-10).advance(whole, 300)
    mixed = state()
    for n, engine in [(7, "scipy"), (130, "compiled"), (1, "scipy"), (162, "compiled")]:
        make_propagator("dop853", model, 0.5, "qr", delta=1e-10, engine=engine).advance(mixed, n)
        mixed = copy.deepcopy(mixed)
    for f in ("x", "W", "acc_m", "acc_e", "status", "fail_step"):
        assert np.array_equal(getattr(whole, f), getattr(mixed, f)), f
    assert np.array_equal(whole.extra["dop853_h"], mixed.extra["dop853_h"])
    assert whole.counts == mixed.counts


def test_engine_is_recorded_and_rtol_floored_like_scipy(r1):
    """The engine is part of the provenance; an rtol below SciPy's floor
    100 ε is raised to it, once, for both engines alike."""
    res = varint.lyapunov_spectrum(*r1, 1.0, method="dop853", n_exponents=2)
    assert res.provenance.method_options["engine"] == "compiled"
    for engine in dop853_module.ENGINES:
        with pytest.warns(RuntimeWarning, match="below DOP853's floor"):
            prop = make_propagator("dop853", r1[0], 0.05, "qr", delta=1e-16, engine=engine)
        assert prop.describe()["rtol"] == DK.RTOL_MIN and prop.describe()["atol"] == 1e-16
    with pytest.raises(ValueError, match="unknown engine 'fortran'; expected one of: compiled, "
                                         "scipy"):
        make_propagator("dop853", r1[0], 0.05, "qr", engine="fortran")

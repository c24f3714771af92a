"""What a logarithmic-Hamiltonian map (``chaos_map(..., time_transform="log")``)
gives besides its values: the final states, their energy errors and the
accuracy verdict, each against the same orbits run by
:meth:`LogHamiltonian.advance` output by output and measured by
:class:`varint.accuracy.Reference`, as every other map measures them."""

import math
import warnings

import numpy as np
import pytest
import sympy as sp

from varint import chaos_map
from varint.accuracy import AccuracyWarning, Reference
from varint.models import from_potential
from varint.models.cr3bp import CR3BP, SUN_JUPITER_MU
from varint.time_transform import LogHamiltonian

EPS = 1e-3   # the softening of the other tests' Plummer models: their LH kernels


@pytest.fixture(scope="module")
def plummer():
    x, y = sp.symbols("x y")
    return from_potential(-1 / sp.sqrt(x**2 + y**2 + sp.Float(EPS)**2), [x, y])


def _orbits(seed, m=6):
    """Bound eccentric orbits of the softened point mass (E < 0)."""
    rng = np.random.default_rng(seed)
    return np.column_stack([rng.uniform(0.5, 1.0, m), np.zeros(m), np.zeros(m),
                            rng.uniform(0.1, 0.6, m)])


def _by_outputs(lh, X, t_end, h, every):
    """The states at every output, by advance from output to output with
    the orbit's C and p_t (no vectors: they do not enter the orbit)."""
    states, x = [], X.copy()
    C, pt = lh.constants(X), -lh.energy(X)
    t = 0.0
    while t < t_end:
        stop = min(t + every, t_end)
        r = lh.advance(x, np.zeros((len(x), 4, 0)), stop, h, t0=t, C=C, pt=pt)
        assert (r.status == 0).all()
        x, t = r.x, stop
        states.append(x)
    return states


def test_map_states_and_energy_errors_are_those_of_the_orbits(plummer):
    """The map's final states are, bit for bit, the orbits advanced output
    by output; its energy errors are Reference's at those states, and the
    verdict's largest error is the largest over the outputs."""
    X, t_end, h, every = _orbits(0), 12.0, 0.05, 3.0
    r = chaos_map(plummer, X, "fli", t_end=t_end, tau=h, time_transform="log", every=every,
                  progress=False)
    states = _by_outputs(LogHamiltonian(plummer, "ABA864"), X, t_end, h, every)
    assert np.array_equal(r.state, states[-1])
    ref = Reference(plummer, X)
    assert np.array_equal(r.energy_error, ref.errors(states[-1])["energy_error"])
    along = np.array([ref.errors(s)["energy_error"] for s in states])
    assert np.array_equal(r.accuracy.energy_error, along.max(axis=0))
    assert np.array_equal(r.accuracy.t_worst, every * (1 + along.argmax(axis=0)))
    assert (r.accuracy.energy_error > 0).all() and r.accuracy.accurate.all()
    assert r.accuracy.verdict.startswith("accurate")
    # Compilation and run kept apart, as every map's (no pilot: h given).
    assert set(r.provenance.timing) == {"compile", "run"}
    assert r.provenance.timing["run"] > 0


def test_map_verdict_warns_when_the_step_is_too_long():
    """A long fictitious step on the three-body map: the orbits whose
    Jacobi constant drifts beyond energy_tol are flagged and warned about,
    naming h; an energy_tol above every error keeps the same numbers and
    says accurate."""
    model = CR3BP(SUN_JUPITER_MU)
    X = np.array([[0.5, 0.0, 0.0, 0.9], [0.7, 0.0, 0.0, 0.6]])
    with pytest.warns(AccuracyWarning, match=r"relative energy and jacobi error .* smaller "
                      r"fictitious step h \(tau = 0.8"):
        r = chaos_map(model, X, "fli", t_end=20.0, tau=1.6, time_transform="log", every=5.0,
                      progress=False, energy_tol=1e-6)
    assert r.accuracy.over.any() and set(r.accuracy.conserved) == {"energy", "jacobi"}
    ref = Reference(model, X)
    final = ref.errors(r.state)
    assert np.array_equal(r.energy_error, final["energy_error"])
    assert (r.accuracy.conserved["jacobi"] >= final["conserved_error:jacobi"]).all()
    loose = 10 * float(np.max(r.accuracy.worst))
    with warnings.catch_warnings():
        warnings.simplefilter("error", AccuracyWarning)
        s = chaos_map(model, X, "fli", t_end=20.0, tau=1.6, time_transform="log", every=5.0,
                      progress=False, energy_tol=loose)
    assert np.array_equal(s.values, r.values) and s.accuracy.accurate.all()


def test_a_stopped_orbit_has_no_error_and_is_not_accurate():
    """A Sun–Jupiter orbit that meets U ≤ 0 with δ = 0.5 (orbit 9 of
    tests/test_time_transform.py's twelve): its errors are NaN, its
    verdict False, its state and t_stop where its last step left it; the
    others keep theirs."""
    rng = np.random.default_rng(1)
    X = np.column_stack([rng.uniform(0.3, 0.9, 12), rng.uniform(-0.1, 0.1, 12),
                         rng.uniform(-0.2, 0.2, 12), rng.uniform(0.3, 1.0, 12)])
    with pytest.warns(RuntimeWarning, match="stopped by the logarithmic Hamiltonian"):
        r = chaos_map(CR3BP(SUN_JUPITER_MU), X, "fli", t_end=20.0, tau=0.2,
                      time_transform="log", offset=0.5, every=5.0, progress=False,
                      energy_tol=math.inf)
    assert r.status[9] != 0 and (np.delete(r.status, 9) == 0).all()
    assert np.isnan(r.energy_error[9]) and np.isnan(r.accuracy.energy_error[9])
    assert not r.accuracy.accurate[9] and r.accuracy.accurate[np.arange(12) != 9].all()
    assert np.isfinite(r.state).all() and 0.0 <= r.t_stop[9] < 20.0
    assert np.isfinite(np.delete(r.energy_error, 9)).all()


def test_outputs_refuse_bad_steps_and_intervals(plummer):
    """Refused in one line before any kernel runs: a non-positive output
    interval (which would never end) and a non-positive per-orbit h."""
    lh = LogHamiltonian(plummer, "ABA864")
    X = _orbits(2, 2)
    with pytest.raises(ValueError, match="every must be a finite number > 0, got 0"):
        lh.outputs(X, None, 1.0, 0.1, every=0)
    with pytest.raises(ValueError, match=r"h must be finite numbers > 0, got \[0.1, -0.1\]"):
        lh.outputs(X, None, 1.0, [0.1, -0.1])

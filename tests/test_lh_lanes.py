"""The LH map's outputs over SIMD lanes (varint.codegen.lh_lanes) give, for
every orbit, the one-orbit kernel's bits: FLI, status, counts, final and
worst states and their times, on the cored logarithmic potential (a
free drift, libm's log in every kick) and the Sun–Jupiter three-body
problem (a rotating frame: a sine and a cosine in every drift), with
orbits whose steps, output counts and tails differ, more orbits than
lanes, and orbits that fail (U ≤ 0, the step budget) among the others."""

import copy

import numpy as np
import pytest
import sympy as sp

from varint.codegen.lh_lanes import LANE_WIDTH
from varint.models import from_potential
from varint.models.cr3bp import CR3BP, SUN_JUPITER_MU
from varint import time_transform
from varint.time_transform import LANES_WORK, MIN_LANES, LogHamiltonian

FIELDS = ("fli", "status", "x", "t", "x_worst", "t_worst", "counts")


@pytest.fixture(scope="module")
def cored():
    x, y = sp.symbols("x y")
    V = sp.log(sp.Float(0.03)**2 + x**2 + y**2 / sp.Float(0.8)**2) / 2
    return LogHamiltonian(from_potential(V, [x, y]), "ABA864", offset=0.25)


@pytest.fixture(scope="module")
def cr3bp():
    return LogHamiltonian(CR3BP(SUN_JUPITER_MU), "ABA864", offset=0.5)


@pytest.fixture(autouse=True)
def every_run_in_lanes(monkeypatch):
    """These runs are short: take the lanes whatever their work."""
    monkeypatch.setattr(time_transform, "LANES_WORK", 0.0)


def _both(lh, X, W0, t_end, h, **kwargs):
    """outputs over lanes and one orbit at a time, every field bitwise
    equal; the lanes' result."""
    one = copy.copy(lh)
    one.lanes_kernels = (None, None)
    assert lh.lanes_kernels[0 if W0 is None else 1] is not None and len(X) >= MIN_LANES
    a = lh.outputs(X, W0, t_end, h, **kwargs)
    b = one.outputs(X, W0, t_end, h, **kwargs)
    for name in FIELDS:
        assert np.array_equal(getattr(a, name), getattr(b, name), equal_nan=True), name
    return a


def _cored_orbits(m):
    """Orbits of the cored potential at E = 0, some through the core."""
    rng = np.random.default_rng(7)
    X = np.column_stack([rng.uniform(-0.6, 0.6, m), np.zeros(m), rng.uniform(-0.6, 0.6, m),
                         np.zeros(m)])
    # p_y ≥ 0 from E = ½p² + V = 0 (V < 0 inside r ≈ 1).
    V = 0.5 * np.log(0.03**2 + X[:, 0]**2)
    X[:, 3] = np.sqrt(np.maximum(-2 * V - X[:, 2]**2, 0.0) + 0.01)
    return X


@pytest.mark.parametrize("vector", [True, False])
def test_cored_lanes_are_the_one_orbit_bits(cored, vector):
    """More orbits than lanes, each with its own h (steps, outputs and
    tails differ), one with C below V (U ≤ 0 at its first kick)."""
    m = LANE_WIDTH + 5
    X = _cored_orbits(m)
    rng = np.random.default_rng(3)
    W0 = rng.standard_normal(X.shape) if vector else None
    h = rng.uniform(0.02, 0.08, m)
    C = cored.constants(X)
    C[4] = -10.0
    out = _both(cored, X, W0, 23.0, h, every=4.0, C=C)
    assert out.status[4] == -1 and (np.delete(out.status, 4) == 0).all()
    steps = out.counts[:, 0]
    assert len(set(steps.tolist())) > m // 2 and (np.delete(out.counts[:, 1], 4) > 0).all()


def test_cored_budget_stops_every_orbit_in_the_lanes_as_in_one(cored):
    X = _cored_orbits(MIN_LANES + 2)
    out = _both(cored, X, np.ones_like(X), 10.0, 0.05, every=2.0, max_steps=7)
    assert (out.status == -2).all() and (out.counts[:, 0] == 7).all()


# Without a vector (the lanes of its own kernel, 18 CPU s cold) under -m slow:
# the lanes without a vector are checked on the cored potential above, the
# rotating frame's lanes here with one.
@pytest.mark.parametrize("vector", [True, pytest.param(False, marks=pytest.mark.slow)])
def test_cr3bp_lanes_are_the_one_orbit_bits(cr3bp, vector):
    """Twelve Sun–Jupiter orbits (tests/test_time_transform.py's): with δ =
    0.5 orbit 9 meets U ≤ 0 in a rotating frame."""
    rng = np.random.default_rng(1)
    X = np.column_stack([rng.uniform(0.3, 0.9, 12), rng.uniform(-0.1, 0.1, 12),
                         rng.uniform(-0.2, 0.2, 12), rng.uniform(0.3, 1.0, 12)])
    W0 = np.random.default_rng(2).standard_normal(X.shape) if vector else None
    out = _both(cr3bp, X, W0, 20.0, 0.2, every=5.0)
    assert out.status[9] == -1 and (np.delete(out.status, 9) == 0).all()
    assert len(set(out.counts[:, 0].tolist())) > 6


class _Refused:
    """A lanes kernel that must not be called."""

    def __call__(self, *args):
        raise AssertionError("the lanes kernel ran")


def test_lanes_only_from_the_work_that_repays_their_compile(cored, monkeypatch):
    """A pilot-sized run (Σ t_end·U₀/h below LANES_WORK) runs one orbit at
    a time, so it never compiles the lanes kernel; from LANES_WORK on the
    lanes run, and so does a run told that its map takes them
    (``lanes=True``, a pilot); runs_in_lanes says which."""
    monkeypatch.setattr(time_transform, "LANES_WORK", LANES_WORK)
    lh = copy.copy(cored)
    lh.lanes_kernels = (_Refused(), _Refused())
    X = _cored_orbits(16)
    u0 = lh.start_u(X)
    assert u0.sum() > 1.5 * len(X)   # the estimate counts U, not one per unit time
    h = float(np.sum(10.0 * u0)) / LANES_WORK * 1.01     # just below LANES_WORK
    assert not lh.runs_in_lanes(X, 10.0, h, vectors=0)
    lh.outputs(X, None, 10.0, h, every=5.0, max_steps=3)
    assert lh.runs_in_lanes(X, 10.0, h / 1.02, vectors=0)
    with pytest.raises(AssertionError, match="lanes kernel ran"):
        lh.outputs(X, None, 10.0, h / 1.02, every=5.0, max_steps=3)
    with pytest.raises(AssertionError, match="lanes kernel ran"):
        lh.outputs(X, None, 10.0, h, every=5.0, max_steps=3, lanes=True)
    # Too few orbits for lanes: one at a time whatever the work.
    lh.outputs(X[:MIN_LANES - 1], None, 10.0, h / 1e3, every=5.0, max_steps=3, lanes=True)
    assert not lh.runs_in_lanes(X[:MIN_LANES - 1], 10.0, h / 1e3, vectors=0)


def test_lanes_work_counts_physical_time_over_the_step(monkeypatch):
    """lanes_work is Σ t_end·U₀/h: linear in t_end and in U₀, inverse in h
    (one number or one per orbit); an orbit with U₀ ≤ 0 or not finite
    (it stops at once) counts nothing; takes_lanes is monotone in the work
    and needs MIN_LANES orbits."""
    monkeypatch.setattr(time_transform, "LANES_WORK", LANES_WORK)
    u0 = np.array([1.0, 2.0, 0.5, 4.0])
    assert time_transform.lanes_work(u0, 10.0, 0.5) == pytest.approx(150.0)
    assert time_transform.lanes_work(u0, 20.0, 0.5) == pytest.approx(300.0)
    assert time_transform.lanes_work(2 * u0, 10.0, 0.5) == pytest.approx(300.0)
    assert time_transform.lanes_work(u0, 10.0, np.array([0.5, 1.0, 0.5, 1.0])) \
        == pytest.approx(10.0 * (2.0 + 2.0 + 1.0 + 4.0))
    assert time_transform.lanes_work(np.array([1.0, -1.0, 0.0, np.nan]), 10.0, 1.0) == 10.0
    works = np.geomspace(LANES_WORK / 100, LANES_WORK * 100, 41)
    taken = [time_transform.takes_lanes(MIN_LANES, w) for w in works]
    assert taken == sorted(taken) and taken[0] is False and taken[-1] is True
    assert not time_transform.takes_lanes(MIN_LANES - 1, LANES_WORK * 100)


@pytest.mark.parametrize("vector", [True, False])
def test_lanes_that_move_as_the_pool_shrinks_keep_their_bits(cored, vector):
    """Twice the lanes and more, of lengths that differ up to 16 times (each
    its own h), so that once every orbit has started the orbits end in an
    order unlike their lanes' and the pool moves its last lane's orbit into
    each idle lane; the last orbit stops at once (C below V) after the pool
    is full. Every orbit's bits are the one-orbit kernel's."""
    m = 2 * LANE_WIDTH + 3
    X = _cored_orbits(m)
    rng = np.random.default_rng(11)
    W0 = rng.standard_normal(X.shape) if vector else None
    h = 0.02 * 2.0 ** rng.uniform(0.0, 4.0, m)
    C = cored.constants(X)
    C[-1] = -10.0
    assert "if live < nb:" in cored.source()   # the pool shrinks
    out = _both(cored, X, W0, 17.0, h, every=3.0, C=C)
    assert out.status[-1] == -1 and (out.status[:-1] == 0).all()
    steps = out.counts[:-1, 0]
    # Lengths unlike their order: many orbits end before others started earlier.
    assert steps.max() > 8 * steps.min()
    assert np.sum(np.diff(steps[LANE_WIDTH:]) < 0) > 3

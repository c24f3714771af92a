"""Samples of nearby orbits for chaotic comparisons (studies/chaotic.py)."""

from types import SimpleNamespace

import numpy as np

import varint
from studies import chaotic
from studies import claims as rules


def test_nearby_orbits_are_on_the_energy_surface_within_the_radius():
    model, x0 = varint.paper_orbit("C1")
    X = chaotic.nearby(model, x0)
    assert X.shape == (chaotic.SAMPLE, 4) and np.array_equal(X[0], x0)
    assert np.abs(model.energy(X) - model.energy(x0)).max() < 1e-15
    d = np.linalg.norm(X[1:] - x0, axis=1)
    assert (d > 0).all() and d.max() < 20 * chaotic.RADIUS
    assert np.array_equal(X, chaotic.nearby(model, x0))  # seeded


def test_a_sample_beyond_its_horizon_narrows_by_its_own_law():
    """With values m + a_i t^-1/2 exactly, the sample carried from T to
    100 T is m + a_i (100 T)^-1/2: the fitted law is the one put in."""
    rng = np.random.default_rng(0)
    a = rng.standard_normal(64)
    t = np.geomspace(1e3, 1e6, 61)
    x1 = 0.05 + a[:, None] * t[None, :] ** -0.5
    fake = SimpleNamespace(t=t, exponents=np.stack([x1, 0 * x1], axis=2))
    values, how = chaotic.sample_at(fake, 1e8)
    # The median of 64 is the mean of two middle values: carried too.
    mid = np.median(x1[:, -1])
    assert np.allclose(values, mid + (x1[:, -1] - mid) * 100 ** -0.5, rtol=0, atol=1e-12)
    assert "t^-0.50" in how
    inside, at = chaotic.sample_at(fake, 1e5)
    assert np.array_equal(inside, x1[:, 40]) and "1e+05" in at


def test_one_value_against_a_sample():
    sample = np.linspace(0.04, 0.05, 64)
    assert rules.in_sample(0.045, sample).holds
    assert rules.in_sample(0.039, sample).holds is False
    assert rules.in_sample(0.045, sample[:4]).holds is None

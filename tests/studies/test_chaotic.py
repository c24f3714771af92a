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


def test_a_sample_is_read_only_at_the_times_it_covers():
    t = np.geomspace(1e3, 1e6, 61)
    x1 = np.arange(64)[:, None] + 0 * t[None, :] + t[None, :] * 1e-9
    fake = SimpleNamespace(t=t, exponents=np.stack([x1, 0 * x1], axis=2))
    assert np.array_equal(chaotic.sample_at(fake, 1e5), x1[:, 40])
    assert chaotic.sample_at(fake, 1e8) is None


def test_one_value_against_a_sample():
    sample = np.linspace(0.04, 0.05, 64)
    assert rules.in_sample(0.045, sample).holds
    assert rules.in_sample(0.039, sample).holds is False
    assert rules.in_sample(0.045, sample[:4]).holds is None

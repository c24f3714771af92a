"""λ of the Ferrers bar outside it (:func:`varint.models.ferrers.ferrers_lambda`):
Newton's method from below, stopped at a step of 1e-4 (c² + λ), against
40-digit values, and the potential's derivatives it gives."""

import mpmath
import numpy as np
import pytest

from tests.models.test_rotating_systems import _AXES2, _exact
from varint.models.ferrers import ferrers_grad_hess, ferrers_lambda, inside_table

_BARS = [(_AXES2, 0.1), (np.array([16.0, 4.0, 0.25]), 0.7)]


def _outside(rng, axes2, count, scale):
    """``count`` points outside the bar, at most ``scale`` times its axes,
    a third of them near each axis (the start max(Σ X − a², X_i − a_i²)
    then comes from a different term)."""
    points = rng.uniform(-1, 1, (40 * count, 3))
    points[: 14 * count] *= [1.0, 0.1, 0.1]
    points[14 * count: 27 * count] *= [0.1, 1.0, 0.1]
    points[27 * count:] *= [0.1, 0.1, 1.0]
    points *= scale * np.sqrt(axes2)
    outside = points[(points ** 2 / axes2).sum(1) > 1]
    assert len(outside) >= count
    return outside[rng.permutation(len(outside))[:count]]


def _lambda_40(q, axes2):
    with mpmath.workdps(40):
        A = [mpmath.mpf(float(a)) for a in axes2]
        X = [mpmath.mpf(float(v)) ** 2 for v in q]
        return float(mpmath.findroot(lambda u: sum(X[i] / (A[i] + u) for i in range(3)) - 1,
                                     (mpmath.mpf(0), sum(X)), solver="anderson"))


@pytest.mark.parametrize("axes2, gm", _BARS)
def test_lambda_is_below_the_root_within_its_bound(axes2, gm):
    """The iterates rise to the root, and the last step's square bounds
    the error (ferrers_lambda's docstring): λ within 1e-8 (c² + λ) of the
    40-digit root and not above it but by round-off (measured 6e-9), at
    200 points outside the bar to ten times its axes, 40 just outside its
    surface (m² = 1 + 1e-6) and 120 far along the axes, for two bars."""
    rng = np.random.default_rng(29)
    surface = _outside(rng, axes2, 40, 1.5)
    surface *= (1 + 1e-6) / np.sqrt((surface ** 2 / axes2).sum(1))[:, None]
    far = np.diag(np.sqrt(axes2)) * rng.uniform(1.001, 30.0, (40, 1, 1))
    for q in np.concatenate([_outside(rng, axes2, 100, 2.0), _outside(rng, axes2, 100, 10.0),
                             surface, far.reshape(-1, 3)]):
        exact = _lambda_40(q, axes2)
        lam = ferrers_lambda(q * q, axes2)
        assert lam > 0.0
        assert abs(lam - exact) <= 1e-8 * (axes2[2] + lam)
        assert lam <= exact + 4e-16 * (axes2[0] + lam)   # round-off at convergence


@pytest.mark.parametrize("axes2, gm", _BARS)
def test_outside_derivatives_against_40_digits(axes2, gm):
    """The stopped λ moves Φ, ∇Φ and D²Φ by its error to the fourth,
    third and second power: at 150 points outside the bar to twice its
    axes (where the W's own partial fractions keep their digits) and 30
    just outside its surface, each within 1e-13 of its 40-digit value's
    largest entry, for two bars."""
    rng = np.random.default_rng(31)
    table = inside_table(axes2, gm)
    surface = _outside(rng, axes2, 30, 1.5)
    surface *= (1 + 1e-6) / np.sqrt((surface ** 2 / axes2).sum(1))[:, None]
    for q in np.concatenate([_outside(rng, axes2, 150, 2.0), surface]):
        g, D = np.zeros(3), np.zeros((3, 3))
        phi = ferrers_grad_hess(q, axes2, gm, g, D, True, table)
        _, _, (phi0, g0, D0) = _exact(q, axes2, gm)
        g0 = np.array([float(v) for v in g0])
        D0 = np.array([[float(v) for v in row] for row in D0])
        assert abs(phi - float(phi0)) <= 1e-13 * abs(float(phi0))
        assert np.abs(g - g0).max() <= 1e-13 * np.abs(g0).max()
        assert np.abs(D - D0).max() <= 1e-13 * np.abs(D0).max()

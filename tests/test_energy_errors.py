"""The compiled energy errors of a prepared run's short call
(:func:`varint.kernels.energy_errors.energy_errors`) are, bit for bit, the
general path's: :meth:`varint.accuracy.Reference.errors` of NumPy's T and V
and the largest errors, their times and the verdict of
:func:`varint.accuracy.assess`."""

import numpy as np
import pytest

from varint import accuracy
from varint.kernels.energy_errors import energy_errors
from varint.models import FPUT, HenonHeiles


def _general(model, x0, x, t, tol):
    """The general path's errors (M, s) and verdict, by NumPy."""
    reference = accuracy.Reference(model, x0)
    m, s = len(x0), len(t)
    errors = reference.errors(x)["energy_error"].reshape(s, m).swapaxes(0, 1)
    verdict = accuracy.assess(t, {"energy_error": errors}, np.zeros(m, dtype=np.int64), tol,
                              0.1, single=False)
    return errors, verdict


def _compiled(model, x0, x, t, tol):
    n = model.n_dof
    both = np.concatenate((x0, x))
    with np.errstate(all="ignore"):
        kinetic, potential = model.kinetic(both[:, n:]), model.potential(both[:, :n])
    return energy_errors(kinetic, potential, len(x0), t, tol)


@pytest.mark.parametrize("model", [HenonHeiles(), FPUT(8, beta=1.0)], ids=["HH", "FPUT"])
@pytest.mark.parametrize("m, s", [(1, 1), (1, 5), (3, 4)])
def test_the_errors_and_the_verdict_are_the_general_paths(model, m, s):
    rng = np.random.default_rng(5)
    x0 = 0.2 * rng.standard_normal((m, model.dim))
    x = np.tile(x0, (s, 1)) + 1e-4 * rng.standard_normal((s * m, model.dim))
    t = 0.1 * np.arange(1, s + 1)
    tol = float(np.median(_general(model, x0, x, t, 1.0)[0]))   # some orbits above, some not
    errors, verdict = _general(model, x0, x, t, tol)
    got, largest, t_worst, accurate, finite = _compiled(model, x0, x, t, tol)
    assert finite
    np.testing.assert_array_equal(got, errors, strict=True)
    np.testing.assert_array_equal(largest, verdict.energy_error, strict=True)
    np.testing.assert_array_equal(t_worst, verdict.t_worst, strict=True)
    np.testing.assert_array_equal(accurate, verdict.accurate, strict=True)


def test_ties_take_the_first_output_and_a_zero_scale_is_one():
    # At the origin T = V = 0: the scale is 1, as Reference's. Equal errors
    # at outputs 1 and 3: the time of the first, as argmax.
    model = HenonHeiles()
    x0 = np.zeros((1, 4))
    p = np.array([0.0, 0.0, 0.1, 0.0])
    x = np.array([0.5 * p, p, 0.5 * p, p])
    t = np.array([1.0, 2.0, 3.0, 4.0])
    errors, verdict = _general(model, x0, x, t, 1e-3)
    got, largest, t_worst, accurate, finite = _compiled(model, x0, x, t, 1e-3)
    np.testing.assert_array_equal(got, errors, strict=True)
    assert errors[0, 1] == errors[0, 3] == 0.5 * (0.1 * 0.1)   # |H| / 1
    assert t_worst[0] == verdict.t_worst[0] == 2.0 and not accurate[0] and finite


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_an_error_that_is_not_finite_is_reported(bad):
    model = HenonHeiles()
    x0 = np.array([[0.1, 0.0, 0.0, 0.2]])
    x = np.array([[0.1, 0.0, 0.0, 0.2], [bad, 0.0, 0.0, 0.2]])
    assert not _compiled(model, x0, x, np.array([1.0, 2.0]), 1e-3)[-1]
    # At the start: its H is not finite.
    assert not _compiled(model, x[1:], x0, np.array([1.0]), 1e-3)[-1]

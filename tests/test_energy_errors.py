"""The compiled energy errors of a prepared run's short call
(:func:`varint.kernels.energy_errors.energy_errors`, and
:func:`~varint.kernels.energy_errors.state_energy_errors` with T computed
from the states) are, bit for bit, the general path's:
:meth:`varint.accuracy.Reference.errors` of NumPy's T and V and the largest
errors, their times and the verdict of :func:`varint.accuracy.assess`."""

from types import SimpleNamespace

import numpy as np
import pytest

import varint
from varint import accuracy
from varint.kernels.energy_errors import (SEQUENTIAL_TERMS, energy_errors, hamiltonian_errors,
                                         state_energy_errors)
from varint.models import FPUT, HenonHeiles, Model, ThreeDof
from varint.run import Run


def _general(model, x0, x, t, tol):
    """The general path's errors (M, s) and verdict, by NumPy."""
    reference = accuracy.Reference(model, x0)
    m, s = len(x0), len(t)
    errors = reference.errors(x)["energy_error"].reshape(s, m).swapaxes(0, 1)
    verdict = accuracy.assess(t, {"energy_error": errors}, np.zeros(m, dtype=np.int64), tol,
                              0.1, single=False)
    return errors, verdict


def _unpacked(found, finite, m, s, tol):
    """(errors (m, s), largest, t_worst, accurate, finite) of a kernel's
    compact result, as the short call reads it."""
    largest = found[:m]
    return found[2 * m:].reshape(m, s), largest, found[m:2 * m], largest <= tol, finite


def _compiled(model, x0, x, t, tol, from_states=False):
    n = model.n_dof
    both = np.concatenate((x0, x))
    with np.errstate(all="ignore"):
        kinetic, potential = model.kinetic(both[:, n:]), model.potential(both[:, :n])
    found = (state_energy_errors(both, potential, model.inverse_mass, len(x0), t)
             if from_states else energy_errors(kinetic, potential, len(x0), t))
    return _unpacked(*found, len(x0), len(t), tol)


@pytest.mark.parametrize("model, from_states", [
    (HenonHeiles(), False), (HenonHeiles(), True), (ThreeDof(), True),
    (FPUT(8, beta=1.0), False)], ids=["HH", "HH-T-compiled", "ThreeDof-T-compiled", "FPUT"])
@pytest.mark.parametrize("m, s", [(1, 1), (1, 5), (3, 4)])
def test_the_errors_and_the_verdict_are_the_general_paths(model, from_states, m, s):
    rng = np.random.default_rng(5)
    x0 = 0.2 * rng.standard_normal((m, model.dim))
    x = np.tile(x0, (s, 1)) + 1e-4 * rng.standard_normal((s * m, model.dim))
    t = 0.1 * np.arange(1, s + 1)
    tol = float(np.median(_general(model, x0, x, t, 1.0)[0]))   # some orbits above, some not
    errors, verdict = _general(model, x0, x, t, tol)
    got, largest, t_worst, accurate, finite = _compiled(model, x0, x, t, tol, from_states)
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
    for from_states in (False, True):
        assert not _compiled(model, x0, x, np.array([1.0, 2.0]), 1e-3, from_states)[-1]
        # At the start: its H is not finite.
        assert not _compiled(model, x[1:], x0, np.array([1.0]), 1e-3, from_states)[-1]
    # T alone overflowing (p ~ 1e200): not finite either, as NumPy's T.
    x[1] = [0.1, 0.0, 1e200, 0.2]
    assert not _compiled(model, x0, x, np.array([1.0, 2.0]), 1e-3, True)[-1]


def _numpy_kinetic(inverse_mass, p):
    """The base model's own T (:meth:`varint.models.base.Model.kinetic`)."""
    return Model.kinetic(SimpleNamespace(inverse_mass=inverse_mass), p)


@pytest.mark.parametrize("n", range(1, SEQUENTIAL_TERMS))
def test_t_from_the_states_is_numpys_below_eight_terms(n):
    # Momenta over 1e-150..1e150 (products that underflow to 0 or overflow
    # to inf among them), zeros of both signs, masses far from 1: the
    # errors from the compiled T are those from NumPy's T, bit for bit.
    rng = np.random.default_rng(n)
    rows, m = 400, 4
    x = rng.standard_normal((rows, 2 * n)) * 10.0 ** rng.integers(-150, 151, (rows, 2 * n))
    x[rng.random((rows, 2 * n)) < 0.1] = 0.0
    x[rng.random((rows, 2 * n)) < 0.1] = -0.0
    inverse_mass = rng.uniform(1e-3, 1e3, n)
    potential = rng.standard_normal(rows)
    t = np.arange(1.0, rows // m)
    kinetic = _numpy_kinetic(inverse_mass, x[:, n:])
    with np.errstate(all="ignore"):
        want, want_finite = energy_errors(kinetic, potential, m, t)
    got, finite = state_energy_errors(x, potential, inverse_mass, m, t)
    assert finite == want_finite
    np.testing.assert_array_equal(got, want, strict=True)
    # Finite everywhere on moderate momenta, and still the same bits.
    x[:, n:] = rng.standard_normal((rows, n))
    want, want_finite = energy_errors(_numpy_kinetic(inverse_mass, x[:, n:]), potential, m, t)
    got, finite = state_energy_errors(x, potential, inverse_mass, m, t)
    assert finite and want_finite
    np.testing.assert_array_equal(got, want, strict=True)


def test_from_eight_terms_numpy_sums_in_another_order():
    # Why the short call keeps NumPy's T from 8 degrees of freedom on: its
    # pairwise sum rounds differently from the sequential one.
    rng = np.random.default_rng(8)
    n = SEQUENTIAL_TERMS
    p = rng.standard_normal((2000, n)) * 10.0 ** rng.integers(-3, 4, (2000, n))
    terms = np.ones(n) * p * p
    sequential = np.zeros(len(p))
    for j in range(n):
        sequential += terms[:, j]
    assert np.count_nonzero(0.5 * sequential != _numpy_kinetic(np.ones(n), p)) > 0


@pytest.mark.parametrize("model, compiled_t", [
    (ThreeDof(), True), (FPUT(8, beta=1.0), False)], ids=["ThreeDof", "FPUT-8"])
def test_a_prepared_short_call_compiles_t_only_below_eight_terms(model, compiled_t,
                                                                 monkeypatch):
    # The short call takes T from the states below 8 degrees of freedom and
    # the model's NumPy T from 8 on; either way its energy errors and verdict
    # are the one-shot call's, bit for bit.
    general = []
    with_orbits = Run.with_orbits
    monkeypatch.setattr(Run, "with_orbits",
                        lambda self, *a: general.append(a) or with_orbits(self, *a))
    rng = np.random.default_rng(11)
    states = 0.05 * rng.standard_normal((3, model.dim))
    run = varint.prepare(model, "integrate", 0.3, tau=0.1, t_out=3)
    run(states[0])
    assert run._again.short is not None and (run._again.short.state_kernel is not None) == compiled_t
    for x0 in states[1:]:
        got, alone = run(x0), varint.integrate(model, x0, 0.3, tau=0.1, t_out=3)
        np.testing.assert_array_equal(got.energy_error, alone.energy_error, strict=True)
        assert got.accuracy.energy_error == alone.accuracy.energy_error
        assert got.accuracy.t_worst == alone.accuracy.t_worst
        assert got.accuracy.accurate == alone.accuracy.accurate
    assert not general      # every call after the first was a short one


def _hamiltonian_models():
    from varint.models.bar import bar_orbit

    from .flows.steppers import coupled_general, cr3bp, relativistic

    bar, bx0 = bar_orbit("regular")
    x0 = np.array([0.3, 0.2, 0.1, 0.5])
    return {"general": (coupled_general(), x0), "cr3bp": (cr3bp(), x0),
            "relativistic": (relativistic(), x0), "bar": (bar, bx0)}


@pytest.mark.parametrize("name", ["general", "cr3bp", "relativistic", "bar"])
@pytest.mark.parametrize("m, s", [(1, 1), (1, 5), (3, 4)])
def test_a_hamiltonian_models_errors_and_verdict_are_the_general_paths(name, m, s):
    # H over the rows and V at the start (row_energies), then the scale,
    # errors and largest ones compiled: the general path's bits (the
    # reference's scale |H − V| + |V|, or |H| for a general H, whose V the
    # kernel takes as zeros).
    model, base = _hamiltonian_models()[name]
    assert accuracy.hamiltonian_energy(model)
    rng = np.random.default_rng(7)
    x0 = base + 1e-2 * rng.standard_normal((m, model.dim))
    x = np.tile(x0, (s, 1)) + 1e-4 * rng.standard_normal((s * m, model.dim))
    t = 0.1 * np.arange(1, s + 1)
    _, found = accuracy.reference_and_errors(model, x0, x)
    errors = found["energy_error"].reshape(s, m).swapaxes(0, 1)
    tol = float(np.median(errors))
    verdict = accuracy.assess(t, {"energy_error": errors}, np.zeros(m, dtype=np.int64), tol,
                              0.1, single=False)
    h, v = model.row_energies(np.concatenate((x0, x)), m)
    assert (v is None) == (name == "general")
    got, largest, t_worst, accurate, finite = _unpacked(
        *hamiltonian_errors(h, np.zeros(m) if v is None else v, m, t), m, s, tol)
    assert finite
    np.testing.assert_array_equal(got, errors, strict=False)
    assert got.tobytes() == np.ascontiguousarray(errors).tobytes()
    assert largest.tobytes() == verdict.energy_error.tobytes()
    assert t_worst.tobytes() == verdict.t_worst.tobytes()
    np.testing.assert_array_equal(accurate, verdict.accurate, strict=True)


def test_a_zero_hamiltonian_scale_is_one():
    # |H₀ − V₀| + |V₀| = 0: the scale is 1, as energy_scale's np.where.
    h, v = np.array([0.0, 0.5, 0.25]), np.array([0.0])
    found, finite = hamiltonian_errors(h, v, 1, np.array([1.0, 2.0]))
    assert finite and found.tolist() == [0.5, 1.0, 0.5, 0.25]

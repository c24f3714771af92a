"""The part stepper's checks in one call (``PartsPropagator.advance_checks``,
the ``CHECKS`` body of :mod:`varint.kernels.parts`): the orbits it copies at
the check steps are bit for bit those of an ``advance`` to each check in
turn, with the same final state and counts, for a lattice, a rotating
frame's A + V and a time-dependent general H (its time momentum too); an
orbit that escapes has copies up to its escape only; and a pilot that
measures them chooses what the pilot advancing check by check chooses."""

import numpy as np
import pytest
import sympy as sp

from varint import stepsize
from varint.accuracy import Reference
from varint.methods import make_propagator
from varint.models import DisorderedKG, from_hamiltonian
from varint.models.bar import bar_orbit
from varint.protocol import STATUS_OK, Status
from varint.state import RunState, initial_deviations


def assert_bitwise_equal(a, b):
    a, b = np.asarray(a), np.asarray(b)
    assert a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()


def _timed_general():
    """A general H(q, p, t) (tests/flows/test_general_methods.py's), run by
    Gauss–Legendre steps through the part stepper in the extended phase
    space."""
    q, p, t = sp.symbols("q p t")
    H = (q ** 2 + 1) * (p ** 2 + 1) / 2 * (1 + sp.cos(t) / 10)
    return from_hamiltonian(H, [q], [p], time=t), np.array([[0.5, 0.1], [0.3, -0.2]])


def _kg():
    kg = DisorderedKG(32, W=4.0, seed=1)     # beyond the generated steppers
    return kg, np.array([kg.initial_block(4, 0.4), kg.initial_block(2, 0.3)])


def _bar():
    """The bar's rotating frame A + V on the part flows: without its extra
    force (`galaxy_force`: disc, bulge and bar in one compiled kernel) it gets
    no generated stepper."""
    model, x0 = bar_orbit("chaotic")
    model.extra_force = None     # a fresh model: no other test sees it
    return model, x0[None]


def _start(model, X, k=2):
    return RunState.start(X.copy(), initial_deviations(model.dim, k, len(X), 0))


def _by_checks(prop, state, checks):
    """The states at the checks, advancing to each in turn."""
    x, p_t, taken = [], [], []
    for s in checks:
        prop.advance(state, int(s - state.step))
        x.append(state.x.copy())
        p_t.append(state.extra.get("p_t", np.zeros(state.n_orbits)).copy())
        taken.append(state.status == STATUS_OK)
    return np.array(x), np.array(p_t), np.array(taken)


@pytest.mark.parametrize("system, tau, renorm", [(_kg, 0.1, "qr"), (_bar, 0.3, "qr"),
                                                 (_timed_general, 0.2, "none")])
def test_copies_at_the_checks_are_the_states_of_advancing_to_each(system, tau, renorm):
    model, X = system()
    prop = make_propagator("tm", model, tau, renorm, None)
    assert prop.takes_checks()
    checks = stepsize._checks(137).copy()
    one, each = _start(model, X), _start(model, X)
    x, p_t = prop.advance_checks(one, checks)
    x_each, p_t_each, taken = _by_checks(prop, each, checks)
    assert taken.all() and x.shape == (len(checks), len(X), model.dim)
    assert_bitwise_equal(x, x_each)
    if model.parts.timed:
        assert_bitwise_equal(p_t, p_t_each)
        assert np.abs(p_t).max() > 0     # the time momentum moved
    else:
        assert p_t is None
    for a, b in ((one.x, each.x), (one.W, each.W), (one.acc_m, each.acc_m),
                 (one.acc_e, each.acc_e), (one.status, each.status)):
        assert_bitwise_equal(a, b)
    assert one.step == each.step == checks[-1]
    assert one.counts == each.counts


def test_an_escaped_orbit_has_copies_up_to_its_escape():
    model, X = _bar()
    free = make_propagator("tm", model, 0.3, "qr", None)
    x, _ = free.advance_checks(_start(model, X, 1), stepsize._checks(400).copy())
    radius = np.sqrt((x[:, 0, :3] ** 2).sum(axis=1))
    # Escapes once it goes further out than at any of its first 10 checks.
    model.escape_radius = float(radius[:10].max())
    prop = make_propagator("tm", model, 0.3, "qr", None)
    checks = stepsize._checks(400).copy()
    one, each = _start(model, X, 1), _start(model, X, 1)
    x, _ = prop.advance_checks(one, checks)
    x_each, _, taken = _by_checks(prop, each, checks)
    assert one.status[0] == each.status[0] == Status.ESCAPED
    assert 0 < taken.sum() < len(checks)
    assert_bitwise_equal(np.isfinite(x).all(axis=2), taken)
    assert_bitwise_equal(x[taken], x_each[taken])
    assert one.fail_step[0] == each.fail_step[0]


# The time-dependent H's pilot (a kernel of its own, one vector with QR: 19
# CPU s cold) under -m slow: its copies at the checks, the time momentum
# too, are checked by default above, and the pilot's law on the other two.
@pytest.mark.parametrize("system", [_kg, _bar, pytest.param(_timed_general, marks=pytest.mark.slow)])
def test_the_pilot_chooses_what_advancing_check_by_check_chooses(system, monkeypatch):
    model, X = system()
    sch = stepsize.default_scheme(model, None)
    W0 = initial_deviations(model.dim, 1, len(X), 0)

    def pilot():
        counts = {}
        errors = stepsize.pilot_errors(model, X, 0.25, 20.0, sch, Reference(model, X), counts,
                                       (W0, "qr", None, False))
        tau, choice = stepsize.choose_step(model, X, 30.0, 1e-7, W0=W0, renorm="qr")
        return errors, counts, tau, choice

    one_call = pilot()
    monkeypatch.setattr(type(make_propagator("tm", model, 0.1, "qr", None)), "takes_checks",
                        lambda self: False)
    by_checks = pilot()
    assert_bitwise_equal(one_call[0], by_checks[0])
    assert (one_call[0] > 0).all()
    assert one_call[1:] == by_checks[1:]

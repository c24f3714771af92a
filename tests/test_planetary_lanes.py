"""Planetary flows over SIMD lanes (varint.kernels.planetary_lanes): many
grid points stepped together end bit for bit where each point's one-orbit
part stepper ends, including lanes whose Kepler drift leaves the common
path (unresolved pericentres, stepped alone) and lanes that meet."""

import numpy as np
import pytest

import varint
from varint.kernels.planetary_lanes import lane_steps
from varint.methods.parts import _tables, parts_steps
from varint.models import Planetary

JUPITER = dict(a=5.204, M=0.600, omega=0.257, e=0.048)
WH10 = varint.get_scheme("SABA1").repeated(10)


def _grid(model):
    """A grid of Saturn's (a, e) over the chaotic zone and beyond, and two
    near-parabolic Saturns whose pericentre passages a step of 1 does not
    resolve (their drifts leave the common path)."""
    g = varint.element_grid(model, [JUPITER, dict(a=9.0, e=0.0, M=0.871, omega=1.616)], 2,
                            np.linspace(6.5, 10.0, 5), np.linspace(0.0, 0.6, 4))
    eccentric = [model.from_elements([JUPITER, dict(a=9.0, e=e, M=0.05, omega=1.616)])
                 for e in (0.97, 0.995)]
    return np.vstack([g.states, eccentric])


def _lanes(model, X, W, tau, n_steps, scheme):
    k = W.shape[2]
    parts, h, par, n_work = _tables(model, scheme, tau)
    Xl = np.ascontiguousarray(X.T)
    Vl = np.ascontiguousarray(np.moveaxis(W, 0, 2).transpose(1, 0, 2))   # (k, 2N, L)
    steps = lane_steps(model.n_planets, True, k, model.parts.apply)
    alone = steps(Xl, Vl, parts, h, par, n_work, n_steps)
    return Xl.T, Vl.transpose(2, 1, 0), alone


@pytest.mark.parametrize("k", [1, pytest.param(2, marks=pytest.mark.slow)])
def test_lanes_end_bitwise_where_each_point_ends(k):
    model = Planetary([1.0, 0.000954, 0.000285])
    X = _grid(model)
    rng = np.random.default_rng(30)
    W = rng.standard_normal((len(X), model.dim, k))
    n_steps, tau = 40, 10.0
    Xl, Wl, alone = _lanes(model, X, W, tau, n_steps, WH10)
    assert alone > 0             # the eccentric lanes took the one-orbit drift
    for m in range(len(X)):
        x, w = parts_steps(model, X[m], W[m], tau, n_steps, WH10)
        assert np.array_equal(Xl[m], x), m
        assert np.array_equal(Wl[m], w), m


def test_lanes_mark_an_encounter_as_the_one_orbit_flow_does():
    model = Planetary([1.0, 0.000954, 0.000285], close_encounter=1.0)
    # Saturn on Jupiter's orbit, a little ahead: within a Hill radius.
    x = model.from_elements([JUPITER, dict(a=5.204, e=0.048, M=0.62, omega=0.257)])
    X = np.vstack([x, _grid(model)[:3]])
    W = np.ones((len(X), model.dim, 1))
    Xl, _, _ = _lanes(model, X, W, 10.0, 1, WH10)
    assert Xl[0, 0] == np.inf
    assert np.isfinite(Xl[1:]).all()
    # The one-orbit flow marks the same orbit (+inf: non-finite) at once.
    with pytest.raises(FloatingPointError, match="after 0 steps"):
        parts_steps(model, x, W[0], 10.0, 1, WH10)


def test_lanes_refuse_democratic_coordinates():
    model = Planetary([1.0, 0.000954, 0.000285], coordinates="democratic")
    with pytest.raises(ValueError, match="Jacobi coordinates only"):
        lane_steps(model.n_planets, False, 1, model.parts.apply)

"""Surfaces of section: crossings on the plane to round-off, at the place an
independent integrator (heyoka's Taylor method with event detection) puts
them, converging with the scheme's order; grids of initial conditions on
the section at the right energy."""

import numpy as np
import pytest

import varint
from varint.protocol import Status
from tests.helpers import fitted_slope

N_CROSS = 12


@pytest.fixture(scope="module")
def hh():
    return varint.models.HenonHeiles()


@pytest.fixture(scope="module")
def heyoka_crossings(hh):
    """The first crossings of R1 with x = 0 (x increasing) by heyoka's
    Taylor integrator at machine precision, with its event detection."""
    hy = pytest.importorskip("heyoka")
    from varint.baselines.taylor import heyoka_system

    system, variables = heyoka_system(hh.symbolic())
    event = hy.t_event(variables[0], direction=hy.event_direction.positive)
    x0 = varint.paper_orbit("R1")[1]
    ta = hy.taylor_adaptive(system, x0.copy(), t_events=[event])
    out = []
    while len(out) < N_CROSS:
        outcome = ta.propagate_until(1e4)[0]
        assert outcome == hy.taylor_outcome(-1)  # stopped by the event
        if ta.time > 0:  # x0 itself is on the plane; not a crossing
            out.append(np.concatenate([[ta.time], ta.state]))
    return np.array(out)


def test_crossings_lie_on_the_plane_and_conserve_energy(hh):
    x0 = varint.paper_orbit("C1")[1]
    r = varint.surface_of_section(hh, x0, 2000.0, tau=0.01)
    pts = r.points[:r.n_points]
    assert r.n_points > 250
    assert np.abs(pts[:, 0]).max() < 1e-15
    assert (pts[:, 2] > 0).all()  # p_x > 0: crossing with x increasing
    assert r.energy_error[:r.n_points].max() < 1e-11
    assert np.all(np.diff(r.times[:r.n_points]) > 0)
    assert np.isnan(r.points[r.n_points:]).all()


def test_crossings_agree_with_heyoka_event_detection(hh, heyoka_crossings):
    x0 = varint.paper_orbit("R1")[1]
    r = varint.surface_of_section(hh, x0, 200.0, tau=0.005, max_points=N_CROSS)
    assert r.n_points == N_CROSS
    assert np.abs(r.times - heyoka_crossings[:, 0]).max() < 1e-10
    assert np.abs(r.points - heyoka_crossings[:, 1:]).max() < 1e-10


def test_crossing_error_falls_with_the_order_of_the_scheme(hh, heyoka_crossings):
    x0 = varint.paper_orbit("R1")[1]
    taus = np.array([0.08, 0.04, 0.02])
    errors = []
    for tau in taus:
        r = varint.surface_of_section(hh, x0, 200.0, tau=tau, scheme="SBAB2C",
                                      max_points=N_CROSS)
        errors.append(np.abs(r.points - heyoka_crossings[:, 1:]).max())
    assert fitted_slope(taus, errors) == pytest.approx(4.0, abs=0.4)


def test_directions(hh):
    x0 = varint.paper_orbit("R1")[1]
    up = varint.surface_of_section(hh, x0, 500.0, direction=1)
    down = varint.surface_of_section(hh, x0, 500.0, direction=-1)
    both = varint.surface_of_section(hh, x0, 500.0, direction=0)
    assert (down.points[:down.n_points, 2] < 0).all()
    assert abs(int(up.n_points) - int(down.n_points)) <= 1
    assert both.n_points == up.n_points + down.n_points
    merged = np.sort(np.concatenate([up.times[:up.n_points], down.times[:down.n_points]]))
    assert np.array_equal(merged, both.times[:both.n_points])


def test_batch_is_the_single_orbits(hh):
    x0 = np.array([varint.paper_orbit(n)[1] for n in ("R1", "C1")])
    batch = varint.surface_of_section(hh, x0, 300.0)
    for m in range(2):
        one = varint.surface_of_section(hh, x0[m], 300.0)
        assert np.array_equal(one.points[:one.n_points], batch.points[m, :batch.n_points[m]])
    assert batch.provenance.counts["steps"] == 2 * round(300.0 / 0.01)


def test_many_crossings_overflow_the_buffer_without_loss(hh):
    # More crossings than the kernel's per-call buffer: continued calls.
    from varint import sections

    x0 = varint.paper_orbit("C1")[1]
    r = varint.surface_of_section(hh, x0, 3e4, tau=0.05, direction=0)
    assert r.n_points > sections._BUFFER
    assert np.all(np.diff(r.times[:r.n_points]) > 0)
    one = varint.surface_of_section(hh, x0, 3e4, tau=0.05, direction=0, max_points=100)
    assert one.n_points == 100 and np.array_equal(one.points, r.points[:100])


def test_escaping_orbit_stops_with_its_crossings(hh):
    x0 = varint.solve_momentum(hh, [0.0, 0.0], [0.0, 0.0], 0.3)
    r = varint.surface_of_section(hh, x0, 1e3, escape_radius=5.0)
    assert r.status == Status.ESCAPED and r.t[0] < 1e3


def test_section_grid(hh):
    u, v = np.linspace(-0.6, 0.9, 31), np.linspace(-0.5, 0.5, 21)
    g = varint.section_grid(hh, 0.125, u, v)
    assert g.mask.shape == (21, 31) and len(g) == g.mask.sum() > 0
    assert np.allclose(hh.energy(g.states), 0.125, rtol=0, atol=1e-15)
    assert (g.states[:, 0] == 0).all() and (g.states[:, 2] >= 0).all()
    U, V = np.meshgrid(u, v)
    assert np.array_equal(g.states[:, 1], U[g.mask]) and np.array_equal(g.states[:, 3], V[g.mask])
    # A point is allowed exactly where V(0, y) + p_y²/2 ≤ E.
    allowed = hh.potential(np.stack([0 * U, U], axis=-1)) + V ** 2 / 2 <= 0.125
    assert np.array_equal(g.mask, allowed)


@pytest.mark.parametrize("kwargs, match", [
    ({"plane": 2}, "plane must be a coordinate index in 0..1"),
    ({"direction": 2}, "direction must be 1, -1 or 0"),
    ({"max_points": 0}, "max_points must be a positive integer"),
    ({"tau": 0}, "tau must be a positive finite number"),
    ({"scheme": "nope"}, "unknown scheme"),
])
def test_bad_section_arguments(hh, kwargs, match):
    with pytest.raises(ValueError, match=match):
        varint.surface_of_section(hh, varint.paper_orbit("R1")[1], 10.0, **kwargs)


@pytest.mark.parametrize("kwargs, match", [
    ({"axes": (0, 1)}, "axes must be two distinct state indices"),
    ({"energy": float("nan")}, "energy must be a finite number"),
    ({"u": []}, "u must be a non-empty array"),
])
def test_bad_grid_arguments(hh, kwargs, match):
    args = {"energy": 0.125, "u": [0.0, 0.1], "v": [0.0]}
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        varint.section_grid(hh, **args)

"""Planetary flows over SIMD lanes (varint.kernels.planetary_lanes): many
grid points stepped together end bit for bit where each point's one-orbit
part stepper ends, including lanes whose Kepler drift leaves the common
path (unresolved pericentres, stepped alone) and lanes that meet."""

import platform
import re
import warnings

import numba
import numpy as np
import pytest

import varint
from varint.kernels.planetary_batch import LANES
from varint.kernels.planetary_lanes import _planet_drift, kick_lanes, lane_steps
from varint.methods.parts import _tables, parts_steps
from varint.models import Planetary

JUPITER = dict(a=5.204, M=0.600, omega=0.257, e=0.048)
WH10 = varint.get_scheme("SABA1").repeated(10)


def _grid(model):
    """A grid of Saturn's (a, e) over the chaotic zone and beyond, and two
    near-parabolic Saturns whose pericentre passages a step of 1 does not
    resolve (their drifts leave the common path): 32 orbits, the width of
    a map's block of lanes (``LANES``), so that the lane kernels these
    tests compile for their width are the ones the maps run (a width of
    its own would compile the lanes' step a second time)."""
    g = varint.element_grid(model, [JUPITER, dict(a=9.0, e=0.0, M=0.871, omega=1.616)], 2,
                            np.linspace(6.5, 10.0, 6), np.linspace(0.0, 0.6, 5))
    eccentric = [model.from_elements([JUPITER, dict(a=9.0, e=e, M=0.05, omega=1.616)])
                 for e in (0.97, 0.995)]
    X = np.vstack([g.states, eccentric])
    assert len(X) == LANES
    return X


def _lanes(model, X, W, tau, n_steps, scheme):
    k = W.shape[2]
    parts, h, par, n_work = _tables(model, scheme, tau)
    Xl = np.ascontiguousarray(X.T)
    Vl = np.ascontiguousarray(np.moveaxis(W, 0, 2).transpose(1, 0, 2))   # (k, 2N, L)
    steps = lane_steps(model.n_planets, True, k, model.parts.apply, len(X))
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
    # As many lanes as the grid (the lane kernels compile per width: these
    # are the ones the test above compiled), the encounter in the first.
    X = _grid(model)
    X[0] = x
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
        lane_steps(model.n_planets, False, 1, model.parts.apply, 4)


@pytest.mark.skipif(platform.machine().lower() not in ("x86_64", "amd64"),
                    reason="reads x86 assembly")
def test_the_lane_loops_compile_to_vector_instructions():
    # What the lanes are for: the solve, the tangent and state updates and
    # the kick each compile to packed double instructions (SSE2's *pd at
    # least, on any x86-64), not one lane at a time (*sd only) — as they
    # did while a run-time row length or planet index blocked LLVM.
    model = Planetary([1.0, 0.000954, 0.000285])
    X = _grid(model)
    _lanes(model, X, np.ones((len(X), model.dim, 1)), 10.0, 1, WH10)     # compiles them
    packed = re.compile(r"\n\s+v?(?:mul|add|sub|div|sqrt|fn?m(?:add|sub)\d*)pd\s")
    kernels = {"kick": kick_lanes(2, True, 1, len(X))}
    for i in range(2):
        kernels[f"solve {i}"], kernels[f"finish {i}"] = _planet_drift(i, 2, 1, len(X))
    for name, kernel in kernels.items():
        (asm,) = kernel.inspect_asm().values()
        assert len(packed.findall(asm)) >= 20, name


def _map(model, X, **options):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")          # the eccentric lanes' unresolved pericentres
        return varint.chaos_map(model, X, "megno", t_end=1500.0, tau=10.0, threshold=4.0,
                                scheme=WH10, progress=False, escape_radius=20.0, **options)


def test_a_map_in_lanes_is_bitwise_the_map_one_orbit_at_a_time_whatever_its_chunks():
    # MEGNO with early stopping, escapes and failed drifts (the eccentric
    # lanes): lanes (default) against one orbit at a time, one chunk
    # against chunks of 7 (blocks part-filled and refilled as orbits stop)
    # and one thread against all. The reference one orbit at a time on one
    # thread (it needs no threads); one thread as numba's thread count, so
    # that the runs asked to be parallel share the lanes' parallel batch
    # (a serial one is another compile, and steps the same single block: a
    # call of at most LANES orbits is one block either way).
    model = Planetary([1.0, 0.000954, 0.000285])
    X = _grid(model)
    one = _map(model, X, lanes=False, chunk_size=len(X), parallel=False)
    assert (one.status > 0).any() and (one.status < 0).any()   # failures and early stops
    threads = numba.get_num_threads()
    for options, n_threads in ((dict(chunk_size=len(X)), threads),
                               (dict(chunk_size=7, parallel=True), threads),
                               (dict(chunk_size=len(X), parallel=True), 1)):
        numba.set_num_threads(n_threads)
        try:
            lanes = _map(model, X, **options)
        finally:
            numba.set_num_threads(threads)
        for key in ("values", "status", "t_stop"):
            assert np.array_equal(getattr(lanes, key), getattr(one, key), equal_nan=True), \
                (key, options)


def test_lanes_option_is_checked():
    model = Planetary([1.0, 0.000954, 0.000285])
    with pytest.raises(ValueError, match="lanes must be True or False, got 'yes'"):
        _map(model, _grid(model)[:4], lanes="yes")


def test_serial_and_parallel_batches_run_one_kernel():
    """The parallel batch is the serial kernel on threads (it does not
    depend on ``parallel``): a map run serial and parallel compiles it
    once."""
    from varint.kernels.interval import no_accumulator
    from varint.kernels.planetary_batch import lane_batch

    model = Planetary([1.0, 0.000954, 0.000285])
    parts = model.parts

    def batch(parallel):
        return lane_batch(model.n_planets, 1, parts.apply, parts.field, no_accumulator,
                          False, parallel)

    serial, parallel = batch(False), batch(True)
    assert serial is not parallel and hasattr(serial, "py_func")
    cells = dict(zip(parallel.__code__.co_freevars, parallel.__closure__, strict=True))
    assert cells["batch"].cell_contents is serial

"""Chaos maps: values equal single-orbit runs, bitwise the same however the
map is chunked, resumed or distributed (Dask LocalCluster), early stopping
skips exactly the work it should, and the known structure of the
Hénon–Heiles section at H = 0.125 comes out."""

import json
import warnings

import numpy as np
import pytest

import varint
from varint.protocol import Status
from varint import maps as cm
from varint.state import initial_deviations

T_END = 800.0
TAU = 0.05


@pytest.fixture(scope="module")
def hh():
    return varint.models.HenonHeiles()


@pytest.fixture(scope="module")
def orbits(hh):
    """R1, C1 and a line of orbits through the section (y, p_y = 0)."""
    ys = np.linspace(-0.35, 0.6, 14)
    line = [varint.solve_momentum(hh, [0.0, y], [0.0, 0.0], 0.125) for y in ys]
    return np.array([varint.paper_orbit("R1")[1], varint.paper_orbit("C1")[1]] + line)


@pytest.fixture(scope="module")
def full_map(hh, orbits):
    return varint.chaos_map(hh, orbits, "sali", t_end=T_END, tau=TAU, progress=False)


def _same(a, b):
    assert a.values.tobytes() == b.values.tobytes()
    assert a.t_stop.tobytes() == b.t_stop.tobytes()
    assert a.status.tobytes() == b.status.tobytes()
    assert a.state.tobytes() == b.state.tobytes()


@pytest.mark.parametrize("indicator", ["sali", "x1", "gali"])
def test_values_are_those_of_single_orbit_runs(hh, orbits, indicator):
    r = varint.chaos_map(hh, orbits, indicator, t_end=T_END, tau=TAU, threshold=None,
                         chunk_size=4, progress=False)
    assert (r.status == 0).all() and np.allclose(r.t_stop, T_END)
    # parallel=True: the kernel the map compiled (same code, one compilation).
    opts = {"tau": TAU, "t_out": 1, "parallel": True}
    for m in (0, 1, 7):
        if indicator == "sali":
            W = initial_deviations(4, 2, 1, 0, [m])[0]
            ref = varint.sali(hh, orbits[m], T_END, deviations=W, **opts).sali[-1]
        elif indicator == "x1":
            W = initial_deviations(4, 1, 1, 0, [m])[0]
            ref = varint.lyapunov_spectrum(hh, orbits[m], T_END, deviations=W,
                                           **opts).exponents[-1, 0]
        else:  # the map shows GALI_N = GALI_2 of the default orders 2, 3, 4
            W = initial_deviations(4, 4, 1, 0, [m])[0]
            ref = varint.gali(hh, orbits[m], T_END, deviations=W, **opts).gali[2][-1]
        assert r.values[m] == pytest.approx(ref, rel=1e-12, abs=0)


def test_megno_map_stops_orbits_above_a_threshold(hh, orbits):
    # MEGNO grows on chaotic orbits (Ȳ ≈ χ₁t/2) and tends to 2 on regular
    # ones, so "decided" means above the threshold.
    r = varint.chaos_map(hh, orbits[:2], "megno", t_end=T_END, tau=TAU, threshold=5.0,
                         progress=False)
    W = initial_deviations(4, 1, 1, 0, [0])[0]
    ref = varint.megno(hh, orbits[0], T_END, tau=TAU, deviations=W, t_out=1, parallel=True)
    assert r.status[0] == 0 and r.values[0] == pytest.approx(ref.mean_megno[-1], rel=1e-12)
    assert 1.0 < r.values[0] < 2.5
    assert r.status[1] == Status.DECIDED and r.values[1] > 5.0 and r.t_stop[1] < T_END / 2


def test_every_method_maps_every_indicator(hh, orbits):
    """Indicators are the same objects in maps and single runs, and every
    method computes them: a MEGNO map by the Taylor method holds the
    values of single Taylor runs."""
    r = varint.chaos_map(hh, orbits[:2], "megno", t_end=50.0, tau=TAU, threshold=None,
                         method="taylor", progress=False)
    for m in (0, 1):
        W = initial_deviations(4, 1, 1, 0, [m])[0]
        ref = varint.megno(hh, orbits[m], 50.0, tau=TAU, deviations=W, t_out=1, method="taylor")
        assert r.values[m] == pytest.approx(ref.mean_megno[-1], rel=1e-12)


def test_known_structure_of_the_henon_heiles_section(full_map):
    # R1 lies in an island (regular: SALI stays O(1)); C1 in the chaotic
    # sea (SALI falls below the threshold and is stopped early).
    assert full_map.values[0] > 1e-2 and full_map.status[0] == 0
    assert full_map.values[1] < 1e-8 and full_map.status[1] == Status.DECIDED
    assert full_map.t_stop[1] < T_END


def test_chunking_does_not_change_a_bit(hh, orbits, full_map):
    # (No chunk of one orbit: it would run on the serial kernel, which gives
    # the same bits but costs a compilation.)
    for size in (2, 6, 7):
        _same(varint.chaos_map(hh, orbits, "sali", t_end=T_END, tau=TAU, chunk_size=size,
                               progress=False), full_map)


def test_early_stopping_skips_exactly_the_undecided_steps(hh, orbits, full_map):
    free = varint.chaos_map(hh, orbits, "sali", t_end=T_END, tau=TAU, threshold=None,
                            progress=False)
    decided = full_map.decided
    assert decided.sum() >= 2 and (free.status == 0).all()
    n_end = round(T_END / TAU)
    stop_steps = np.round(full_map.t_stop[decided] / TAU).astype(int)
    skipped = int(np.sum(n_end - stop_steps))
    assert skipped > 0
    assert full_map.provenance.counts["steps"] == free.provenance.counts["steps"] - skipped
    # Decided at a check time, at the first one below the threshold, with
    # the value the full run had there.
    for m in np.flatnonzero(decided)[:3]:
        W = initial_deviations(4, 2, 1, 0, [m])[0]
        run = varint.sali(hh, orbits[m], T_END, tau=TAU, deviations=W, t_out=full_map.t,
                          parallel=True)
        first = np.flatnonzero(run.sali < 1e-8)[0]
        assert full_map.t_stop[m] == pytest.approx(run.t[first])
        assert full_map.values[m] == run.sali[first]
    regular = ~decided
    assert np.array_equal(full_map.values[regular], free.values[regular])


def test_resumes_from_finished_chunks(hh, orbits, full_map, tmp_path, monkeypatch):
    calls = []
    original = cm.run_chunk

    def interrupt_third(*args):
        out = original(*args)
        calls.append(1)
        if len(calls) == 3:
            out.interrupted = True  # as after Ctrl-C inside the chunk's run
        return out

    monkeypatch.setattr(cm, "run_chunk", interrupt_third)
    with pytest.warns(RuntimeWarning, match="interrupted: 2 of 4 chunks"):
        part = varint.chaos_map(hh, orbits, "sali", t_end=T_END, tau=TAU, chunk_size=4,
                                checkpoint=tmp_path, progress=False)
    assert part.interrupted and np.isnan(part.values).sum() == len(orbits) - 8
    monkeypatch.setattr(cm, "run_chunk", original)
    calls.clear()
    counting = lambda *args: (calls.append(1), original(*args))[1]  # noqa: E731
    monkeypatch.setattr(cm, "run_chunk", counting)
    done = varint.chaos_map(hh, orbits, "sali", t_end=T_END, tau=TAU, chunk_size=4,
                            checkpoint=tmp_path, progress=False)
    assert len(calls) == 2 and done.provenance.options["chunks_resumed"] == 2
    _same(done, full_map)
    # A third call computes nothing.
    calls.clear()
    again = varint.chaos_map(hh, orbits, "sali", t_end=T_END, tau=TAU, chunk_size=4,
                             checkpoint=tmp_path, progress=False)
    assert not calls
    _same(again, full_map)


def test_checkpoint_of_other_parameters_is_refused(hh, orbits, tmp_path):
    varint.chaos_map(hh, orbits[:4], "sali", t_end=10.0, checkpoint=tmp_path, progress=False)
    with pytest.raises(varint.CheckpointError,
                       match=r"t_end \(checkpoint: 10.0, this call: 20.0\)"):
        varint.chaos_map(hh, orbits[:4], "sali", t_end=20.0, checkpoint=tmp_path,
                         progress=False)
    with pytest.raises(varint.CheckpointError, match="indicator"):
        varint.chaos_map(hh, orbits[:4], "x1", t_end=10.0, checkpoint=tmp_path, progress=False)
    assert json.loads((tmp_path / "map.json").read_text())["t_end"] == 10.0


def test_damaged_chunk_is_recomputed(hh, orbits, full_map, tmp_path):
    varint.chaos_map(hh, orbits, "sali", t_end=T_END, tau=TAU, chunk_size=4,
                     checkpoint=tmp_path, progress=False)
    path = tmp_path / "chunk_000001.npz"
    path.write_bytes(path.read_bytes()[:100])
    with pytest.warns(RuntimeWarning, match="chunk_000001.npz is unreadable"):
        r = varint.chaos_map(hh, orbits, "sali", t_end=T_END, tau=TAU, chunk_size=4,
                             checkpoint=tmp_path, progress=False)
    _same(r, full_map)


def test_section_grid_map(hh):
    grid = varint.section_grid(hh, 0.125, np.linspace(-0.45, 0.7, 9), np.linspace(-0.45, 0.45, 7))
    r = varint.chaos_map(hh, grid, "sali", t_end=20.0, progress=False)
    image = r.image()
    assert image.shape == (7, 9)
    assert np.isnan(image[~grid.mask]).all() and np.isfinite(image[grid.mask]).all()
    assert np.array_equal(r.x0, grid.states)


def test_failed_orbits_are_flagged_not_raised(hh):
    above = varint.solve_momentum(hh, [0.0, 0.0], [0.0, 0.0], 0.3)
    X = np.array([varint.paper_orbit("R1")[1], above])
    with pytest.warns(RuntimeWarning, match="1 of 2 orbits failed"):
        r = varint.chaos_map(hh, X, "sali", t_end=200.0, escape_radius=5.0, progress=False)
    assert r.status[1] == Status.ESCAPED and np.isnan(r.values[1]) and r.t_stop[1] < 200.0
    assert r.status[0] == 0 and np.isfinite(r.values[0])


@pytest.mark.parametrize("kwargs, match", [
    ({"indicator": "megnox"}, "unknown indicator 'megnox'; expected one of: .*sali"),
    ({"indicator": "gali_9"}, "GALI order k must be in 2..4"),
    ({"threshold": "low"}, "threshold must be a finite number"),
    ({"chunk_size": 0}, "chunk_size must be a positive integer"),
    ({"seed": -1}, "seed must be a non-negative integer"),
    ({"tau": -0.1}, "tau must be a positive finite number"),
])
def test_bad_arguments(hh, orbits, kwargs, match):
    args = {"indicator": "sali", "t_end": 1.0}
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        varint.chaos_map(hh, orbits[:2], progress=False, **args)


def test_a_single_state_is_refused(hh, orbits):
    with pytest.raises(ValueError, match=r"initial_conditions must have shape \(M, 2N\)"):
        varint.chaos_map(hh, orbits[0], t_end=1.0)


@pytest.fixture(scope="module")
def dask_client():
    distributed = pytest.importorskip("distributed")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                           dashboard_address=None)
        client = distributed.Client(cluster)
    yield client
    client.close()
    cluster.close()


def test_dask_cluster_gives_the_same_bits(hh, orbits, full_map, dask_client, tmp_path):
    r = varint.chaos_map(hh, orbits, "sali", t_end=T_END, tau=TAU, chunk_size=4,
                         client=dask_client, progress=False)
    _same(r, full_map)
    assert r.provenance.options["client"] == "dask (2 threads)"
    # Finished chunks of a distributed map resume locally, and vice versa.
    varint.chaos_map(hh, orbits, "sali", t_end=T_END, tau=TAU, chunk_size=4,
                     client=dask_client, checkpoint=tmp_path, progress=False)
    (tmp_path / "chunk_000000.npz").unlink()
    _same(varint.chaos_map(hh, orbits, "sali", t_end=T_END, tau=TAU, chunk_size=4,
                           checkpoint=tmp_path, progress=False), full_map)


def test_default_check_times_start_at_the_first_check_step(hh, orbits):
    """Checks of early stopping are log-spaced from FIRST_CHECK_STEP steps
    on (and the end): earlier ones cost more than they could save."""
    r = varint.chaos_map(hh, orbits[:3], "sali", t_end=200 * TAU, tau=TAU, progress=False)
    steps = np.round(r.t / TAU).astype(int)
    every = varint.state.output_steps(200 * TAU, TAU)
    assert steps.tolist() == every[every >= cm.FIRST_CHECK_STEP].tolist()
    assert steps[0] < 1.3 * cm.FIRST_CHECK_STEP and steps[-1] == 200
    short = varint.chaos_map(hh, orbits[:3], "sali", t_end=20 * TAU, tau=TAU, progress=False)
    assert np.round(short.t / TAU).astype(int).tolist() == [20]

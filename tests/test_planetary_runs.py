"""Planetary systems through the whole run machinery (method="tm" →
varint.methods.planetary): MEGNO against the heyoka reference and its laws,
the WHT corrector at outputs (energy error, its tangent as the derivative
of the processed map), bitwise chunking, resume and threads, failures,
and MEGNO stability maps over orbital elements."""

import math
import warnings

import numpy as np
import pytest

import varint
from varint.methods.planetary import MAPPED_STATE, PlanetaryPropagator
from varint.models import Planetary

from tests.helpers import assert_bitwise_equal

JUPITER = dict(a=5.204, M=0.600, omega=0.257, e=0.048)
WH10 = varint.get_scheme("SABA1").repeated(10)


@pytest.fixture(scope="module")
def jupiter_saturn():
    """Jupiter and a Saturn of Saturn's mass at (a, e): regular at
    (9.0, 0.05), chaotic at (7.86, 0.214) (as in REBOUND's MEGNO example)."""
    model = Planetary([1.0, 0.000954, 0.000285])

    def state(a, e):
        return model.from_elements([JUPITER, dict(a=a, e=e, M=0.871, omega=1.616)])

    return model, state


def test_tm_runs_the_wisdom_holman_map(jupiter_saturn):
    model, state = jupiter_saturn
    r = varint.megno(model, state(9.0, 0.05), 100.0, tau=1.0)
    assert r.provenance.method_options["scheme"]["name"] == "SABA1"
    assert r.provenance.method_options["stepper"] == "parts"
    assert r.provenance.method_options["corrector"] is None
    assert set(r.accuracy.conserved) == {"energy", "angular_momentum"}


def test_megno_of_a_regular_orbit_is_the_taylor_references(jupiter_saturn):
    """Ȳ → 2 on a torus (Cincotta & Simó 2000): at every output to 3e4 the
    WH map (10 steps of 1 per interval) gives heyoka's values (tol 1e-15)
    to 1e-3 (measured: the same to 4 decimals), and the last is 2 ± 0.05."""
    model, state = jupiter_saturn
    x0 = state(9.0, 0.05)
    wh = varint.megno(model, x0, 3e4, tau=10.0, scheme=WH10, t_out=6)
    ref = varint.megno(model, x0, 3e4, tau=10.0, method="taylor", t_out=6, tol=1e-15)
    assert np.max(np.abs(wh.megno - ref.megno)) < 1e-3
    assert abs(wh.megno[-1] - 2.0) < 0.05


def test_megno_of_a_chaotic_orbit_grows(jupiter_saturn):
    """Ȳ ≈ λt/2 on a chaotic orbit: past 10 by t = 1e4 and still growing
    (measured 22 → 69 from 1e4 to 3e4), as heyoka's (31 → 59)."""
    model, state = jupiter_saturn
    x0 = state(7.86, 0.214)
    wh = varint.megno(model, x0, 3e4, tau=10.0, scheme=WH10, t_out=[1e4, 3e4])
    ref = varint.megno(model, x0, 3e4, tau=10.0, method="taylor", t_out=[1e4, 3e4])
    for r in (wh, ref):
        assert r.megno[0] > 10 and r.megno[1] > 1.5 * r.megno[0]
    assert wh.accuracy.accurate


def test_corrector_at_outputs_cuts_the_run_energy_error():
    """ε = 1e-4, τ = T/32: the third-order corrector cuts the largest
    energy error over 200 orbits 40-fold (measured 4.4e-8 → 1.0e-9), the
    fifth-order one further (3.5e-11). Run as MEGNO (the orbit, hence the
    energy error, is that of a run without vectors): the one-orbit MEGNO
    kernel the other tests compile, not one of its own (~20 CPU s cold)."""
    model = Planetary([1.0, 1e-4, 3e-5])
    x0 = model.from_elements([dict(a=1.0, e=0.05), dict(a=1.6, e=0.02, M=2.0, inc=0.1)])
    tau = 2 * math.pi / 32
    t_end = 200 * 32 * tau
    errs = {c: np.max(varint.megno(model, x0, t_end, tau=tau, t_out=20,
                                   corrector=c).energy_error) for c in (None, 3, 5)}
    assert errs[3] < errs[None] / 20 and errs[5] < errs[3] / 5, errs


def test_processed_tangent_is_the_derivative_of_the_processed_map():
    """With renorm "none" the vectors are the tangent map of x₀ ↦ C(Wⁿ(C⁻¹(x₀))):
    fourth-order differences of the run's final state agree to 1e-7. The
    map is run one column at a time (one vector: the kernel
    test_planetary_lanes compiles, not one for twelve, ~20 CPU s cold)."""
    model = Planetary([1.0, 1e-3, 3e-4])
    x0 = model.from_elements([dict(a=1.0, e=0.05), dict(a=1.6, e=0.1, M=2.0, inc=0.1)])

    def final(x, w=0):
        # Always one vector, column w of the identity (the state does not
        # depend on it): one stepper for the map and its differences.
        r = varint.integrate(model, x, 20.0, tau=0.25, t_out=1, corrector=3,
                             deviations=np.eye(12)[:, w:w + 1],
                             scheme=varint.get_scheme("SABA1").repeated(2))
        return r.state, r.deviations

    M = np.hstack([final(x0, i)[1] for i in range(12)])
    fd = np.empty((12, 12))
    # Steps of 1e-5 of each coordinate's size: 1 for q, m′ for p = m′v.
    size = np.concatenate([np.ones(6), np.repeat(model.kepler_mass, 3)])
    for i in range(12):
        e = np.zeros(12)
        e[i] = 1e-5 * size[i]
        fd[:, i] = (8 * (final(x0 + e)[0] - final(x0 - e)[0])
                    - (final(x0 + 2 * e)[0] - final(x0 - 2 * e)[0])) / (12 * e[i])
    assert np.max(np.abs(M - fd)) <= 1e-7 * np.max(np.abs(M))


def test_corrected_runs_are_bitwise_across_chunks_threads_and_resume(tmp_path, monkeypatch):
    """Bitwise: outputs every interval or only at the end (other chunks),
    one thread or two, and a run crashed after its second chunk and
    resumed from its checkpoint."""
    model = Planetary([1.0, 1e-3, 3e-4])
    x0 = np.stack([model.from_elements([dict(a=1.0, e=0.05, M=m),
                                        dict(a=1.6, e=0.1, M=2.0, inc=0.1)]) for m in (0, 1, 2)])

    def run(**kw):
        return varint.megno(model, x0, 50.0, tau=0.5, corrector=3, **kw)

    reference = run(t_out=1)
    many = run(t_out=100)
    assert many.state.tobytes() == reference.state.tobytes()
    assert many.megno[:, -1].tobytes() == reference.megno[:, -1].tobytes()
    assert_bitwise_equal(run(t_out=1, parallel=False), run(t_out=1, parallel=True))

    class Crash(Exception):
        pass

    from varint import driver

    monkeypatch.setattr(driver, "_QUICK_CHUNK", 0.0)
    original = PlanetaryPropagator.advance
    calls = []

    def crashing(self, state, n):
        original(self, state, n)
        calls.append(n)
        if len(calls) == 2:
            raise Crash

    with monkeypatch.context() as patch:
        patch.setattr(PlanetaryPropagator, "advance", crashing)
        with pytest.raises(Crash):
            run(t_out=10, checkpoint=tmp_path / "c.ckpt", checkpoint_interval=0)
    from varint import checkpoint as ckpt

    saved = ckpt.read(tmp_path / "c.ckpt").state
    assert 0 < saved.step < 100 and MAPPED_STATE in saved.extra
    resumed = run(t_out=10, checkpoint=tmp_path / "c.ckpt", checkpoint_interval=0)
    assert_bitwise_equal(resumed, run(t_out=10))


def test_bad_corrector_options_are_refused(jupiter_saturn):
    model, state = jupiter_saturn
    x0 = state(9.0, 0.05)
    with pytest.raises(ValueError, match="one of 3, 5, 7, 11, 17, got 4"):
        varint.megno(model, x0, 10.0, tau=1.0, corrector=4)
    with pytest.raises(ValueError, match="not of scheme 'SABA2'"):
        varint.megno(model, x0, 10.0, tau=1.0, corrector=3, scheme="SABA2")
    dem = Planetary([1.0, 0.000954, 0.000285], coordinates="democratic")
    with pytest.raises(ValueError, match="need Jacobi coordinates"):
        varint.megno(dem, dem.from_cartesian(*model.to_cartesian(x0)), 10.0, tau=1.0,
                     corrector=3)
    with pytest.raises(TypeError, match="unknown option 'corrector'"):
        varint.megno(*varint.paper_orbit("R1"), 10.0, tau=0.05, corrector=3)


def test_unresolved_pericentres_are_warned_and_singular_starts_refused():
    """A step longer than a planet's pericentre passage time √(q³/μ(1+e))
    gets an AccuracyWarning naming the planet and both times;
    a planet on the star is refused before any work, by the gradient of
    U (the start check evaluates ∇U alone: Planetary.checked_kernels).
    (MEGNO runs: the
    kernel the other tests compile; the checks come before any kernel.)"""
    model = Planetary([1.0, 1e-3, 3e-4])
    x0 = model.from_elements([dict(a=1.0, e=0.9), dict(a=2.0, e=0.1, M=2.0)])
    with pytest.warns(varint.AccuracyWarning, match=r"planet 1 .*pericentre passage time "
                                                    r"0\.0229, .*step 0\.1:"):
        varint.megno(model, x0, 1.0, tau=0.1)
    with warnings.catch_warnings():
        warnings.simplefilter("error", varint.AccuracyWarning)
        varint.megno(model, x0, 1.0, tau=0.1, scheme=varint.get_scheme("SABA1").repeated(10))
    x0[0:3] = 0.0
    with pytest.raises(ValueError, match="not finite at the initial state.*the gradient"):
        varint.megno(model, x0, 1.0, tau=0.1)


def test_megno_stability_map_over_elements(jupiter_saturn):
    """A 4 × 3 map of Saturn's (a, e): the regular corner near 2, the
    chaotic one stopped early above the threshold; bitwise the same for any
    chunk size. One orbit at a time (``lanes=False``: the MEGNO kernel the
    other tests compile; that the SIMD lanes, the default, give the same
    bits is test_planetary_lanes's, which compiles them)."""
    model, _ = jupiter_saturn
    grid = varint.element_grid(model, [JUPITER, dict(a=9.0, e=0.05, M=0.871, omega=1.616)], 2,
                               [7.43, 7.86, 8.7, 9.0], [0.05, 0.143, 0.214])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = varint.chaos_map(model, grid, "megno", t_end=2e4, tau=10.0, scheme=WH10,
                             threshold=8.0, lanes=False)
        again = varint.chaos_map(model, grid, "megno", t_end=2e4, tau=10.0, scheme=WH10,
                                 threshold=8.0, chunk_size=5, lanes=False)
    image = r.image()
    assert image.shape == (3, 4)
    assert abs(image[0, 3] - 2.0) < 0.2                  # a = 9.0, e = 0.05
    assert image[2, 1] > 8.0 and r.t_stop[r.decided].max() < 2e4   # (7.86, 0.214)
    assert r.values.tobytes() == again.values.tobytes()


def test_megno_map_on_a_dask_cluster_is_bitwise_the_local_map(jupiter_saturn):
    """A large planetary grid goes to a Dask cluster like any map: the
    model pickles to the workers, chunks run there, and the values, stop
    times and statuses are the local map's bit for bit. (One orbit at a
    time, as the map above: the lanes are test_planetary_lanes's.)"""
    distributed = pytest.importorskip("distributed")
    model, _ = jupiter_saturn
    grid = varint.element_grid(model, [JUPITER, dict(a=9.0, e=0.05, M=0.871, omega=1.616)], 2,
                               [7.43, 7.86, 8.7, 9.0], [0.05, 0.214])
    args = dict(t_end=5e3, tau=10.0, scheme=WH10, threshold=8.0, progress=False, lanes=False)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        local = varint.chaos_map(model, grid, "megno", **args)
        # Threads, not processes: the workers share this process's
        # compiled kernels (the distribution, not the compile, is tested).
        with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                                      dashboard_address=None) as cluster, \
                distributed.Client(cluster) as client:
            remote = varint.chaos_map(model, grid, "megno", chunk_size=3, client=client, **args)
    assert remote.provenance.options["client"].startswith("dask")
    assert local.decided.any() and not local.decided.all()   # both kinds of point
    for name in ("values", "t_stop", "status"):
        assert getattr(remote, name).tobytes() == getattr(local, name).tobytes(), name


def test_close_encounters_stop_orbits():
    """Two planets 0.15 apart (2 mutual Hill radii of 0.076): with
    close_encounter = 3 the orbit stops with status CLOSE_ENCOUNTER at once
    (the other orbit of the batch, far apart, goes on); without it, it runs
    through. (MEGNO, one thread: the one-orbit kernel the other tests
    compile; the orbit and its status are those of a run without vectors.)"""
    els = [[dict(a=1.0, e=0.0), dict(a=1.02, e=0.0, M=0.15)],
           [dict(a=1.0, e=0.0), dict(a=3.0, e=0.0, M=2.0)]]
    for close, want in ((3.0, int(varint.Status.CLOSE_ENCOUNTER)), (None, 0)):
        model = Planetary([1.0, 1e-3, 3e-4], close_encounter=close)
        x0 = np.stack([model.from_elements(e) for e in els])
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            r = varint.megno(model, x0, 20.0, tau=0.05, t_out=4, errors="flag", parallel=False)
        assert r.status[0] == want and r.status[1] == 0
        if close:
            assert r.provenance.counts["steps"] < 500


def test_close_encounters_are_not_taken_for_escapes_in_a_map():
    """With an escape_radius (whose test the part stepper runs before the
    non-finite one) an encounter is still CLOSE_ENCOUNTER, and a real
    escape (a hyperbolic outer planet) still ESCAPED."""
    model = Planetary([1.0, 1e-3, 3e-4], close_encounter=3.0)
    X = np.stack([model.from_elements(e) for e in (
        [dict(a=1.0, e=0.0), dict(a=1.02, e=0.0, M=0.15)],
        [dict(a=1.0, e=0.0), dict(a=3.0, e=0.0, M=2.0)],
        [dict(a=1.0, e=0.0), dict(a=-3.0, e=1.5, f=0.0)])])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = varint.chaos_map(model, X, "megno", t_end=200.0, tau=0.5, escape_radius=8.0,
                             progress=False)
    assert r.status.tolist() == [int(varint.Status.CLOSE_ENCOUNTER), 0,
                                 int(varint.Status.ESCAPED)]

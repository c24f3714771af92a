"""Results carry their provenance and survive a save/load round trip."""

import numpy as np

import varint


def test_provenance_records_what_determines_the_run(c1):
    # The whole spectrum with ABA864: the kernel of the printed result below.
    model, x0 = c1
    r = varint.lyapunov_spectrum(model, x0, 20.0, tau=0.1, scheme="ABA864", seed=11)
    p = r.provenance
    assert p.kind == "lyapunov" and p.method == "tm"
    assert p.model["name"] == "HenonHeiles" and np.allclose(p.x0, x0)
    assert p.method_options["scheme"]["name"] == "ABA864"
    assert (p.tau, p.t_end, p.seed) == (0.1, 20.0, 11)
    assert {"python", "varint", "numpy", "scipy", "numba"} <= set(p.versions)
    assert p.counts["steps"] == 200 and p.counts["gradient"] >= 200 * 7
    assert p.wall_time > 0


def test_save_and_load_round_trip(tmp_path, r1):
    g = varint.gali(*r1, 30.0, k=(2, 4))
    g.save(tmp_path / "g.npz")
    h = varint.load_result(tmp_path / "g.npz")
    assert type(h) is varint.GALIResult
    assert np.array_equal(h.t, g.t) and set(h.gali) == {2, 4}
    assert np.array_equal(h.gali[4], g.gali[4])
    assert h.provenance == g.provenance
    i = varint.integrate(*r1, 10.0, t_out=5, deviations=np.eye(4)[:, :1])
    i.save(tmp_path / "i.npz")
    j = varint.load_result(tmp_path / "i.npz")
    assert np.array_equal(j.states, i.states) and np.array_equal(j.deviations, i.deviations)


def test_output_times(c1):
    model, x0 = c1
    r = varint.integrate(model, x0, 1.0, tau=0.1, t_out=[0.3, 0.5, 1.0])
    assert np.allclose(r.t, [0.3, 0.5, 1.0]) and r.states.shape == (3, 4)
    # Default for indicators: log-spaced, ~10 per decade, ending at t_end.
    lce = varint.lyapunov_spectrum(model, x0, 100.0, tau=0.1)
    assert lce.t[-1] == 100.0 and 25 <= len(lce.t) <= 35
    assert np.all(np.diff(np.log(lce.t)) > 0)
    # Only the final time for integrate by default.
    assert varint.integrate(model, x0, 1.0, tau=0.1).t.tolist() == [1.0]


# -- what a result says when printed (issue 32, item 8) ------------------------------------


def test_a_printed_result_is_a_summary_not_its_arrays(r1):
    """repr names the model, method, scheme, τ and time range, gives the
    headline values read off the arrays and the verdict, and lists the
    fields: a few hundred characters, not kilobytes of arrays."""
    model, x0 = r1
    r = varint.lyapunov_spectrum(model, x0, 200.0, tau=0.05, scheme="ABA864")
    text = repr(r)
    assert len(text) < 800, text
    assert "HenonHeiles" in text and "tm (ABA864)" in text and "tau=0.05" in text
    assert f"t = {r.t[0]:g} … 200" in text
    for i in range(4):
        assert f"X{i + 1} = {r.exponents[-1, i]:.4g}" in text
    assert r.accuracy.verdict in text and "exponents (" in text
    g = varint.gali(model, x0, 50.0, tau=0.05, k=(2, 4))
    assert f"GALI_4 = {g.gali[4][-1]:.4g}" in repr(g)
    # A batch: the median and range over its orbits.
    s = varint.sali(model, np.array([x0, x0 * 0.95]), 50.0, tau=0.05)
    last = s.sali[:, -1]
    assert f"SALI = {np.median(last):.4g} (median of 2; {last.min():.3g} … {last.max():.3g})" \
        in repr(s)
    assert "2 orbits" in repr(s)


def test_every_result_class_prints_its_summary(r1):
    """Every registered result class uses the summary repr, also those
    defined in other modules (local exponents, ensembles)."""
    # Their modules load on demand: import them, so that the test does not
    # depend on which tests ran before it.
    import varint.ensemble  # noqa: F401
    import varint.indicators.local_exponents  # noqa: F401
    from varint.results import _CLASSES, _Result

    assert {"LocalExponentsResult", "EnsembleResult", "ChaosMapResult"} <= set(_CLASSES)
    for cls in _CLASSES.values():
        assert cls.__repr__ is _Result.__repr__, cls.__name__


def test_a_map_models_verdict_is_no_verdict():
    """A symplectic map has no energy: its result says so instead of
    'relative energy error 0' (README: a map's energy error is no verdict)."""
    from varint.accuracy import NO_MAP_VERDICT

    sm = varint.models.StandardMap(1.2)
    r = varint.run(sm, [1.0, 0.5], "x1", 50.0)
    assert r.accuracy.verdict == NO_MAP_VERDICT and "energy error 0" not in repr(r)
    grid = varint.phase_grid(sm, np.linspace(0.1, 6, 3), np.linspace(-3, 3, 2))
    m = varint.chaos_map(sm, grid, "sali", t_end=20.0)
    assert m.accuracy.verdict == NO_MAP_VERDICT
    # It survives a save and load.
    import io

    buffer = io.BytesIO()
    r.save(buffer)
    assert varint.load_result(io.BytesIO(buffer.getvalue())).accuracy.verdict == NO_MAP_VERDICT


def test_a_tdh_verdict_says_it_checks_the_orbit_only(r1):
    """TDHcc's X1 is off by its own tangent error while the orbit's energy
    is accurate: the verdict must say what it does not check."""
    model, x0 = r1
    tdh = varint.run(model, x0, "x1", 2000.0, tau=0.05, method="tdhcc")
    # The whole spectrum, whose X1 is the same vector's: the kernel of the
    # printed result above.
    tm = varint.run(model, x0, "lyapunov", 2000.0, tau=0.05, scheme="ABA864")
    assert tdh.accuracy.accurate and tdh.accuracy.energy_error < 1e-6
    assert abs(tdh.exponents[-1, 0] / tm.exponents[-1, 0] - 1) > 0.05   # X1 far off
    assert "checks the orbit only" in tdh.accuracy.verdict
    assert "checks the orbit only" not in tm.accuracy.verdict


def test_accuracy_warnings_point_at_the_users_line(r1):
    """An AccuracyWarning names the caller's file and line, whatever the
    depth of varint's own frames (issue 32: it named varint/api.py)."""
    import inspect
    import warnings

    model, x0 = r1
    # One indicator (X1), one orbit: the three entry points share one kernel.
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        line = inspect.currentframe().f_lineno + 1
        varint.lyapunov_spectrum(model, x0, 100.0, tau=0.6, scheme="SABA1", n_exponents=1)
        varint.run(model, x0, "x1", 100.0, tau=0.6, scheme="SABA1")
        grid = varint.section_grid(model, 0.125, [0.0], [0.0])
        varint.chaos_map(model, grid, "x1", t_end=100.0, tau=0.6, scheme="SABA1")
    accuracy = [w for w in caught if issubclass(w.category, varint.AccuracyWarning)]
    assert len(accuracy) == 3
    assert [(w.filename, w.lineno) for w in accuracy] == [
        (__file__, line), (__file__, line + 1), (__file__, line + 3)]

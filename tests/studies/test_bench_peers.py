"""The peers benchmark: its classification rule, its cost–error
interpolation, the reference loops it races (the same algorithm as varint's,
the same equations as heyoka's own), and the quick run's tables — never its
timings."""

import json
import math
from types import SimpleNamespace

import numpy as np
import pytest

import varint
from studies import bench_peers as bp
from studies.bench_chaos_map import section


def test_antimode_is_the_valley_between_two_modes():
    """Two log-normal clusters at 5 and 60 (FLI-like), 1000 orbits each:
    the threshold lies in the empty decade between them, and with a
    single cluster Otsu's threshold is used instead."""
    rng = np.random.default_rng(1)
    values = np.concatenate([10 ** rng.normal(np.log10(5), 0.05, 1000),
                             10 ** rng.normal(np.log10(60), 0.05, 1000)])
    threshold, rule = bp.antimode(values)
    assert rule == "antimode"
    assert 8 < threshold < 35
    assert np.mean(values > threshold) == 0.5
    _, rule = bp.antimode(10 ** rng.normal(0.0, 0.1, 500))
    assert rule == "Otsu"


def test_agreement_counts_failed_orbits_as_disagreeing():
    ref = np.array([True, False, True, False])
    values = np.array([2e-9, 0.5, np.nan, 1e-12])  # SALI: chaotic below 1e-8
    assert bp.agreement("sali", values, ref, 1e-8) == 0.25 * 2
    assert bp.agreement("fli", np.array([20.0, 3.0, 30.0, 2.0]), ref, 10.0) == 1.0


def test_cost_at_interpolates_a_power_law_exactly():
    """On cost = error^(-1/4) (a 4th-order method) log–log interpolation is
    exact; the front drops points beaten by cheaper ones; outside its
    range the cost is bounded or unreachable."""
    pts = [(e ** -0.25, e) for e in (1e-4, 1e-8, 1e-12)] + [(1e4, 1e-6)]
    front = bp.pareto(pts)
    assert [e for _, e in front] == [1e-4, 1e-8, 1e-12]
    cost, how = bp.cost_at(front, 1e-10)
    assert how == "interpolated" and math.isclose(cost, 1e-10 ** -0.25, rel_tol=1e-12)
    assert bp.cost_at(front, 1e-2) == (front[0][0], "at most")
    assert bp.cost_at(front, 1e-14) == (None, "unreachable")


def test_equal_quality_picks_the_fastest_heyoka_at_least_as_good():
    """varint (98 %) against heyoka batch 8 tol 1e-6 (97 %, 4× faster) and
    tol 1e-9 (99 %, 3× faster) and 1e-15 (100 %, slower): the target ratio
    uses tol 1e-6, the equal-quality ratio the fastest run at ≥ 98 %."""
    rows = [{"indicator": "fli", "peer": "varint", "config": "defaults", "orbits_per_s": 100.0,
             "agreement": 0.98}]
    rows += [{"indicator": "fli", "peer": "heyoka", "config": f"hand, batch 8, tol {tol:g}",
              "orbits_per_s": rate, "agreement": agree}
             for tol, rate, agree in ((1e-6, 400.0, 0.97), (1e-9, 300.0, 0.99),
                                      (1e-15, 50.0, 1.0))]
    (eq,) = bp.equal_quality(rows)
    assert eq["varint_over_hy_b8_1e6"] == 0.25 and eq["hy_b8_1e6_agreement"] == 0.97
    assert eq["heyoka_equal"] == "hand, batch 8, tol 1e-09"
    assert math.isclose(eq["varint_over_heyoka_equal"], 1 / 3)
    rows[0]["agreement"] = 1.0 + 1e-9  # no heyoka run is as good
    assert bp.equal_quality(rows)[0]["varint_over_heyoka_equal"] is None


@pytest.fixture(scope="module")
def orbits():
    model = varint.models.HenonHeiles()
    grid = section(model, 6)
    return model, grid, bp.seeded_vectors(4, 1, len(grid.states))


@pytest.mark.slow
def test_compiled_limit_is_varints_algorithm(orbits):
    """The plain SoA loop runs SBAB2C with its corrector as varint does: on
    the regular orbits (FLI < 8 at t = 100, where round-off is not
    amplified exponentially) FLI and MEGNO agree to 1e-8."""
    model, grid, W = orbits
    t_end, tau = 100.0, 0.05
    fli, megno = bp.soa_fli_megno(grid.states.T.copy(), W[:, :, 0].T.copy(),
                                  *bp.stage_tables(varint.get_scheme("SBAB2C"), tau),
                                  round(t_end / tau), tau, 4)
    v_fli = varint.chaos_map(model, grid, "fli", t_end=t_end, tau=tau, scheme="SBAB2C",
                             progress=False).values
    v_megno = varint.chaos_map(model, grid, "megno", t_end=t_end, tau=tau, scheme="SBAB2C",
                               progress=False).values
    regular = v_fli < 8
    assert regular.sum() >= 5
    np.testing.assert_allclose(fli[regular], v_fli[regular], atol=1e-8)
    np.testing.assert_allclose(megno[regular], v_megno[regular], atol=1e-8)


def test_heyoka_hand_written_and_derived_systems_agree(orbits):
    """The hand-written tangent system and heyoka's var_ode_sys are the
    same equations: at tol 1e-15 with the same checks their FLI and MEGNO
    agree to 1e-8 on regular orbits, and the MEGNO integrals give Ȳ within
    1 % of varint's on them at the paper's τ = 0.05 (varint averages on
    the τ grid, so the map's default step, ~0.7, is too coarse a grid for
    a 1 % comparison at t = 100)."""
    model, grid, W = orbits
    t_end = 100.0
    values = {}
    for ind in ("fli", "megno"):
        for system, batch in (("hand", 8), ("var_ode_sys", 4)):
            values[ind, system] = bp.HeyokaMap(model, ind, system, batch, 1e-15).run(
                grid.states, W, t_end)
    regular = values["fli", "hand"] < 8
    for ind in ("fli", "megno"):
        np.testing.assert_allclose(values[ind, "hand"][regular],
                                   values[ind, "var_ode_sys"][regular], atol=1e-8)
    v = varint.chaos_map(model, grid, "megno", t_end=t_end, scheme="SBAB2C", tau=0.05,
                         progress=False).values
    np.testing.assert_allclose(values["megno", "hand"][regular], v[regular], rtol=1e-2)


def _table_rows(markdown, title):
    """The data rows of the Markdown table whose title starts with ``title``."""
    lines = markdown.splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith("### " + title))
    assert lines[start + 1] == "" and lines[start + 2].startswith("| ")
    assert set(lines[start + 3]) <= set("|:-")  # the alignment row
    rows = []
    for line in lines[start + 4:]:
        if not line.startswith("|"):
            break
        rows.append(line)
    return rows


@pytest.mark.slow
def test_quick_run_tables(tmp_path):
    """The quick run, every case: each map table has varint (defaults and
    SBAB2C), heyoka on both systems at every batch and tolerance, the
    compiled limit where it applies, and an agreement for each; the spectra,
    orbit and FPU tables have their errors and ratios; the Markdown tables
    have one line per row; the files exist."""
    res = bp.main(["--quick", "--out", str(tmp_path)])
    text = (tmp_path / "bench_peers.md").read_text()
    maps = res["maps"]
    for ind in bp.INDICATORS:
        rows = [r for r in maps["rows"] if r["indicator"] == ind]
        peers = [r["peer"] for r in rows]
        assert peers.count("varint") == 2
        assert peers.count("heyoka") == 2 * len(bp.MAP_BATCHES) * 2  # quick: two tolerances
        assert peers.count("numba") == (ind != "sali")
        for r in rows:
            assert 0.0 <= r["agreement"] <= 1.0 and r["orbits_per_s"] > 0
            assert r["orbits_per_s_2_threads"] is None or r["orbits_per_s_2_threads"] > 0
        assert maps["thresholds"][ind]["rule"] in ("fixed", "antimode", "Otsu")
        assert len(_table_rows(text, f"{ind.upper()} map")) == len(rows)
        # The reference's own integrator (hand-written, batch 8, tol 1e-15)
        # checked every 10 instead of every time unit classifies alike.
        same = next(r for r in rows if r["config"] == "hand, batch 8, tol 1e-15")
        assert same["agreement"] >= 0.9
    assert [e["indicator"] for e in maps["equal_quality"]] == list(bp.INDICATORS)
    assert all(e["varint_over_hy_b8_1e6"] > 0 for e in maps["equal_quality"])
    assert len(_table_rows(text, "Maps, varint's defaults")) == len(bp.INDICATORS)
    assert {r["driving"] for r in maps["variants"]} >= {
        "no normalising, ensemble_propagate_until_batch"}
    for name, sp in res["spectra"].items():
        assert {r["peer"] for r in sp["rows"]} == {"varint", "heyoka"}
        assert all(np.isfinite(r["X1_error"]) for r in sp["rows"])
        assert sp["equal_error"]
        assert len(_table_rows(text, f"Spectrum {name}")) == len(sp["rows"])
    orbit = res["orbit"]
    assert {r["peer"] for r in orbit["rows"]} >= {"varint", "heyoka"}
    c = [r for r in orbit["rows"] if r["peer"] == "C"]
    if c:  # the C loop is the same algorithm: the same energy error
        assert math.isclose(c[0]["energy_error"], orbit["rows"][0]["energy_error"], rel_tol=1e-3)
    for r in res["fpu"]["rows"]:  # the numba loop is varint's algorithm
        assert math.isclose(r["X1_numba"], r["X1_varint"], rel_tol=1e-6)
    assert res["fpu"]["heyoka"]
    for name in ("bench_peers.md", "bench_peers.json", "bench_peers_maps.csv",
                 "bench_peers_spectra.csv", "bench_peers_orbit.csv", "bench_peers_fpu.csv"):
        assert (tmp_path / name).exists()
    assert json.loads((tmp_path / "bench_peers.json").read_text())["quick"] is True


@pytest.mark.slow
def test_map_agreement_is_measured_against_the_reference(monkeypatch):
    """With the reference's classes inverted, every contender's agreement
    becomes one minus its agreement with the true reference (all orbits of
    the section are bounded, so every value is finite): the column compares
    each contender with the reference, not with itself or a constant."""
    monkeypatch.setattr(bp, "MAP_BATCHES", (8,))
    monkeypatch.setattr(bp, "map_variants", lambda *a, **k: [])
    args = (True, 1, False, ("fli",), 8, False)
    true = bp.maps_case(*args)
    reference = bp.map_reference

    def inverted(*a, **k):
        classes, thresholds = reference(*a, **k)
        return {ind: ~c for ind, c in classes.items()}, thresholds

    monkeypatch.setattr(bp, "map_reference", inverted)
    flipped = bp.maps_case(*args)
    assert 0.0 < true["chaotic_fraction"]["fli"] < 1.0
    assert [r["config"] for r in true["rows"]] == [r["config"] for r in flipped["rows"]]
    assert len(true["rows"]) == 2 + 2 * 2 + 1  # varint ×2, heyoka 2 systems × 2 tols, numba
    for a, b in zip(true["rows"], flipped["rows"], strict=True):
        assert a["agreement"] + b["agreement"] == pytest.approx(1.0)
        assert a["agreement"] >= 0.9  # every contender classifies these orbits well


@pytest.mark.slow
def test_r1_error_is_measured_against_the_reference(monkeypatch):
    """The |ΔX1| column is the distance to the extended-precision reference:
    the accurate runs are within 1e-8 of it, and with the reference's X1
    moved by δ = 1e-3 every error moves to δ within the run's true error
    (triangle inequality)."""
    true = bp.spectra_case(True, 1, ("R1",))["R1"]
    assert min(r["X1_error"] for r in true["rows"]) < 1e-8
    assert all(r["X1_error"] < 1e-5 for r in true["rows"])
    delta, reference = 1e-3, bp.reference

    def moved(*a, **k):
        ref = reference(*a, **k)
        return SimpleNamespace(t=ref.t, exponents=ref.exponents + delta)

    monkeypatch.setattr(bp, "reference", moved)
    shifted = bp.spectra_case(True, 1, ("R1",))["R1"]
    assert shifted["X1_ref"] == pytest.approx(true["X1_ref"] + delta, abs=1e-15)
    for a, b in zip(true["rows"], shifted["rows"], strict=True):
        assert a["config"] == b["config"]
        assert abs(b["X1_error"] - delta) <= a["X1_error"] + 1e-12


@pytest.mark.slow
def test_pynamicalsys_absent_is_skipped_with_a_message(monkeypatch, capsys):
    monkeypatch.setitem(__import__("sys").modules, "pynamicalsys", None)
    monkeypatch.setattr(bp, "MAP_BATCHES", (8,))
    res = bp.maps_case(True, 1, True, ("sali",), 6, False)
    assert "pynamicalsys is not installed" in capsys.readouterr().out
    assert all(r["peer"] != "pynamicalsys" for r in res["rows"])


@pytest.mark.slow
def test_c1_accuracy_is_the_reference_distribution(monkeypatch):
    """On the chaotic orbit a contender reaches reference accuracy when its
    X1 over 64 nearby orbits has the reference integrator's distribution:
    some contenders do; with the reference's sample moved by 0.05 (its
    median is ~0.05) none does, and nothing is compared at equal accuracy."""
    true = bp.spectra_case(True, 1, ("C1",))["C1"]
    assert any(r["same_law"] for r in true["rows"]) and true["equal_error"]
    assert true["reference_sample"]["n"] == 64
    sample = bp.reference_sample
    monkeypatch.setattr(bp, "reference_sample", lambda *a, **k: sample(*a, **k) + 0.05)
    moved = bp.spectra_case(True, 1, ("C1",))["C1"]
    assert not any(r["same_law"] for r in moved["rows"]) and not moved["equal_error"]


def test_the_fpu_reference_loop_is_varints_map():
    """The plain loop the FPU case races (four arrays, the previous bond's
    force carried along the sites) computes the same map as varint's
    ABA864 step with one vector normalised every step: the same orbit,
    vector and X1 to round-off. A chain of 64 sites, as the race's own
    sizes beyond 8 are: varint's generic stepper (no stepper generated for
    a chain this long), the kernel the study's larger chains run."""
    n, tau, steps = 64, 0.05, 200
    model, x0 = varint.models.FPUBeta(n, 1.5), bp.fpu_state(n)
    w0 = bp.seeded_vectors(2 * n, 1, 1, seed=0)[0]
    kinds, h, _ = bp.stage_tables(varint.get_scheme("ABA864"), tau)
    x, w = x0.copy(), w0[:, 0].copy()
    x1 = bp.fpu_tangent(x, w, 1.5, kinds, h, steps) / (steps * tau)
    r = varint.lyapunov_spectrum(model, x0, steps * tau, tau=tau, n_exponents=1,
                                 scheme="ABA864", deviations=w0, t_out=1, progress=False)
    assert np.max(np.abs(r.state - x)) < 1e-13
    assert np.max(np.abs(r.deviations[:, 0] - w)) < 1e-11
    assert abs(r.exponents[-1, 0] - x1) < 1e-12 * abs(x1) + 1e-15

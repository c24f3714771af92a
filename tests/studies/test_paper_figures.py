"""Figs. 2–11 in quick mode (R1, C1, C2, R2 to t = 1e4, R3 to 1e3): every
figure and claims file is written, and the laws that already show at these
horizons hold."""

import json

import numpy as np
import pytest

from studies import laws, paper_figures

FIGURES = ("fig02_r1_lyapunov", "fig03_r1_step_sizes", "fig04_r1_gali", "fig05_c1",
           "fig07_c2_lyapunov", "fig08_c2_gali", "fig09_r2_lyapunov",
           "fig10_r2_gali", "fig11_r3_gali")


@pytest.fixture(scope="module")
def quick(figures_quick, paper_quick_dir):
    ctx = paper_figures.Context(paper_quick_dir, quick=True, fresh=False)
    return figures_quick["claims"], ctx


def claim(claims, group, start):
    return next(c for c in claims[group] if c["claim"].startswith(start))


def test_every_figure_with_its_claims(quick, paper_quick_dir):
    claims, _ = quick
    for name in FIGURES:
        assert (paper_quick_dir / f"{name}.png").exists(), name
    for n in (2, 3, 4, 5, 7, 8, 9, 10, 11):  # Fig. 6: studies/sections.py
        saved = json.loads((paper_quick_dir / f"paper_fig{n:02d}.claims.json").read_text())
        assert saved, n
        for c in saved:
            assert set(c) >= {"claim", "paper", "ours", "holds", "figure", "rules"}
            assert (paper_quick_dir / c["figure"]).exists(), c["claim"]
            # Every verdict names its rules; every difference its reason.
            assert c["holds"] is None or c["rules"], c["claim"]
            assert c["holds"] is not False or c["note"], c["claim"]
    assert sum(len(v) for v in claims.values()) >= 30


def test_dop853_claims_say_how_far_they_were_checked(quick):
    claims, _ = quick
    c = claim(claims, "fig2", "R1, DOP853: X1, X2 ∝ 1/t")
    assert c["checked_to"] == paper_figures.DOP853_T_END["R1"][1] and c["horizon"] == 1e8
    assert claim(claims, "fig10", "R2, DOP853: GALI_k")["checked_to"] < 1e6


def test_claims_that_hold_at_the_quick_horizon(quick):
    claims, _ = quick
    assert claim(claims, "fig3", "R1, DOP853: the X1 curves for τ = 0.05 and 0.1")["holds"]
    assert claim(claims, "fig4", "R1, TM: GALI_k follow the regular laws")["holds"]
    assert claim(claims, "fig4", "R1, TDHcc: GALIs follow the laws to t ≈ 1e+04")["holds"]
    assert claim(claims, "fig5", "C1, TM: GALIs decay exponentially")["holds"]
    # Claims about t = 1e8 are not judged at t = 1e4.
    assert claim(claims, "fig7", "C2, TM: χ1 ≈ 4e-6")["holds"] is None
    assert claim(claims, "fig2", "R1: TDHeps is the best")["holds"] is None


def test_tdh_methods_leave_the_regular_law_on_r1(quick):
    _, ctx = quick
    tm = ctx.lyap("R1", "tm")
    for m in ("tdhcc", "tdhes"):
        dep, _ = paper_figures.stretch_departure(ctx.lyap("R1", m), tm)
        assert dep.holds and dep.value < 1e4, m


def test_the_longest_stored_dop853_run_is_used(quick, tmp_path):
    """The longest stored DOP853 run (C2's to 1e8 once run, else a shorter
    one, whose claims say how far they were checked); without any, the
    paper's horizon; --dop853-t-end asks for one; in quick mode the quick
    default stays."""
    _, ctx = quick
    runs = tmp_path / "runs"
    runs.mkdir()
    key = "lyapunov-C2-dop853-delta1e-05-tau0.05-t"
    full = paper_figures.Context(tmp_path, quick=False, fresh=False)
    assert full.horizon("lyapunov", "C2", "dop853") == paper_figures.DOP853_T_END["C2"][0]
    for ext in ("npz", "json"):
        (runs / f"{key}100000.{ext}").write_text("")
    assert full.horizon("lyapunov", "C2", "dop853", delta=1e-5) == 1e5
    for ext in ("npz", "json"):
        (runs / f"{key}1e+08.{ext}").write_text("")
    assert full.horizon("lyapunov", "C2", "dop853", delta=1e-5) == 1e8
    asked = paper_figures.Context(tmp_path, quick=False, fresh=False, dop853_t_end=3e8)
    assert asked.horizon("lyapunov", "C2", "dop853", delta=1e-5) == 3e8
    assert full.horizon("gali", "C2", "dop853") == paper_figures.DOP853_T_END["C2"][0]
    assert ctx.horizon("lyapunov", "C2", "dop853") == paper_figures.DOP853_T_END["C2"][1]


@pytest.mark.parametrize("orbit", ["R1", "C1"])
def test_tm_spectrum_sums_to_zero(quick, orbit):
    # The tangent map of a symplectic scheme has determinant 1, so
    # Σ X_i = 0 to round-off and, for N = 2, |X1 + X4| = |X2 + X3|.
    _, ctx = quick
    r = ctx.lyap(orbit, "tm")
    late = r.t >= 100
    assert np.max(np.abs(r.exponents[late].sum(axis=1))) < 1e-12


def test_low_gali_of_the_fpu_torus_stay_constant(quick):
    # R3 lies on a 4-torus: GALI_2..4 ≈ const (Skokos et al. 2008).
    _, ctx = quick
    r = ctx.gali("R3", "tm", tau=paper_figures.R3_TAU)
    for k in (2, 3, 4):
        assert abs(laws.slope(r.t, r.gali[k], 10.0)) < 0.1, k
        assert r.gali[k][-1] > 0.1, k

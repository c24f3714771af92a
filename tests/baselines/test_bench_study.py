"""The baselines benchmarks run in quick mode, and their figures support
the design choices of baselines.blocks and the compiled DOP853 engine
(timings are not asserted: the machine is shared)."""

from studies import bench_baselines, bench_dop853


def test_bench_baselines_quick(tmp_path):
    res = bench_baselines.main(["--quick", "--out", str(tmp_path)])
    rows = {(r["config"], r["k"]): r for r in res["methods"]}
    for k in (1, 4):
        # Blocks: CVODE is more accurate than restarting every τ, heyoka
        # stays at round-off either way.
        assert (rows["cvode 1e-10, blocks of 10 tu", k]["orbit_error"]
                < rows["cvode 1e-10, restart every tau", k]["orbit_error"])
        assert rows["taylor double, blocks of 5 tu", k]["orbit_error"] < 1e-13
        # DOP853 restarted every τ = 0.05 is at round-off for either δ.
        assert rows["dop853 delta=1e-5", k]["orbit_error"] < 1e-13
    assert {r["system"] for r in res["kvec"]} == {"k columns", "full 2N x 2N"}
    assert (tmp_path / "bench_baselines.claims.json").exists()
    assert (tmp_path / "bench_baselines.csv").exists()


def test_bench_dop853_quick(tmp_path):
    """The DOP853 speed study runs; both engines do the same work per unit
    time (up to the initial-step selection, spread over different
    horizons)."""
    res = bench_dop853.main(["--quick", "--out", str(tmp_path)])
    rows = {(r["config"], r["tau"]): r for r in res["rows"]}
    for tau in (0.05, 0.5):
        compiled, scipy = rows["dop853 compiled", tau], rows["dop853 scipy", tau]
        assert abs(compiled["evals_per_tu"] / scipy["evals_per_tu"] - 1) < 0.01
    assert all(v > 0 for v in res["ratios"].values())
    assert (tmp_path / "bench_dop853.csv").exists()

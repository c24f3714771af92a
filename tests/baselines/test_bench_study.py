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


def test_bench_libraries_quick(tmp_path):
    """Each baseline and its library driven directly solve the same problem:
    at the same tolerance CVODE's orbit errors are of the same order (within
    10×: where steps and restarts fall moves them) and fall with it, heyoka
    is at round-off either way, DOP853 restarted every τ stays at round-off
    while SciPy over the whole span at δ = 1e-5 does not, and the exponents
    from one QR of every raw output are those of one QR of the final vectors
    (the R factors telescope)."""
    from studies import bench_libraries
    from studies.claims import ROUNDOFF_ERROR

    res = bench_libraries.main(["--quick", "--out", str(tmp_path)])
    rows = {(r["orbit"], r["k"], r["contender"]): r for r in res["rows"]}
    for orbit in ("R1", "C1"):
        for k in (1, 4):
            def err(label, orbit=orbit, k=k):
                return rows[orbit, k, label]["orbit_error"]
            for tol in ("1e-08", "1e-10", "1e-12"):
                ours, theirs = err(f"cvode (varint) tol={tol}"), err(f"scikit-sundae tol={tol} directly")
                assert theirs / 10 <= ours <= 10 * theirs
            assert err("cvode (varint) tol=1e-12") < err("cvode (varint) tol=1e-08")
            assert max(err("taylor (varint)"), err("heyoka directly")) <= ROUNDOFF_ERROR
            assert err("dop853 (varint) δ=1e-5") <= ROUNDOFF_ERROR < err("SciPy δ=1e-05 directly")
            for lib in ("scikit-sundae tol=1e-10", "heyoka", "SciPy δ=1e-08"):
                every = rows[orbit, k, f"{lib} directly"]
                final = rows[orbit, k, f"{lib} directly, final QR only"]
                assert every["orbit_error"] == final["orbit_error"]
                assert abs(every["X_error"] - final["X_error"]) <= 1e-12
    claims = (tmp_path / "bench_libraries.claims.json").read_text()
    assert "driven directly" in claims

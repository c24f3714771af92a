"""The sections study (the paper's Figs. 1 and 6) in quick mode, and the
chaos-map benchmark's quick mode (slow: it times Python loops)."""

import pytest

from studies import bench_chaos_map, sections


def test_sections_quick(tmp_path):
    res = sections.main(["--quick", "--out", str(tmp_path)])
    assert res["r1_curves"] == 5
    assert res["max_abs_x"] < 1e-15
    assert res["coverage"]["C1"] > 10 * res["coverage"]["R1"]
    assert res["sali_r1"] > 1e-2 and res["sali_c1"] < 1e-8
    assert all(c["holds"] is not False for c in res["claims"])
    for name in ("sections.claims.json", "sections_fig1.png", "sections_fig6.png",
                 "sections_sali_map.png"):
        assert (tmp_path / name).exists()


@pytest.mark.slow
def test_bench_chaos_map_quick(tmp_path):
    res = bench_chaos_map.main(["--quick", "--out", str(tmp_path)])
    rows = {r["method"]: r for r in res["rows"]}
    assert rows["varint, early stopping"]["steps"] < rows["varint, no early stopping"]["steps"]
    assert all(r["agree_with_map"] >= 0.75 for r in res["rows"])
    assert (tmp_path / "bench_chaos_map.claims.json").exists()

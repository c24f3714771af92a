"""The TDH benchmark's quick mode runs and measures every method."""

import pytest

from studies import bench_tdh


@pytest.mark.slow
def test_bench_tdh_quick(tmp_path):
    rows = bench_tdh.main(["--quick", "--out", str(tmp_path)])["rows"]
    assert [r["method"] for r in rows] == ["tm", "tdhcc", "tdhes", "tdhes analytic", "tdheps",
                                          "tdheps SBAB1", "tm adaptive"]
    assert rows[0]["vs_tm"] == 1.0 and all(r["ns_per_interval"] > 0 for r in rows)
    assert (tmp_path / "bench_tdh.csv").exists()

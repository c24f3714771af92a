"""The bar race's time split in quick mode: the regular orbit never leaves
the bar, the chaotic one does, and each part of the split is there."""

from studies import bar_time_split


def test_bar_time_split_quick(tmp_path):
    out = bar_time_split.main(["--quick", "--out", str(tmp_path)])
    assert out["regular"]["fraction_outside"] == 0.0
    assert out["regular"]["lambda_outside"] is None
    assert set(out["regular"]["kick_ns"]) == {"inside"}
    chaotic = out["chaotic"]
    assert 0.05 < chaotic["fraction_outside"] < 0.95
    low, median, high = chaotic["lambda_outside"]
    assert 0 < low <= median <= high
    assert set(chaotic["kick_ns"]) == {"inside", "outside"}
    assert set(chaotic["call_ms"]) == {"t_end", "one_step", "steps"}
    assert (tmp_path / "bar_time_split.json").exists()

"""The checkpoint-cost study's quick mode: a checkpoint is its arrays plus a
small constant, and the default interval writes only at start and end."""

from studies import checkpoint_cost


def test_checkpoint_cost_quick(tmp_path):
    res = checkpoint_cost.main(["--quick", "--out", str(tmp_path)])
    for row in res["files"]:
        assert 0 < row["file_bytes"] - row["array_bytes"] < 16_000, row["case"]
    writes = {r["checkpoints"]: r["writes"] for r in res["overhead"]}
    assert writes["none"] == 0 and writes["default (60 s)"] == 2  # at start and at the end
    # Chunks last about CHUNK_SECONDS each (outputs inside a chunk cost no
    # extra call), so a quick run has a few.
    assert writes["every chunk"] > writes["default (60 s)"]
    assert (tmp_path / "checkpoint_cost.json").exists()

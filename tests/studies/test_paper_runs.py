"""The stored paper runs: their CPU time over sessions (measured, not
extrapolated), their code, and the paper's settings behind their keys."""

import json
import os
import signal

import pytest

from studies import paper_runs
from varint.checkpoint import read as read_checkpoint
from tests.helpers import hook_advance


def test_tm_runs_renormalise_every_interval_under_the_old_key():
    """The paper's TM renormalises every τ; the key of a stored run leaves
    that out, as every stored TM run was made so."""
    assert paper_runs.method_options("tm", "R1") == {"renormalize_every": 1}
    assert paper_runs.stored_key("lyapunov", "R1", "tm", 0.05, 1e8) == \
        "lyapunov-R1-tm-tau0.05-t1e+08"


def test_a_resumed_run_counts_the_cpu_of_every_session(tmp_path, monkeypatch):
    """Interrupted after a few chunks and run again, the stored CPU time is
    varint's own measure over both sessions (provenance.cpu_time, summed in
    the checkpoint): more than the second session's alone, which did only
    part of the work; the sidecar names the code and the machine."""
    with monkeypatch.context() as patch:
        hook_advance(patch, "tm", 3, lambda: os.kill(os.getpid(), signal.SIGINT))
        with pytest.raises(KeyboardInterrupt), pytest.warns(RuntimeWarning):
            paper_runs.run(tmp_path, "lyapunov", "R1", "tm", 0.05, 2e3)
    key = paper_runs.stored_key("lyapunov", "R1", "tm", 0.05, 2e3)
    checkpoint = tmp_path / "runs" / "checkpoints" / f"{key}.ckpt"
    before = read_checkpoint(checkpoint).cpu_time
    assert before > 0
    s = paper_runs.run(tmp_path, "lyapunov", "R1", "tm", 0.05, 2e3)
    meta = json.loads((tmp_path / "runs" / f"{key}.json").read_text())
    assert s.resumed and s.cpu_basis == "measured"
    assert s.cpu == s.result.provenance.cpu_time == meta["cpu"]
    # The second session's integration lies inside what this study timed
    # around its call.
    assert before < s.cpu <= before + meta["cpu_session"] + 1e-6
    assert meta["code"]["source"] and meta["machine"]["cores"] >= 1
    assert not checkpoint.exists()  # removed once the result is stored


def test_a_sidecar_from_before_sessions_were_timed_says_extrapolated():
    assert paper_runs.cpu_basis({"resumed": True}).startswith("extrapolated")
    assert paper_runs.cpu_basis({"resumed": False}) == "measured"
    assert paper_runs.cpu_basis({"resumed": True, "cpu_basis": "measured"}) == "measured"

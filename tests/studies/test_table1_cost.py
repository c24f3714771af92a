"""The cost study of Table I's rows: the projection does not scale a run's
fixed cost, and each row's progress (stored, checkpointed, not run) is read
from the stored runs and checkpoints."""

import json

import pytest

import varint
from studies import table1, table1_cost
from studies.paper_runs import SEED, stored_key


def test_projection_scales_only_the_part_proportional_to_t():
    # A run costing 2 s of setting up plus 1e-5 s per unit of time: the
    # average cost per unit time of a short run would overestimate the
    # 1e8 run 3× (2.1 s to 1e4); the slope gives it exactly.
    horizons = (1e4, 1e5)
    cpu = [2.0 + 1e-5 * t for t in horizons]
    projected, marginal = table1_cost.project(horizons, cpu)
    assert marginal == pytest.approx(1e-5)
    assert projected == pytest.approx(2.0 + 1e-5 * 1e8)
    # Noise larger than the work between the horizons: the longer run's
    # average, an upper bound.
    projected, marginal = table1_cost.project(horizons, [3.0, 2.9])
    assert marginal == pytest.approx(2.9 / 1e5) and projected == pytest.approx(2.9e3)


def _key(spec):
    _, method, tau, delta, *_ = spec
    return stored_key("lyapunov", "R1", method, tau, table1.T_END, delta=delta)


def test_progress_reads_stored_runs_and_checkpoints(tmp_path):
    runs = tmp_path / "runs"
    (runs / "checkpoints").mkdir(parents=True)
    tm, dop, eps = table1.PAPER_TABLE[4], table1.PAPER_TABLE[0], table1.PAPER_TABLE[13]
    # TM τ = 0.05: a stored run to 1e8 (its sidecar's CPU time).
    (runs / f"{_key(tm)}.npz").write_bytes(b"")
    (runs / f"{_key(tm)}.json").write_text(json.dumps({"cpu": 224.0}))
    # DOP853 τ = 0.05: an unfinished run's checkpoint, written by a real run
    # stopped at t = 2 (40 intervals of τ).
    model, x0 = varint.paper_orbit("R1")
    checkpoint = runs / "checkpoints" / f"{_key(dop)}.ckpt"
    varint.lyapunov_spectrum(model, x0, 2.0, tau=0.05, method="dop853", seed=SEED,
                             checkpoint=checkpoint, progress=False, delta=1e-5)
    assert table1_cost.progress_of(tmp_path, tm) == (1e8, 224.0, None, None)
    stored_t, stored_cpu, ckpt_t, ckpt_wall = table1_cost.progress_of(tmp_path, dop)
    assert (stored_t, stored_cpu) == (None, None)
    assert ckpt_t == pytest.approx(2.0) and ckpt_wall >= 0
    assert table1_cost.progress_of(tmp_path, eps) == (None, None, None, None)


def test_measure_runs_the_row_in_scratch(tmp_path):
    # Row 17, the paper's TM at tau = 0.5: its energy error passes varint's
    # tolerance, and the run says so.
    with pytest.warns(varint.AccuracyWarning, match=r"of tau = 0\.5\)"):
        cpu, wall_per_cpu = table1_cost.measure(table1.PAPER_TABLE[16], (100.0, 1000.0), 1,
                                                tmp_path)
    assert len(cpu) == 2 and all(c > 0 for c in cpu) and wall_per_cpu > 0
    assert sorted(p.name for p in (tmp_path / "runs").glob("*.npz")) == [
        "lyapunov-R1-tm-tau0.5-t100.npz", "lyapunov-R1-tm-tau0.5-t1000.npz"]


@pytest.mark.parametrize("argv, message", [
    (["--t-end", "1e4"], "given twice"),
    (["--t-end", "1e4", "--t-end", "1e4"], "given twice"),
    (["--t-end", "1e4", "--t-end", "1e9"], r"in \(0, 1e\+08\]"),
    (["--repeats", "0"], "positive integer"),
])
def test_bad_arguments_fail_before_any_run(tmp_path, argv, message):
    with pytest.raises(ValueError, match=message):
        table1_cost.main(argv + ["--out", str(tmp_path)])
    assert not list(tmp_path.iterdir())

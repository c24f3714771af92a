"""Table I's quick mode (R1 to t = 1e4, DOP853 to 1e3): the table is
complete, projections are labelled, and the laws that show at this horizon
hold."""

import csv

import pytest

from studies import table1


@pytest.fixture(scope="module")
def quick(table1_quick, paper_quick_dir):
    return table1_quick, paper_quick_dir


def test_minutes():
    assert table1.minutes("8h18m") == 498
    assert table1.minutes("27m") == 27
    with pytest.raises(ValueError, match="4h40m"):
        table1.minutes("4:40")


def test_all_rows_with_paper_and_ours(quick):
    res, out = quick
    rows = res["rows"]
    assert len(rows) == 17 == len(table1.PAPER_TABLE)
    with open(out / "table1.csv") as f:
        lines = list(csv.DictReader(f))
    assert len(lines) == 17
    for col in ("integrator", "method", "tau", "delta", "t_end", "energy_error_paper",
                "energy_error", "X1_paper", "X1", "cpu_paper", "cpu_s"):
        assert all(line[col] != "" for line in lines if col != "delta"
                   or line["integrator"] == "DOP853"), col
    for row in rows:
        # Nothing reaches 1e8 in quick mode: every CPU time to 1e8 and every
        # DOP853 energy error at 1e8 is a labelled projection.
        assert row["cpu_projected"] and row["cpu_to_1e8_s"] > row["cpu_s"]
        if row["method"] == "DOP853":
            assert row["energy_error_1e8_projected"] is not None
    assert (out / "table1_energy.png").exists() and (out / "table1.claims.json").exists()


def test_laws_at_the_quick_horizon(quick):
    res, _ = quick
    by = {(r["method"], r["tau"], r["delta"]): r for r in res["rows"]}
    tm = [by["TM", tau, None] for tau in (0.05, 0.1, 0.2, 0.5)]
    # The tangent map of a regular orbit: X1 ≈ (ln t + c)/t whatever τ
    # (the paper: TM gets the right X1 even at τ = 0.5).
    x1 = [r["X1"] for r in tm]
    assert max(x1) / min(x1) < 1.05
    # SBAB2C is of order 4 in τ: the energy error (its maximum over the
    # run) grows about 16× per doubling of τ.
    e = [r["energy_error_max"] for r in tm]
    assert all(8 < b / a < 40 for a, b in zip(e[:3], e[1:3]))
    # TDHcc and TDHes have left the regular law by t = 1e4 at τ = 0.05.
    for m in ("TDHcc", "TDHes"):
        assert by[m, 0.05, None]["X1"] > 1.5 * by["TM", 0.05, None]["X1"]
    # TDHeps levels off higher for larger τ (Fig. 3b).
    assert by["TDHeps", 0.5, None]["X1"] > by["TDHeps", 0.2, None]["X1"] \
        > by["TDHeps", 0.05, None]["X1"]
    claims = {c["claim"]: c for c in res["claims"]}
    growth = next(c for k, c in claims.items() if k.startswith("The DOP853 energy error"))
    assert growth["holds"]

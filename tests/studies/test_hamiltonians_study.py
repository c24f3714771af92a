"""studies/hamiltonians.py: in the default suite, the published values in
quick mode (seconds) and the bookkeeping that turns timings into the
targets' verdicts; the map comparison in quick mode (minutes) is slow."""

import json

import pytest

from studies import hamiltonians


def test_published_values_quick(tmp_path):
    res = hamiltonians.main(["--quick", "--part", "published", "--out", str(tmp_path)])
    rows = {r["quantity"]: r for r in res["published"]["rows"]}
    for name in ("L1", "L2", "L3", "L4"):
        r = rows[f"C({name}), Earth–Moon"]
        assert abs(r["difference"]) < 5e-5
    assert abs(rows["C(L4) − (3 − μ(1 − μ))"]["ours"]) < 1e-15
    arenstorf = [r for q, r in rows.items() if q.startswith("Arenstorf")]
    assert min(r["ours"] for r in arenstorf) < 1e-9           # heyoka closes it
    claims = json.loads((tmp_path / "hamiltonians.claims.json").read_text())
    assert sum("Earth–Moon" in c["claim"] for c in claims) == 4


def test_equal_agreement_picks_the_cheapest_peer_that_reaches_ours():
    rows = [{"contender": "varint defaults", "seconds": 1.0, "agreement": 0.95},
            {"contender": "heyoka tol 1e-6", "seconds": 2.0, "agreement": 0.90},
            {"contender": "heyoka tol 1e-8", "seconds": 4.0, "agreement": 0.96},
            {"contender": "heyoka tol 1e-10", "seconds": 6.0, "agreement": 0.99}]
    s = hamiltonians._equal_agreement(rows)
    assert s["heyoka"] == "heyoka tol 1e-8" and s["speedup"] == 4.0 and s["heyoka_reaches"]
    s = hamiltonians._equal_agreement(rows[:2])
    assert s["heyoka"] == "heyoka tol 1e-6" and not s["heyoka_reaches"]


def test_precision_summary_reads_heyoka_at_our_errors():
    """heyoka's cost at varint's error, log-log interpolated on its front:
    at error 1e-8 between (1 s, 1e-6) and (4 s, 1e-10) it is 2 s."""
    rows = [{"contender": "heyoka", "seconds": 1.0, "error": 1e-6},
            {"contender": "heyoka", "seconds": 4.0, "error": 1e-10},
            {"contender": "GL8", "seconds": 1.0, "error": 1e-8},
            {"contender": "GL8", "seconds": 3.0, "error": 1e-12}]
    out = hamiltonians._precision_summary(rows)
    assert out["GL8"]["worst"] == pytest.approx(2.0)
    assert "heyoka" not in out


@pytest.mark.slow
def test_published_and_maps_quick(tmp_path):
    res = hamiltonians.main(["--quick", "--part", "maps", "--repeats", "1",
                             "--out", str(tmp_path)])
    for ind, s in res["maps"]["summary"].items():
        assert 0.5 <= s["varint_agreement"] <= 1.0, ind
        assert s["speedup"] > 0
    claims = json.loads((tmp_path / "hamiltonians.claims.json").read_text())
    assert any("map with defaults" in c["claim"] for c in claims)


def _stored_bar_race(path, t_end):
    rows = [{"orbit": "regular", "contender": c, "seconds": s, "x1": 0.04, "x1_reference": 0.05,
             "error": 0.01, "t_end": t_end}
            for c, s in (("galpy lyapunov rtol 1e-06", 600.0), ("AGAMA der=True", 0.001),
                         ("varint ABA864 τ = 0.4", 0.0003))]
    path.write_text(json.dumps({"bar": {"rows": rows, "load": [3.0, 2.0, 1.0], "clock": "cpu"},
                                "_provenance": {"created": "2026-11-30T05:00:00+00:00",
                                                "code": {"commit": "abc"}}}))
    return path


def test_stored_galpy_rows_name_their_run_and_are_refused_at_another_horizon(tmp_path):
    """--galpy-stored takes only galpy's rows, each marked with the run it
    comes from; a stored run to another t_end cannot stand in."""
    path = _stored_bar_race(tmp_path / "hamiltonians_bar.json", 100.0)
    rows = hamiltonians.stored_galpy_rows(path, "regular", 100.0)
    assert [r["contender"] for r in rows] == ["galpy lyapunov rtol 1e-06"]
    assert rows[0]["stored"] == {"file": str(path), "created": "2026-11-30T05:00:00+00:00",
                                 "commit": "abc", "load": [3.0, 2.0, 1.0], "clock": "cpu"}
    with pytest.raises(SystemExit, match="t = 100.0, this race to t = 20.0"):
        hamiltonians.stored_galpy_rows(path, "regular", 20.0)
    with pytest.raises(SystemExit, match="no galpy row of the 'chaotic' orbit"):
        hamiltonians.stored_galpy_rows(path, "chaotic", 100.0)

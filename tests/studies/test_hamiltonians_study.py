"""studies/hamiltonians.py in quick mode: the published values it
reproduces, and the map comparison's bookkeeping (every contender timed and
scored against the reference). Minutes: slow."""

import json

import pytest

from studies import hamiltonians

pytestmark = pytest.mark.slow


def test_published_and_maps_quick(tmp_path):
    res = hamiltonians.main(["--quick", "--part", "published,maps", "--repeats", "1",
                             "--out", str(tmp_path)])
    rows = {r["quantity"]: r for r in res["published"]["rows"]}
    for name in ("L1", "L2", "L3", "L4"):
        r = rows[f"C({name}), Earth–Moon"]
        assert abs(r["difference"]) < 5e-5
    assert abs(rows["C(L4) − (3 − μ(1 − μ))"]["ours"]) < 1e-15
    arenstorf = [r for q, r in rows.items() if q.startswith("Arenstorf")]
    assert min(r["ours"] for r in arenstorf) < 1e-9           # heyoka closes it
    for ind, s in res["maps"]["summary"].items():
        assert 0.5 <= s["varint_agreement"] <= 1.0, ind
        assert s["speedup"] > 0
    claims = json.loads((tmp_path / "hamiltonians.claims.json").read_text())
    assert any("Earth–Moon" in c["claim"] for c in claims)
    assert any("map with defaults" in c["claim"] for c in claims)

"""The work–precision study's quick mode: the cost–error relations theory
predicts (never wall time), and the Pareto front."""

from itertools import pairwise

import numpy as np
import pytest

import varint
from studies import work_precision as wp


@pytest.fixture(scope="module")
def result(tmp_path_factory):
    out = tmp_path_factory.mktemp("work_precision")
    return wp.main(["--quick", "--out", str(out)]), out


def rows_of(res, case, family=None):
    return [r for r in res["rows"] if r["case"] == case
            and (family is None or r["family"] == family)]


def test_halving_tau_doubles_tm_force_evaluations_and_cuts_its_error(result):
    """On R1 at t = 100 the error falls by about 2^p per halving of τ
    (p = 2, 4 or 6; at least 2^(p−0.5)) until it meets round-off (~5e-13
    for TM here: SRKN14a at τ = 0.05), so pairs ending below 1e-11 are
    left out of the error check."""
    res, _ = result
    tm = rows_of(res, "tangent_R1", "TM")
    for config in {r["config"] for r in tm}:
        pts = sorted((r for r in tm if r["config"] == config), key=lambda r: -r["tau"])
        p = varint.get_scheme(config.split()[1]).order
        for a, b in pairwise(pts):
            assert 1.9 < b["evaluations"] / a["evaluations"] < 2.1, config
            if b["error"] > 1e-11:
                assert a["error"] / b["error"] > 2 ** (p - 0.5), (config, a["error"], b["error"])


def test_tighter_tolerances_cost_more_and_give_smaller_errors(result):
    """CVODE: more evaluations and a smaller error for each tighter
    tolerance. heyoka's Taylor method: a smaller error; its step count is no
    measure of cost (tighter tolerances raise the order and lengthen the
    steps), so only its error is checked."""
    res, _ = result
    for family in ("CVODE", "Taylor"):
        pts = sorted(rows_of(res, "tangent_R1", family), key=lambda r: -r["tolerance"])
        assert len(pts) >= 3
        assert all(a["error"] > b["error"] for a, b in pairwise(pts)), family
        if family == "CVODE":
            assert all(a["evaluations"] < b["evaluations"] for a, b in pairwise(pts))
    # DOP853 restarted every τ with τ below its natural step: τ sets error
    # and cost; with a long interval δ does.
    dop = rows_of(res, "tangent_R1", "DOP853")
    for name in {r["series"] for r in dop}:
        pts = sorted((r for r in dop if r["series"] == name), key=lambda r: r["evaluations"])
        assert len(pts) >= 2
        assert all(a["error"] > b["error"] for a, b in pairwise(pts)), name


def test_energy_error_is_bounded_for_tm_and_drifts_for_dop853(result):
    """Symplectic schemes: the largest energy error up to t = 400 is that up
    to t = 40 within a factor 3; DOP853 (not symplectic) drifts linearly,
    about 10× over the same span."""
    res, _ = result
    for r in rows_of(res, "energy_R1", "TM"):
        # Plus the round-off floor: at ~1e-14 (SRKN14a at τ = 0.05) the
        # error is round-off, which grows as √t (Brouwer's law), √10 ≈ 3.2.
        assert r["error"] < 3 * r["error_to_t_end_over_10"] + 1e-13, r["label"]
    for r in rows_of(res, "energy_R1", "DOP853"):
        if r["series"].startswith("DOP853 δ=1e-5"):
            assert r["error"] > 3 * r["error_to_t_end_over_10"], r["label"]


def test_the_pareto_front_is_exactly_the_undominated_configurations(result):
    res, _ = result
    for case in {r["case"] for r in res["rows"]}:
        for cost in ("seconds", "evaluations"):
            rows = [r for r in rows_of(res, case) if wp._ok(r, cost)]
            for r in rows:
                dominated = any(o is not r and o[cost] <= r[cost] and o["error"] <= r["error"]
                                and (o[cost] < r[cost] or o["error"] < r["error"])
                                for o in rows)
                assert r[f"pareto_{cost}"] == (not dominated), (case, cost, r["label"])


def test_winners_cover_the_error_range_and_name_the_crossovers(result):
    res, _ = result
    for case, s in res["summary"].items():
        for cost in ("seconds", "evaluations"):
            seg = s[cost]["winners"]
            errs = [r["error"] for r in rows_of(res, case) if wp._ok(r, cost)]
            assert np.isclose(seg[0][0], max(errs)) and np.isclose(seg[-1][1], min(errs))
            assert all(a[2] != b[2] for a, b in pairwise(seg))


def test_claims_and_files(result):
    res, out = result
    assert res["claims"]
    assert (out / "work_precision.claims.json").exists()
    for case in wp.CASES:
        assert (out / f"work_precision_{case.name}.png").exists()
    assert not (out / "work_precision.partial.json").exists()

"""REPORT.md from the quick results: Table I row by row, every claims file,
each figure beside its claims."""

import json

from studies import report


def test_report_assembles_everything(table1_quick, figures_quick, paper_quick_dir, tmp_path):
    # A claims file of another study is picked up as well.
    (paper_quick_dir / "other_study.claims.json").write_text(json.dumps(
        [{"claim": "a | claim", "paper": "-", "ours": "1", "holds": False, "figure": None,
          "note": ""}]))
    text = report.main(["--out", str(paper_quick_dir)])["text"]
    assert (paper_quick_dir / "REPORT.md").read_text() == text
    table = [line for line in text.splitlines()
             if line.startswith(("| SBAB2C | ", "| DOP853 | DOP853 | "))]
    assert len(table) == 17
    for n in (2, 3, 4, 5, 7, 8, 9, 10, 11):
        assert f"paper_fig{n:02d}.claims.json" in text
    assert "![fig04_r1_gali.png](fig04_r1_gali.png)" in text
    assert "a \\| claim" in text and "**differs**" in text
    # The sections study (Figs. 1 and 6) is another script's: named as missing.
    assert "Missing: `sections.claims.json`" in text
    # The paper's claims and our own checks are counted apart, and the rules
    # are listed with their tolerances.
    paper, own = text.split("### The paper's claims")[1].split("### varint's own checks")
    assert "Fig. 2 — R1" in paper and "| other_study |" in own.split("## How")[0]
    assert "| `levels_off` |" in text and "| `above` | ratio > 3 |" in text


def test_report_counts_by_source_and_marks_short_horizons(tmp_path):
    items = [
        {"claim": "a", "paper": "", "ours": "", "holds": True, "figure": None, "note": "",
         "rules": [{"rule": "inverse_t", "window": [1e3, 1e5]}], "checked_to": 1e5,
         "horizon": 1e8},
        {"claim": "b", "paper": "", "ours": "", "holds": False, "figure": None,
         "note": "unexplained", "rules": []},
        {"claim": "c", "paper": "", "ours": "", "holds": True, "figure": None, "note": "",
         "source": "own"},
    ]
    (tmp_path / "paper_fig02.claims.json").write_text(json.dumps(items))
    text = report.build(tmp_path)
    paper, own = text.split("### The paper's claims")[1].split("### varint's own checks")
    total = "| **all the paper's claims (text, figures)** | **2** | **1** | **1** | **1** | **0** |"
    assert total in paper
    assert "| **all own checks** | **1** | **1** | **0** | **0** | **0** |" in own
    assert "holds (to 1e+05; paper 1e+08) | inverse_t [1e+03–1e+05]" in text
    assert "c *(own check)*" in text


def test_report_names_missing_studies(tmp_path):
    text = report.build(tmp_path)
    assert "table1.csv is missing" in text and "paper_fig02.claims.json" in text


def test_the_report_lists_every_verdict_that_changed_and_why(tmp_path):
    """Against verdicts_previous.json: a claim whose verdict changed is a
    row (with the horizon it is now checked to, and its note); one that did
    not change is not; a new claim is counted apart."""
    before = {"commit": "abc1234", "claims": {"paper_fig09": [
        {"claim": "law", "holds": False, "checked_to": 1e5},
        {"claim": "same", "holds": True, "checked_to": None}]}}
    (tmp_path / "verdicts_previous.json").write_text(json.dumps(before))
    now = [{"claim": "law", "paper": "", "ours": "slope -1", "holds": True, "note": "why",
            "rules": [], "checked_to": 1e6, "horizon": 1e6},
           {"claim": "same", "paper": "", "ours": "", "holds": True, "note": "", "rules": []},
           {"claim": "fresh", "paper": "", "ours": "", "holds": True, "note": "", "rules": []}]
    (tmp_path / "paper_fig09.claims.json").write_text(json.dumps(now))
    lines = report.changed_section(report.load_claims(tmp_path), tmp_path)
    rows = [line for line in lines if line.startswith("| paper_fig09")]
    assert len(rows) == 1 and "| law |" in rows[0] and "**differs** | holds" in rows[0]
    assert "checked to t = 1e+06 (before: 1e+05); why" in rows[0]
    assert any("paper_fig09 1" in line for line in lines)
    assert report.changed_section({}, tmp_path / "nowhere") == []

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


def test_report_names_missing_studies(tmp_path):
    text = report.build(tmp_path)
    assert "table1.csv is missing" in text and "paper_fig02.claims.json" in text

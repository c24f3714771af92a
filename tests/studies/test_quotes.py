"""Every measured number of README.md and the documentation comes from a
stored result (studies/quotes.py): a quote that differs from its source,
a quote without one, or a measured-looking number typed outside a quote
fails here."""

import json
import shutil

import pytest

from studies import quotes
from studies.common import RESULTS


def test_every_quote_of_the_readme_is_what_its_stored_result_gives():
    """Rewrite README.md with ``python studies/quotes.py`` after a study is
    re-run."""
    text = quotes.README.read_text()
    assert quotes.MARKER.search(text), "README.md quotes nothing"
    assert quotes.stale(text) == []


def test_the_readme_types_no_measured_number_outside_a_quote():
    assert quotes.unsourced(quotes.README.read_text()) == []


@pytest.mark.parametrize("page", quotes.docs_pages(), ids=lambda p: p.name)
def test_every_documentation_page_quotes_stored_results_only(page):
    rst = page.read_text()
    for m in quotes.ROLE.finditer(rst):
        quotes.render(m[1])  # raises without a stored source
    assert quotes.unsourced(quotes.rst_prose(rst)) == []


def test_a_result_that_changes_makes_its_quote_stale(tmp_path):
    """The check can fail: with one stored number changed, the quote that
    reads it no longer matches README.md, and a quote with no source is
    reported as such."""
    folder = tmp_path / "results"
    shutil.copytree(RESULTS, folder, ignore=shutil.ignore_patterns("runs", "quick", "*.png",
                                                                    "*.npz"))
    text = quotes.fill(quotes.README.read_text(), quotes.Results(folder))
    assert quotes.stale(text, quotes.Results(folder)) == []
    data = json.loads((folder / "roundoff_floor.json").read_text())
    data["varint_floor"]["3"] *= 10
    (folder / "roundoff_floor.json").write_text(json.dumps(data))
    text += "\n<!--q:no_such_quote-->1<!--/q-->\n"
    found = {name: now for name, _, now in quotes.stale(text, quotes.Results(folder))}
    assert set(found) == {"roundoff_floor", "no_such_quote"}
    assert found["no_such_quote"].startswith("no stored source")


def test_measured_numbers_are_recognised_and_parameters_are_not():
    found = quotes.unsourced("It took 3.2 s.\nτ = 0.05 and t = 1e4.\n9.5× faster\n"
                             "error 1.57e-7\n<!--q:x-->7.6 ns<!--/q--> quoted\n`0.4 ms` code\n")
    assert [line for line, _ in found] == [1, 3, 4]
    prose = quotes.rst_prose("Costs :q:`blocks_gain`.\n\n>>> f(2.5)\n3.5\n\nIt is 1.5 ms.\n")
    assert [line for line, _ in quotes.unsourced(prose)] == [6]

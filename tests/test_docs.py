"""The documentation's pages run as written: every ``>>>`` example of
docs/*.rst and docs/user_guide/*.rst, with its output (the site's gallery
runs when the site is built; see docs/contributing.rst)."""

import doctest
from pathlib import Path

import pytest

DOCS = Path(__file__).resolve().parent.parent / "docs"
PAGES = sorted(p for pattern in ("*.rst", "user_guide/*.rst") for p in DOCS.glob(pattern))


def test_the_pages_are_found():
    assert DOCS / "getting_started.rst" in PAGES and DOCS / "user_guide/maps.rst" in PAGES


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(DOCS)))
def test_page_examples(page):
    result = doctest.testfile(str(page), module_relative=False, report=True, verbose=False,
                              optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    assert result.failed == 0, f"{result.failed} example(s) of {page.name} failed (see above)"

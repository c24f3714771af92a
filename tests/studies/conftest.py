"""Fixtures of the paper studies' tests: their quick runs, made once per
session in one directory, so the figures reuse Table I's stored R1 runs and
the report reads what both wrote."""

import pytest


@pytest.fixture(scope="session")
def paper_quick_dir(tmp_path_factory):
    return tmp_path_factory.mktemp("paper_quick")


@pytest.fixture(scope="session")
def table1_quick(paper_quick_dir):
    from studies import table1

    return table1.main(["--quick", "--out", str(paper_quick_dir)])


@pytest.fixture(scope="session")
def figures_quick(paper_quick_dir, table1_quick):
    from studies import paper_figures

    return paper_figures.main(["--quick", "--out", str(paper_quick_dir)])

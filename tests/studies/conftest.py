"""Fixtures of the paper studies' tests: their quick runs, made once per
session in one directory, so the figures reuse Table I's stored R1 runs and
the report reads what both wrote."""

import warnings

import pytest

from varint import AccuracyWarning


@pytest.fixture(scope="session")
def paper_quick_dir(tmp_path_factory):
    return tmp_path_factory.mktemp("paper_quick")


def coarse_steps_warn(study, argv):
    """``study.main(argv)``, checking its accuracy warnings: the paper runs R1
    at its coarsest step, tau = 0.5, whose energy error passes the
    tolerance (the paper shows what such a step does to X1); those runs,
    and only those, must say so."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        made = study.main(argv)
    for w in caught:
        if issubclass(w.category, AccuracyWarning):
            assert "of tau = 0.5)" in str(w.message), str(w.message)
        else:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    return made


@pytest.fixture(scope="session")
def table1_quick(paper_quick_dir):
    from studies import table1

    return coarse_steps_warn(table1, ["--quick", "--out", str(paper_quick_dir)])


@pytest.fixture(scope="session")
def figures_quick(paper_quick_dir, table1_quick):
    from studies import paper_figures

    return coarse_steps_warn(paper_figures, ["--quick", "--out", str(paper_quick_dir)])

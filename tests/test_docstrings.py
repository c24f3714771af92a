"""The Examples sections of the package's docstrings run as written: every
``>>>`` line of every module of varint (and varint.baselines), with its
output. An example too long for the test suite says ``# doctest: +SKIP``."""

import doctest
import importlib
import pkgutil

import pytest

import varint

#: Modules that run a job when imported.
_SKIP = {"varint.__main__"}


def _modules():
    names = {"varint"}
    for package in (varint, importlib.import_module("varint.baselines")):
        names.add(package.__name__)
        names.update(m.name for m in pkgutil.walk_packages(package.__path__,
                                                           package.__name__ + "."))
    return sorted(names - _SKIP)


def _examples():
    finder = doctest.DocTestFinder(exclude_empty=True)
    for name in _modules():
        module = importlib.import_module(name)
        for test in finder.find(module, name):
            if test.examples:
                yield pytest.param(test, id=test.name)


@pytest.mark.parametrize("test", list(_examples()))
def test_docstring_examples(test):
    runner = doctest.DocTestRunner(
        optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE, verbose=False)
    out = []
    runner.run(test, out=out.append, clear_globs=True)
    assert runner.summarize(verbose=False).failed == 0, "".join(out)


def test_every_public_function_has_an_example():
    """The run functions users start from show how they are called."""
    for name in ("run", "lyapunov_spectrum", "gali", "sali", "megno", "integrate",
                 "chaos_map", "surface_of_section", "section_grid", "paper_orbit",
                 "select_scheme", "departure", "load_result"):
        doc = getattr(varint, name).__doc__ or ""
        assert "Examples\n" in doc and ">>>" in doc, f"varint.{name} has no Examples section"

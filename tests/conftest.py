"""Shared fixtures: the paper's orbits, built once per session; and how
pytest-xdist shares the tests out among its workers."""

import pytest
from xdist.scheduler import LoadFileScheduling

import varint

#: Test files whose tests share session fixtures, run as one xdist work
#: unit: the paper studies' quick runs (tests/studies/conftest.py), made
#: once, in one worker, and read by all four files.
SHARED_UNITS = {f"tests/studies/{name}.py": "paper_quick"
                for name in ("test_table1", "test_paper_figures", "test_report",
                             "test_roundoff_floor")}


class FileScheduling(LoadFileScheduling):
    """``--dist loadfile``: each test file runs in one worker, and the
    files of :data:`SHARED_UNITS` together.

    A file's tests mostly run the same models, schemes and indicators,
    hence the same generated kernels, and share module fixtures (a study's
    quick run). Shared out one test at a time, neighbouring tests ran in
    both workers at once, each compiling the kernel, or running the study,
    the other was (on cold caches, as in CI, compiling is most of the
    suite's time). ``xdist_group`` marks cannot say this under pytest 9:
    pytest-xdist ≤ 3.8 tags a grouped test by renaming its ``_nodeid``,
    which pytest 9 no longer reads, so every test was its own unit."""

    def _split_scope(self, nodeid):
        path = super()._split_scope(nodeid)
        return SHARED_UNITS.get(path, path)


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config, log):
    if config.getvalue("dist") == "loadfile":
        return FileScheduling(config, log)
    return None


@pytest.fixture(autouse=True)
def _no_remembered_calls():
    """Each test starts with no one-shot call remembered (varint.remembered):
    a test that patches what a run calls gets the run it patched."""
    from varint import remembered

    remembered.forget()


@pytest.fixture(scope="session")
def r1():
    return varint.paper_orbit("R1")


@pytest.fixture(scope="session")
def c1():
    return varint.paper_orbit("C1")

"""Shared fixtures: the paper's orbits, built once per session; and how
pytest-xdist shares the tests out among its workers."""

import json
import re
from pathlib import Path

import pytest
from xdist.scheduler import LoadFileScheduling

import varint

#: The stored profiles of the cold suite (studies/suite_profile.py, one per
#: stop: ``suite_profile_stopNN.json``); the newest gives each file's cost.
PROFILES = Path(__file__).resolve().parent.parent / "studies" / "results"

#: Test files run as one xdist work unit (one worker, one after another):
#:
#: * "paper_quick": the paper studies' quick runs (tests/studies/conftest.py),
#:   session fixtures made once and read by all four files;
#: * the others: files that compile the same kernels, each of which the two
#:   workers of a cold run both compiled when the files ran in different
#:   workers (``duplicates`` of studies/results/suite_profile_stop50.json,
#:   CPU seconds of the second compile): a compensated generated stepper
#:   (34 s); a generated stepper over SIMD lanes (18 s) and a map's batch
#:   kernel (3 s); a Poincaré-section kernel (15 s); a TDH batch kernel
#:   (14 s); "result_classes" also runs every result class's runs of
#:   test_tables, test_xarray and test_stored_files on one set of kernels;
#: * from stop 55's duplicates (studies/results/suite_profile_stop55.json):
#:   a time-dependent general H's checked part-stepper kernel, with its
#:   Gauss–Legendre steps (38 s); two rotating frames' part-stepper kernels
#:   (16 s); a generated stepper of R1's compensation ladder (7 s);
#: * from stop 58's duplicates (studies/results/suite_profile.json): the
#:   generated stepper of Hénon–Heiles' whole spectrum with ABA864 that
#:   test_departure and test_results both compile (8 s).
SHARED_UNITS = {
    **{f"tests/studies/{name}.py": "paper_quick"
       for name in ("test_table1", "test_paper_figures", "test_report", "test_roundoff_floor")},
    "tests/studies/test_compensated_floor.py": "compensated_stepper",
    "tests/studies/test_compensation_levels.py": "compensated_stepper",
    "tests/test_bad_input.py": "lanes_stepper",
    "tests/test_cli.py": "lanes_stepper",
    "tests/test_compiling.py": "lanes_stepper",
    "tests/test_sections.py": "result_classes",
    "tests/test_stored_files.py": "result_classes",
    "tests/test_tables.py": "result_classes",
    "tests/test_xarray.py": "result_classes",
    "tests/studies/test_accuracy.py": "tdh_batch",
    "tests/studies/test_work_precision.py": "tdh_batch",
    "tests/test_selection.py": "compensated_stepper",
    "tests/flows/test_general_methods.py": "general_parts",
    "tests/test_parts_checks.py": "general_parts",
    "tests/flows/test_split.py": "rotating_parts",
    "tests/test_rotating_generated.py": "rotating_parts",
    "tests/test_departure.py": "hh_aba864_stepper",
    "tests/test_results.py": "hh_aba864_stepper",
}


def file_costs(folder=PROFILES):
    """Per test file, the CPU seconds it took in the newest stored cold
    profile of ``folder`` (its tests' and their child processes'), and the
    profile's mean seconds per test (for files it does not know); ``({},
    None)`` without a profile."""
    stops = {int(m.group(1)): path for path in folder.glob("suite_profile_stop*.json")
             if (m := re.fullmatch(r"suite_profile_stop(\d+)\.json", path.name))}
    if not stops:
        return {}, None
    files = json.loads(stops[max(stops)].read_text())["files"]
    costs = {name: f["cpu_s"] + f.get("child_cpu_s", 0.0) for name, f in files.items()}
    return costs, sum(costs.values()) / max(1, sum(f["tests"] for f in files.values()))


def unit_cost(tests, costs, per_test):
    """The expected CPU seconds of a work unit (a file, or the files of a
    name of :data:`SHARED_UNITS`) of ``tests`` node ids: its files' stored
    costs; a file the profile does not know counts its tests at
    ``per_test`` (its number of tests, xdist's own order, without a
    profile)."""
    files = {nodeid.split("::")[0] for nodeid in tests}
    known = [costs[f] for f in files if f in costs]
    unknown = sum(1 for nodeid in tests if nodeid.split("::")[0] not in costs)
    return sum(known) + unknown * (per_test if per_test is not None else 1.0)


class FileScheduling(LoadFileScheduling):
    """``--dist loadfile``: each test file runs in one worker, and the
    files of :data:`SHARED_UNITS` together; the dearest unit left goes to
    the next worker that asks (:func:`unit_cost`), so the workers end
    together (xdist hands out the units with the most tests first: a file
    of few, long tests, such as test_planetary_runs, 12 tests and 152 CPU
    s in stop 52's profile, may come last, one worker running it while
    the other has finished).

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

    def _assign_work_unit(self, node):
        if not hasattr(self, "_costs"):
            self._costs = file_costs()
        dearest = max(self.workqueue,
                      key=lambda unit: unit_cost(self.workqueue[unit], *self._costs))
        self.workqueue.move_to_end(dearest, last=False)
        super()._assign_work_unit(node)


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

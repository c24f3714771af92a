"""How the suite's test files are shared out among pytest-xdist's workers
(tests/conftest.py): the dearest unit left first, priced by the newest
stored cold profile."""

import json
from collections import OrderedDict

from tests.conftest import FileScheduling, file_costs, unit_cost


def _profile(folder, stop, files):
    (folder / f"suite_profile_stop{stop}.json").write_text(json.dumps({"files": {
        name: {"cpu_s": cpu, "child_cpu_s": child, "tests": tests}
        for name, (cpu, child, tests) in files.items()}}))


def test_the_newest_profile_prices_the_files(tmp_path):
    # Stop 10 is newer than stop 9 (by number, not by name's order).
    _profile(tmp_path, 9, {"tests/a.py": (500.0, 0.0, 1)})
    _profile(tmp_path, 10, {"tests/a.py": (3.0, 1.0, 2), "tests/b.py": (20.0, 0.0, 6)})
    (tmp_path / "suite_profile_stop10_old.json").write_text("not a profile")
    costs, per_test = file_costs(tmp_path)
    assert costs == {"tests/a.py": 4.0, "tests/b.py": 20.0}
    assert per_test == 24.0 / 8


def test_a_unit_costs_its_files_and_unknown_files_their_tests(tmp_path):
    costs = {"tests/a.py": 4.0, "tests/b.py": 20.0}
    tests = ["tests/a.py::x", "tests/a.py::y", "tests/b.py::z", "tests/new.py::w",
             "tests/new.py::v"]
    assert unit_cost(tests, costs, 0.5) == 4.0 + 20.0 + 2 * 0.5
    # Without a profile: the number of tests, as xdist orders the units.
    assert file_costs(tmp_path) == ({}, None)
    assert unit_cost(tests, {}, None) == 5


class _Node:
    """A worker as the scheduler sees it: it records the tests sent."""

    shutting_down = False

    def __init__(self):
        self.sent = []

    def send_runtest_some(self, indexes):
        self.sent.append(indexes)


def test_the_dearest_unit_left_goes_to_the_next_worker():
    """Four cheap tests in one file, one dear test in another: xdist's own
    order (most tests first) sends the cheap file first, this scheduler the
    dear one."""
    collection = [f"tests/a.py::t{i}" for i in range(4)] + ["tests/b.py::t"]
    scheduler = FileScheduling.__new__(FileScheduling)
    scheduler.workqueue = OrderedDict(
        [("tests/a.py", {n: False for n in collection[:4]}), ("tests/b.py", {collection[4]: False})])
    scheduler.assigned_work, scheduler.registered_collections = {}, {}
    scheduler._costs = ({"tests/a.py": 2.0, "tests/b.py": 60.0}, 1.0)
    first, second = _Node(), _Node()
    for node in (first, second):
        scheduler.registered_collections[node] = collection
        scheduler._assign_work_unit(node)
    assert first.sent == [[4]] and second.sent == [[0, 1, 2, 3]]
    assert not scheduler.workqueue

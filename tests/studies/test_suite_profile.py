"""The suite profile's table of duplicate compiles counts a kernel twice
only when the same kernel was compiled twice: the skeleton's closures,
one function for every step body, are told apart by what they close over
(the body, numba's options), not by their name alone."""

from numba import njit

import json

from studies.suite_profile import compare, compiled_key, duplicates
from varint.kernels.interval import batch_loop, serial_batch
from varint.kernels.map_stepper import map_body
from varint.models.maps import (
    _coupled_iterate,
    _coupled_jacobian,
    _standard_iterate,
    _standard_jacobian,
)

ARGS = ("float64", "array(float64, 1d, C)")


def key(dispatcher):
    """The key of a compile of ``dispatcher`` for ``ARGS`` (nothing is compiled)."""
    return compiled_key({"dispatcher": dispatcher, "args": ARGS})


def standard_batch():
    """The batch loop of the standard map, made anew (past the factories'
    caches: a new body, a new orbit loop, a new dispatcher)."""
    body = map_body.__wrapped__(2, 1, _standard_iterate, _standard_jacobian)
    return serial_batch.__wrapped__(body)


def test_one_closure_made_twice_has_one_key():
    """Two dispatchers of one kernel (made again, as in another process):
    numba's cache could serve the second, so it is a duplicate."""
    first, second = standard_batch(), standard_batch()
    assert first is not second and first.py_func.__closure__[0].cell_contents \
        is not second.py_func.__closure__[0].cell_contents
    assert key(first) == key(second)
    assert "serial_batch.<locals>.batch@interval.py" in key(first)


def test_closures_of_different_bodies_or_options_have_different_keys():
    """The batch loop of another map, of other sizes, or compiled with
    ``parallel=True`` is another kernel, although the function and the
    name of what it closes over (``orbit_loop.<locals>.orbit``) are the
    same."""
    base = key(standard_batch())
    coupled = key(batch_loop(map_body(4, 1, _coupled_iterate, _coupled_jacobian), False))
    sizes = key(batch_loop(map_body(2, 2, _standard_iterate, _standard_jacobian), False))
    serial = standard_batch()
    parallel = key(njit(parallel=True)(serial.py_func))
    assert len({base, coupled, sizes, parallel}) == 4 and "[parallel](" in parallel
    other_args = compiled_key({"dispatcher": standard_batch(), "args": ("int64",)})
    assert other_args != base


def _user_closure(scale, inner):
    @njit
    def f(x):
        return scale * inner(x)

    return f


@njit
def _double(x):
    return 2.0 * x


@njit
def _half(x):
    return 0.5 * x


def test_a_closure_outside_varint_is_told_apart_by_names_and_values():
    """A closure whose cells varint's cache key cannot name (functions of
    this test) is described by names, recursively, and plain values by
    value; the key says it is so (``~``)."""
    one = key(_user_closure(3.0, _double))
    assert "#~" in one
    assert one == key(_user_closure(3.0, _double))
    assert one != key(_user_closure(3.0, _half))
    assert one != key(_user_closure(4.0, _double))
    assert key(_double) != key(_half)


def test_duplicates_counts_only_what_was_compiled_again():
    a, b = key(standard_batch()), key(njit(parallel=True)(standard_batch().py_func))
    rows = {"gw0": {"tests/x.py::t1": {"compiled": [[a, 2.0], [b, 5.0]]}},
            "gw1": {"tests/y.py::t2": {"compiled": [[a, 3.0]]}}}
    table = duplicates(rows)
    assert table["keys"] == 1
    assert table["functions"][a] == {"times": 2, "extra_s": 2.0, "processes": ["gw0", "gw1"],
                                     "files": ["tests/x.py", "tests/y.py"]}
    assert table["extra_s"] == 2.0


def _row(cpu, child=0.0, compile_s=0.0, compiles=0):
    return {"s": cpu, "cpu_s": cpu, "child_cpu_s": child, "compile_s": compile_s,
            "compiles": compiles, "compiled": []}


def test_compare_sums_each_files_cpu_and_its_childrens(tmp_path):
    """The cut of a comparison is the sum over its files of (process CPU +
    children's CPU) before minus after; a file only one side ran counts on
    that side; rows without child CPU (older runs) count none."""
    before, after = tmp_path / "before", tmp_path / "after"
    before.mkdir()
    after.mkdir()
    # t1 compiled two kernels, one of them with parallel=True.
    t1 = {**_row(10.0, 5.0, 8.0, 2), "compiled": [["m:f@m.py(int64)", 3.0],
                                                   ["m:g@m.py[parallel](int64)", 5.0]]}
    (before / "gw0.rows.json").write_text(json.dumps({
        "tests/a.py::t1": t1, "tests/a.py::t2": _row(2.0),
        "tests/b.py::t": {k: v for k, v in _row(7.0).items() if k != "child_cpu_s"}}))
    (after / "main.rows.json").write_text(json.dumps({
        "tests/a.py::t1": _row(4.0, 1.0, 3.0, 1), "tests/a.py::t2": _row(2.0),
        "tests/c.py::t": _row(1.0)}))
    (after / "load.json").write_text(json.dumps({"load_start": [1.0], "load_end": [2.0]}))
    table = compare([("pair", str(before), str(after))])
    entry = table["comparisons"]["pair"]
    assert entry["files"]["tests/a.py"]["before"] == {
        "cpu_s": 12.0, "child_cpu_s": 5.0, "compile_s": 8.0, "compiles": 2, "tests": 2,
        "parallel_compiles": 1, "parallel_s": 5.0}
    assert entry["files"]["tests/a.py"]["after"]["cpu_s"] == 6.0
    assert entry["files"]["tests/a.py"]["after"]["parallel_compiles"] == 0
    assert "after" not in entry["files"]["tests/b.py"]
    assert entry["before_cpu_s"] == 12.0 + 5.0 + 7.0 and entry["after_cpu_s"] == 6.0 + 1.0 + 1.0
    assert entry["cut_cpu_s"] == table["cut_cpu_s"] == 24.0 - 8.0
    assert entry["load"] == {"before": None, "after": {"load_start": [1.0], "load_end": [2.0]}}

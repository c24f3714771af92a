"""Where the default test suite's time goes: per test file, the wall and CPU
seconds its tests took (setup, call and teardown together) and the share of
the CPU seconds numba spent compiling, measured on cold caches (fresh varint and numba caches, as
CI has them) in one process (``-n 0``), so a file's compile time is the
compilation its own tests caused, in the order pytest runs them.

Compilation is timed (process CPU time: on a loaded machine wall time
counts the other processes too) with numba's event API (``numba:compile`` events,
outermost only, so a function compiled while compiling another is counted
once); heyoka's LLVM compilation of its Taylor integrators is not a numba
event and counts as running time. Groups of files can be profiled one run at
a time and merged into the stored table (``--merge``), as the whole suite in
one process takes long.

The same timer rides along any pytest run as a plugin: with
``VARINT_SUITE_PROFILE=DIR`` and ``-p studies.suite_profile`` each process
(every xdist worker) writes ``DIR/<worker>.rows.json``, with what each test
compiled (:func:`compiled_key`); ``--rows DIR`` makes the table from them,
and the table of functions compiled more than once (:func:`duplicates`; so
the cold suite run of ``studies/suite_time.py``, two workers as CI has
them, gives its own profile).

Usage: ``python studies/suite_profile.py [--merge] [--cache DIR] [--rows DIR]
[--out DIR] [-- PYTEST ARGS (files)]``
"""

from __future__ import annotations

import hashlib
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

from varint.kernels.closures import Unnamed, closure_key

try:
    from common import parse_args, save_json
except ImportError:  # imported as studies.suite_profile
    from .common import parse_args, save_json

ROOT = Path(__file__).resolve().parent.parent


def compiled_key(data):
    """What a ``numba:compile`` event compiles, the same in every process:
    the function's module, qualified name and source file's name (a
    generated module's name carries its hash, not its folder), for a
    closure what it closes over (:func:`closes_over`) and the argument
    types. Two events with one key compiled the same function for the same
    types twice: in two processes, or in one through two dispatchers (a
    closure or generated module made again). A kernel compiled with
    ``parallel=True`` (numba's parfor lowering) has ``[parallel]`` before
    its argument types."""
    dispatcher = data.get("dispatcher")
    func = getattr(dispatcher, "py_func", None)
    code = getattr(func, "__code__", None)
    if code is None:    # a lifted loop or another dispatcher without a function
        return type(dispatcher).__name__
    parallel = "[parallel]" if getattr(dispatcher, "targetoptions", {}).get("parallel") else ""
    return (f"{func.__module__}:{func.__qualname__}@{os.path.basename(code.co_filename)}"
            f"{closes_over(dispatcher)}{parallel}"
            f"({', '.join(str(a) for a in data.get('args', ()))})")


def closes_over(dispatcher):
    """What tells the closure kernel ``dispatcher`` apart from another of
    the same function ('' for a function without cells): the names of the
    values it closes over, readable, then ``#`` and a digest of all that is
    compiled into it. The digest is varint's key of the kernel's disk cache
    (:func:`varint.kernels.closures.closure_key`: every function it closes
    over by its code, recursively, plain values by value, numba's options
    such as ``parallel``), so two compiles share a key exactly when numba's
    cache could have served the second. A closure over something that key
    cannot name (a function of a test or study) gets a digest of the same
    description by names (:func:`_named`), recursively; then, and only
    then, closures that differ in an object's contents other than its type
    may share a key, and the digest starts with ``~``."""
    func = dispatcher.py_func
    if not func.__closure__:
        return ""
    names = ",".join(_name(c.cell_contents) for c in func.__closure__)
    try:
        digest = closure_key(dispatcher)[:12]
    except Unnamed:
        text = repr(_named(dispatcher, 0))
        digest = "~" + hashlib.sha256(text.encode()).hexdigest()[:11]
    return f"[{names}#{digest}]"


def _name(value):
    """A value a closure closes over, briefly: a function by its module and
    qualified name, a number or string by value, anything else by type."""
    value = getattr(value, "py_func", value)
    if hasattr(value, "__qualname__"):
        return f"{getattr(value, '__module__', '')}.{value.__qualname__}"
    if isinstance(value, (bool, int, float, str)):
        return repr(value)
    return type(value).__name__


def _named(value, depth):
    """A process-independent description of ``value`` by names: a
    dispatcher by its function and numba's options, a function by its
    module, qualified name and, recursively, the values it closes over;
    plain values by value, containers item by item, anything else by
    type."""
    if depth > 32:
        return "..."
    options = getattr(value, "targetoptions", None)
    value = getattr(value, "py_func", value)
    if callable(value) and hasattr(value, "__qualname__"):
        cells = tuple(_named(c.cell_contents, depth + 1)
                      for c in getattr(value, "__closure__", None) or ())
        return (_name(value), cells, sorted((k, repr(v)) for k, v in (options or {}).items()))
    if value is None or isinstance(value, (bool, int, float, complex, str, bytes)):
        return repr(value)
    if isinstance(value, (tuple, list)):
        return tuple(_named(v, depth + 1) for v in value)
    return type(value).__name__


class CompileTimer:
    """A pytest plugin: per test id, the seconds of its setup, call and
    teardown, the seconds numba spent compiling during them and the number
    of functions it compiled (outermost ``numba:compile`` events only: a
    generated stepper's ``orbit``, compiled inside its ``batch_serial``,
    counts in the caller's), and the CPU seconds of the child processes it
    ran and waited for (``child_cpu_s``: a test that runs a script in a
    subprocess, such as the CUDA simulator's, spends its time there)."""

    def __init__(self, path, nested=False):
        self.path = Path(path)
        # With ``nested``, every compile event is kept too (the functions
        # an outer compile compiled inside it, each with its own seconds
        # and depth): a function compiled for a second signature while
        # compiling its caller shows only there.
        self.nested = nested
        self.stack = []
        self.depth = 0
        self.started = 0.0
        self.compiling = 0.0
        self.compiled = 0
        self.what = []
        self.inner = []
        self.file = None
        self.rows = defaultdict(lambda: {"s": 0.0, "cpu_s": 0.0, "child_cpu_s": 0.0,
                                         "compile_s": 0.0, "compiles": 0, "compiled": [],
                                         "inner": []})

    def on_start(self, event):
        if self.depth == 0:
            self.started = time.process_time()
            self.key = compiled_key(event.data)
        elif self.nested:
            self.stack.append((compiled_key(event.data), time.process_time()))
        self.depth += 1

    def on_end(self, event):
        self.depth -= 1
        if self.depth == 0:
            seconds = time.process_time() - self.started
            self.compiling += seconds
            self.compiled += 1
            self.what.append([self.key, round(seconds, 2)])
        elif self.nested:
            key, started = self.stack.pop()
            self.inner.append([key, round(time.process_time() - started, 2), self.depth])

    def pytest_sessionstart(self, session):
        from numba.core import event

        timer = self

        class Listener(event.Listener):
            def on_start(self, e):
                timer.on_start(e)

            def on_end(self, e):
                timer.on_end(e)

        event.register("numba:compile", Listener())

    def pytest_runtest_protocol(self, item, nextitem):
        self.item_start = time.perf_counter()
        self.item_cpu = time.process_time()
        self.item_children = _children_cpu()
        self.item_compile = self.compiling
        self.item_compiled = self.compiled
        self.what = []
        self.inner = []

    def pytest_runtest_logfinish(self, nodeid, location):
        row = self.rows[nodeid]
        row["s"] += time.perf_counter() - self.item_start
        row["cpu_s"] += time.process_time() - self.item_cpu
        row["child_cpu_s"] += _children_cpu() - self.item_children
        row["compile_s"] += self.compiling - self.item_compile
        row["compiles"] += self.compiled - self.item_compiled
        row["compiled"] += self.what
        row["inner"] += self.inner
        self.what = []
        self.inner = []
        # Written after each file too: a run cut short (a loaded machine,
        # a killed worker) still leaves the rows of the files it finished.
        path = nodeid.split("::")[0]
        if path != self.file:
            self.file = path
            self.path.write_text(json.dumps(self.rows))

    def pytest_sessionfinish(self, session):
        self.path.write_text(json.dumps(self.rows))


def _children_cpu():
    """User and system CPU seconds of this process's finished children."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def pytest_configure(config):
    """As a plugin (``-p studies.suite_profile``): time this process's tests
    into ``$VARINT_SUITE_PROFILE/<worker>.rows.json``."""
    folder = os.environ.get("VARINT_SUITE_PROFILE")
    # An xdist controller (numprocesses set) runs no test: its workers time them.
    if folder and not getattr(config.option, "numprocesses", None):
        worker = os.environ.get("PYTEST_XDIST_WORKER", "main")
        config.pluginmanager.register(CompileTimer(
            Path(folder) / f"{worker}.rows.json",
            nested=bool(os.environ.get("VARINT_SUITE_PROFILE_NESTED"))))


def _extra(parser):
    parser.add_argument("--merge", action="store_true",
                        help="add these files to the stored table instead of replacing it")
    parser.add_argument("--cache", type=Path,
                        default=Path(tempfile.gettempdir()) / f"varint-suite-profile-{os.getuid()}",
                        help="folder of the fresh caches the files run with")
    parser.add_argument("--rows", type=Path, default=None,
                        help="make the table from the plugin's files in this folder "
                             "instead of running pytest")
    parser.add_argument("--note", default=None,
                        help="what the table's run was (kept beside it, e.g. an interruption)")
    parser.add_argument("--compare", nargs=3, action="append", default=None,
                        metavar=("LABEL", "BEFORE", "AFTER"),
                        help="instead of a profile: per test file, the CPU seconds, child "
                             "CPU seconds and compiles of the plugin's rows in folder "
                             "BEFORE against those in AFTER (each run cold on the same "
                             "files; a load.json beside the rows gives the run's load); "
                             "repeatable, stored as suite_cut_<--name>.json")
    parser.add_argument("--signatures", type=Path, default=None, metavar="DIR",
                        help="instead of a profile: per compiled function, the signatures "
                             "compiled, seconds each and the test that compiled each, from "
                             "the plugin's rows in DIR (run with "
                             "VARINT_SUITE_PROFILE_NESTED=1 to see nested compiles too); "
                             "and in its subfolders; stored as signatures_<--name>.json")
    parser.add_argument("--name", default="cut",
                        help="the stored comparison's name (suite_cut_NAME.json)")
    parser.add_argument("pytest_args", nargs="*", help="pytest arguments (files) after --")


def profile(cache, pytest_args):
    """Run pytest once, cold and in one process; per test, its seconds and
    compile seconds (a dict), and pytest's return code."""
    shutil.rmtree(cache, ignore_errors=True)
    for path in ROOT.glob("**/__pycache__/*.nb[ic]"):
        path.unlink()
    cache.mkdir(parents=True)
    rows = cache / "rows.json"
    code = (f"import sys, pytest; sys.path.insert(0, {str(ROOT / 'studies')!r}); "
            f"from suite_profile import CompileTimer; "
            f"sys.exit(pytest.main(sys.argv[1:], plugins=[CompileTimer({str(rows)!r})]))")
    env = {**os.environ, "VARINT_CACHE_DIR": str(cache / "varint")}
    proc = subprocess.run([sys.executable, "-c", code, "-n", "0", "-p", "no:cacheprovider",
                           "-q", *pytest_args], cwd=ROOT, env=env)
    return json.loads(rows.read_text()), proc.returncode


def by_file(rows):
    """Per test file: wall seconds, CPU seconds, compile CPU seconds, the
    compile share of the CPU seconds, the functions numba compiled (None
    where the rows predate the count), the number of tests and the CPU
    seconds of their child processes (0 where the rows predate it)."""
    files = defaultdict(lambda: {"s": 0.0, "cpu_s": 0.0, "compile_s": 0.0, "compiles": 0,
                                 "tests": 0, "child_cpu_s": 0.0})
    for nodeid, row in rows.items():
        f = files[nodeid.split("::")[0]]
        for key in ("s", "cpu_s", "compile_s"):
            f[key] += row[key]
        f["child_cpu_s"] += row.get("child_cpu_s", 0.0)
        f["compiles"] = None if f["compiles"] is None or "compiles" not in row \
            else f["compiles"] + row["compiles"]
        f["tests"] += 1
    return {name: {"s": round(f["s"], 1), "cpu_s": round(f["cpu_s"], 1),
                   "compile_s": round(f["compile_s"], 1),
                   "compile_share": round(f["compile_s"] / f["cpu_s"], 2) if f["cpu_s"] else 0.0,
                   "compiles": f["compiles"], "tests": f["tests"],
                   "child_cpu_s": round(f["child_cpu_s"], 1)}
            for name, f in sorted(files.items(), key=lambda kv: -kv[1]["cpu_s"])}


def duplicates(rows_by_process):
    """Functions numba compiled more than once for the same argument types
    (:func:`compiled_key`) in one suite run, from each process's rows (a
    dict: process name -> its rows): per key, how many times, the CPU
    seconds of all but the longest, the processes and test files that
    compiled it; the total of those seconds first. A function both xdist
    workers compiled (at once, before either had written it to the shared
    cache) shows up here, and one compiled again in one process (made anew,
    e.g. in a cache folder of its own)."""
    seen = defaultdict(list)
    for process, rows in rows_by_process.items():
        for nodeid, row in rows.items():
            for key, seconds in row.get("compiled", []):
                seen[key].append((seconds, process, nodeid.split("::")[0]))
    table = {}
    for key, events in seen.items():
        if len(events) > 1:
            times = sorted(s for s, _, _ in events)
            table[key] = {"times": len(events), "extra_s": round(sum(times[:-1]), 2),
                          "processes": sorted({p for _, p, _ in events}),
                          "files": sorted({f for _, _, f in events})}
    table = dict(sorted(table.items(), key=lambda kv: -kv[1]["extra_s"]))
    return {"extra_s": round(sum(t["extra_s"] for t in table.values()), 1),
            "keys": len(table), "functions": table}


def split_key(key):
    """A :func:`compiled_key` cut in two: the function (module, name,
    file and what it closes over) and its argument types, the last
    bracketed group."""
    if not key.endswith(")"):
        return key, ""
    depth = 0
    for i in range(len(key) - 1, -1, -1):
        depth += {")": 1, "(": -1}.get(key[i], 0)
        if depth == 0:
            return key[:i], key[i + 1:-1]
    return key, ""


def signatures(rows_by_process):
    """Per compiled function (a dispatcher: :func:`split_key`'s first part),
    every compile the plugin saw of it, outermost and, where the rows have
    them (``VARINT_SUITE_PROFILE_NESTED``), nested: its argument types, CPU
    seconds, depth (0: outermost), process and test. Then per function
    without what it closes over (``module:name@file``): how many distinct
    closures of it were compiled (the same code specialised on other
    values). A dispatcher with two signatures, or a function with two
    closures, is a compile a normalised call might save. The seconds of a
    nested compile are part of its caller's."""
    by_function = defaultdict(list)
    for process, rows in rows_by_process.items():
        for nodeid, row in rows.items():
            events = [(k, s, 0) for k, s in row.get("compiled", [])]
            events += [tuple(e) for e in row.get("inner", [])]
            for key, seconds, depth in events:
                function, args = split_key(key)
                by_function[function].append({"args": args, "s": seconds, "depth": depth,
                                              "process": process, "test": nodeid})
    functions = {}
    for function, events in by_function.items():
        sigs = sorted({e["args"] for e in events})
        functions[function] = {"signatures": len(sigs),
                               "s": round(sum(e["s"] for e in events if e["depth"] == 0), 2),
                               "nested_s": round(sum(e["s"] for e in events if e["depth"]), 2),
                               "compiles": sorted(events, key=lambda e: -e["s"])}
    functions = dict(sorted(functions.items(), key=lambda kv: -(kv[1]["s"] + kv[1]["nested_s"])))
    closures = defaultdict(set)
    for function in functions:
        closures[function.split("[", 1)[0]].add(function)
    return {"functions": functions,
            "several_signatures": {f: v["signatures"] for f, v in functions.items()
                                   if v["signatures"] > 1},
            "several_closures": {f: len(c) for f, c in sorted(closures.items(),
                                                               key=lambda kv: -len(kv[1]))
                                 if len(c) > 1}}


def _rows_of(folder):
    """The plugin's rows of every process in ``folder``, merged, and the
    folder's ``load.json`` (None where it has none)."""
    rows = {}
    for path in sorted(Path(folder).glob("*.rows.json")):
        rows.update(json.loads(path.read_text()))
    load = Path(folder) / "load.json"
    return rows, json.loads(load.read_text()) if load.exists() else None


def parallel_compiles(rows):
    """Per test file: how many of its outermost compiles were of kernels
    compiled with ``parallel=True`` (keys with ``[parallel]``,
    :func:`compiled_key`) and their CPU seconds (rows without the mark
    count none)."""
    out = defaultdict(lambda: {"parallel_compiles": 0, "parallel_s": 0.0})
    for nodeid, row in rows.items():
        for key, seconds in row.get("compiled", ()):
            if "[parallel](" in key:
                f = out[nodeid.split("::")[0]]
                f["parallel_compiles"] += 1
                f["parallel_s"] = round(f["parallel_s"] + seconds, 2)
    return dict(out)


def compare(pairs):
    """Per comparison (label, rows before, rows after): per test file, the
    CPU seconds (the test processes' and their children's), compile seconds
    and compiles before and after (those of ``parallel=True`` kernels
    apart, :func:`parallel_compiles`), their sums, and each run's load. Only
    what each pair ran is compared: a pair runs the same files twice, on
    the old tree and the new, each on fresh caches."""
    out = {}
    for label, before, after in pairs:
        entry = {"files": {}, "load": {}}
        for when, folder in (("before", before), ("after", after)):
            rows, load = _rows_of(folder)
            entry["load"][when] = load
            parallel = parallel_compiles(rows)
            for name, f in by_file(rows).items():
                entry["files"].setdefault(name, {})[when] = {
                    **{key: f[key] for key in ("cpu_s", "child_cpu_s", "compile_s", "compiles",
                                               "tests")},
                    **parallel.get(name, {"parallel_compiles": 0, "parallel_s": 0.0})}
        for when in ("before", "after"):
            entry[f"{when}_cpu_s"] = round(sum(f[when]["cpu_s"] + f[when]["child_cpu_s"]
                                               for f in entry["files"].values()
                                               if when in f), 1)
        entry["cut_cpu_s"] = round(entry["before_cpu_s"] - entry["after_cpu_s"], 1)
        out[label] = entry
    return {"comparisons": out,
            "cut_cpu_s": round(sum(e["cut_cpu_s"] for e in out.values()), 1)}


def main(argv=None):
    args = parse_args(__doc__.splitlines()[0], argv, extra=_extra)
    if args.compare:
        table = {**compare(args.compare), "note": args.note}
        save_json(args.out, f"suite_cut_{args.name}", table)
        for label, e in table["comparisons"].items():
            print(f"{label:24s} {e['before_cpu_s']:8.1f} -> {e['after_cpu_s']:8.1f} s CPU "
                  f"({e['cut_cpu_s']:+.1f} cut)")
        print(f"{'total cut':24s} {table['cut_cpu_s']:8.1f} s CPU")
        return table
    if args.signatures:
        # Rows in subfolders too (runs of groups of files side by side).
        by_process = {str(p.relative_to(args.signatures)).removesuffix(".rows.json"):
                      json.loads(p.read_text())
                      for p in sorted(args.signatures.rglob("*.rows.json"))}
        table = {**signatures(by_process), "note": args.note}
        save_json(args.out, f"signatures_{args.name}", table)
        for function, f in list(table["functions"].items())[:40]:
            print(f"{f['s']:8.1f} s {f['nested_s']:8.1f} s nested {f['signatures']:3d} sig "
                  f"{len(f['compiles']):3d}x  {function[:100]}")
        return table
    load_start = [round(x, 2) for x in os.getloadavg()]
    if args.rows is None:
        rows, code = profile(args.cache, args.pytest_args)
        by_process = {"main": rows}
    else:
        rows, code, by_process = {}, None, {}
        for path in sorted(args.rows.glob("*.rows.json")):
            by_process[path.name.split(".")[0]] = json.loads(path.read_text())
            rows.update(by_process[path.name.split(".")[0]])
    path = Path(args.out) / "suite_profile.json"
    stored = json.loads(path.read_text()) if args.merge and path.exists() else {}
    stored.pop("_provenance", None)
    tests = {**stored.get("tests", {}),
             **{k: {key: round(v[key], 2) if key != "compiles" else v[key]
                    for key in ("s", "cpu_s", "child_cpu_s", "compile_s", "compiles") if key in v}
                for k, v in rows.items()}}
    # From rows, the load now is not the run's (the note says what it was);
    # the rows' folder by name only (a path of this machine means nothing
    # elsewhere).
    measured = args.rows is None
    runs = [*stored.get("runs", []),
            {"args": args.pytest_args, "rows": None if measured else args.rows.name,
             "returncode": code, "note": args.note,
             "load_start": load_start if measured else None,
             "load_end": [round(x, 2) for x in os.getloadavg()] if measured else None}]
    files = by_file(tests)
    # The duplicates of this run alone (a merged table's runs did not share
    # their processes).
    twice = duplicates(by_process)
    save_json(args.out, "suite_profile", {"files": files, "runs": runs,
                                          "duplicates": twice, "tests": tests})
    for name, f in list(files.items())[:40]:
        print(f"{f['s']:8.1f} s {f['cpu_s']:8.1f} s CPU {f['compile_share']:5.0%} compile "
              f"{f['compiles'] if f['compiles'] is not None else '-':>5} fns "
              f"{f['tests']:4d}  {name}")
    print(f"compiled again: {twice['keys']} functions, {twice['extra_s']:.0f} s CPU")
    for key, t in list(twice["functions"].items())[:15]:
        print(f"{t['extra_s']:8.1f} s {t['times']:3d}x  {key[:110]}")
    return files


if __name__ == "__main__":
    main()

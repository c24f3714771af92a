"""Start-up of a fresh process: ``import varint`` and the first run with
warm caches (issue 28, "imports on demand", "every kernel cached").

A researcher's session is many short processes, so the time before the
first number matters as much as the time per step. Each figure is the
median over fresh processes (wall time inside the child, from before
``import varint`` to after it, and from after it to the end of the first
run, :data:`CASES`; and the CPU time of both, less inflated than the wall
time when other processes share the machine); one earlier process per case compiles and caches
the kernels first, so every timed process finds the caches warm. The
heavy modules that ``import varint`` alone loaded are listed per source
tree.

With ``--against DIR`` a second source tree (e.g. a plain copy of an
older commit) is timed in the same run, its processes interleaved with
this tree's (a, b, a, b, …), so that the load of the shared machine falls
on both alike; each tree keeps its own kernel cache directory.

Usage: ``python studies/startup.py [--quick] [--out DIR] [--against DIR]
[--cases floor r1 map1 map2 lattice potential] [--processes N] [--label L]
[--part totals|breakdown]``; stored as ``startup.json``
(``startup_<label>.json``). ``--part breakdown`` times the same processes
part by part (:data:`PARTS`: where a first run's distance to the floor
goes), stored as ``startup_breakdown.json`` (``startup_breakdown_<label>.json``).

The ``potential`` case is the first use of a model no process has built
before (:data:`CASES`: a coupling drawn at random per process, so its
kernels are compiled in the timed process while every other cache is
warm); its ``announced`` says whether the process printed the compile
message ("compiling kernels …", :mod:`varint.compiling`) on stderr.
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from studies.common import parse_args, save_json

HEAVY = ("sympy", "scipy", "scipy.linalg", "matplotlib", "numba", "pandas", "xarray",
         "dask", "heyoka")
#: What a fresh process runs after ``import varint``: the floor (numpy,
#: numba and one small cached kernel: numba loads its registries, and SciPy's
#: BLAS with them, at the first call of any compiled function), the R1
#: spectrum of the paper to t = 100, or a FLI map of 256 Hénon–Heiles orbits
#: on the x = 0 section at E = 1/8 to t = 100 on 1 or 2 threads (four blocks
#: of 64 SIMD lanes: with 2 threads, ``parallel=True``, the parallel kernel
#: over blocks; one
#: block, 64 orbits, would run serially whatever the threads), or the
#: largest Lyapunov exponent of 8 sites excited in a disordered
#: Klein–Gordon chain of 64 sites to t = 10 (its part stepper, a closure
#: of the skeleton; the full spectrum's 128 vectors would time the run).
CASES = {
    "floor": "from varint.kernels.checks import tangent_overflow; "
             "tangent_overflow(np.zeros((2, 1)))",
    "r1": "m, x = varint.paper_orbit('R1'); "
          "varint.lyapunov_spectrum(m, x, t_end=100.0, tau=0.05, progress=False)",
    "map1": "numba.set_num_threads(1); " + (MAP := (
        "model = varint.models.HenonHeiles(); "
        "grid = varint.section_grid(model, 0.125, np.linspace(-0.45, 0.65, 16), "
        "np.linspace(-0.45, 0.45, 16)); "
        "varint.chaos_map(model, grid, 'fli', t_end=100.0, progress=False)")),
    # Forced: on a busy machine the default stays on one thread
    # (varint.threads), and this case times the parallel kernel's load.
    "map2": "numba.set_num_threads(2); " + MAP.replace("progress=False)",
                                                       "progress=False, parallel=True)"),
    "lattice": "m = varint.models.DisorderedKG(64, seed=1); "
               "x = m.initial_block(width=8, seed=1); "
               "varint.lyapunov_spectrum(m, x, t_end=10.0, tau=0.1, n_exponents=1, "
               "progress=False)",
    # A new model: its coupling is drawn per process, so that its ∇V, D²V,
    # third-derivative kernels and its stepper are compiled now (progress
    # on, as on a terminal, so that the compile is announced).
    "potential": "import random, sympy as sp; q1, q2 = sp.symbols('q1 q2'); "
                 "c = sp.Rational(random.SystemRandom().randrange(1, 10**9), 10**9); "
                 "m = varint.models.from_potential((q1**2 + q2**2) / 2 + c * q1**2 * q2 "
                 "- q2**3 / 3, [q1, q2]); "
                 "varint.lyapunov_spectrum(m, [0.0, 0.1, 0.3, 0.0], t_end=10.0, tau=0.05, "
                 "scheme='ABA864', progress=True)",
}
CHILD = f"""
import sys, time, json
t0, c0 = time.perf_counter(), time.process_time()
import varint
t1, c1 = time.perf_counter(), time.process_time()
heavy = [m for m in {HEAVY!r} if m in sys.modules]
import numba, numpy as np
exec(sys.argv[1])
t2, c2 = time.perf_counter(), time.process_time()
after = [m for m in {HEAVY!r} if m in sys.modules]
print(json.dumps({{"import": t1 - t0, "run": t2 - t1, "cpu": c2 - c0, "heavy": heavy,
                  "heavy_run": after}}))
"""

#: ``--part breakdown``: the same processes, with the CPU time of each
#: part of the start-up measured inside them (exclusive: a part called
#: within another is counted once, in itself). The parts are the costs
#: suspected for the first run's distance to the floor: imports (each
#: module's code, including numba's and SciPy's), the cyclic garbage
#: collector's passes (young: generations 0 and 1; full: every object of
#: the process, :mod:`varint.collector`), numba's registries (loaded at the first call of
#: any compiled function), numba's cache files (index and data read and
#: unpickled; the LLVM object code loaded), varint's verification of every
#: cached file (HMAC-SHA256, :mod:`varint.cachedir`), the execution of
#: verified generated modules, and the rest (Python of the run, arithmetic).
#: numba's cache classes are patched where they are defined, so varint's
#: subclasses (:mod:`varint.codecache`) count in the same rows.
PARTS = ("imports", "gc: young collections", "gc: full collections", "numba: registries at the first call",
         "numba cache: index read + unpickle", "numba cache: data read + unpickle",
         "numba cache: LLVM object loading", "varint: HMAC verification",
         "varint: generated module exec", "rest")
BREAKDOWN_CHILD = """
import gc, sys, time, json
import _frozen_importlib
clock = time.process_time
parts = dict.fromkeys(PARTS_, 0.0)
stack = [["rest", clock(), 0.0]]


def enter(name):
    stack.append([name, clock(), 0.0])


def leave():
    name, start, inner = stack.pop()
    spent = clock() - start
    parts[name] += spent - inner
    stack[-1][2] += spent


def timed(owner, attr, name):
    inner = getattr(owner, attr)

    def wrapper(*args, **kwargs):
        enter(name)
        try:
            return inner(*args, **kwargs)
        finally:
            leave()
    setattr(owner, attr, wrapper)


def on_gc(phase, info):
    if phase == "start":
        enter("gc: full collections" if info["generation"] == 2 else "gc: young collections")
    else:
        leave()


gc.callbacks.append(on_gc)
timed(_frozen_importlib, "_load_unlocked", "imports")
t0 = time.perf_counter()
import varint
import numpy as np
from numba.core import base, caching
from numba.core.typing import context
from varint import cachedir, codecache
for owner in (base.BaseContext, context.BaseContext):
    timed(owner, "refresh", "numba: registries at the first call")
for owner in (caching.IndexDataCacheFile, codecache._SignedCacheFile):
    timed(owner, "_load_index", "numba cache: index read + unpickle")
    timed(owner, "_load_data", "numba cache: data read + unpickle")
timed(caching.CompileResultCacheImpl, "rebuild", "numba cache: LLVM object loading")
timed(cachedir, "verify", "varint: HMAC verification")
timed(cachedir, "secret", "varint: HMAC verification")
timed(codecache, "_execute", "varint: generated module exec")
exec(sys.argv[1])
while len(stack) > 1:
    leave()
total = clock() - stack[0][1]
parts["rest"] += total - stack[0][2]
print(json.dumps({"cpu": total, "wall": time.perf_counter() - t0, "parts": parts}))
""".replace("PARTS_", repr(PARTS))


def child(root, cache, case, pycache, script=CHILD):
    """One fresh process on source tree ``root`` running ``case``
    (:data:`CASES`): its import and run seconds and the heavy modules the
    import loaded. Python's bytecode is cached in ``pycache`` as an
    installed package's is (whatever ``PYTHONDONTWRITEBYTECODE`` says):
    compiling varint's modules from source costs ~0.3 s a process."""
    env = dict(os.environ, PYTHONPATH=str(root), VARINT_CACHE_DIR=str(cache),
               PYTHONPYCACHEPREFIX=str(pycache))
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    done = subprocess.run([sys.executable, "-c", script, CASES[case]], cwd=root, env=env,
                          check=True, capture_output=True, text=True)
    out = json.loads(done.stdout.strip().splitlines()[-1])
    out["announced"] = "compiling" in done.stderr
    return out


def main(argv=None):
    def extra(parser):
        parser.add_argument("--against", type=Path, default=None,
                            help="a second source tree, timed in the same run")
        parser.add_argument("--cases", nargs="+", choices=list(CASES), default=list(CASES),
                            help="which first runs to time (default all)")
        parser.add_argument("--processes", type=int, default=7,
                            help="timed fresh processes per tree (default 7)")
        parser.add_argument("--label", default=None,
                            help="stored as startup_<label>.json (e.g. a subset of cases)")
        parser.add_argument("--part", choices=("totals", "breakdown"), default="totals",
                            help="breakdown: the CPU time of each part of the start-up "
                                 "(PARTS), stored as startup_breakdown[_<label>].json")
    args = parse_args(__doc__.splitlines()[0], argv, extra)
    n = 3 if args.quick else max(5, args.processes)
    trees = {"this": Path(__file__).resolve().parent.parent}
    if args.against is not None:
        trees["against"] = args.against.resolve()
    scratch = Path(tempfile.mkdtemp(prefix="varint-startup-"))
    caches = {}
    pycache = scratch / "pycache"
    for label, root in trees.items():
        caches[label] = scratch / label
        caches[label].mkdir(mode=0o700)
        for case in args.cases:
            child(root, caches[label], case, pycache)   # compiles and caches the kernels
    script = BREAKDOWN_CHILD if args.part == "breakdown" else CHILD
    samples = {(label, case): [] for label in trees for case in args.cases}
    load_before = os.getloadavg()
    for _ in range(n):
        for case in args.cases:
            for label, root in trees.items():
                samples[label, case].append(child(root, caches[label], case, pycache, script))
    if args.part == "breakdown":
        return breakdown(args, trees, samples, n, load_before)
    data = {"processes": n, "trees": {k: v.name for k, v in trees.items()}}
    for (label, case), rows in samples.items():
        imports = [r["import"] for r in rows]
        runs = [r["run"] for r in rows]
        totals = [a + b for a, b in zip(imports, runs, strict=True)]
        cpus = [r["cpu"] for r in rows]
        data.setdefault(label, {})[case] = {
            "import_median_s": statistics.median(imports),
            "import_range_s": [min(imports), max(imports)],
            "first_run_median_s": statistics.median(runs),
            "import_plus_first_run_median_s": statistics.median(totals),
            "import_plus_first_run_range_s": [min(totals), max(totals)],
            "import_plus_first_run_cpu_median_s": statistics.median(cpus),
            "heavy_after_import": rows[-1]["heavy"],
            "heavy_after_run": rows[-1]["heavy_run"],
            "announced": sum(r["announced"] for r in rows),
        }
        row = data[label][case]
        print(f"{label:8s} {case:5s} import {row['import_median_s']:.3f} s, first run "
              f"{row['first_run_median_s']:.3f} s, together "
              f"{row['import_plus_first_run_median_s']:.3f} s, CPU "
              f"{row['import_plus_first_run_cpu_median_s']:.3f} s (medians of {n}); "
              f"import loaded {', '.join(rows[-1]['heavy']) or 'none of ' + '/'.join(HEAVY)}; "
              f"the run {', '.join(rows[-1]['heavy_run'])}")
    load = {"before": load_before, "after": os.getloadavg(), "cpus": os.cpu_count()}
    data["load"] = load
    print(f"load {load['before']} -> {load['after']} on {load['cpus']} CPUs")
    print(save_json(args.out, "startup" if args.label is None else f"startup_{args.label}", data,
                    times="measured: wall time inside fresh child processes, medians"))
    return data


def breakdown(args, trees, samples, n, load_before):
    """Print and store the medians of each part's CPU seconds (:data:`PARTS`)
    per tree and case, and each case's distance to the floor part by part
    (the median of each part, not of the differences: the parts' medians
    need not add up to the total's)."""
    data = {"processes": n, "trees": {k: v.name for k, v in trees.items()}, "parts": PARTS}
    for (label, case), rows in samples.items():
        data.setdefault(label, {})[case] = {
            "cpu_median_s": statistics.median(r["cpu"] for r in rows),
            "wall_median_s": statistics.median(r["wall"] for r in rows),
            "parts_median_s": {p: statistics.median(r["parts"][p] for r in rows) for p in PARTS},
        }
    columns = [(label, case) for label in trees for case in args.cases]
    print(f"{'CPU seconds, medians of ' + str(n):38s}" + "".join(
        f"{label[:7] + ' ' + case:>16s}" for label, case in columns))
    for part in PARTS + ("total",):
        cells = [data[label][case]["cpu_median_s"] if part == "total"
                 else data[label][case]["parts_median_s"][part] for label, case in columns]
        print(f"{part:38s}" + "".join(f"{c:16.3f}" for c in cells))
    load = {"before": load_before, "after": os.getloadavg(), "cpus": os.cpu_count()}
    data["load"] = load
    print(f"load {load['before']} -> {load['after']} on {load['cpus']} CPUs")
    name = "startup_breakdown" if args.label is None else f"startup_breakdown_{args.label}"
    print(save_json(args.out, name, data,
                    times="measured: CPU time of each part inside fresh child processes, "
                          "medians"))
    return data


if __name__ == "__main__":
    main()

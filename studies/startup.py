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
[--cases floor r1 map1 map2 lattice potential] [--processes N] [--label L]``;
stored as ``startup.json`` (``startup_<label>.json``).

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


def child(root, cache, case, pycache):
    """One fresh process on source tree ``root`` running ``case``
    (:data:`CASES`): its import and run seconds and the heavy modules the
    import loaded. Python's bytecode is cached in ``pycache`` as an
    installed package's is (whatever ``PYTHONDONTWRITEBYTECODE`` says):
    compiling varint's modules from source costs ~0.3 s a process."""
    env = dict(os.environ, PYTHONPATH=str(root), VARINT_CACHE_DIR=str(cache),
               PYTHONPYCACHEPREFIX=str(pycache))
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    done = subprocess.run([sys.executable, "-c", CHILD, CASES[case]], cwd=root, env=env,
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
    samples = {(label, case): [] for label in trees for case in args.cases}
    load_before = os.getloadavg()
    for _ in range(n):
        for case in args.cases:
            for label, root in trees.items():
                samples[label, case].append(child(root, caches[label], case, pycache))
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


if __name__ == "__main__":
    main()

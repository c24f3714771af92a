"""Where one cold kernel compile goes (issue 26: why one compile costs 4-8 s).

For each case, ``--repeats`` new interpreters with empty varint and numba
cache directories run one representative first call, with numba's event
API (:mod:`numba.core.event`) listening to every kind it emits
(``numba:compile``, ``numba:run_pass``, ``numba:compiler_lock``,
``numba:llvm_lock``). Times are *exclusive*: a nested event (a helper
compiled while typing its caller, a pass inside a compile) is subtracted
from its parent, so the kinds and passes add up to the total. Per case the
median over repeats is stored: the compile seconds, the process CPU
seconds, the wall and CPU seconds of the case's code (its first call, the
model made and the kernels compiled or loaded; the imports excluded), the
CPU seconds of its run alone (``general``: the call, the model made before), the seconds per compiler pass (``numba:run_pass`` by pass name),
the time under the LLVM lock (LLVM's optimisation and code generation; in
total, and by the dispatcher being compiled: numba links a callee's module
into its caller's and optimises the whole again) and the number of dispatcher compiles with the largest by exclusive seconds.

Cases: ``stepper`` (the generated one-orbit stepper, SALI of Hénon–Heiles
R1), ``lattice`` (the part stepper of a disordered Klein–Gordon lattice
from :func:`varint.kernels.interval.batch_loop`, a Lyapunov spectrum) and
``tdh`` (Hénon–Heiles with the TDH scheme ``tdhes``), ``general`` (a
general H(q, p) of :func:`varint.models.from_hamiltonian`, its default
scheme GL8 on the part stepper, two vectors); ``skeleton`` compiles
four skeleton kernels in one process, as a test suite does (the lattice's
spectrum for k = 4 and k = 1, Hénon–Heiles by ``tdhes`` and ``tdhcc``): what
a helper compiled once and called, rather than inlined into each, saves.

``--second`` runs, after each case's first process, a second new process
on the cache folders the first left (stored as ``<case>, second process``):
what the disk caches save a new process. ``--baseline DIR`` runs every
child also on the varint of the source tree DIR (``git worktree add DIR
<commit>``), interleaved, stored as ``<case> (baseline)``.

``--profile`` instead runs each case once under :mod:`cProfile` and stores
the functions with the largest own time (cProfile slows the compile; use it
for shares, not seconds).

Usage: ``python studies/compile_cost.py [--cases stepper lattice tdh skeleton]
[--repeats N] [--second] [--baseline DIR] [--profile] [--quick] [--out DIR]``
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

try:
    from common import parse_args, save_json
except ImportError:  # imported as studies.compile_cost
    from .common import parse_args, save_json

#: The first call of each case, in a new process with empty caches.
CASES = {
    "stepper": ("m = varint.models.HenonHeiles(); "
                "r = varint.sali(m, np.array([0.0, 0.558, 0.23337397, 0.0]), t_end=10.0, "
                "tau=0.05, progress=False); value = r.sali"),
    "lattice": ("m = varint.models.DisorderedKG(16, seed=1); x = m.initial_block(width=4, seed=1); "
                "r = varint.lyapunov_spectrum(m, x, t_end=2.0, tau=0.1, progress=False); "
                "value = r.exponents"),
    "tdh": ("m = varint.models.HenonHeiles(); "
            "r = varint.integrate(m, np.array([0.0, 0.558, 0.23337397, 0.0]), 5.0, tau=0.1, "
            "method='tdhes', deviations=np.eye(4)); value = r.deviations"),
    "general": ("import sympy as sp; q = sp.symbols('q1 q2'); p = sp.symbols('p1 p2'); "
                "H = (p[0]**2 + p[1]**2) / 2 + sp.Rational(1, 10) * q[0] * p[0] * p[1] "
                "+ (q[0]**2 + q[1]**2) / 2 + q[0]**2 * q[1]; "
                "m = varint.models.from_hamiltonian(H, q, p); "
                "run_start = time.process_time(); "
                "r = varint.lyapunov_spectrum(m, np.array([0.1, 0.05, 0.2, 0.1]), 10.0, tau=0.1, "
                "n_exponents=2, progress=False); value = r.exponents; "
                "run_cpu = time.process_time() - run_start"),
    "skeleton": ("m = varint.models.DisorderedKG(16, seed=1); x = m.initial_block(width=4, seed=1); "
                 "a = varint.lyapunov_spectrum(m, x, t_end=2.0, tau=0.1, progress=False); "
                 "b = varint.lyapunov_spectrum(m, x, t_end=2.0, tau=0.1, n_exponents=1, progress=False); "
                 "h = varint.models.HenonHeiles(); x0 = np.array([0.0, 0.558, 0.23337397, 0.0]); "
                 "c = varint.integrate(h, x0, 5.0, tau=0.1, method='tdhes', deviations=np.eye(4)); "
                 "e = varint.integrate(h, x0, 5.0, tau=0.1, method='tdhcc', deviations=np.eye(4)); "
                 "value = np.concatenate([a.exponents.ravel(), b.exponents.ravel(), "
                 "c.deviations.ravel(), e.deviations.ravel()])"),
}

#: The child: an exclusive-time listener on every numba event, then the case.
CHILD = r"""
import cProfile, json, pstats, sys, time
import numpy as np
from numba.core import event
import varint
from varint import compiling

stack, kinds, passes, compiles, llvm = [], {}, {}, {}, {}


def dispatcher_name(data):
    return getattr(data["dispatcher"], "__qualname__", None) or str(data["dispatcher"])

class Listener(event.Listener):
    def on_start(self, e):
        stack.append([e.kind, e.data, time.perf_counter(), 0.0])

    def on_end(self, e):
        kind, data, start, inner = stack.pop()
        elapsed = time.perf_counter() - start
        own = elapsed - inner
        if stack:
            stack[-1][3] += elapsed
        kinds[kind] = kinds.get(kind, 0.0) + own
        if kind == "numba:run_pass":
            passes[data["name"]] = passes.get(data["name"], 0.0) + own
        elif kind == "numba:compile":
            name = dispatcher_name(data)
            compiles[name] = compiles.get(name, 0.0) + own
        elif kind == "numba:llvm_lock":
            # LLVM's work for the innermost function being compiled: its
            # own module and, at its end, the callees linked into it again.
            name = next((dispatcher_name(d) for k, d, _, _ in reversed(stack)
                         if k == "numba:compile"), "(none)")
            llvm[name] = llvm.get(name, 0.0) + own

for kind in ("numba:compile", "numba:run_pass", "numba:compiler_lock", "numba:llvm_lock"):
    event.register(kind, Listener())

profiler = cProfile.Profile() if PROFILE else None
if profiler:
    profiler.enable()
case_start, case_cpu = time.perf_counter(), time.process_time()
exec(CASE)
case_seconds, case_cpu = time.perf_counter() - case_start, time.process_time() - case_cpu
if profiler:
    profiler.disable()
    stats = pstats.Stats(profiler).sort_stats("tottime")
    own = sorted(stats.stats.items(), key=lambda kv: -kv[1][2])[:40]
    top = [[f"{f}:{n}:{fn}", round(st[2], 3), round(st[3], 3), st[1]] for (f, n, fn), st in own]
else:
    top = []
print(json.dumps({"compile": compiling.compile_seconds(), "cpu": time.process_time(),
                  "case": case_seconds, "case cpu": case_cpu,
                  "run cpu": globals().get("run_cpu", case_cpu),
                  "kinds": kinds, "passes": passes, "compiles": compiles, "llvm": llvm,
                  "top": top,
                  "value": np.ascontiguousarray(value).tobytes().hex()}))
"""


def child(case, profile, second=False, tree=None):
    """One new interpreter with empty caches: its measurements as a dict;
    with ``second``, a list of two: a second new interpreter on the cache
    folders the first left (what the disk caches save). ``tree``: another
    source tree's varint (run in that folder, first on the path)."""
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, VARINT_CACHE_DIR=os.path.join(cache, "varint"),
                   NUMBA_CACHE_DIR=os.path.join(cache, "numba"))
        if tree is not None:
            env["PYTHONPATH"] = str(tree)
        code = f"CASE = {CASES[case]!r}\nPROFILE = {profile!r}\n" + CHILD
        runs = []
        for _ in range(2 if second else 1):
            done = subprocess.run([sys.executable, "-c", code], env=env, cwd=tree,
                                  capture_output=True, text=True)
            if done.returncode:
                raise RuntimeError(f"case {case!r} failed:\n{done.stderr[-3000:]}")
            runs.append(json.loads(done.stdout.strip().splitlines()[-1]))
    return runs if second else runs[0]


def median_of(runs, key):
    """Per name, the median over runs of ``run[key][name]`` (0 when absent)."""
    names = {name for run in runs for name in run[key]}
    return {name: statistics.median(run[key].get(name, 0.0) for run in runs) for name in names}


def largest(table, n):
    """The ``n`` largest entries of a name -> seconds table, rounded."""
    return {k: round(v, 3) for k, v in sorted(table.items(), key=lambda kv: -kv[1])[:n]}


def summarise(runs):
    """The medians of one case's repeats."""
    first = runs[0]
    return {
        "median compile s": round(statistics.median(r["compile"] for r in runs), 3),
        "median process CPU s": round(statistics.median(r["cpu"] for r in runs), 3),
        "median case wall s": round(statistics.median(r["case"] for r in runs), 3),
        "median case CPU s": round(statistics.median(r["case cpu"] for r in runs), 3),
        "median run CPU s": round(statistics.median(r["run cpu"] for r in runs), 3),
        "event kinds, exclusive median s": largest(median_of(runs, "kinds"), 10),
        "passes, exclusive median s (largest)": largest(median_of(runs, "passes"), 12),
        "LLVM lock by dispatcher compiled, median s (largest)": largest(median_of(runs, "llvm"),
                                                                        12),
        "dispatcher compiles": len(first["compiles"]),
        "dispatchers, exclusive median s (largest)": largest(median_of(runs, "compiles"), 12),
        "same bits in every repeat": len({r["value"] for r in runs}) == 1,
    }


def main(argv=None):
    def extra(parser):
        parser.add_argument("--cases", nargs="+", default=list(CASES), choices=list(CASES))
        parser.add_argument("--repeats", type=int, default=3)
        parser.add_argument("--profile", action="store_true",
                            help="one cProfile run per case instead of timed repeats")
        parser.add_argument("--baseline", default=None,
                            help="another source tree, run interleaved with this one")
        parser.add_argument("--second", action="store_true",
                            help="after each first process, a second one on its cache folders")

    args = parse_args(__doc__, argv, extra=extra)
    load = os.getloadavg()
    rows, raw = {}, {}
    if args.profile:
        for case in args.cases:
            run = child(case, True)
            rows[case] = {"compile s (under cProfile)": round(run["compile"], 3),
                          "largest own time (file:line:function, own s, cumulative s, calls)":
                              run["top"]}
    else:
        # Repeats interleave the cases, so a change of load hits all alike.
        trees = {"": None} if args.baseline is None else {"": None, " (baseline)": args.baseline}
        for _ in range(args.repeats):
            for case in args.cases:
                for label, tree in trees.items():
                    if args.second:
                        first, again = child(case, False, second=True, tree=tree)
                        raw.setdefault(case + label, []).append(first)
                        raw.setdefault(f"{case}, second process{label}", []).append(again)
                    else:
                        raw.setdefault(case + label, []).append(child(case, False, tree=tree))
        rows = {case: summarise(runs) for case, runs in raw.items()}
    for case, row in rows.items():
        print(case, json.dumps(row, indent=1))
    name = "compile_cost_profile" if args.profile else "compile_cost"
    save_json(args.out, name, {"summary": rows, "repeats": args.repeats, "baseline": args.baseline,
                               "loadavg at start": load,
                               "loadavg at end": os.getloadavg(),
                               "finished": time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime())})


if __name__ == "__main__":
    main()

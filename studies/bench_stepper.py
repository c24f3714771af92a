"""Speed of the generated TM stepper against plain compiled loops of the same
algorithm, and the taxes around it (issue 12's targets).

One run, interleaved, minimum of repeats, CPU time (varint's
``time.process_time``, the C loops' ``CLOCK_PROCESS_CPUTIME_ID``: the
machine is shared); each ratio with its spread over the repeats (the ratio
within each turn, smallest to largest); printed and stored as
``bench_stepper.json``:

1. orbit only, Hénon–Heiles, ABA864, τ = 0.05: varint against a C loop of
   the same 15 stages (``gcc -O3 -march=native``);
2. R1 full spectrum, SBAB2C, QR every step: varint against the C loop of
   :mod:`bench_tm` (and varint with its adaptive sparse renormalisation);
3. the same run with 1000 outputs against 2 outputs;
4. the first run in a new process whose kernels an earlier process compiled,
   beside the floor timed the same way in the same run (numba's first call
   of one small cached kernel: its registries, which every first run pays);
5. a FLI map of Hénon–Heiles orbits on the x = 0 section at E = 1/8 to
   t = 1e3 (``chaos_map`` defaults, SIMD lanes): orbits per second on 1 and
   2 threads.

Usage: ``python studies/bench_stepper.py [--quick] [--out DIR] [--csv FILE]``
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

import numba
import numpy as np

import varint
from varint.methods import make_propagator
from varint.methods.tm import TangentMapPropagator
from varint.schemes import DRIFT, stage_arrays
from varint.state import RunState

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from studies.bench_tm import C_LOOP as C_SPECTRUM, c_program, run_c  # noqa: E402
from studies.common import STARTED, interleaved, parse_args, ratio_spread, save_json  # noqa: E402

TAU = 0.05


def orbit_c_source(scheme, tau):
    """A C loop of the scheme's stages for the Hénon–Heiles orbit alone, the
    stage coefficients written in as constants (what a person would write)."""
    kinds, h, _ = stage_arrays(varint.get_scheme(scheme), tau)
    body = []
    for kind, c in zip(kinds, h, strict=True):
        c = float(c)                      # repr: a C literal, not "np.float64(...)"
        if kind == DRIFT:
            body.append(f"q0 += {c!r}*p0; q1 += {c!r}*p1;")
        else:
            body.append(f"p0 -= {c!r}*(q0 + 2*q0*q1); p1 -= {c!r}*(q1 + q0*q0 - q1*q1);")
    return textwrap.dedent("""\
        #include <stdio.h>
        #include <stdlib.h>
        #include <time.h>
        int main(int argc, char **argv) {
            long n = atol(argv[1]);
            double q0 = 0.0, q1 = 0.558, p0 = atof(argv[2]), p1 = 0.0;
            struct timespec a, b;
            clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &a);
            for (long s = 0; s < n; s++) {
                %s
            }
            clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &b);
            double sec = (b.tv_sec - a.tv_sec) + 1e-9*(b.tv_nsec - a.tv_nsec);
            printf("%%.6f %%.17e\\n", sec, q1);
            return 0;
        }
        """) % "\n        ".join(body)


def varint_ns_per_step(prop, x0, k, n_steps):
    """ns/step (CPU) of one advance() of a compiled propagator."""
    W0 = np.eye(x0.size)[:, :k][None]
    state = RunState.start(x0[None], W0)
    t0 = time.process_time()
    prop.advance(state, n_steps)
    return (time.process_time() - t0) / n_steps * 1e9, state


#: What :func:`first_run_seconds` times in a fresh process after ``import
#: varint`` and the model (numba imported): R1's spectrum to t = 100, or
#: the floor, the first call of one small cached kernel (numba's registries
#: and one cache load, which any first run pays: on this shared machine the
#: same floor has taken 0.8–1.3 s of CPU across sessions, so the row is
#: read against the floor of the same run).
FIRST_RUNS = {
    "r1": "import time, varint; m, x = varint.paper_orbit('R1'); t = time.process_time(); "
          "varint.lyapunov_spectrum(m, x, t_end=100.0, tau=0.05); "
          "print(time.process_time() - t)",
    "floor": "import time, varint, numpy as np; m, x = varint.paper_orbit('R1'); "
             "from varint.kernels.checks import tangent_overflow; t = time.process_time(); "
             "tangent_overflow(np.zeros((2, 1))); print(time.process_time() - t)",
}


def first_run_seconds(repeats=2, case="r1"):
    """CPU seconds of an R1 spectrum to t = 100 in a fresh process (import
    excluded), after an earlier process compiled and cached the kernels
    (``case`` "floor": the floor, :data:`FIRST_RUNS`).

    Python's bytecode of varint is cached too, in a folder of this run
    (``PYTHONPYCACHEPREFIX``), whatever ``PYTHONDONTWRITEBYTECODE`` says: an
    installed package has its ``.pyc`` files, and compiling varint's
    modules from source in every process (~0.1 s of this row) measured the
    environment, not varint (as :mod:`studies.startup` does)."""
    code = FIRST_RUNS[case]
    env = dict(os.environ)
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    env["PYTHONPATH"] = root + os.pathsep + env.get("PYTHONPATH", "")
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    with tempfile.TemporaryDirectory(prefix="varint-bytecode-") as pycache:
        env["PYTHONPYCACHEPREFIX"] = pycache
        times = [float(subprocess.run([sys.executable, "-c", code], check=True, env=env,
                                      capture_output=True, text=True).stdout.split()[-1])
                 for _ in range(repeats + 1)]
    return times[0], min(times[1:])


def outputs_tasks(n_steps, warm_rounds=1):
    """R1's spectrum with 1000 outputs and with 2, the same steps, each
    called ``warm_rounds`` times first (compiled, and past the compact
    stepper where the rounds' work passes ``COMPACT_WORK``)."""
    model, x0 = varint.paper_orbit("R1")
    t_end = n_steps * TAU
    grids = {"1000 outputs": np.linspace(t_end / 1000, t_end, 1000),
             "2 outputs": np.array([t_end / 2, t_end])}
    tasks = {name: (lambda grid=grid: varint.lyapunov_spectrum(
        model, x0, t_end=t_end, tau=TAU, t_out=grid, progress=False)) for name, grid in
        grids.items()}
    for _ in range(warm_rounds):
        for task in tasks.values():
            task()
    return tasks


def fli_map_rate(n_side, t_end, threads):
    """Orbits per second of a FLI map of the x = 0 section at E = 1/8 on
    ``threads`` threads (best of 2; the first call compiles)."""
    model = varint.models.HenonHeiles()
    grid = varint.section_grid(model, 0.125, np.linspace(-0.45, 0.65, n_side),
                               np.linspace(-0.45, 0.45, n_side))
    old = numba.get_num_threads()
    numba.set_num_threads(threads)
    try:
        varint.chaos_map(model, grid, "fli", t_end=1.0)
        best, result = np.inf, None
        for _ in range(2):
            t0 = time.perf_counter()
            result = varint.chaos_map(model, grid, "fli", t_end=t_end)
            best = min(best, time.perf_counter() - t0)
    finally:
        numba.set_num_threads(old)
    n = int(np.isfinite(np.asarray(result.values, dtype=float)).sum())
    return n / best, n


def main(argv=None):
    def extra(parser):
        parser.add_argument("--csv", help="also write the table to this CSV file")

    args = parse_args(__doc__.split("\n\n")[0], argv, extra)
    n_steps = 20_000 if args.quick else 2_000_000
    repeats = 2 if args.quick else 5
    rows = []

    def row(case, a, b, unit, target, turns=None):
        spread = ratio_spread(turns, b, a) if turns else None
        va, vb = (best[a], best[b]) if turns else (a, b)
        rows.append({"case": case, "varint": va, "reference": vb, "unit": unit,
                     "ratio": va / vb, "spread": None if spread is None else list(spread),
                     "target": target})

    model, x0 = varint.paper_orbit("R1")
    with c_program(orbit_c_source("ABA864", TAU)) as c_orbit, \
            c_program(C_SPECTRUM) as c_spec:
        orbit = make_propagator("tm", model, TAU, "none", scheme="ABA864")
        every = make_propagator("tm", model, TAU, "qr", scheme="SBAB2C", renormalize_every=1)
        sparse = make_propagator("tm", model, TAU, "qr", scheme="SBAB2C")
        # Warm up with the timed call's own length: a call's work picks its
        # stepper (compact below COMPACT_WORK orbit-steps, written out
        # above), so a shorter warm-up would leave the written-out
        # stepper's compile in the first repeat and in the ratio spreads.
        for p, k in ((orbit, 0), (every, 4), (sparse, 4)):
            varint_ns_per_step(p, x0, k, n_steps)
        tasks = {"orbit": lambda: varint_ns_per_step(orbit, x0, 0, n_steps),
                 "every": lambda: varint_ns_per_step(every, x0, 4, n_steps),
                 "sparse": lambda: varint_ns_per_step(sparse, x0, 4, n_steps)}
        if c_orbit is not None:
            for key, exe in (("c_orbit", c_orbit), ("c_spec", c_spec)):
                tasks[key] = (lambda exe=exe: (run_c(exe, n_steps, repr(float(x0[2])))[0]
                                               / n_steps * 1e9, None))
        turns = {}
        best, _ = interleaved(tasks, repeats, self_timed=set(tasks), turns=turns)
    print(f"# ns per step (CPU), best of {repeats} interleaved ({n_steps} steps); load "
          f"{STARTED['load']} at the start")
    print(f"{'case':46}{'varint':>10}{'C loop':>10}{'ratio':>8}{'target':>8}")
    if c_orbit is not None:
        for label, a, b, target in (
                ("HH orbit only, ABA864", "orbit", "c_orbit", 1.15),
                ("R1 spectrum SBAB2C, QR every step", "every", "c_spec", 0.9),
                ("R1 spectrum SBAB2C, sparse renormalisation", "sparse", "c_spec", 0.9)):
            row(label, a, b, "ns/step", target, turns)
            r = rows[-1]
            print(f"{label:46}{r['varint']:10.1f}{r['reference']:10.1f}{r['ratio']:8.2f}"
                  f"{target:8.2f}")

    turns = {}
    # Both calls share one stepper (one model, k and accumulator), whose
    # work in this process picks it: the full run warms it up past
    # COMPACT_WORK so that the written-out stepper's compile is not in a
    # timed turn (stop 59's cold run: a spread up to 144); the quick run
    # keeps the compact one throughout.
    warm_rounds = 1 if args.quick else TangentMapPropagator.COMPACT_WORK // (n_steps // 5) + 1
    best, _ = interleaved(outputs_tasks(n_steps // 10, warm_rounds), repeats,
                          clock=time.process_time,
                          turns=turns)
    row("1000 outputs / 2 outputs", "1000 outputs", "2 outputs", "s", 1.2, turns)
    r = rows[-1]
    print(f"\n1000 outputs / 2 outputs over {n_steps // 10} steps: {r['ratio']:.2f} "
          f"({r['varint']:.3f} s / {r['reference']:.3f} s; target <= 1.2)")

    cold, warm = first_run_seconds(1 if args.quick else 2)
    _, floor = first_run_seconds(1 if args.quick else 2, "floor")
    print(f"first R1 spectrum (t = 100) in a new process, kernels cached: {warm:.2f} s "
          f"(the process that filled the cache: {cold:.2f} s; target <= 0.5 s); the floor "
          f"in the same run (numba's first call of one cached kernel): {floor:.2f} s, "
          f"R1 - floor {warm - floor:.2f} s")
    rows.append({"case": "first run in a new process (s)", "varint": warm, "reference": cold,
                 "unit": "s", "ratio": warm, "spread": None, "target": 0.5, "floor": floor})

    side = 6 if args.quick else 45                 # 45 x 45 grid: about 1990 orbits
    t_map = 20.0 if args.quick else 1e3
    r1, n = fli_map_rate(side, t_map, 1)
    r2, _ = fli_map_rate(side, t_map, 2)
    print(f"\nFLI map, {n} orbits of the x = 0 section, t = {t_map:g}: {r1:.0f} orbits/s "
          f"on 1 thread, {r2:.0f} on 2 ({r2 / r1:.2f}x; target >= 1.0 under load)")
    rows.append({"case": "FLI map orbits/s, 1 thread", "varint": r1, "reference": r2,
                 "unit": "orbits/s (wall)", "ratio": r2 / r1, "spread": None, "target": 1.0})

    if args.csv:
        with open(args.csv, "w") as f:
            f.write("case,varint,reference,ratio,target\n")
            f.writelines(f"{r['case']},{r['varint']:.4g},{r['reference']:.4g},"
                         f"{r['ratio']:.3f},{r['target']}\n" for r in rows)
    save_json(args.out, "bench_stepper", {"n_steps": n_steps, "repeats": repeats, "rows": rows},
              times="CPU (process_time; the C loops' CLOCK_PROCESS_CPUTIME_ID), except the "
                    "rows whose unit says wall")
    return 0


if __name__ == "__main__":
    sys.exit(main())

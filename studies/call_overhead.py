"""The fixed cost of one ``varint.integrate`` call, this code against a
baseline copy of varint (issue 27: at global errors 1e-8/1e-10 on R1 the
fixed per-call cost was about half of varint's time against heyoka).

Two calls of the frontier study's kind (orbit + one tangent vector, R1,
``varint.integrate(model, x0, t_end, tau=..., scheme=..., deviations=w)``):

* ``fixed``: one step (t_end = τ = 0.05, s15odr8): almost all of it is the
  call's fixed cost (option checks, initial-state checks, the conserved
  quantities, the propagator, the driver, the accuracy verdict, the result
  and its provenance);
* ``frontier``: t_end = 1e3 at τ = 0.4 with s35odr10, the frontier study's
  best varint run near error 1e-8;
* ``prepared``: the ``fixed`` call as a prepared run's call
  (``varint.prepare(model, "integrate", 0.05, tau=0.05, scheme="s15odr8",
  deviations=w)`` once, then ``run(x0)``): issue 28's "fixed cost of a
  one-step run" (:mod:`studies.call_profile` gives its stages);
* ``prepared_new``: the same prepared run, every call from another x0 of
  a fixed seeded set of :data:`NEW_STATES` states near R1 (offsets of
  1e-6, seed 2), taken in turn, so that nothing kept from one x0 to the
  next can flatter ``prepared``; its SHA-256 covers the results of the
  whole set;
* ``prepared_nov``: ``prepared`` as on a CPU with AVX-512, where NumPy's
  power is SVML's (issue 28): in the worker, both codes,
  ``potential_rows.NUMPY_POWER_IS_LIBM = False`` and the memoised compiled
  V's forgotten (``rows_from.cache_clear()``), then a new
  ``HenonHeiles()``: main before call18 makes no compiled V of ``y ** 3``
  there (NumPy's V at each call), call18's leaves only the cube to NumPy
  (:class:`varint.models.potential_rows.NumPyPowers`). The flag is set
  back once the run's first call has made its short path;
* ``generated``: ``prepared`` on a model built from an expression,
  ``from_potential((x**2 + y**2)/2 + x**2*y**2, [x, y])`` (the x²y²
  coupled oscillators: squares only, so its compiled V is made on every
  CPU, :mod:`varint.models.potential_rows`), from (0.3, 0.2, 0.1, −0.2).

Each code runs in its own worker process (``python -c`` with the code's
directory first on ``sys.path``), the workers alternate (interleaved
rounds), each round takes the minimum over many calls, and the result is
the minimum over rounds, in µs of CPU time (``time.process_time``) and of
wall time. The workers also return the SHA-256 of the results' numbers:
the two codes must agree bitwise.

Usage::

    git archive main varint | tar -x -C /tmp/base
    python studies/call_overhead.py --baseline /tmp/base

The stored result compared this branch with ``main`` as it was when the
branch started (its commit message gives the figures). call18's is also in
``results/call18/``, with a second run of 7 rounds in the same load window
(``call_overhead_repeat.json``).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from studies.common import parse_args, save_json  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]

#: The worker: run in a fresh interpreter with one code's directory first
#: on sys.path; prints one JSON line.
WORKER = r"""
import functools, hashlib, itertools, json, sys, time
sys.path.insert(0, sys.argv[1])
import numpy as np
import sympy as sp
import varint
from varint.models import potential_rows
from varint.models.henon_heiles import HenonHeiles
calls = int(sys.argv[2])
hh, hh_x0 = varint.paper_orbit("R1")
qx, qy = sp.symbols("x y")
generated = varint.models.from_potential((qx**2 + qy**2) / 2 + qx**2 * qy**2, [qx, qy],
                                         name="x2y2")
gen_x0 = np.array([0.3, 0.2, 0.1, -0.2])
w0 = np.random.default_rng(1).standard_normal(len(hh_x0))
w0 /= np.linalg.norm(w0)
new = [hh_x0 + 1e-6 * d
       for d in np.random.default_rng(2).standard_normal((int(sys.argv[3]), len(hh_x0)))]
cases = {"fixed": (0.05, 0.05, "s15odr8"), "frontier": (1e3, 0.4, "s35odr10"),
         "prepared": (0.05, 0.05, "s15odr8"), "prepared_new": (0.05, 0.05, "s15odr8"),
         "prepared_nov": (0.05, 0.05, "s15odr8"), "generated": (0.05, 0.05, "s15odr8")}
out = {"varint": varint.__file__}
for name, (t_end, tau, scheme) in cases.items():
    model, x0 = (generated, gen_x0) if name == "generated" else (hh, hh_x0)
    if name == "prepared_nov":
        # As on a CPU with AVX-512 (see the module docstring).
        libm = potential_rows.NUMPY_POWER_IS_LIBM
        potential_rows.NUMPY_POWER_IS_LIBM = False
        potential_rows.rows_from.cache_clear()
        model = HenonHeiles()
    def call():
        return varint.integrate(model, x0, t_end, tau=tau, scheme=scheme,
                                deviations=w0[:, None])
    starts = [x0]
    if name.startswith("prepared") or name == "generated":
        run = varint.prepare(model, "integrate", t_end, tau=tau, scheme=scheme,
                             deviations=w0[:, None])
        run(x0)         # builds the run; later calls take the short path
        call = functools.partial(run, x0)
    if name == "prepared_nov":
        potential_rows.NUMPY_POWER_IS_LIBM = libm
        potential_rows.rows_from.cache_clear()
    if name == "prepared_new":
        starts, turn = new, itertools.cycle(new)
        def call():
            return run(next(turn))
    h = hashlib.sha256()
    for x in starts:
        r = run(x) if name == "prepared_new" else call()
        for a in (r.state, r.deviations, r.energy_error, r.t):
            h.update(np.ascontiguousarray(a).tobytes())
    n = max(3, calls // 50) if name == "frontier" else calls
    cpu = wall = float("inf")
    for _ in range(n):
        c0, t0 = time.process_time(), time.perf_counter()
        call()
        wall = min(wall, time.perf_counter() - t0)
        cpu = min(cpu, time.process_time() - c0)
    out[name] = {"cpu_us": cpu * 1e6, "wall_us": wall * 1e6, "sha256": h.hexdigest()}
print(json.dumps(out))
"""


#: The cases each worker times (:data:`WORKER`).
CASES = ("fixed", "frontier", "prepared", "prepared_new", "prepared_nov", "generated")

#: How many states ``prepared_new`` takes in turn.
NEW_STATES = 64


def worker(code_dir, calls):
    """One worker's minima (see :data:`WORKER`)."""
    done = subprocess.run([sys.executable, "-c", WORKER, str(code_dir), str(calls),
                           str(NEW_STATES)],
                          capture_output=True, text=True, check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def main(argv=None):
    def extra(parser):
        parser.add_argument("--baseline", type=Path, default=None,
                            help="directory holding the baseline's varint package (default: "
                                 "this code itself, which measures only the noise)")
        parser.add_argument("--rounds", type=int, default=5)
        parser.add_argument("--calls", type=int, default=400)

    args = parse_args(__doc__.splitlines()[0], argv, extra)
    rounds, calls = (2, 50) if args.quick else (args.rounds, args.calls)
    baseline = ROOT if args.baseline is None else args.baseline.resolve()
    contenders = {"this": ROOT, "baseline": baseline}
    best = {}
    load_before = os.getloadavg()
    for _ in range(rounds):
        for label, code in contenders.items():
            got = worker(code, calls)
            for case in CASES:
                b = best.setdefault(label, {}).setdefault(case, dict(got[case]))
                for key in ("cpu_us", "wall_us"):
                    b[key] = min(b[key], got[case][key])
                if b["sha256"] != got[case]["sha256"]:
                    raise RuntimeError(f"{label} {case}: results differ between workers")
    summary = {}
    for case in CASES:
        this, base = best["this"][case], best["baseline"][case]
        summary[case] = {"this_cpu_us": this["cpu_us"], "baseline_cpu_us": base["cpu_us"],
                         "this_wall_us": this["wall_us"],
                         "baseline_wall_us": base["wall_us"],
                         "cut_cpu_us": base["cpu_us"] - this["cpu_us"],
                         "ratio_cpu": base["cpu_us"] / this["cpu_us"],
                         "bitwise_equal": this["sha256"] == base["sha256"]}
    # The fixed cost's share of the frontier run, each code.
    for label in contenders:
        summary[f"fixed_share_{label}"] = (best[label]["fixed"]["cpu_us"]
                                           / best[label]["frontier"]["cpu_us"])
    data = {"rounds": rounds, "calls": calls, "new_states": NEW_STATES,
            "baseline": str(args.baseline),
            "load": {"before": load_before, "after": os.getloadavg(), "cpus": os.cpu_count()},
            "best": best, "summary": summary}
    save_json(args.out, "call_overhead", data)
    print(f"load {data['load']['before']} -> {data['load']['after']}")
    for case in CASES:
        s = summary[case]
        print(f"{case}: CPU {s['baseline_cpu_us']:.0f} -> {s['this_cpu_us']:.0f} µs "
              f"({s['ratio_cpu']:.2f}x), bitwise equal: {s['bitwise_equal']}")
    return data


if __name__ == "__main__":
    main()

"""Which compensation the frontier needs: the TM method's
``compensated=False``, ``"orbit"``, ``"step"`` and ``True`` on C2 and R1 against
heyoka at global error 1e-10 (issue 27, the target C2 at 1e-10 ≥ 1.0×).

Why a level of its own: the compensated stepper is bound by its
floating-point operations (a compensated update is four operations instead
of one fused multiply–add, and a stage of s35odr10 on Hénon–Heiles with
one vector makes eight updates, four of the orbit and four of the vector).
Compensating the orbit's alone (``compensated="orbit"``) gives full
compensation's orbit bit for bit; the vector's own round-off matters only
where its error does not follow the orbit's, which this study measures
(the error of each level, state and vector apart). The step level
(``compensated="step"``) adds the orbit's stages plainly to its
displacement since the step began and that displacement to the state by
compensated summation once per step: fewer operations on the step's
critical path than ``"orbit"``, other bits, a floor near its.

Case: the paper's C2 and R1 to t = 1e3 (``--quick``: C2 only, τ = 0.25
and 0.2, one repeat), the orbit and the seeded unit tangent vector of
:mod:`studies.frontier`, s35odr10 through prepared runs
(:func:`studies.frontier.prepared_runner`) at each level over a ladder of
steps; heyoka as in :mod:`studies.frontier` at the tolerances around 1e-10
(:data:`TOLS`). Errors as in :mod:`studies.frontier` (the larger relative
error of state and vector against the extended-precision Taylor
reference), cost the CPU time of one call on one thread, the minimum over
the repeats of all contenders called in turn
(:func:`studies.frontier.interleaved`); the cost at 1e-10 is read off each
contender's cost–error front (:func:`studies.claims.cost_at`) and the
ratio is heyoka's over varint's (> 1: varint is faster). Only ratios
within one run mean anything; the load is stored with them.

Usage: ``python studies/compensation_levels.py [--quick] [--out DIR]``
"""

from __future__ import annotations

import os
import sys
from pathlib import Path


if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import numba  # noqa: E402

import varint  # noqa: E402
from studies.bench_peers import seeded_vectors  # noqa: E402
from studies.claims import cost_at, pareto  # noqa: E402
from studies.common import parse_args, save_csv, save_json  # noqa: E402
from studies.frontier import (heyoka_runner, interleaved, prepared_runner,  # noqa: E402
                              relative)
from varint.cache import reference  # noqa: E402

LEVELS = (False, "orbit", "step", True)
TAUS = (0.3125, 0.25, 0.2, 0.16, 0.125, 0.1)
QUICK_TAUS = (0.25, 0.2)
#: heyoka's tolerances whose errors bracket 1e-10 on both orbits
#: (``studies/results/frontier.json``).
TOLS = (1e-11, 1e-12, 1e-13, 1e-14)
TARGET = 1e-10


def level_name(level):
    return {False: "plain", "orbit": "+co", "step": "+cs", True: "+c"}[level]


def orbit_rows(name, t_end, taus, repeats):
    model, x0 = varint.paper_orbit(name)
    w0 = seeded_vectors(model.dim, 1, 1, seed=0)[0][:, 0]
    ref = reference(model, x0, t_end, tau=0.1, deviations=w0[:, None])
    tasks, meta = {}, {}
    for level in LEVELS:
        for tau in taus:
            label = f"s35odr10{level_name(level)} tau={tau:g}"
            tasks[label] = prepared_runner(model, "s35odr10", tau, w0, level)
            meta[label] = {"contender": "varint", "level": level_name(level), "tau": tau,
                           "steps": round(t_end / tau)}
    for tol in TOLS:
        label = f"heyoka tol={tol:g}"
        tasks[label] = heyoka_runner(model, tol)
        meta[label] = {"contender": "heyoka", "level": "heyoka", "tol": tol}
    for task in tasks.values():
        task(x0, w0, t_end)         # compile, prepare
    calls = {label: (lambda f=task: f(x0, w0, t_end)) for label, task in tasks.items()}
    rows = []
    for label, (wall, cpu, (x, w)) in interleaved(calls, repeats).items():
        rows.append({"orbit": name, "config": label, **meta[label],
                     "error_state": relative(x, ref.state),
                     "error_vector": relative(w, ref.deviations[:, 0]),
                     "error": max(relative(x, ref.state), relative(w, ref.deviations[:, 0])),
                     "seconds": wall, "cpu_seconds": cpu})
    return rows


def costs(rows):
    """Per orbit and contender (level or heyoka): the CPU cost at
    :data:`TARGET` and heyoka's ratio to it; each level's floor."""
    out = []
    for name in dict.fromkeys(r["orbit"] for r in rows):
        mine = [r for r in rows if r["orbit"] == name]
        fronts = {}
        for level in dict.fromkeys(r["level"] for r in mine):
            rs = [r for r in mine if r["level"] == level]
            fronts[level] = (cost_at(pareto([(r["cpu_seconds"], r["error"]) for r in rs]),
                                     TARGET), min(r["error"] for r in rs))
        heyoka = fronts["heyoka"][0][0]
        for level, ((cost, how), floor) in fronts.items():
            out.append({"orbit": name, "contender": level, "cpu_seconds_at_1e-10": cost,
                        "how": how, "floor": floor,
                        "ratio": None if cost is None or heyoka is None else heyoka / cost})
    return out


def main(argv=None):
    args = parse_args(__doc__.splitlines()[0], argv)
    numba.set_num_threads(1)
    load = {"before": list(os.getloadavg()), "cpus": os.cpu_count()}
    orbits = ("C2",) if args.quick else ("C2", "R1")
    taus = QUICK_TAUS if args.quick else TAUS
    repeats = 1 if args.quick else 15
    rows = [r for name in orbits for r in orbit_rows(name, 1e3, taus, repeats)]
    load["after"] = list(os.getloadavg())
    table = costs(rows)
    save_csv(args.out, "compensation_levels", rows,
             ["orbit", "config", "contender", "level", "tau", "steps", "tol", "error_state",
              "error_vector", "error", "seconds", "cpu_seconds"])
    result = {"rows": rows, "costs": table, "load": load, "repeats": repeats,
              "quick": args.quick}
    save_json(args.out, "compensation_levels", result)
    print(f"load {load}")
    for r in rows:
        print(f"{r['orbit']} {r['config']:26s} cpu {r['cpu_seconds'] * 1e3:8.4f} ms  "
              f"state {r['error_state']:.2e}  vector {r['error_vector']:.2e}")
    for r in table:
        c, ratio = r["cpu_seconds_at_1e-10"], r["ratio"]
        cost = "-" if c is None else f"{c * 1e3:.4f} ms"
        print(f"{r['orbit']} {r['contender']:7s} at 1e-10: {cost} ({r['how']}), floor "
              f"{r['floor']:.2e}, heyoka/varint {'-' if ratio is None else round(ratio, 2)}")
    return result


if __name__ == "__main__":
    main()

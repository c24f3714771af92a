"""What ``compensated="step"`` costs per step over the plain stepper
(issue 27: C2 at 1e-10, where s35odr10 with ``compensated="step"`` is
varint's cheapest run).

The cost of a step, without the call's fixed cost: the CPU time of a
prepared run (:func:`studies.frontier.prepared_runner`) to a long horizon
less that of the same run to a short one, over the steps between them.
Both levels and both horizons are called in turn (:func:`studies.common.
interleaved`, this process's CPU time, one thread), the minimum over the
repeats, so that the machine's load falls on all alike; the ratio of the
levels' per-step costs is the figure (only ratios within one run mean
anything; the load is stored with them).

Case: the paper's C2 with the seeded unit tangent vector of
:mod:`studies.frontier`, s35odr10 and SRKN14a at τ = 0.2 and 0.125
(``--quick``: s35odr10 only, horizons ten times shorter, three repeats).

Accuracy beside the cost (a cheaper step must not be a less accurate one):
the global error (the larger relative error of the final state and of
the final tangent vector against the extended-precision Taylor reference,
:func:`varint.cache.reference`) of each level, on the timed cases at the
long horizon and on the case of ``tests/test_compensated.py::
test_step_compensation_against_the_reference`` (R1 and C2, SRKN14a at
τ = 1/32 to t = 400, its tangent vector; its bound on R1 is 1e-13) and
three neighbours of it (p_x + 10⁻³ k, the tangent vector of seed k, k =
1 … 3): one orbit's round-off error is one draw of a random walk, whose
spread over the four shows what a difference between two variants
means. Not with ``--quick``.

Measured (21 repeats, this machine's CPU time): on main before the change
(``step_compensation_cost_before.json``, 63e9f7c, load 0.4 → 1.0) +cs cost
+68.7 % (s35odr10) and +60.8 % (SRKN14a) per step over plain; with each
kick's p left unmaterialised and only the changed compensations kept
(stop 50's ``step_compensation_cost.json``, 7af3a92, load 1.6 → 1.2)
+19.1 % and +22.4 %, the results bitwise those of before.

Rerun at stop 51 on main (``step_compensation_cost.json``, and
``_main_alt1``/``_alt2``, load 10–13 on 2 CPUs): +cs over plain per step
+21.4 %, +19.9 %, +12.7 % (s35odr10) and +35.2 %, +26.1 %, +33.1 %
(SRKN14a); at this load a run's ratio moves by ±8 points. The errors
(geometric means over the test case's four realisations, stored with
them): R1 1.41e-13 with +cs against 1.37e-12 plain, C2 9.8e-14 against
2.9e-12. The test's own realisation is the luckiest of R1's four (3.6e-14;
the others 1.0e-13 to 3.4e-13).

Tried at stop 51 and not taken, each stored with its diff of
``varint/codegen/tm.py`` and run as above (the study's code the same):

* ``_displaced_drift`` (front16's idea): each drift's q for the forces as
  fma(h, δp, q_start + (δq + h p_start)), the kick's δp one fused
  multiply–add from the forces instead of a multiply–add and an addition.
  Not faster: +16.8 %, +34.5 %, +22.1 % (s35odr10; ``_alt1``, ``_alt2``)
  against main's above. Less accurate: the forces read q rounded twice
  instead of once (start + displacement), and the errors rose to R1
  2.8e-13 and C2 1.35e-13 (R1's state's 2.3e-14 against 1.6e-14), the
  test's realisation on R1 to 9.0e-13, above its bound 1e-13.
* ``_zero_start``: that, and each step's displacement started at zero with
  the compensation subtracted at the step's end (Kahan's y = δ − c), so
  that the next step's first stages do not wait on the two subtractions
  that form c. +22.9 % (one run); R1 4.5e-13 (C2 9.6e-14): the stages
  then read a state off by the compensation for a whole step.

Usage: ``python studies/step_compensation_cost.py [--quick] [--out DIR]``
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import numba  # noqa: E402
import numpy as np  # noqa: E402

import varint  # noqa: E402
from studies.bench_peers import seeded_vectors  # noqa: E402
from studies.common import interleaved, parse_args, save_csv, save_json  # noqa: E402
from studies.frontier import prepared_runner, relative  # noqa: E402
from varint.cache import reference  # noqa: E402

#: scheme -> step.
CASES = {"s35odr10": 0.2, "SRKN14a": 0.125}
LEVELS = (False, "step")
#: The two horizons whose difference is timed.
HORIZONS = (200.0, 1000.0)


#: The case of test_step_compensation_against_the_reference: orbits, scheme,
#: step and horizon.
TEST_CASE = (("R1", "C2"), "SRKN14a", 1 / 32, 400.0)
#: Its realisations: k = 0 is the test's own, k > 0 its neighbours
#: (module docstring).
REALISATIONS = 4


def level_name(level):
    return "+cs" if level == "step" else "plain"


def global_error(model, x0, w0, t_end, scheme, tau, level):
    """The larger relative error of the final state and tangent vector of
    ``varint.integrate`` against the Taylor reference (as the frontier's)."""
    ref = reference(model, x0, t_end, tau=0.1, deviations=w0[:, None])
    r = varint.integrate(model, x0, t_end, tau=tau, scheme=scheme, deviations=w0[:, None],
                         compensated=level)
    return {"state_error": relative(r.state, ref.state),
            "vector_error": relative(r.deviations[:, 0], ref.deviations[:, 0])}


def accuracy(model, x0, w0, cases, t_end):
    """Rows of :func:`global_error` for every level, on the timed cases (C2
    to ``t_end``) and on the test's case (module docstring)."""
    rows = []
    for scheme, tau in cases.items():
        for level in LEVELS:
            rows.append({"orbit": "C2", "scheme": scheme, "tau": tau, "t_end": t_end,
                         "level": level_name(level),
                         **global_error(model, x0, w0, t_end, scheme, tau, level)})
    names, scheme, tau, t_end = TEST_CASE
    for name in names:
        m, x_test = varint.paper_orbit(name)
        for k in range(REALISATIONS):
            x = np.array(x_test, dtype=float)
            x[m.dim // 2] += 1e-3 * k               # p_x
            # k = 0: the test's tangent vector.
            w = np.random.default_rng(k).standard_normal(m.dim)
            w /= np.linalg.norm(w)
            for level in LEVELS:
                rows.append({"orbit": name, "realisation": k, "scheme": scheme, "tau": tau,
                             "t_end": t_end, "level": level_name(level),
                             **global_error(m, x, w, t_end, scheme, tau, level)})
    for r in rows:
        r["error"] = max(r["state_error"], r["vector_error"])
    return rows


def spread(errors):
    """Per orbit and level of the test's case, the geometric means over its
    realisations of the state's, the vector's and the global error."""
    out = []
    for name in TEST_CASE[0]:
        for level in LEVELS:
            mine = [e for e in errors if e["orbit"] == name and "realisation" in e
                    and e["level"] == level_name(level)]
            if mine:
                out.append({"orbit": name, "level": level_name(level), "realisations": len(mine),
                            **{f"geomean_{c}": float(np.exp(np.mean(np.log([e[c] for e in mine]))))
                               for c in ("state_error", "vector_error", "error")}})
    return out


def main(argv=None):
    args = parse_args(__doc__.splitlines()[0], argv)
    numba.set_num_threads(1)
    load = {"before": list(os.getloadavg()), "cpus": os.cpu_count()}
    cases = {"s35odr10": CASES["s35odr10"]} if args.quick else CASES
    horizons = tuple(t / 10 for t in HORIZONS) if args.quick else HORIZONS
    repeats = 3 if args.quick else 21
    model, x0 = varint.paper_orbit("C2")
    w0 = seeded_vectors(model.dim, 1, 1, seed=0)[0][:, 0]
    tasks = {}
    for scheme, tau in cases.items():
        for level in LEVELS:
            run = prepared_runner(model, scheme, tau, w0, level)
            for t_end in horizons:
                run(x0, w0, t_end)          # compile, prepare
                tasks[(scheme, level, t_end)] = (lambda f=run, te=t_end: f(x0, w0, te))
    best, _ = interleaved(tasks, repeats, clock=time.process_time)
    rows = []
    for scheme, tau in cases.items():
        per = {}
        for level in LEVELS:
            short, long = (best[(scheme, level, t)] for t in horizons)
            steps = round((horizons[1] - horizons[0]) / tau)
            per[level] = (long - short) / steps
            rows.append({"scheme": scheme, "tau": tau, "level": level_name(level),
                         "short_cpu_seconds": short, "long_cpu_seconds": long,
                         "steps_between": steps, "per_step_ns": 1e9 * per[level]})
        rows[-1]["over_plain"] = per["step"] / per[False] - 1.0
    load["after"] = list(os.getloadavg())
    errors = [] if args.quick else accuracy(model, x0, w0, cases, horizons[1])
    means = spread(errors)
    save_csv(args.out, "step_compensation_cost", rows,
             ["scheme", "tau", "level", "short_cpu_seconds", "long_cpu_seconds",
              "steps_between", "per_step_ns", "over_plain"])
    result = {"rows": rows, "errors": errors, "error_means": means, "horizons": horizons, "repeats": repeats, "load": load,
              "quick": args.quick}
    save_json(args.out, "step_compensation_cost", result)
    print(f"load {load}; {repeats} repeats, min; CPU time per step (horizons {horizons})")
    for r in rows:
        over = "" if "over_plain" not in r else f"  +cs over plain {r['over_plain']:+.1%}"
        print(f"{r['scheme']:9s} tau={r['tau']:<6g} {r['level']:6s} "
              f"{r['per_step_ns']:7.1f} ns/step{over}")
    for e in errors:
        print(f"{e['orbit']} {e.get('realisation', '')} {e['scheme']:9s} tau={e['tau']:<8g} "
              f"t={e['t_end']:<6g} "
              f"{e['level']:6s} error {e['error']:.2e} (state {e['state_error']:.2e}, "
              f"vector {e['vector_error']:.2e})")
    for m in means:
        print(f"{m['orbit']} {m['level']:6s} geometric mean over {m['realisations']}: error "
              f"{m['geomean_error']:.2e} (state {m['geomean_state_error']:.2e}, vector "
              f"{m['geomean_vector_error']:.2e})")
    return result


if __name__ == "__main__":
    main()

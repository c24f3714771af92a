"""Cost and accuracy of the baselines against the TM method, and each
design choice of :mod:`baselines` measured: blocks with virtual
renormalisation versus restarting every τ, and their length; CVODE's
Jacobian (exact, from the model's Hessian and third derivatives, versus
SUNDIALS' finite differences) and linear solver; k deviation vectors versus
the full 2N × 2N variational matrix in heyoka. Each baseline against its
library driven directly is ``studies/bench_libraries.py``.

Set-up: Hénon–Heiles R1, τ = 0.05, t = 1000 (10 with ``--quick``), QR every
τ, k = 1 and k = 4 vectors; CVODE's linear solvers on R3 (FPU-β, N = 8,
τ = 0.02, k = 16: 272 equations), t = 100 (2). Each time is the minimum of
repeats taken in turn (:func:`studies.common.interleaved`) of a warm
propagator told the run's horizon (the fixed cost of setting up a run,
about 20 ms for heyoka, is left out), in ms of CPU time
(``time.process_time``, one thread) per unit of integration time; errors
are against the extended-precision Taylor reference (orbit: max |x − x_ref|
at the end; X: max |X_i − X_i,ref|). The machine is shared: only ratios
within one run mean anything.

Usage: ``python studies/bench_baselines.py [--quick] [--out DIR]``
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import varint  # noqa: E402
from studies.claims import costs_more, dominates  # noqa: E402
from studies.common import (Claims, interleaved, parse_args, ratio_spread,  # noqa: E402
                            save_csv, save_json)
from varint.cache import reference  # noqa: E402
from varint.methods import make_propagator  # noqa: E402
from varint.state import RunState, initial_deviations  # noqa: E402

#: (label, method, options); the defaults' rows say so. Blocks are given
#: in intervals of τ = 0.05 (1000 = 50 time units).
CONFIGS = [
    ("tm SBAB2C", "tm", {"scheme": "SBAB2C"}),
    ("tm ABA864", "tm", {"scheme": "ABA864"}),
    ("taylor double (default: blocks of 50 tu)", "taylor", {}),
    ("taylor double, blocks of 5 tu", "taylor", {"block": 100}),
    ("taylor double, restart every tau", "taylor", {"block": 1}),
    ("taylor extended (reference)", "taylor", {"precision": "extended"}),
    ("cvode 1e-10 (default: 1000 tu, exact Jacobian)", "cvode", {}),
    ("cvode 1e-10, finite-difference Jacobian", "cvode", {"jacobian": "differences"}),
    ("cvode 1e-10, blocks of 50 tu", "cvode", {"block": 1000}),
    ("cvode 1e-10, blocks of 10 tu", "cvode", {"block": 200}),
    ("cvode 1e-10, 10 tu, finite differences", "cvode", {"block": 200,
                                                        "jacobian": "differences"}),
    ("cvode 1e-10, restart every tau", "cvode", {"block": 1}),
    ("dop853 delta=1e-5", "dop853", {"delta": 1e-5}),
    ("dop853 delta=1e-10", "dop853", {"delta": 1e-10}),
    ("dop853 delta=1e-5, SciPy's solver", "dop853", {"delta": 1e-5, "engine": "scipy"}),
    ("dop853 delta=1e-5, lanes engine", "dop853", {"delta": 1e-5, "engine": "lanes"}),
]
#: CVODE's linear solvers on a chain (R3): the Newton systems of 272
#: equations.
LINSOLVERS = [
    ("dense, exact Jacobian", {"linsolver": "dense"}),
    ("dense, finite differences", {"linsolver": "dense", "jacobian": "differences"}),
    ("gmres, exact J·v", {"linsolver": "gmres", "jacobian": "exact"}),
    ("gmres, J·v by differences (default above 100 equations)", {"linsolver": "gmres"}),
]


def _warm(method, model, tau, x0, W0, n, **options):
    """A propagator compiled and warmed up, told the run's horizon ``n``,
    and a callable advancing a fresh state by ``n`` intervals."""
    prop = make_propagator(method, model, tau, "qr", **options)
    prop.advance(RunState.start(x0[None], W0), 1)
    if hasattr(prop, "set_horizon"):
        prop.set_horizon(n)

    def run():
        state = RunState.start(x0[None], W0)
        prop.advance(state, n)
        return state
    return run


def methods_table(t_end, ks, repeats, quick):
    """Each configuration's propagator advancing a run state to ``t_end``
    (the run loop itself, without the fixed cost of setting up a run);
    SciPy's own solver (Python at every step) only in the full run's first
    turn, a tenth of the span."""
    model, x0 = varint.paper_orbit("R1")
    n = int(round(t_end / 0.05))
    rows = []
    for k in ks:
        W0 = initial_deviations(4, k, 1, seed=0)
        ref = reference(model, x0, t_end, 0.05, kind="lyapunov_spectrum", deviations=W0[0],
                        t_out=1)
        tasks = {label: _warm(method, model, 0.05, x0, W0, n, **options)
                 for label, method, options in CONFIGS if options.get("engine") != "scipy"}
        best, out = interleaved(tasks, repeats, clock=time.process_time)
        if not quick:
            # Python at every step: one run of a tenth of the span, scaled.
            slow = [c for c in CONFIGS if c[2].get("engine") == "scipy"]
            for label, method, options in slow:
                run = _warm(method, model, 0.05, x0, W0, n // 10, **options)
                seconds, _ = interleaved({label: run}, 1, clock=time.process_time)
                best[label], out[label] = 10 * seconds[label], None
        for label, _, _ in CONFIGS:
            if label not in best:
                continue
            seconds, state = best[label], out[label]
            if state is None:
                rows.append({"config": label, "k": k, "ms_per_tu": 1e3 * seconds / t_end,
                             "work_per_tu": None, "orbit_error": None, "X_error": None,
                             "time": "derived: a tenth of the span, times 10"})
                continue
            counts = state.counts
            work = counts.get("rhs_evaluations", counts.get("taylor_steps", counts.get("gradient")))
            rows.append({"config": label, "k": k, "ms_per_tu": 1e3 * seconds / t_end,
                         "work_per_tu": work / t_end,
                         "orbit_error": float(np.abs(state.x[0] - ref.state).max()),
                         "X_error": float(np.abs(state.renormalized("qr").log_growth()[0] / (n * 0.05)
                                                 - ref.exponents[-1]).max()),
                         "time": "measured"})
    return rows


def batch_table(t_end, repeats, orbits=64):
    """DOP853 on a batch of ``orbits`` orbits near R1 and C1 (k = 4): the
    compiled engine (one orbit after the other) against the lanes engine,
    CPU time per orbit and unit time, interleaved."""
    model, r1 = varint.paper_orbit("R1")
    _, c1 = varint.paper_orbit("C1")
    X = np.stack([r1, c1] * (orbits // 2))
    W0 = initial_deviations(4, 4, orbits, seed=0)
    n = int(round(t_end / 0.05))
    tasks = {}
    for engine in ("compiled", "lanes"):
        prop = make_propagator("dop853", model, 0.05, "qr", engine=engine)
        prop.advance(RunState.start(X[:2], W0[:2]), 1)
        tasks[engine] = (lambda prop=prop: prop.advance(RunState.start(X, W0), n))
    turns = {}
    best, _ = interleaved(tasks, repeats, clock=time.process_time, turns=turns)
    return [{"engine": engine, "orbits": orbits, "ms_per_tu_per_orbit":
             1e3 * best[engine] / t_end / orbits,
             "spread_vs_compiled": ratio_spread(turns, engine, "compiled")}
            for engine in tasks]


def linsolver_table(t_end, repeats):
    """CVODE's linear solver and Jacobian on R3 with 16 vectors (272
    equations): every combination, interleaved."""
    model, x0 = varint.paper_orbit("R3")
    tau, k = 0.02, model.dim
    n = int(round(t_end / tau))
    W0 = initial_deviations(model.dim, k, 1, seed=0)
    tasks = {label: _warm("cvode", model, tau, x0, W0, n, **options)
             for label, options in LINSOLVERS}
    best, out = interleaved(tasks, repeats, clock=time.process_time)
    ref = out[LINSOLVERS[0][0]]
    return [{"config": label, "equations": model.dim * (1 + k),
             "ms_per_tu": 1e3 * best[label] / t_end,
             "rhs_per_tu": out[label].counts["rhs_evaluations"] / t_end,
             "orbit_vs_dense_exact": float(np.abs(out[label].x[0] - ref.x[0]).max())}
            for label, _ in LINSOLVERS]


def kvec_table(t_end, ks):
    """heyoka alone: integrating k columns versus the full matrix, over the
    same blocks of τ outputs the Taylor baseline uses (integration only)."""
    import heyoka as hy

    from varint.baselines.taylor import heyoka_system

    model, x0 = varint.paper_orbit("R1")
    system, variables = heyoka_system(model.symbolic())
    d = len(variables)
    grid = 0.05 * np.arange(21)
    rows = []
    for k in ks:
        for label, args, width in (("k columns", variables[:k], k),
                                   ("full 2N x 2N", hy.var_args.vars, d)):
            ta = hy.taylor_adaptive(hy.var_ode_sys(system, args, order=1),
                                    np.zeros(d * (1 + width)))
            y0 = np.concatenate([x0, np.eye(d)[:, :width].ravel()])

            def run(ta=ta, y0=y0):
                for _ in range(int(round(t_end))):
                    ta.time = 0.0
                    ta.state[:] = y0
                    ta.propagate_grid(grid)

            run()
            seconds, _ = interleaved({label: run}, 3, clock=time.process_time)
            seconds = seconds[label]
            rows.append({"k": k, "system": label, "equations": d * (1 + width),
                         "ms_per_tu": 1e3 * seconds / t_end})
    return rows


def _print(title, rows, columns):
    print(f"\n{title}")
    print("  ".join(f"{c:>12}" if c != "config" else f"{c:<34}" for c in columns))
    for row in rows:
        cells = []
        for c in columns:
            v = row[c]
            cells.append(f"{v:<34}" if c == "config" else
                         f"{v:>12.3g}" if isinstance(v, float) else f"{v!s:>12}")
        print("  ".join(cells))


def add_claims(claims, rows, kvec, linsolvers, ks, batch=None):
    """The cost claims, from the tables (as run, or from
    ``bench_baselines.json``), by the rules :func:`claims.costs_more` and
    :func:`claims.dominates`: each choice of the defaults against the
    alternatives measured beside it."""
    by = {(r["config"], r["k"]): r for r in rows}
    cv = "cvode 1e-10 (default: 1000 tu, exact Jacobian)"
    ty = "taylor double (default: blocks of 50 tu)"
    for k in ks:
        for family, block, restart in (("cvode", cv, "cvode 1e-10, restart every tau"),
                                       ("taylor", ty, "taylor double, restart every tau")):
            dearer = costs_more(by[restart, k]["ms_per_tu"], by[block, k]["ms_per_tu"])
            claims.add(f"{family}: blocks with virtual renormalisation are cheaper than "
                       f"restarting every tau (k = {k})", "-",
                       f"{dearer.value:.1f}x faster; orbit error "
                       f"{by[block, k]['orbit_error']:.1e} vs {by[restart, k]['orbit_error']:.1e}",
                       dearer.holds, rules=[dearer])
        fd = by["cvode 1e-10, finite-difference Jacobian", k]
        dearer = costs_more(by[cv, k]["ms_per_tu"], fd["ms_per_tu"])
        claims.add(f"cvode: the exact Jacobian costs no more than SUNDIALS' difference quotients "
                   f"(k = {k})", "-", f"exact/differences {dearer.text}; orbit error "
                   f"{by[cv, k]['orbit_error']:.1e} (exact) vs {fd['orbit_error']:.1e}",
                   not dearer.holds, rules=[dearer],
                   note="the same tolerance, another Newton iteration: the error moves with "
                        "where the steps fall, by up to a few times either way")
        for default, other, what in (
                (cv, "cvode 1e-10, blocks of 50 tu", "blocks of 1000 time units"),
                (cv, "cvode 1e-10, blocks of 10 tu", "blocks of 1000 time units"),
                (cv, "cvode 1e-10, 10 tu, finite differences",
                 "the exact Jacobian and blocks of 1000 time units together"),
                (ty, "taylor double, blocks of 5 tu", "blocks of 50 time units")):
            a, b = by[default, k], by[other, k]
            j = dominates(a["ms_per_tu"], a["orbit_error"], b["ms_per_tu"], b["orbit_error"])
            claims.add(f"{default.split(' (')[0]}: {what} as fast and as accurate as "
                       f"'{other}' (k = {k})", "-", j.text, j.holds, rules=[j])
    for k in (1, 2):
        cols = [r for r in kvec if r["k"] == k]
        dearer = costs_more(cols[1]["ms_per_tu"], cols[0]["ms_per_tu"])
        claims.add(f"heyoka: {k} columns cost less than the full 4x4 variational matrix",
                   "-", f"full matrix {dearer.value:.2f}x the cost", dearer.holds,
                   rules=[dearer])
    if batch:
        eng = {r["engine"]: r for r in batch}
        dearer = costs_more(eng["compiled"]["ms_per_tu_per_orbit"],
                            eng["lanes"]["ms_per_tu_per_orbit"])
        claims.add(f"dop853: on a batch of {eng['lanes']['orbits']} orbits the lanes engine "
                   "costs less per orbit than the compiled one (one orbit after the other)",
                   "-", f"compiled {dearer.text} the lanes engine's cost", dearer.holds,
                   rules=[dearer])
    lin = {r["config"]: r for r in linsolvers}
    best = min(linsolvers, key=lambda r: r["ms_per_tu"])
    default = lin[LINSOLVERS[3][0]]
    j = costs_more(default["ms_per_tu"], best["ms_per_tu"])
    claims.add(f"cvode on {default['equations']} equations (R3, k = 16): the default, GMRES "
               "with difference Jacobian-vector products, costs no more than the fastest "
               "linear solver measured", "-", f"{default['ms_per_tu']:.3g} ms/tu; fastest: "
               f"{best['config']} {best['ms_per_tu']:.3g} ms/tu ({j.text})", not j.holds,
               rules=[j])


def main(argv=None):
    def extra(parser):
        parser.add_argument("--judge-stored", action="store_true",
                            help="judge the claims again from the stored measurements")

    args = parse_args(__doc__.splitlines()[0], argv, extra)
    if args.judge_stored:
        stored = json.loads((args.out / "bench_baselines.json").read_text())
        claims = Claims("bench_baselines", args.out)
        add_claims(claims, stored["methods"], stored["kvec"], stored["linsolvers"], (1, 4),
                   stored.get("batch"))
        claims.save()
        save_json(args.out, "bench_baselines", {**stored, "claims": claims.items},
                  judged_again=True)
        return stored
    t_end = 10.0 if args.quick else 1000.0
    ks = (1, 4)
    repeats = 1 if args.quick else 5
    rows = methods_table(t_end, ks, repeats, args.quick)
    _print(f"R1, tau = 0.05, t = {t_end:g}, QR every tau (min of runs, warm)", rows,
           ["config", "k", "ms_per_tu", "work_per_tu", "orbit_error", "X_error"])
    kvec = kvec_table(t_end, (1, 2))
    _print("heyoka, double: k columns versus the full variational matrix", kvec,
           ["k", "system", "equations", "ms_per_tu"])
    linsolvers = linsolver_table(2.0 if args.quick else 100.0, repeats)
    _print("cvode on R3 (FPU, N = 8), k = 16: linear solver and Jacobian", linsolvers,
           ["config", "equations", "ms_per_tu", "rhs_per_tu", "orbit_vs_dense_exact"])

    batch = batch_table(2.0 if args.quick else 100.0, repeats)
    _print("DOP853 on a batch of orbits (R1 and C1, k = 4): engines", batch,
           ["engine", "orbits", "ms_per_tu_per_orbit"])

    claims = Claims("bench_baselines", args.out)
    add_claims(claims, rows, kvec, linsolvers, ks, batch)
    claims.save()
    save_csv(args.out, "bench_baselines", rows, list(rows[0]))
    save_csv(args.out, "bench_baselines_kvec", kvec, list(kvec[0]))
    save_csv(args.out, "bench_baselines_linsolver", linsolvers, list(linsolvers[0]))
    result = {"methods": rows, "kvec": kvec, "linsolvers": linsolvers, "batch": batch,
              "claims": claims.items}
    save_json(args.out, "bench_baselines", result,
              times="measured (CPU), except rows whose 'time' says derived")
    return result


if __name__ == "__main__":
    main()

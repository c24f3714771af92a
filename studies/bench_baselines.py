"""Cost and accuracy of the baselines against the TM method, and the two
design choices of :mod:`baselines`: blocks with virtual renormalisation
versus restarting every τ, and k deviation vectors versus the full
2N × 2N variational matrix in heyoka.

Set-up: Hénon–Heiles R1, τ = 0.05, t = 100 (10 with ``--quick``), QR every
τ, k = 1 and k = 4 vectors. Each time is the minimum of three warm runs of
the propagator (the fixed cost of setting up a run, about 20 ms for heyoka,
is left out), in ms of wall time per unit of integration time; errors
are against the extended-precision Taylor reference (orbit: max |x − x_ref|
at the end; X: max |X_i − X_i,ref|). The machine is shared: only ratios
within one run mean anything.

Usage: ``python studies/bench_baselines.py [--quick] [--out DIR]``
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import varint  # noqa: E402
from studies.claims import costs_more  # noqa: E402
from studies.common import Claims, parse_args, save_csv, save_json  # noqa: E402
from varint.cache import reference  # noqa: E402
from varint.methods import make_propagator  # noqa: E402
from varint.state import RunState, initial_deviations  # noqa: E402

CONFIGS = [
    ("tm SBAB2C", "tm", {"scheme": "SBAB2C"}),
    ("tm ABA864", "tm", {"scheme": "ABA864"}),
    ("taylor double, blocks of 5 tu", "taylor", {}),
    ("taylor double, restart every tau", "taylor", {"block": 1}),
    ("taylor extended (reference)", "taylor", {"precision": "extended"}),
    ("cvode 1e-10, blocks of 10 tu", "cvode", {}),
    ("cvode 1e-10, restart every tau", "cvode", {"block": 1}),
    ("dop853 delta=1e-5", "dop853", {"delta": 1e-5}),
    ("dop853 delta=1e-10", "dop853", {"delta": 1e-10}),
]


def _time(fn, repeats=3):
    best, out = np.inf, None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def methods_table(t_end, ks, repeats):
    """Each configuration's propagator advancing a run state to ``t_end``
    (the run loop itself, without the fixed cost of setting up a run)."""
    model, x0 = varint.paper_orbit("R1")
    n = int(round(t_end / 0.05))
    rows = []
    for k in ks:
        W0 = initial_deviations(4, k, 1, seed=0)
        ref = reference(model, x0, t_end, 0.05, kind="lyapunov_spectrum", deviations=W0[0],
                        t_out=1)
        for label, method, options in CONFIGS:
            prop = make_propagator(method, model, 0.05, "qr", **options)
            prop.advance(RunState.start(x0[None], W0), 1)  # compile and warm up

            def run():
                state = RunState.start(x0[None], W0)
                prop.advance(state, n)
                return state

            seconds, state = _time(run, repeats)
            counts = state.counts
            work = counts.get("rhs_evaluations", counts.get("taylor_steps", counts.get("gradient")))
            rows.append({"config": label, "k": k, "ms_per_tu": 1e3 * seconds / t_end,
                         "work_per_tu": work / t_end,
                         "orbit_error": float(np.abs(state.x[0] - ref.state).max()),
                         "X_error": float(np.abs(state.renormalized("qr").log_growth()[0] / (n * 0.05)
                                                 - ref.exponents[-1]).max())})
    return rows


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

            def run():
                for _ in range(int(round(t_end))):
                    ta.time = 0.0
                    ta.state[:] = y0
                    ta.propagate_grid(grid)

            run()
            seconds, _ = _time(run)
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


def add_claims(claims, rows, kvec, ks):
    """The cost claims, from the two tables (as run, or from
    ``bench_baselines.json``), by the rule :func:`claims.costs_more`."""
    by = {(r["config"], r["k"]): r for r in rows}
    for k in ks:
        for family, block, restart in (("cvode", "cvode 1e-10, blocks of 10 tu",
                                        "cvode 1e-10, restart every tau"),
                                       ("taylor", "taylor double, blocks of 5 tu",
                                        "taylor double, restart every tau")):
            dearer = costs_more(by[restart, k]["ms_per_tu"], by[block, k]["ms_per_tu"])
            claims.add(f"{family}: blocks with virtual renormalisation are cheaper than "
                       f"restarting every tau (k = {k})", "-",
                       f"{dearer.value:.1f}x faster; orbit error "
                       f"{by[block, k]['orbit_error']:.1e} vs {by[restart, k]['orbit_error']:.1e}",
                       dearer.holds, rules=[dearer])
    for k in (1, 2):
        cols = [r for r in kvec if r["k"] == k]
        dearer = costs_more(cols[1]["ms_per_tu"], cols[0]["ms_per_tu"])
        claims.add(f"heyoka: {k} columns cost less than the full 4x4 variational matrix",
                   "-", f"full matrix {dearer.value:.2f}x the cost", dearer.holds,
                   rules=[dearer])


def main(argv=None):
    args = parse_args(__doc__.splitlines()[0], argv)
    t_end = 10.0 if args.quick else 100.0
    ks = (1, 4)
    rows = methods_table(t_end, ks, repeats=1 if args.quick else 3)
    _print(f"R1, tau = 0.05, t = {t_end:g}, QR every tau (min of runs, warm)", rows,
           ["config", "k", "ms_per_tu", "work_per_tu", "orbit_error", "X_error"])
    kvec = kvec_table(t_end, (1, 2))
    _print("heyoka, double: k columns versus the full variational matrix", kvec,
           ["k", "system", "equations", "ms_per_tu"])

    claims = Claims("bench_baselines", args.out)
    add_claims(claims, rows, kvec, ks)
    claims.save()
    save_csv(args.out, "bench_baselines", rows, list(rows[0]))
    save_csv(args.out, "bench_baselines_kvec", kvec, list(kvec[0]))
    result = {"methods": rows, "kvec": kvec, "claims": claims.items}
    save_json(args.out, "bench_baselines", result)
    return result


if __name__ == "__main__":
    main()

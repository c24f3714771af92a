"""Benchmark: a SALI chaos map of the Hénon–Heiles section x = 0, p_x ≥ 0 at
H = 0.125 (200 × 200 grid, t = 1e3, τ = 0.05), against doing the same with a
Python loop over heyoka and over pynamicalsys.

varint.chaos_map runs the map compiled and parallel over orbits, with and
without early stopping (SALI < 1e-8); with ``--dask N`` also on a local
Dask cluster of N single-threaded workers. The loops run a sample of the
same orbits, one at a time, with the same check times and threshold, and
are extrapolated to the whole map in orbits per second (printed, not
asserted: timings on a shared machine are noisy). The verdicts
(chaotic = SALI below 1e-8) of the sample are compared with the map's.

* heyoka: double-precision Taylor integrator on the orbit and two
  deviation vectors (``var_ode_sys``), ``propagate_until`` every τ, vectors
  normalised there — the usual user loop.
* pynamicalsys 1.7.0 (``--compare``; not a dependency of varint, install it
  with ``pip install pynamicalsys==1.7.0``): ``HamiltonianSystem("henon
  heiles").SALI`` with its 4th-order Yoshida integrator ("svy4", τ = 0.05)
  and the same threshold.

Run: ``python studies/bench_chaos_map.py [--quick] [--compare] [--dask 2]``.
"""

from __future__ import annotations

import os
import sys
import time

import numpy as np

import varint
from varint.models import HenonHeiles
from varint.state import initial_deviations

try:
    from common import Claims, Stopwatch, figure, parse_args, save_csv, save_json
except ImportError:  # imported as studies.bench_chaos_map
    from .common import Claims, Stopwatch, figure, parse_args, save_csv, save_json

ENERGY, TAU, THRESHOLD = 0.125, 0.05, 1e-8


def section(model, n_grid):
    """The map's initial conditions: an n_grid × n_grid grid of (y, p_y) on
    the section x = 0, p_x ≥ 0 at H = ENERGY (the allowed points)."""
    return varint.section_grid(model, ENERGY, np.linspace(-0.45, 0.7, n_grid),
                               np.linspace(-0.45, 0.45, n_grid))


def heyoka_loop(model, X, t_end, steps, indices, seed=0):
    """SALI of each orbit of X by a Python loop over heyoka; returns
    (values, seconds without the one-off compilation)."""
    import heyoka as hy

    from varint.baselines.taylor import heyoka_system

    system, variables = heyoka_system(model.symbolic())
    ta = hy.taylor_adaptive(hy.var_ode_sys(system, variables[:2], order=1),
                            np.zeros(model.dim * 3))
    vs = ta.get_vslice(order=1)
    checks = set(int(s) for s in steps)
    out = np.empty(len(X))
    start = time.perf_counter()
    for m, (x, index) in enumerate(zip(X, indices, strict=True)):
        W = initial_deviations(model.dim, 2, 1, seed, [index])[0]
        ta.time = 0.0
        ta.state[:model.dim] = x
        ta.state[vs] = W.ravel()
        sali = np.nan
        for n in range(1, int(round(t_end / TAU)) + 1):
            ta.propagate_until(n * TAU)
            W = ta.state[vs].reshape(model.dim, 2)
            W /= np.linalg.norm(W, axis=0)
            ta.state[vs] = W.ravel()
            if n in checks:
                sali = min(np.linalg.norm(W[:, 0] + W[:, 1]), np.linalg.norm(W[:, 0] - W[:, 1]))
                if sali < THRESHOLD:
                    break
        out[m] = sali
    return out, time.perf_counter() - start


def pynamicalsys_loop(X, t_end):
    """SALI of each orbit by pynamicalsys (its own seeds and checks);
    returns (values, seconds without the one-off compilation), or None."""
    try:
        from pynamicalsys import HamiltonianSystem
    except ImportError:
        return None
    ds = HamiltonianSystem(model="henon heiles")
    ds.integrator("svy4", time_step=TAU)
    ds.SALI(X[0, :2], X[0, 2:], 10 * TAU, threshold=THRESHOLD)  # compile
    out = np.empty(len(X))
    start = time.perf_counter()
    for m, x in enumerate(X):
        out[m] = ds.SALI(x[:2], x[2:], t_end, threshold=THRESHOLD)[1]
    return out, time.perf_counter() - start


def _dask_map(model, grid, t_end, workers):
    from distributed import Client, LocalCluster

    with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster, Client(cluster) as client:
        varint.chaos_map(model, grid, "sali", t_end=10 * TAU, tau=TAU, client=client)  # compile
        with Stopwatch() as sw:
            r = varint.chaos_map(model, grid, "sali", t_end=t_end, tau=TAU, client=client)
    return r, sw.seconds


def main(argv=None):
    def extra(parser):
        parser.add_argument("--compare", action="store_true",
                            help="also time pynamicalsys (if installed)")
        parser.add_argument("--dask", type=int, default=0, metavar="N",
                            help="also run on a local Dask cluster of N workers")

    args = parse_args(__doc__.split("\n\n")[0], argv, extra)
    n_grid, t_end, n_sample = (40, 500.0, 8) if args.quick else (200, 1e3, 40)
    model = HenonHeiles()
    grid = section(model, n_grid)
    m = len(grid)
    with Stopwatch() as compile_sw:
        varint.chaos_map(model, grid, "sali", t_end=10 * TAU, tau=TAU, progress=False)
    runs = {}
    for label, threshold in (("varint, early stopping", "default"),
                             ("varint, no early stopping", None)):
        with Stopwatch() as sw:
            r = varint.chaos_map(model, grid, "sali", t_end=t_end, tau=TAU, threshold=threshold,
                                 progress=False)
        runs[label] = (r, sw.seconds)
    ref, ref_seconds = runs["varint, early stopping"]
    load = os.getloadavg()[0]
    if args.dask:
        runs[f"varint on Dask, {args.dask} workers"] = _dask_map(model, grid, t_end, args.dask)

    sample = np.linspace(0, m - 1, n_sample).round().astype(int)
    verdict = ref.values < THRESHOLD
    rows = [{"method": label, "orbits": m, "seconds": s, "orbits_per_second": m / s,
             "steps": r.provenance.counts["steps"],
             "agree_with_map": float(np.mean((r.values < THRESHOLD) == verdict))}
            for label, (r, s) in runs.items()]
    chaotic = verdict[sample]
    hy_values, hy_seconds = heyoka_loop(model, grid.states[sample], t_end, ref.t / TAU, sample)
    rows.append({"method": "Python loop over heyoka (Taylor, double)", "orbits": n_sample,
                 "seconds": hy_seconds, "orbits_per_second": n_sample / hy_seconds,
                 "steps": None,
                 "agree_with_map": float(np.mean((hy_values < THRESHOLD) == chaotic))})
    if args.compare:
        py = pynamicalsys_loop(grid.states[sample], t_end)
        if py is None:
            print("pynamicalsys is not installed: pip install pynamicalsys==1.7.0 to compare")
        else:
            rows.append({"method": "Python loop over pynamicalsys 1.7.0 (svy4)",
                         "orbits": n_sample, "seconds": py[1],
                         "orbits_per_second": n_sample / py[1], "steps": None,
                         "agree_with_map": float(np.mean((py[0] < THRESHOLD) == chaotic))})
    base = rows[0]["orbits_per_second"]
    for row in rows:
        row["speedup_of_varint"] = base / row["orbits_per_second"]

    print(f"SALI map of Hénon–Heiles x = 0 at H = {ENERGY}: {n_grid}×{n_grid} grid, {m} "
          f"allowed orbits, t = {t_end:g}, τ = {TAU}, threshold {THRESHOLD:g}; "
          f"compilation {compile_sw.seconds:.1f} s (once per process)")
    head = f"{'method':45} {'orbits':>7} {'seconds':>8} {'orbits/s':>9} {'varint x':>8} agree"
    print(head)
    print("-" * len(head))
    for row in rows:
        print(f"{row['method']:45} {row['orbits']:7d} {row['seconds']:8.2f} "
              f"{row['orbits_per_second']:9.1f} {row['speedup_of_varint']:8.1f} "
              f"{row['agree_with_map']:5.0%}")
    columns = list(rows[0])
    save_csv(args.out, "bench_chaos_map", rows, columns)
    result = {"grid": n_grid, "orbits": m, "t_end": t_end, "rows": rows, "load_average": load,
              "compile_seconds": compile_sw.seconds,
              "decided": int(ref.decided.sum()),
              "chaotic_fraction": float(np.mean(ref.values < THRESHOLD))}
    save_json(args.out, "bench_chaos_map", result)

    claims = Claims("bench_chaos_map", args.out)
    claims.add(f"A {n_grid}×{n_grid} SALI map of the Hénon–Heiles section to t = {t_end:g} "
               "runs in under a minute on this machine's 2 cores", "—",
               f"{ref_seconds:.1f} s ({m / ref_seconds:.0f} orbits/s; without early "
               f"stopping {runs['varint, no early stopping'][1]:.1f} s)",
               ref_seconds < 60 if not args.quick else None, figure="bench_chaos_map.png",
               note=f"load average {load:.1f} on {os.cpu_count()} cores during the run "
                    "(the machine is shared)")
    for row in rows[2:]:
        if row["method"].startswith("varint on Dask"):
            same = bool(np.array_equal(runs[row["method"]][0].values, ref.values,
                                       equal_nan=True))
            claims.add(f"The same map on a local Dask cluster ({args.dask} workers) gives the "
                       "same values", "—", f"values bitwise equal: {same}; {row['seconds']:.1f} "
                       f"s ({row['orbits_per_second']:.0f} orbits/s)", same)
            continue
        claims.add(f"varint against a {row['method']}", "—",
                   f"{row['speedup_of_varint']:.0f}× more orbits per second "
                   f"({row['orbits_per_second']:.1f} vs {base:.0f}); verdicts agree on "
                   f"{row['agree_with_map']:.0%} of {row['orbits']} orbits", None)
    claims.save()

    path, plt = figure(args.out, "bench_chaos_map")
    fig, ax = plt.subplots(figsize=(6, 4.8), layout="constrained")
    ref.plot(ax)
    ax.set_title(f"SALI at t ≤ {t_end:g} ({m / ref_seconds:.0f} orbits/s)")
    fig.savefig(path, dpi=130)
    plt.close(fig)
    result["claims"] = claims.items
    return result


if __name__ == "__main__":
    main()
    sys.exit(0)

"""Benchmark: a MEGNO stability map of a two-planet system, varint against
REBOUND's WHFast with variational particles, per thread, with the
classification of both checked against a tight reference.

The system is REBOUND's MEGNO example (after Rein & Tamayo 2015): the Sun,
Jupiter (a = 5.204, e = 0.048) and a Saturn-mass planet whose (a, e) spans
[7, 10] × [0, 0.5] — the 5:2 and 2:1 mean-motion resonances with Jupiter
and the chaotic zone of orbit crossings. G = 1, AU, solar masses (a year
is 2π). Both codes start from the same Cartesian state of every grid point
(:meth:`varint.models.Planetary.to_rebound`) and take the same step dt = 1
(Jupiter's period / 75, REBOUND's example).

* varint: ``chaos_map(..., "megno")`` with ``method="tm"`` — the
  Wisdom–Holman map in Jacobi coordinates, ten steps of dt per
  renormalisation interval τ = 10 (``SplittingScheme.repeated(10)``),
  one thread (``numba.set_num_threads(1)``); with early stopping (an orbit
  is frozen once Ȳ > 4 at a check time) and without.
* REBOUND: as its documentation does it (the MEGNO tutorial "Stability
  map with MEGNO and WHFast" and python_examples/megno) — one
  ``Simulation`` per grid point, ``integrator = "whfast"``, ``dt = 1``,
  ``init_megno()``, ``exit_max_distance = 20`` (an escape ends the
  simulation: unstable), ``integrate(t_end, exact_finish_time=0)``,
  ``megno()``, one after the other in this process. REBOUND refuses MEGNO
  with ``safe_mode = 0`` ("MEGNO is not compatible with WHFast's
  safe_mode=0", REBOUND 5.2.2), so WHFast runs in its default safe mode.
  varint stops escaping orbits likewise (``escape_radius=20``: |q| of the
  Jacobi positions).
* The reference: heyoka's Taylor integrator at tolerance 1e-15 on the same
  model and MEGNO code (``method="taylor"``), on a random sample of the
  grid; with ``--ias15`` also REBOUND's IAS15 with ``init_megno()``.

An orbit is chaotic when Ȳ > 4 at t_end (or it failed: non-finite, or
stopped early above the threshold); agreement is the fraction of the sample
where a code's verdict is the reference's.

The grid is timed in blocks of 64 points, the two codes alternating which
goes first in each block, and the times summed: CPU time of this process
(every contender runs on one thread), which the other users of a shared
machine do not inflate, and wall time beside it; the load average is
recorded. The whole grid runs once (no repeats: its cost); the kernel
section below takes the minimum of repeats. A kernel section times one step of each code on one
orbit (CPU time, minimum of 5 interleaved repeats).

Scaling (this machine has 2 shared cores): the map runs 1e3 orbits of the
outer planet (t_end = 1e3 · 2π · 8.5^1.5), not the 1e4 of the target;
``--long N`` also races both codes over the full 1e4 orbits on N points of
the grid (without a reference). ``--quick``: a 4 × 4 grid, 20 orbits.

``--grid N --sample M``: an N × N grid and M reference points (a smaller
check of the race).

Run: ``python studies/bench_planetary.py [--quick] [--ias15] [--long 32]
[--grid 32] [--sample 128]``.
"""

from __future__ import annotations

import math
import os
import sys
import time
import warnings

import numba
import numpy as np

import varint
from varint.kernels.planetary_batch import LANES
from varint.models import Planetary

try:
    from common import Claims, figure, parse_args, save_csv, save_json
except ImportError:  # imported as studies.bench_planetary
    from .common import Claims, figure, parse_args, save_csv, save_json

MASSES = (1.0, 0.000954, 0.000285)
JUPITER = dict(a=5.204, M=0.600, omega=0.257, e=0.048)
SATURN = dict(M=0.871, omega=1.616)
A_RANGE, E_RANGE = (7.0, 10.0), (0.0, 0.5)
DT, SUBSTEPS = 1.0, 10
THRESHOLD = 4.0
ESCAPE = 20.0
BLOCK = 64
#: One orbit of the outer planet at the middle of the grid, a = 8.5.
OUTER_PERIOD = 2 * math.pi * 8.5 ** 1.5


def grid(model, n):
    """The n × n grid of Saturn's (a, e)."""
    return varint.element_grid(model, [JUPITER, dict(a=9.0, e=0.0, **SATURN)], 2,
                               np.linspace(*A_RANGE, n), np.linspace(*E_RANGE, n))


def varint_map(model, X, t_end, threshold, method="tm", **options):
    """MEGNO of the orbits X by varint.chaos_map; returns (values, status,
    t_stop)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if method == "tm":
            options.setdefault("scheme", varint.get_scheme("SABA1").repeated(SUBSTEPS))
        r = varint.chaos_map(model, X, "megno", t_end=t_end, tau=DT * SUBSTEPS,
                             threshold=threshold, method=method, progress=False,
                             chunk_size=len(X), escape_radius=ESCAPE, **options)
    return r.values, r.status, r.t_stop


def rebound_megno(model, x0, t_end, seed, integrator="whfast"):
    """⟨Y⟩ of one grid point by REBOUND, as its documentation does it."""
    sim = model.to_rebound(x0)
    sim.integrator = integrator
    if integrator == "whfast":
        sim.dt = DT
    sim.init_megno(seed=seed)
    sim.exit_max_distance = ESCAPE
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")   # "timestep larger than orbital period", as the docs
        try:
            sim.integrate(t_end, exact_finish_time=0)
        except Exception:                 # an escape or a collision: unstable
            return np.nan
    return sim.megno()


def chaotic(values, status=None):
    """The verdict: Ȳ > THRESHOLD, or the orbit failed (non-finite value or
    a failure status)."""
    values = np.asarray(values, dtype=float)
    verdict = ~np.isfinite(values) | (values > THRESHOLD)
    if status is not None:
        verdict |= np.asarray(status) > 0
    return verdict


def agreement(verdict, reference):
    """The fraction of orbits whose verdicts are the reference's."""
    return float(np.mean(np.asarray(verdict) == np.asarray(reference)))


def kernel_times(model, x0, repeats=5, t_end=2e4):
    """CPU nanoseconds per step of dt of varint's WH map (τ = dt, and ten
    steps per τ) and of REBOUND's WHFast with MEGNO, on one orbit; the
    minimum of ``repeats`` interleaved repeats."""
    import rebound  # noqa: F401  (only here and in rebound_megno)

    wh10 = varint.get_scheme("SABA1").repeated(SUBSTEPS)
    contenders = {
        "varint WH, tau = dt": lambda: varint.megno(model, x0, t_end, tau=DT, t_out=1),
        "varint WH x10 per tau": lambda: varint.megno(model, x0, t_end, tau=DT * SUBSTEPS,
                                                      scheme=wh10, t_out=1),
        "REBOUND WHFast + MEGNO": lambda: rebound_megno(model, x0, t_end, 0),
    }
    for run in contenders.values():
        run()                                             # compile, warm up
    best = {name: math.inf for name in contenders}
    for _ in range(repeats):
        for name, run in contenders.items():
            t0 = time.process_time()
            run()
            best[name] = min(best[name], time.process_time() - t0)
    return {name: 1e9 * s / (t_end / DT) for name, s in best.items()}


def race(model, X, t_end, seed=0):
    """The grid in blocks, varint (early stopping, and none) and REBOUND
    alternating; returns their values, statuses and summed CPU and wall
    times (CPU time of this process: every contender runs on one thread
    here, and other users' load does not enter it)."""
    out = {"varint": [], "varint, no early stopping": [], "REBOUND": []}
    status = {"varint": [], "varint, no early stopping": []}
    seconds = dict.fromkeys(out, 0.0)
    wall = dict.fromkeys(out, 0.0)
    for b, start in enumerate(range(0, len(X), BLOCK)):
        block = X[start:start + BLOCK]

        def run_varint(block=block):
            values, st, _ = varint_map(model, block, t_end, THRESHOLD)
            return "varint", values, st

        def run_plain(block=block):
            values, st, _ = varint_map(model, block, t_end, None)
            return "varint, no early stopping", values, st

        def run_rebound(block=block, start=start):
            return "REBOUND", np.array([rebound_megno(model, x, t_end, seed + start + i)
                                        for i, x in enumerate(block)]), None

        order = (run_varint, run_plain, run_rebound)
        for run in (order if b % 2 == 0 else order[::-1]):
            t0, w0 = time.process_time(), time.perf_counter()
            name, values, st = run()
            seconds[name] += time.process_time() - t0
            wall[name] += time.perf_counter() - w0
            out[name].append(values)
            if st is not None:
                status[name].append(st)
    values = {k: np.concatenate(v) for k, v in out.items()}
    status = {k: np.concatenate(v) for k, v in status.items()}
    return values, status, seconds, wall


def main(argv=None):
    def extra(parser):
        parser.add_argument("--ias15", action="store_true",
                            help="also REBOUND's IAS15 as a second reference on the sample")
        parser.add_argument("--long", type=int, default=0, metavar="N",
                            help="also race both codes over 1e4 outer orbits on N grid points")
        parser.add_argument("--grid", type=int, default=32, metavar="N",
                            help="an N × N grid (default 32: 1024 points)")
        parser.add_argument("--sample", type=int, default=128, metavar="N",
                            help="grid points checked against the reference (default 128)")

    args = parse_args(__doc__.split("\n\n")[0], argv, extra)
    n_grid, orbits, n_sample = (4, 20, 4) if args.quick else (args.grid, 1000, args.sample)
    n_sample = min(n_sample, n_grid * n_grid)
    t_end = orbits * OUTER_PERIOD
    numba.set_num_threads(1)                     # per thread, as REBOUND runs
    model = Planetary(MASSES)
    g = grid(model, n_grid)
    X = g.states
    load_start = os.getloadavg()[0]

    t0 = time.perf_counter()
    # Compile once per process (the lanes too: a block's worth of points).
    varint_map(model, X[:LANES], 20 * DT * SUBSTEPS, THRESHOLD)
    varint_map(model, X[:LANES], 20 * DT * SUBSTEPS, None)
    compile_seconds = time.perf_counter() - t0
    kernels = kernel_times(model, X[len(X) // 2], repeats=2 if args.quick else 5,
                           t_end=2e3 if args.quick else 2e4)

    values, status, seconds, wall = race(model, X, t_end)
    sample = np.sort(np.random.default_rng(2026).choice(len(X), n_sample, replace=False))
    t0 = time.perf_counter()
    ref_values, ref_status, _ = varint_map(model, X[sample], t_end, None, method="taylor",
                                           tol=1e-15)
    ref_seconds = time.perf_counter() - t0
    reference = chaotic(ref_values, ref_status)
    verdicts = {name: chaotic(v[sample], status.get(name, np.zeros(len(v), int))[sample])
                for name, v in values.items()}
    rows = []
    for name in values:
        rows.append({"code": name, "grid_points": len(X), "seconds": seconds[name],
                     "wall_seconds": wall[name],
                     "seconds_per_point": seconds[name] / len(X),
                     "varint_speedup": seconds[name] / seconds["varint"],
                     "varint_speedup_wall": wall[name] / wall["varint"],
                     "agreement_with_reference": agreement(verdicts[name], reference),
                     "chaotic_fraction": float(np.mean(chaotic(
                         values[name], status.get(name))))})
    second = {}
    if args.ias15:
        t0 = time.perf_counter()
        ias = np.array([rebound_megno(model, X[m], t_end, m, "ias15") for m in sample])
        second = {"seconds": time.perf_counter() - t0,
                  "agreement_with_heyoka": agreement(chaotic(ias), reference),
                  "agreement": {name: agreement(verdicts[name], chaotic(ias)) for name in values}}
    long = {}
    if args.long:
        pick = np.linspace(0, len(X) - 1, args.long).round().astype(int)
        long_values, _, long_seconds, long_wall = race(model, X[pick], 10 * t_end if not args.quick
                                            else 2 * t_end)
        long = {"grid_points": len(pick), "orbits": 10 * orbits if not args.quick else 2 * orbits,
                "seconds": long_seconds, "wall_seconds": long_wall,
                "varint_speedup_rebound": long_seconds["REBOUND"] / long_seconds["varint"],
                "varint_speedup_rebound_no_early_stopping":
                    long_seconds["REBOUND"] / long_seconds["varint, no early stopping"],
                "verdicts_agree_varint_rebound": agreement(
                    chaotic(long_values["varint"]), chaotic(long_values["REBOUND"]))}
    load_end = os.getloadavg()[0]

    speed = seconds["REBOUND"] / seconds["varint"]
    print(f"MEGNO map, {n_grid}×{n_grid} grid of Saturn's (a, e), {orbits:g} outer orbits "
          f"(t = {t_end:.4g}), dt = {DT}, one thread; compile {compile_seconds:.0f} s once; "
          f"load average {load_start:.1f} → {load_end:.1f}")
    for row in rows:
        print(f"  {row['code']:28} {row['seconds']:8.1f} s CPU ({row['wall_seconds']:.1f} s wall)  "
              f"{row['seconds_per_point'] * 1e3:8.2f} ms/point  agreement {row['agreement_with_reference']:.1%}")
    print(f"  reference (heyoka, tol 1e-15) on {n_sample} points: {ref_seconds:.0f} s")
    print("  kernels (CPU ns per step of dt): " + ", ".join(f"{k}: {v:.0f}"
                                                          for k, v in kernels.items()))
    result = {"grid": n_grid, "grid_points": len(X), "outer_orbits": orbits, "t_end": t_end,
              "dt": DT, "substeps": SUBSTEPS, "threshold": THRESHOLD, "sample": int(n_sample),
              "rows": rows, "reference_seconds": ref_seconds, "kernels_ns_per_step": kernels,
              "compile_seconds": compile_seconds, "ias15": second, "long": long,
              "load_average": [load_start, load_end], "cores": os.cpu_count(),
              "versions": varint.results.package_versions("rebound", "heyoka"),
              "rebound_safe_mode": 1,
              "speedup_rebound_over_varint": speed}
    save_csv(args.out, "bench_planetary", rows, list(rows[0]))
    save_json(args.out, "bench_planetary", result)
    np.savez(args.out / "bench_planetary_map.npz", a=g.u, e=g.v, sample=sample,
             reference=ref_values, **{name.replace(" ", "_").replace(",", ""): v
                                      for name, v in values.items()})

    claims = Claims("bench_planetary", args.out, source="own")
    agree = {row["code"]: row["agreement_with_reference"] for row in rows}
    claims.add(f"MEGNO map of a two-planet system ({len(X)} grid points, {orbits:g} outer "
               "orbits), varint against REBOUND WHFast + variational particles per thread, at "
               "least REBOUND's classification agreement with a tight reference: ≥ 3×",
               "≥ 3× (issue target)",
               f"{speed:.1f}× with early stopping ("
               f"{seconds['REBOUND'] / seconds['varint, no early stopping']:.1f}× without); "
               f"agreement with heyoka (tol 1e-15) on {n_sample} points: varint "
               f"{agree['varint']:.1%}, REBOUND {agree['REBOUND']:.1%}",
               None if args.quick else (speed >= 3 and agree["varint"] >= agree["REBOUND"]),
               figure="bench_planetary.png",
               note=f"scaled: {orbits:g} outer orbits instead of 1e4 (2 shared cores); CPU "
                    f"times (wall {wall['REBOUND'] / wall['varint']:.1f}×), load average "
                    f"{load_start:.1f} → {load_end:.1f}; REBOUND in safe "
                    "mode (it refuses MEGNO with safe_mode = 0)")
    if long:
        claims.add(f"The same race over the full 1e4 outer orbits ({long['grid_points']} "
                   "points)", "≥ 3×",
                   f"{long['varint_speedup_rebound']:.1f}× with early stopping "
                   f"({long['varint_speedup_rebound_no_early_stopping']:.1f}× without)",
                   None if args.quick else long["varint_speedup_rebound"] >= 3,
                   note="no reference at this horizon (its cost)")
    claims.save()

    path, plt = figure(args.out, "bench_planetary")
    fig, axes = plt.subplots(1, 2, figsize=(10, 4), layout="constrained", sharey=True)
    extent = [*A_RANGE, *E_RANGE]
    for ax, name in zip(axes, ("varint", "REBOUND"), strict=True):
        image = np.clip(np.nan_to_num(values[name], nan=4.0), 1.8, 4.0).reshape(n_grid, n_grid)
        art = ax.imshow(image, origin="lower", extent=extent, aspect="auto", cmap="RdYlGn_r",
                        interpolation="nearest")
        ax.set_title(f"{name}: {seconds[name]:.0f} s")
        ax.set_xlabel("$a$ of the outer planet")
    axes[0].set_ylabel("$e$ of the outer planet")
    fig.colorbar(art, ax=axes, label=r"MEGNO $\langle Y\rangle$ (clipped to [1.8, 4])")
    fig.savefig(path, dpi=130)
    plt.close(fig)
    result["claims"] = claims.items
    return result


if __name__ == "__main__":
    main()
    sys.exit(0)

"""Speed of the compiled DOP853 engine against SciPy's solver and the TM
method, on the paper's Table I set-up.

Hénon–Heiles R1, full spectrum (k = 4), QR every τ, through
:func:`varint.lyapunov_spectrum`: ``method="dop853"`` with
``engine="compiled"`` (:mod:`baselines.dop853_kernel`) and
``engine="scipy"`` at τ = 0.05, δ = 1e-5 and at τ = 0.5, δ = 1e-10 (the
extremes of Table I's DOP853 rows), and ``method="tm"`` (SBAB2C, τ = 0.05).
Each configuration runs to its own horizon (long enough to take about a
second, fast ones longer), once to compile, then three times with the
configurations interleaved, so that the load of the shared machine falls on
all alike; the minimum of the three is kept. Reported: wall time per unit
of integration time, right-hand-side (or force) evaluations per unit time,
the time to reach the paper's t = 1e8 at that rate, and the ratios within
this one run, which are what mean anything on a shared machine.

Usage: ``python studies/bench_dop853.py [--quick] [--out DIR]``
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import varint  # noqa: E402
from studies.common import parse_args, save_csv, save_json  # noqa: E402

#: (label, τ, method options, horizon in full mode). Horizons make each run
#: take about a second.
CONFIGS = [
    ("dop853 compiled", 0.05, {"method": "dop853", "delta": 1e-5, "engine": "compiled"}, 1e4),
    ("dop853 scipy", 0.05, {"method": "dop853", "delta": 1e-5, "engine": "scipy"}, 200.0),
    ("tm SBAB2C", 0.05, {"method": "tm", "scheme": "SBAB2C"}, 2e5),
    ("dop853 compiled", 0.5, {"method": "dop853", "delta": 1e-10, "engine": "compiled"}, 5e4),
    ("dop853 scipy", 0.5, {"method": "dop853", "delta": 1e-10, "engine": "scipy"}, 500.0),
]
#: Horizons are divided by this with ``--quick``.
QUICK_DIVISOR = 100
REPEATS = 3
#: The paper's horizon.
PAPER_T = 1e8


def _run(model, x0, t_end, tau, options):
    t0 = time.perf_counter()
    res = varint.lyapunov_spectrum(model, x0, t_end, tau=tau, t_out=1, progress=False,
                                   **options)
    return time.perf_counter() - t0, res


def measure(quick):
    """One row per configuration: the minimum over :data:`REPEATS`
    interleaved runs."""
    model, x0 = varint.paper_orbit("R1")
    horizons = [t / QUICK_DIVISOR if quick else t for *_, t in CONFIGS]
    for _, tau, options, _ in CONFIGS:
        _run(model, x0, 10 * tau, tau, options)  # compile
    best = [np.inf] * len(CONFIGS)
    results = [None] * len(CONFIGS)
    for _ in range(REPEATS):
        for i, ((_, tau, options, _), t_end) in enumerate(zip(CONFIGS, horizons, strict=True)):
            seconds, results[i] = _run(model, x0, t_end, tau, options)
            best[i] = min(best[i], seconds)
    rows = []
    for (label, tau, options, _), t_end, seconds, res in zip(CONFIGS, horizons, best, results, strict=True):
        counts = res.provenance.counts
        work = counts.get("rhs_evaluations", counts.get("gradient"))
        rows.append({"config": label, "tau": tau, "delta": options.get("delta", "-"),
                     "t_end": t_end, "ms_per_tu": 1e3 * seconds / t_end,
                     "evals_per_tu": work / t_end,
                     "hours_to_1e8": seconds / t_end * PAPER_T / 3600,
                     "X1": float(res.exponents[-1, 0])})
    return rows


def ratios(rows):
    """Speed-ups within the run: compiled over SciPy at each (τ, δ), and the
    TM method over the compiled engine at τ = 0.05."""
    by = {(r["config"], r["tau"]): r["ms_per_tu"] for r in rows}
    out = {f"scipy / compiled, tau = {tau}": by["dop853 scipy", tau] / by["dop853 compiled", tau]
           for tau in (0.05, 0.5)}
    out["compiled / tm, tau = 0.05"] = by["dop853 compiled", 0.05] / by["tm SBAB2C", 0.05]
    return out


def _print(rows, speedups):
    columns = ["config", "tau", "delta", "t_end", "ms_per_tu", "evals_per_tu", "hours_to_1e8"]
    print(f"R1, k = 4, QR every tau; min of {REPEATS} interleaved runs")
    print(f"{'config':<16}" + "".join(f"{c:>14}" for c in columns[1:]))
    for r in rows:
        print(f"{r['config']:<16}" + "".join(
            f"{r[c]:>14.4g}" if isinstance(r[c], float) else f"{r[c]!s:>14}"
            for c in columns[1:]))
    for name, value in speedups.items():
        print(f"{name:<30} {value:8.1f}")


def main(argv=None):
    args = parse_args(__doc__.splitlines()[0], argv)
    rows = measure(args.quick)
    speedups = ratios(rows)
    _print(rows, speedups)
    save_csv(args.out, "bench_dop853", rows, list(rows[0]))
    result = {"rows": rows, "ratios": speedups}
    save_json(args.out, "bench_dop853", result)
    return result


if __name__ == "__main__":
    main()

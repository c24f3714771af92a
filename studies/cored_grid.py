"""Which grid of the small-core map can judge a race: the exploration behind
the cored race's grid of ``studies/map_steps.py`` (issue 27).

The criterion, written before any run (map_steps' "A grid that can
judge", the rule of the three-body race):

- the reference (heyoka, tol 1e-15, normalising every time unit, as
  :func:`studies.map_steps.reference`) calls 25–75 % of the grid's orbits
  chaotic, and at most 5 % of them have an FLI within ±1.5 of the threshold
  (:func:`studies.map_steps.judging`);
- the threshold is fixed in advance, FLI = 2 ln t as on the three-body map,
  not the reference's antimode: a regular orbit's deviation grows
  linearly (FLI ≈ ln t + ln a, the shear a of its torus), a chaotic one
  exponentially (FLI ≈ λ t; Guzzo, Lega & Froeschlé 2002), so growth faster
  than t² is chaos whatever the grid holds, whereas an antimode is fitted
  to the FLIs and moves with the grid's own mix (the old grid's, 15.6 at
  t = 200, moves to 33.9 at t = 1000, above two orbits of FLI 15–16);
- the potential stays a small-core one: the cored logarithmic potential
  of the race, R_c = 0.03 ≤ 0.05, and the grid's orbits pass close to the
  centre: each row keeps the smallest pericentre distance over the grid's
  orbits to t_end and the median over orbits of each orbit's smallest one
  (heyoka's events at ṙ = 0,
  :func:`studies.map_steps.closest_approach`).

Candidates (:data:`CANDIDATES`): the old grid (the section y = 0,
p_y ≥ 0 at E = 0, (x, p_x) ∈ [−0.9, 0.9]²) to t = 200 and 1000, and
grids about the centre of the section, where box orbits (|x p_y| small:
little angular momentum) cross the core and the chaotic layers lie.

Usage: ``python studies/cored_grid.py [--quick]``; results
``cored_grid.{json,csv}`` (``--quick``: the first three candidates, under
``results/quick``). State the machine load (recorded in the JSON).
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import varint
from studies.bench_peers import HeyokaMap, antimode, seeded_vectors
from studies.common import parse_args, save_csv, save_json
from studies.map_steps import (BATCH, CORE_RADIUS, INDICATOR, REF_EVERY, REF_TOL, closest_approach,
                               cored_logarithmic, fli_threshold, judging)

#: (label, energy, x range, p_x range, grid points in x and p_x, t_end).
CANDIDATES = [
    ("old grid, t 200", 0.0, (-0.9, 0.9), (-0.9, 0.9), (12, 10), 200.0),
    ("old grid, t 1000", 0.0, (-0.9, 0.9), (-0.9, 0.9), (12, 10), 1000.0),
    ("wide, t 1000", 0.0, (-0.95, 0.95), (-1.2, 1.2), (20, 13), 1000.0),
    ("centre |x| 0.3, t 1000", 0.0, (-0.3, 0.3), (0.4, 1.2), (16, 13), 1000.0),
    ("centre |x| 0.15, t 1000", 0.0, (-0.15, 0.15), (0.3, 0.9), (12, 10), 1000.0),
    ("centre |x| 0.1, t 1000", 0.0, (-0.1, 0.1), (0.3, 0.85), (12, 10), 1000.0),
    ("centre |x| 0.1, t 500", 0.0, (-0.1, 0.1), (0.3, 0.85), (12, 10), 500.0),
    ("centre |x| 0.1, t 2000", 0.0, (-0.1, 0.1), (0.3, 0.85), (12, 10), 2000.0),
]


def grid_of(model, energy, xr, pr, n):
    """The section y = 0, p_y ≥ 0 at ``energy`` on an n[0] × n[1] grid of
    (x, p_x)."""
    return varint.section_grid(model, energy, np.linspace(*xr, n[0]), np.linspace(*pr, n[1]),
                               plane=1)


def explore(label, energy, xr, pr, n, t_end):
    """One candidate's row: the reference's judging figures at 2 ln t, its
    antimode for comparison, the pericentres and the seconds the reference
    took."""
    import heyoka as hy

    hy.set_nthreads(1)
    model = cored_logarithmic()
    X = grid_of(model, energy, xr, pr, n).states
    t0 = time.perf_counter()
    values = HeyokaMap(model, INDICATOR, "var_ode_sys", BATCH, REF_TOL,
                       every=REF_EVERY).run(X, seeded_vectors(model.dim, 1, len(X)), t_end)
    seconds = time.perf_counter() - t0
    threshold = fli_threshold(t_end)[0]
    judged = judging(values, threshold)
    mode = antimode(values)[0]
    closest = closest_approach(X, t_end)
    regular, chaos = values[values <= threshold], values[values > threshold]
    return {"candidate": label, "energy": energy, "x": list(xr), "px": list(pr),
            "grid": list(n), "orbits": len(X), "t_end": t_end, "threshold": threshold,
            "chaotic": judged["chaotic"], "in_band": judged["in_band"], "judging": judged["ok"],
            "regular_max": float(regular.max()) if len(regular) else None,
            "chaotic_min": float(chaos.min()) if len(chaos) else None,
            "antimode": mode, "antimode_chaotic": float(np.mean(values > mode)),
            "closest_min": float(closest.min()), "closest_median": float(np.median(closest)),
            "within_2_rc": float(np.mean(closest < 2 * CORE_RADIUS)),
            "reference_seconds": seconds}


def main(argv=None):
    args = parse_args(__doc__.split("\n\n")[0], argv)
    start = list(os.getloadavg())
    rows = []
    for candidate in CANDIDATES[:3] if args.quick else CANDIDATES:
        row = explore(*candidate)
        rows.append(row)
        print(f"{row['candidate']}: {row['orbits']} orbits, chaotic {row['chaotic']:.1%}, "
              f"in band {row['in_band']:.1%}, judging {row['judging']}; regular FLI ≤ "
              f"{row['regular_max']:.3g}, chaotic ≥ {row['chaotic_min']}; closest "
              f"{row['closest_min']:.2g} (median {row['closest_median']:.2g}); "
              f"{row['reference_seconds']:.3g} s", flush=True)
    save_csv(args.out, "cored_grid", rows,
             ["candidate", "orbits", "t_end", "chaotic", "in_band", "judging", "regular_max",
              "chaotic_min", "antimode_chaotic", "closest_min", "closest_median", "within_2_rc",
              "reference_seconds"])
    save_json(args.out, "cored_grid", {"quick": args.quick, "rows": rows, "load": start,
                                       "load_end": list(os.getloadavg())})
    return rows


if __name__ == "__main__":
    main()

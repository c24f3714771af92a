"""Where varint's and REBOUND's MEGNO verdicts differ on the stored map of
studies/bench_planetary.py, and how sure the agreement figures are.

Reads ``results/bench_planetary_map.npz`` (the race's values: varint,
REBOUND WHFast and the heyoka reference at tolerance 1e-15 on the sample)
and ``results/bench_planetary.json`` (IAS15's agreement with both). A point is chaotic when its Ȳ exceeds the threshold or
its orbit stopped early (NaN: escape, close encounter); for every point
where two verdicts differ it stores the three values, and for each
agreement figure the exact (Clopper–Pearson) 95 % interval of the
binomial proportion, since the sample is 128 points. Then it reruns
varint (the race's Wisdom–Holman map, the same horizon) on the points that
differ with ``--seeds`` other seeds: other random initial deviation
vectors. A finite-time Ȳ depends on that vector near the chaos boundary,
and the pairs of contenders share one: varint and the heyoka reference
draw it from varint's seed, REBOUND's WHFast and IAS15 from REBOUND's.
Run:
``python studies/planetary_agreement.py``.
"""

from __future__ import annotations

import json

import numpy as np
from scipy.stats import beta

try:
    from common import RESULTS, parse_args, save_json
    from bench_planetary import MASSES, OUTER_PERIOD, THRESHOLD, grid, varint_map
except ImportError:  # imported as studies.planetary_agreement
    from .common import RESULTS, parse_args, save_json
    from .bench_planetary import MASSES, OUTER_PERIOD, THRESHOLD, grid, varint_map

from varint.models import Planetary


def clopper_pearson(k, n, level=0.95):
    """The exact two-sided interval of a binomial proportion k/n."""
    alpha = 1 - level
    lo = 0.0 if k == 0 else float(beta.ppf(alpha / 2, k, n - k + 1))
    hi = 1.0 if k == n else float(beta.ppf(1 - alpha / 2, k + 1, n - k))
    return lo, hi


def chaotic(values):
    """Above the threshold, or stopped early (NaN)."""
    return ~(values <= THRESHOLD)


def main(argv=None):
    args = parse_args(__doc__.splitlines()[0], argv, extra=lambda p: p.add_argument(
        "--seeds", type=int, default=8, help="other seeds of varint on the points that differ"))
    z = np.load(RESULTS / "bench_planetary_map.npz")
    race = json.loads((RESULTS / "bench_planetary.json").read_text())
    sample, a, e = z["sample"], z["a"], z["e"]
    values = {"heyoka": z["reference"], "varint": z["varint"][sample],
              "REBOUND": z["REBOUND"][sample]}
    verdict = {k: chaotic(v) for k, v in values.items()}
    n = len(sample)
    agreement = {}
    for name in ("varint", "REBOUND"):
        k = int((verdict[name] == verdict["heyoka"]).sum())
        agreement[name] = {"agree": k, "of": n, "fraction": k / n,
                           "ci95": clopper_pearson(k, n)}
    differ = ~((verdict["varint"] == verdict["heyoka"]) & (verdict["REBOUND"] == verdict["heyoka"]))
    points = [{"grid_index": int(sample[i]), "a": float(a[sample[i] % len(a)]),
               "e": float(e[sample[i] // len(a)]),
               **{k: (None if np.isnan(v[i]) else float(v[i])) for k, v in values.items()}}
              for i in np.flatnonzero(differ)]
    finite = values["heyoka"][np.isfinite(values["heyoka"])]
    # The race's horizon and grid, as bench_planetary.py ran them.
    t_end = race["t_end"] if not args.quick else 10 * OUTER_PERIOD
    model = Planetary(MASSES)
    X = grid(model, len(a)).states
    seeds = list(range(1, args.seeds + 1)) if not args.quick else [1]
    for p in points:
        x = X[p["grid_index"]][None]
        ys = np.array([varint_map(model, x, t_end, None, seed=s)[0][0] for s in seeds])
        p["varint_other_seeds"] = {"seeds": seeds, "values": ys.tolist(),
                                   "chaotic": int(chaotic(ys).sum())}
    data = {"threshold": THRESHOLD, "sample": n, "agreement_with_heyoka": agreement,
            "ias15": race.get("ias15", {}), "t_end": t_end,
            "outer_orbits": race["outer_orbits"] if not args.quick else 10,
            "points_that_differ": points,
            "sample_within_1_of_threshold": int((np.abs(finite - THRESHOLD) < 1).sum())}
    path = save_json(args.out, "planetary_agreement", data)
    for name, g in agreement.items():
        print(f"{name}: {g['agree']}/{g['of']} agree with heyoka, 95% CI "
              f"[{g['ci95'][0]:.3f}, {g['ci95'][1]:.3f}]")
    for p in points:
        print(p)
    print(path)


if __name__ == "__main__":
    main()

"""A short race of the FLI map defaults against heyoka (issue 27, issue 29):
``studies/map_steps.py``'s log race (``--part log``) cut to the rows its
targets are judged by, for a machine too loaded to run all its contenders.

For each map (``core``, ``cr3bp``: :func:`studies.map_steps.race_map`,
quick grids), the same reference (heyoka at tol 1e-15, FLI = 2 ln t,
:func:`studies.map_steps.reference`) and the same rows
(:func:`studies.map_steps._row`): varint's defaults (``chaos_map`` with no
τ or scheme: the LH or constant steps as the switch prices them, pilot
included) and heyoka's ``taylor_adaptive_batch`` (batch 8, its own
variational equations, normalising every 10 time units) at the tolerances
``TOLS`` of the map, one thread each, interleaved, the minimum of the
repeats (wall time). The ratio: heyoka's cheapest tolerance whose agreement
reaches the defaults', seconds over the defaults' seconds.

Stored run (``studies/results/lhprice18/lh_price_race.json``, lhprice18,
3 repeats, load 19.2 → 17.9, wall time): the cored map, defaults (the LH,
h = 0.0247, δ = 0.25) 10.97 s at 100 % against heyoka tol 1e-4 11.11 s at
100 %: 1.01×; the three-body map, defaults (constant SRKN14a, τ = 0.25,
as on main) 0.754 s at 98.7 % against heyoka tol 1e-5 3.24 s at 100 %:
4.30× (pilot 0.25 s, run 0.49 s).

Usage: ``python studies/lh_price_race.py [--maps core,cr3bp] [--repeats N]``;
result ``lh_price_race.json``. State the load (recorded).
"""

from __future__ import annotations

import os
import sys
import warnings
from pathlib import Path

import numba

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import varint
from studies.common import interleaved, parse_args, save_json
from studies.map_steps import (BATCH, EVERY, INDICATOR, HeyokaMap, _row, race_map, reference)

#: heyoka's tolerances per map: the cheapest that reach full agreement in
#: the stored races (core 1e-4, cr3bp 1e-5) and the next looser one.
TOLS = {"core": (1e-3, 1e-4), "cr3bp": (1e-4, 1e-5)}


def race(name, repeats):
    model, grid, t_end = race_map(name, True)
    X = grid.states
    numba.set_num_threads(1)
    ref = reference(name, model, X, t_end)
    tasks = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")

        def defaults():
            return varint.chaos_map(model, grid, INDICATOR, t_end=t_end, progress=False)
        defaults()   # compiles
        tasks["varint defaults"] = defaults
        for tol in TOLS[name]:
            hm = HeyokaMap(model, INDICATOR, "var_ode_sys", BATCH, tol, every=EVERY)
            tasks[f"heyoka batch {BATCH}, tol {tol:g}"] = \
                lambda hm=hm: hm.run(X, ref["W0"], t_end)
        best, outs = interleaved(tasks, repeats)
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    rows = [_row(name, label, best[label], outs[label], ref, len(X), t_end) for label in tasks]
    mine = rows[0]
    prov = outs["varint defaults"].provenance
    mine.update(method=prov.method, tau=prov.tau, counts=dict(prov.counts),
                timing=dict(prov.timing or {}), prices=prov.tau_choice.get("prices"))
    equal = [r for r in rows[1:] if r["agreement"] >= mine["agreement"]]
    summary = {"defaults_seconds": mine["seconds"], "defaults_agreement": mine["agreement"],
               "method": prov.method, "tau": prov.tau}
    if equal:
        cheapest = min(equal, key=lambda r: r["seconds"])
        summary.update(heyoka=cheapest["contender"], heyoka_seconds=cheapest["seconds"],
                       heyoka_agreement=cheapest["agreement"],
                       ratio=cheapest["seconds"] / mine["seconds"])
    for r in rows:
        print(f"{name}: {r['contender']}: {r['seconds']:.4g} s, agreement {r['agreement']:.3f}",
              flush=True)
    print(f"{name}: {summary}", flush=True)
    return rows, summary


def main(argv=None):
    def extra(parser):
        parser.add_argument("--maps", default="core,cr3bp")
        parser.add_argument("--repeats", type=int, default=3)

    args = parse_args(__doc__.split("\n\n")[0], argv, extra)
    result = {"load": list(os.getloadavg()), "repeats": args.repeats, "maps": {}}
    for name in [m for m in args.maps.split(",") if m]:
        rows, summary = race(name, args.repeats)
        result["maps"][name] = {"rows": rows, "summary": summary}
    result["load_end"] = list(os.getloadavg())
    save_json(args.out, "lh_price_race", result)
    return result


if __name__ == "__main__":
    main()

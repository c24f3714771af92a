"""What each way of running the Sun–Jupiter FLI and MEGNO maps of
``studies/hamiltonians.py`` (part ``maps``) costs, and how often it
classifies an orbit as the tight reference does (issue 29, map25).

The map is that study's (:func:`studies.hamiltonians.map_grid`: the
section y = 0, ẏ > 0 at C = 3.05, 40 × 30 points of which 1172 are
allowed, t = 1000; ``--quick``: 10 × 8, t = 200), its reference (heyoka
batch 8 at tol 1e-15, normalising every time unit) and its agreement (the
share of orbits on the reference's side of the antimode of its
log10 values, ``studies/bench_peers.py``). The contenders, one thread each,
each timed by this process's CPU time after an untimed call at the same
settings (the kernels compiled and loaded), the minimum of ``--repeats``:

- ``defaults``: ``chaos_map`` with no τ, scheme or time transform, its
  pilot included, with the scheme, step and the pilot's seconds it reports;
- ``constant``: SRKN14a (the maps' scheme) at given constant steps τ,
  ``time_transform=None``, no pilot;
- ``log``: the logarithmic Hamiltonian (ABA864) at given fictitious steps
  h (FLI only), no pilot;
- heyoka batch 8 at tol 1e-6 and 1e-8 (the cheapest tolerances of the
  study), timed alike.

Each varint row's equal-agreement ratio follows the study's rule
(:func:`studies.hamiltonians._equal_agreement`): heyoka's cheapest
tolerance whose agreement reaches the row's, over the row's seconds.

Usage: ``python studies/map_alternatives.py [--quick] [--out DIR]
[--taus 0.1,0.125,...] [--hs 0.274] [--repeats 2]``; results
``map_alternatives.json``. State the load (recorded) with every figure.
"""

from __future__ import annotations

import os
import sys
import time
import warnings
from pathlib import Path

import numba
import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import varint
from studies.bench_peers import HeyokaMap, agreement, antimode, chaotic, seeded_vectors
from studies.common import parse_args, save_json
from studies.hamiltonians import BATCH, EVERY, REF_EVERY, REF_TOL, map_grid

TAUS = (0.1, 0.125, 0.15, 0.2, 0.25)
HS = (0.274,)
HEYOKA_TOLS = (1e-6, 1e-8)


def best_of(fn, repeats):
    """The least CPU seconds of ``repeats`` calls of ``fn`` and its last output."""
    best, out = np.inf, None
    for _ in range(repeats):
        t0 = time.process_time()
        out = fn()
        best = min(best, time.process_time() - t0)
    return best, out


def main(argv=None):
    def extra(parser):
        parser.add_argument("--taus", default=",".join(map(str, TAUS)),
                            help="the constant steps of SRKN14a, comma-separated")
        parser.add_argument("--hs", default=",".join(map(str, HS)),
                            help="the LH's fictitious steps (FLI), comma-separated")
        parser.add_argument("--repeats", type=int, default=2)

    args = parse_args(__doc__.split("\n\n")[0], argv, extra)
    taus = [float(v) for v in args.taus.split(",") if v.strip()]
    hs = [float(v) for v in args.hs.split(",") if v.strip()]
    model, grid = map_grid(args.quick)
    X = grid.states
    t_end = 200.0 if args.quick else 1000.0
    W0 = seeded_vectors(model.dim, 1, len(X))
    numba.set_num_threads(1)
    import heyoka as hy

    hy.set_nthreads(1)
    start = list(os.getloadavg())
    rows = []
    for ind in ("fli", "megno"):
        ref = HeyokaMap(model, ind, "var_ode_sys", BATCH, REF_TOL, every=REF_EVERY)
        values = ref.run(X, W0, t_end)
        threshold, _ = antimode(values)
        truth = chaotic(ind, values, threshold)
        contenders = {"defaults": {}}
        contenders.update({f"constant tau={t:g}": {"tau": t, "scheme": "SRKN14a",
                                                    "time_transform": None} for t in taus})
        if ind == "fli":
            contenders.update({f"log h={h:g}": {"tau": h, "time_transform": "log"}
                               for h in hs})
        peers = []
        for tol in HEYOKA_TOLS:
            hm = HeyokaMap(model, ind, "var_ode_sys", BATCH, tol, every=EVERY)
            hm.run(X, W0, t_end)
            seconds, out = best_of(lambda hm=hm: hm.run(X, W0, t_end), args.repeats)
            peers.append({"indicator": ind, "contender": f"heyoka batch {BATCH}, tol {tol:g}",
                          "seconds": seconds,
                          "agreement": agreement(ind, np.asarray(out), truth, threshold)})
        for label, kw in contenders.items():
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")

                def go(kw=kw, ind=ind):
                    return varint.chaos_map(model, grid, ind, t_end=t_end, progress=False,
                                            **kw)
                go()
                seconds, out = best_of(go, args.repeats)
            agree = agreement(ind, np.asarray(out.values), truth, threshold)
            meeting = [p for p in peers if p["agreement"] >= agree]
            peer = (min(meeting, key=lambda p: p["seconds"]) if meeting
                    else max(peers, key=lambda p: p["agreement"]))
            scheme = out.provenance.method_options["scheme"]
            rows.append({"indicator": ind, "contender": label, "seconds": seconds,
                         "agreement": agree, "method": out.provenance.method,
                         "scheme": scheme["name"] if isinstance(scheme, dict) else scheme,
                         "tau": out.provenance.tau, "timing": out.provenance.timing,
                         "heyoka": peer["contender"], "ratio": peer["seconds"] / seconds,
                         "load": os.getloadavg()[0]})
            r = rows[-1]
            print(f"{ind} {label}: {r['method']} {r['scheme']} τ = {r['tau']:.4g}, "
                  f"{seconds:.3f} CPU s, agreement {agree:.4f}; {r['heyoka']} "
                  f"{r['ratio']:.2f}×", flush=True)
        rows += peers
        for p in peers:
            print(f"{ind} {p['contender']}: {p['seconds']:.3f} CPU s, agreement "
                  f"{p['agreement']:.4f}", flush=True)
    result = {"quick": args.quick, "orbits": len(X), "t_end": t_end, "clock": "cpu",
              "repeats": args.repeats, "rows": rows, "load": start,
              "load_end": list(os.getloadavg())}
    save_json(args.out, "map_alternatives", result)
    return result


if __name__ == "__main__":
    sys.exit(0 if main() is not None else 1)

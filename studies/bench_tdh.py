"""Speed of the TDH methods against the TM method: nanoseconds per
renormalisation interval τ = 0.05 (QR every interval), for the paper's
orbits and numbers of deviation vectors.

Every method integrates the orbit with SBAB2C (TDHeps at Δt = τ/2, its
leapfrog variant at Δt = τ). Each time is the minimum of three warm runs;
only ratios to the TM row of the same run mean anything (the machine is
shared). The paper's Table I gives, on its machine, TDHcc 1.24×, TDHes
1.20× and TDHeps 1.30× the CPU time of TM (R1, τ = 0.05, k = 4).

Usage: ``python studies/bench_tdh.py [--quick] [--out DIR]``
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import varint  # noqa: E402
from studies.common import parse_args, save_csv  # noqa: E402
from varint.methods import make_propagator  # noqa: E402
from varint.state import RunState  # noqa: E402

METHODS = [("tm", {}), ("tdhcc", {}), ("tdhes", {}), ("tdhes", {"eigensolver": "analytic"}),
           ("tdheps", {}), ("tdheps", {"tangent_scheme": "SBAB1"})]


def ns_per_interval(model, x0, method, options, k, n, repeats=3):
    """Best-of-``repeats`` ns per interval of a propagator (compiled first)."""
    prop = make_propagator(method, model, 0.05, "qr", **options)
    W0 = np.eye(model.dim)[None, :, :k]
    prop.advance(RunState.start(x0[None], W0), 10)
    best = np.inf
    for _ in range(repeats):
        state = RunState.start(x0[None], W0)
        t0 = time.perf_counter()
        prop.advance(state, n)
        best = min(best, time.perf_counter() - t0)
    return best / n * 1e9


def main(argv=None):
    args = parse_args(__doc__.split("\n\n")[0], argv)
    rows = []
    for orbit in ("R1",) if args.quick else ("R1", "R2", "R3"):
        model, x0 = varint.paper_orbit(orbit)
        n = (20_000 if args.quick else 400_000) // max(1, model.n_dof // 2)
        for k in (model.dim,) if args.quick or orbit != "R1" else (1, model.dim):
            print(f"\n{orbit} (N = {model.n_dof}), k = {k}")
            tm = None
            for method, options in METHODS:
                if options.get("eigensolver") == "analytic" and orbit not in ("R1", "C1", "C2"):
                    continue
                ns = ns_per_interval(model, x0, method, options, k, n)
                tm = ns if method == "tm" else tm
                name = method + "".join(f" {v}" for v in options.values())
                rows.append({"orbit": orbit, "k": k, "method": name, "ns_per_interval": ns,
                             "vs_tm": ns / tm})
                print(f"  {name:22s} {ns:9.1f} ns  {ns / tm:5.2f}x TM")
    save_csv(args.out, "bench_tdh", rows, ["orbit", "k", "method", "ns_per_interval", "vs_tm"])
    return {"rows": rows}


if __name__ == "__main__":
    main()

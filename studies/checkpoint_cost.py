"""What checkpoints cost: size, write and read time of one checkpoint for
small and large runs, and the slow-down of a run that writes one after every
chunk of work (the worst case; the default is one a minute).

Usage: ``python studies/checkpoint_cost.py [--quick] [--out DIR]``
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

import varint
from varint import checkpoint as ckpt
from varint.state import RunState

try:
    from common import Stopwatch, parse_args, save_csv, save_json
except ImportError:  # imported as studies.checkpoint_cost
    from .common import Stopwatch, parse_args, save_csv, save_json


def _snapshot(n_orbits, dim, k, n_records):
    rng = np.random.default_rng(0)
    state = RunState.start(rng.standard_normal((n_orbits, dim)),
                           rng.standard_normal((n_orbits, dim, k)))
    records = [{"exponents": rng.standard_normal((n_orbits, k)),
                "energy_error": rng.standard_normal(n_orbits)} for _ in range(n_records)]
    return ckpt.Snapshot({"kind": "study"}, state, records)


def file_costs(cases, repeats, folder):
    """Size, best write and read time of one checkpoint per case."""
    rows = []
    for name, (m, dim, k, n_rec) in cases.items():
        snap = _snapshot(m, dim, k, n_rec)
        path = Path(folder) / f"{name}.ckpt"
        writes, reads = [], []
        for _ in range(repeats):
            with Stopwatch() as sw:
                ckpt.write(path, snap)
            writes.append(sw.seconds)
            with Stopwatch() as sw:
                ckpt.read(path)
            reads.append(sw.seconds)
        payload = sum(getattr(snap.state, a).nbytes for a in ckpt.STATE_ARRAYS) + \
            sum(a.nbytes for r in snap.records for a in r.values())
        rows.append({"case": name, "orbits": m, "dim": dim, "k": k, "records": n_rec,
                     "array_bytes": payload, "file_bytes": path.stat().st_size,
                     "write_s": min(writes), "read_s": min(reads)})
    return rows


def run_overhead(t_end, repeats, folder):
    """Wall time of the paper's C1 spectrum with no checkpoint, one after
    every chunk of work (interval 0) and the default interval; the best of
    ``repeats``, with the number of checkpoints written."""
    model, x0 = varint.paper_orbit("C1")
    varint.lyapunov_spectrum(model, x0, 10.0, tau=0.05, progress=False)  # compile
    real, writes = ckpt.write, []

    def counting(*args):
        writes.append(1)
        real(*args)

    rows = []
    for label, interval in [("none", None), ("every chunk", 0.0), ("default (60 s)", 60.0)]:
        best = np.inf
        for i in range(repeats):
            kw = {} if interval is None else {
                "checkpoint": Path(folder) / f"overhead-{len(rows)}-{i}.ckpt",
                "checkpoint_interval": interval}
            writes.clear()
            ckpt.write = counting
            try:
                with Stopwatch() as sw:
                    varint.lyapunov_spectrum(model, x0, t_end, tau=0.05, progress=False, **kw)
            finally:
                ckpt.write = real
            best = min(best, sw.seconds)
        rows.append({"checkpoints": label, "seconds": best, "writes": len(writes)})
    for row in rows:
        row["ratio"] = row["seconds"] / rows[0]["seconds"]
    return rows


def main(argv=None):
    args = parse_args(__doc__.splitlines()[0], argv)
    cases = {
        "HH, 1 orbit, k=4": (1, 4, 4, 80),
        "HH, 1000 orbits, k=4": (1000, 4, 4, 80),
        "FPU n=256, full spectrum": (1, 512, 512, 80),
        "FPU n=1024, k=16": (1, 2048, 16, 80),
    }
    if not args.quick:
        cases["FPU n=1024, full spectrum"] = (1, 2048, 2048, 80)
    with tempfile.TemporaryDirectory() as folder:
        files = file_costs(cases, 2 if args.quick else 5, folder)
        overhead = run_overhead(2e3 if args.quick else 2e5, 1 if args.quick else 3, folder)
    print(f"{'case':28s} {'arrays':>10s} {'file':>10s} {'write':>9s} {'read':>9s}")
    for r in files:
        print(f"{r['case']:28s} {r['array_bytes']:10d} {r['file_bytes']:10d} "
              f"{r['write_s'] * 1e3:7.2f}ms {r['read_s'] * 1e3:7.2f}ms")
    print(f"\n{'C1 spectrum, checkpoints':28s} {'seconds':>9s} {'writes':>7s} {'ratio':>6s}")
    for r in overhead:
        print(f"{r['checkpoints']:28s} {r['seconds']:9.3f} {r['writes']:7d} {r['ratio']:6.2f}")
    save_csv(args.out, "checkpoint_cost_files", files, list(files[0]))
    save_csv(args.out, "checkpoint_cost_overhead", overhead, list(overhead[0]))
    result = {"files": files, "overhead": overhead}
    save_json(args.out, "checkpoint_cost", result)
    return result


if __name__ == "__main__":
    main(sys.argv[1:])

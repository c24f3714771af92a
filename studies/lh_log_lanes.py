"""The LH lanes' logarithm on the cored map (issue 27, lh22): the lanes
kernel of the cored race map with the model's logarithm as the generated
LH module now writes it (``lane_log``, :mod:`varint.kernels.lh_log`:
``vlog``'s bits without a branch, vectorised in the potential's loop of
its own), against the same source with the C library's ``math.log``
(main before lh22: that loop ran in scalar code), with ``lane_log``
inlined into the kicks' loop (the whole step one loop over the lanes),
and with other pool widths (``LANE_WIDTH``).

Each variant is the emitted source of this tree
(:meth:`varint.time_transform.LogHamiltonian.source`), changed as its
label says, written to a module of its own and compiled once; then every
variant runs ``lanes1`` on the same arguments (the map's 120 orbits in
the map's chunk order with its vectors, the defaults' δ = 0.25 and h =
0.0247, as ``studies/lh_pool.py``), one thread, interleaved, CPU time,
the minimum of ``--repeats``. The FLI of each variant is compared bit
for bit with this tree's (``lane_log``'s variants must equal it, the C
library's may differ in the last place of V: a chaotic orbit's FLI then
differs).

Stored run (``studies/results/lh22/lh_log_lanes.json``, lh22, 3 repeats,
load 0.77 → 1.89, CPU): ``lane_log`` in its own loop 520.0 ms, the C
library's ``math.log`` there (main) 549.7 ms: 1.057×; ``lane_log``
inlined in the kicks' loops 814.9 ms (0.675×: LLVM vectorises the
merged loop, and it runs slower); pool widths 8 and 32 with ``lane_log``
548.1 and 550.9 ms (no gain over 16). The same LH steps but 104 in
7.24e6 (chaotic orbits), FLI equal to this tree's in every ``lane_log``
variant. An earlier run at load 5.7 → 2.9 (whose "inlined" variant was
not inlined): 523.4 against 563.2 ms, 1.076×.

Usage: ``python studies/lh_log_lanes.py [--repeats 4]``; result
``lh_log_lanes.json``. State the load (recorded).
"""

from __future__ import annotations

import hashlib
import importlib
import os
import sys
import tempfile
import time
import warnings
from pathlib import Path
from unittest import mock

import numba
import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from studies.common import parse_args, save_json
from studies.ladder_rule import case
from varint import maps
from varint.codegen import lh_lanes
from varint.state import initial_deviations
from varint.time_transform import offset_constant

#: The defaults' choice on the cored race map (``studies/results/stop55``).
OFFSET, H = 0.25, 0.024689461040723892


def variants(lh):
    """Label → module source."""
    this = lh.source()
    # No call of its own loop but math's: lane_log's group is inlined.
    with mock.patch.object(lh_lanes, "_OWN_LOOP_CALLS", ("math",)):
        merged = lh._emit()
    if merged.count("for b in range(nb)") >= this.count("for b in range(nb)"):
        raise RuntimeError("the inlined variant has as many loops over the lanes as this tree's")
    out = {"lane_log, own loop (this tree)": this,
           "math.log, own loop (main)": this.replace("lane_log(", "math.log("),
           "lane_log inlined in the kicks' loop": merged}
    for width in (8, 32):
        out[f"lane_log, own loop, LANE_WIDTH {width}"] = this.replace(
            f"LANE_WIDTH = {lh_lanes.LANE_WIDTH}", f"LANE_WIDTH = {width}")
    return out


def arguments(model, X, t_end, lh):
    """``lanes1``'s arguments for the map's orbits (module docstring)."""
    order = np.random.default_rng(20100927).permutation(len(X))
    X = np.ascontiguousarray(X[order])
    W = initial_deviations(model.dim, 1, len(X), 0, order)[:, :, 0][:, None, :].copy()
    starts = lh.starts(X)
    C = np.ascontiguousarray(offset_constant(starts.energy, OFFSET), dtype=float)
    return (X, W, -starts.energy, C, np.full(len(X), H), float(t_end), 10.0, 10_000_000,
            lh.kinds, lh.coef, lh.par)


def run(mod, args):
    M, d = args[0].shape
    fli, status = np.zeros(M), np.zeros(M, dtype=np.int64)
    counts = np.zeros((M, 3), dtype=np.int64)
    x_end, t, x_worst, t_worst = np.empty((M, d)), np.zeros(M), np.empty((M, d)), np.zeros(M)
    start = time.process_time()
    mod.lanes1(*args, fli, status, counts, x_end, t, x_worst, t_worst)
    return time.process_time() - start, fli, counts


def main(argv=None):
    def extra(parser):
        parser.add_argument("--repeats", type=int, default=4)

    args = parse_args(__doc__.split("\n\n")[0], argv, extra)
    load = list(os.getloadavg())
    model, X, t_end = case("core")
    lh = maps._log_hamiltonian(model, maps.LOG_MAP_OPTIONS["scheme"], None).with_offset(OFFSET)
    kargs = arguments(model, X, t_end, lh)
    numba.set_num_threads(1)
    with tempfile.TemporaryDirectory() as tmp, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sys.path.insert(0, tmp)
        mods = {}
        for i, (label, source) in enumerate(variants(lh).items()):
            name = f"lh22_variant_{i}_{hashlib.sha256(source.encode()).hexdigest()[:12]}"
            Path(tmp, f"{name}.py").write_text(source)
            mods[label] = importlib.import_module(name)
            run(mods[label], kargs)   # compiles, untimed
        seconds = {label: [] for label in mods}
        outs = {}
        for _ in range(args.repeats):
            for label, mod in mods.items():
                s, fli, counts = run(mod, kargs)
                seconds[label].append(s)
                outs[label] = (fli, counts)
        sys.path.remove(tmp)
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    this = next(iter(mods))
    base = "math.log, own loop (main)"
    rows = []
    for label in mods:
        fli, counts = outs[label]
        rows.append({"variant": label, "cpu_seconds": min(seconds[label]),
                     "all_seconds": seconds[label], "lh_steps": int(counts[:, 0].sum()),
                     "fli_equal_this": bool(np.array_equal(fli, outs[this][0], equal_nan=True)),
                     "speedup_over_main": min(seconds[base]) / min(seconds[label])})
    for r in rows:
        print(f"{r['variant']:45s} {1e3 * r['cpu_seconds']:8.1f} ms CPU  "
              f"{r['speedup_over_main']:.3f}x main  steps {r['lh_steps']}  "
              f"FLI {'=' if r['fli_equal_this'] else '!='} this tree's")
    result = {"load": load, "repeats": args.repeats, "orbits": len(X), "t_end": t_end,
              "offset": OFFSET, "h": H, "rows": rows, "load_end": list(os.getloadavg())}
    print(f"load {load} -> {result['load_end']}")
    save_json(args.out, "lh_log_lanes", result)
    return result


if __name__ == "__main__":
    main()

"""The defaults' switch on a map, this tree against another, interleaved
(issue 27, lh20): CPU seconds of :func:`varint.maps._cheaper_steps` (both
pilots, the prices and the choice) and of the whole map with every
default, cold and warm, and the bits of what they chose.

Each turn runs a fresh child process (``python -c`` in the tree, with
the tree first on ``PYTHONPATH`` and its own numba and varint cache
directories: ``<prefix>_nc`` and ``<prefix>_vc`` of ``--cache-this`` and
``--cache-base``; real directories, as varint's cache refuses others and
then compiles in memory) that builds the map (``studies/ladder_rule.py``'s
``case``: ``core`` and ``cr3bp``, the races' quick maps of
``studies/map_steps.py``; ``two``, the held-out two centres), runs it once
with every default (``chaos_map(model, X, "fli", t_end=...)``, one thread:
"cold", the kernels loaded from the disk caches a first turn filled) and
``--repeats`` more times ("warm"), timing the switch around each call
(CPU). The trees alternate turn by turn (``--rounds`` turns each), so
both see the same load; reported: the minimum per tree of the warm
switch and map and of the cold map, their ratios, and each child's hashes
of the map's values and of its ``tau_choice`` (every pilot's choice, with
its counts: the same bits, or not).

Stored run (``studies/results/lh20/lh_switch_cost.json``, lh20 against
4f2bb83 on this AMD EPYC, the cored map, 3 turns × 3 repeats, load 18.7
→ 15.8: read ratios): the switch 84.99 → 65.86 ms CPU warm (1.29×), the
whole map 908.7 → 766.8 ms warm (1.19×; the switch is ~19 ms of that
difference, the rest the load's noise), cold 2553 → 2866 ms (0.89×: the
kernels' loading from the disk caches, ~1.2 s, dominates, and moves by
hundreds of ms between turns at this load); values and every choice
(δ, h, prices, counts) bit for bit the same in all 18 children. Again
at a lower load (``lh_switch_cost_2.json``, load 4.9 → 3.9): the
switch 66.49 → 61.36 ms warm (1.08×), the map 739.4 → 740.6 ms (1.00×),
cold 2376 → 2465 ms (0.96×), the same bits. The Python the change
removed (the start energies, ~5 ms a switch here) weighs more on a
loaded machine; the rest of the switch is its kernels (the LH lanes'
2.43e6 and the constant ladder's 1.41e6 force evaluations, the same
runs as before). In both runs this tree's cold switch (min 1221 and 1433
ms) was above 4f2bb83's (1104 and 1238 ms), within the turns' spread
(1104–1543 ms) and not explained: to be measured quietly.

Usage: ``python studies/lh_switch_cost.py --base /tmp/main_tree [--maps
core] [--rounds 3] [--repeats 5] [--cache-this P] [--cache-base P]``;
result ``lh_switch_cost.json``.
State the load (recorded).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from studies.common import parse_args, save_json  # noqa: E402

#: The child: one map, cold then warm, printed as one JSON line.
CHILD = r"""
import hashlib, json, sys, time, warnings
import numba, numpy as np
import varint
from varint import maps
from studies.ladder_rule import case
name, repeats = sys.argv[1], int(sys.argv[2])
warnings.simplefilter("ignore")
numba.set_num_threads(1)
model, X, t_end = case(name)
switch, seconds = maps._cheaper_steps, []
def timed(*args):
    start = time.process_time()
    try:
        return switch(*args)
    finally:
        seconds.append(time.process_time() - start)
maps._cheaper_steps = timed
maps_cpu = []
for _ in range(1 + repeats):
    start = time.process_time()
    out = varint.chaos_map(model, X, "fli", t_end=t_end, progress=False)
    maps_cpu.append(time.process_time() - start)
choice = out.provenance.tau_choice
print(json.dumps({"cold_map": maps_cpu[0], "warm_map": min(maps_cpu[1:]),
                  "cold_switch": seconds[0], "warm_switch": min(seconds[1:]),
                  "method": out.provenance.method,
                  "values": hashlib.sha256(np.ascontiguousarray(out.values).tobytes()).hexdigest(),
                  "choice": hashlib.sha256(json.dumps(choice, sort_keys=True,
                                                      default=repr).encode()).hexdigest()}))
"""


def turn(tree, cache, name, repeats):
    """One child's measurements of map ``name`` in ``tree`` with the
    caches ``<cache>_nc`` and ``<cache>_vc``."""
    env = {**os.environ, "PYTHONPATH": str(tree), "NUMBA_CACHE_DIR": f"{cache}_nc",
           "VARINT_CACHE_DIR": f"{cache}_vc"}
    done = subprocess.run([sys.executable, "-c", CHILD, name, str(repeats)], cwd=tree, env=env,
                          capture_output=True, text=True, check=False)
    if done.returncode != 0:
        raise SystemExit(f"the child in {tree} failed:\n{done.stderr[-3000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def main(argv=None):
    def extra(parser):
        parser.add_argument("--base", required=True, help="the other tree (e.g. a worktree "
                            "of main)")
        parser.add_argument("--maps", default="core")
        parser.add_argument("--rounds", type=int, default=3)
        parser.add_argument("--repeats", type=int, default=5)
        parser.add_argument("--cache-this", default="/tmp/lh_switch_cost_this",
                            help="this tree's caches: <prefix>_nc, <prefix>_vc")
        parser.add_argument("--cache-base", default="/tmp/lh_switch_cost_base",
                            help="the other tree's caches: <prefix>_nc, <prefix>_vc")

    args = parse_args(__doc__.split("\n\n")[0], argv, extra)
    trees = {"this": Path(__file__).resolve().parent.parent, "base": Path(args.base).resolve()}
    caches = {"this": args.cache_this, "base": args.cache_base}
    load = list(os.getloadavg())
    rows = []
    for name in [m for m in args.maps.split(",") if m]:
        turns: dict = {label: [] for label in trees}
        for _ in range(args.rounds):
            for label, tree in trees.items():
                turns[label].append(turn(tree, caches[label], name, args.repeats))
        best = {label: {key: min(t[key] for t in ts)
                        for key in ("cold_map", "warm_map", "cold_switch", "warm_switch")}
                for label, ts in turns.items()}
        same = {key: all(t[key] == turns["base"][0][key] for ts in turns.values() for t in ts)
                for key in ("values", "choice", "method")}
        row = {"map": name, "turns": turns, "best": best, "bitwise": same,
               "switch_ratio": best["base"]["warm_switch"] / best["this"]["warm_switch"],
               "warm_map_ratio": best["base"]["warm_map"] / best["this"]["warm_map"],
               "cold_map_ratio": best["base"]["cold_map"] / best["this"]["cold_map"]}
        rows.append(row)
        print(f"{name} ({turns['this'][0]['method']}), CPU, min of {args.rounds} turns × "
              f"{args.repeats} repeats; the same values and choices: {same}")
        for label in trees:
            b = best[label]
            print(f"  {label:<5} switch {1e3 * b['warm_switch']:8.2f} ms warm "
                  f"({1e3 * b['cold_switch']:.2f} cold); map {1e3 * b['warm_map']:8.2f} ms warm, "
                  f"{1e3 * b['cold_map']:.2f} cold")
        print(f"  base/this: switch {row['switch_ratio']:.2f}×, map warm "
              f"{row['warm_map_ratio']:.2f}×, cold {row['cold_map_ratio']:.2f}×", flush=True)
    result = {"base": str(trees["base"]), "rounds": args.rounds, "repeats": args.repeats,
              "maps": rows, "load": load, "load_end": list(os.getloadavg())}
    save_json(args.out, "lh_switch_cost", result)
    return result


if __name__ == "__main__":
    main()

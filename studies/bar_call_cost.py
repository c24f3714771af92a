"""The bar orbit's cost per call and per step (issue 29): this tree against
another (``--base``, a worktree of the commit before), one
``lyapunov_spectrum`` call of the rotating bar's regular orbit (SRKN14a,
one deviation vector, as the race of ``studies/hamiltonians.py --part bar``
calls it).

Case
----
:func:`varint.models.bar.bar_orbit` ("regular"), galpy's deviation vector
(equal components), ``scheme="SRKN14a"``, ``t_out=[t]``:

* ``t = 1, τ = 0.2`` (5 steps): the fixed cost of a call;
* ``t = 100, τ = 0.4`` and ``τ = 0.1`` (250 and 1000 steps): the cost per
  step is their difference over 750 steps.

Each child also reports X1 and the energy error at t = 100 of both named
orbits at τ = 0.4, 0.2, 0.1 (``agreement``: the two trees' values and
their relative difference: bitwise equal, or round-off where the stepper
differs).

Method
------
Each tree runs in child processes (``python -c``, the tree first on
``PYTHONPATH``, its own numba and varint cache folders under
``--cache-root``), alternately, ``--rounds`` times (a, b, a, b, …: the load
of the shared machine falls on both alike). A child warms every
configuration up (and, where the tree runs the bar on a generated stepper,
makes one call of 10⁶ steps, which compiles the stepper with its stages
written out as a user's first long run would: ``TangentMapPropagator.
COMPACT_WORK``), then times each configuration ``--repeats`` times; kept:
the minimum over repeats and rounds of the wall time and, separately, of
the process's CPU time (``time.process_time``: on a loaded machine the
time the call itself computed, without the waits for other jobs). The
load is stored at start and end.

Stored as ``bar_call_cost.json``/``.csv`` under ``--out``.

Usage: ``python studies/bar_call_cost.py --base /path/to/worktree
[--rounds 3] [--repeats 15] [--out DIR]``.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from studies.common import RESULTS, save_csv, save_json

#: (label, t_end, τ) of the timed calls.
CONFIGS = (("t = 1, τ = 0.2", 1.0, 0.2), ("t = 100, τ = 0.4", 100.0, 0.4),
           ("t = 100, τ = 0.1", 100.0, 0.1))

_CHILD = """
import json, math, time
import numpy as np
import varint
from varint.methods.parts import runs_parts
from varint.models.bar import bar_orbit
model, x0 = bar_orbit("regular")
w0 = np.full((6, 1), 1 / math.sqrt(6))
def run(t, tau):
    return varint.lyapunov_spectrum(model, x0, t, tau=tau, scheme="SRKN14a", deviations=w0,
                                    t_out=[t])
if not runs_parts(model, "SRKN14a"):
    run(1.0e4, 0.0099)
configs = {configs!r}
for _, t, tau in configs:
    run(t, tau)
best, cpu = {{}}, {{}}
for _ in range({repeats}):
    for label, t, tau in configs:
        c0, t0 = time.process_time(), time.perf_counter()
        run(t, tau)
        t1, c1 = time.perf_counter(), time.process_time()
        best[label] = min(best.get(label, 1e9), t1 - t0)
        cpu[label] = min(cpu.get(label, 1e9), c1 - c0)
values = {{}}
for name in ("regular", "chaotic"):
    m, x = bar_orbit(name)
    for tau in (0.4, 0.2, 0.1):
        r = varint.lyapunov_spectrum(m, x, 100.0, tau=tau, scheme="SRKN14a", deviations=w0,
                                     t_out=[100.0])
        values[f"{{name}} τ = {{tau}}"] = [repr(float(r.exponents[-1, 0])),
                                          float(r.accuracy.energy_error)]
print("RESULT " + json.dumps({{"best": best, "cpu": cpu, "generated": not runs_parts(model, "SRKN14a"),
                              "values": values}}))
"""


def load():
    """The machine's load averages (1, 5, 15 min)."""
    return list(os.getloadavg())


def child(tree, cache_root, label, repeats):
    """One child process's minima on ``tree``."""
    env = dict(os.environ, PYTHONPATH=str(tree),
               NUMBA_CACHE_DIR=str(Path(cache_root) / f"{label}_nc"),
               VARINT_CACHE_DIR=str(Path(cache_root) / f"{label}_vc"))
    code = _CHILD.format(configs=CONFIGS, repeats=int(repeats))
    out = subprocess.run([sys.executable, "-c", code], cwd=tree, env=env, check=True,
                         capture_output=True, text=True).stdout
    line = next(s for s in out.splitlines() if s.startswith("RESULT "))
    return json.loads(line[len("RESULT "):])


def main(argv=None):
    import argparse

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--base", required=True, help="a worktree of the code to compare with")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--repeats", type=int, default=15)
    parser.add_argument("--cache-root", default="/tmp/bar_call_cost")
    parser.add_argument("--out", default=str(RESULTS))
    args = parser.parse_args(argv)
    here = Path(__file__).resolve().parent.parent
    trees = {"base": Path(args.base).resolve(), "this": here}
    start = load()
    best = {name: {} for name in trees}
    cpu = {name: {} for name in trees}
    generated, values = {}, {}
    for _ in range(args.rounds):
        for name, tree in trees.items():
            r = child(tree, args.cache_root, name, args.repeats)
            generated[name] = r["generated"]
            values[name] = r["values"]
            for label, seconds in r["best"].items():
                best[name][label] = min(best[name].get(label, 1e9), seconds)
                cpu[name][label] = min(cpu[name].get(label, 1e9), r["cpu"][label])
    rows = []
    for clock, minima in (("wall", best), ("cpu", cpu)):
        for name in trees:
            b = minima[name]
            per_step = (b["t = 100, τ = 0.1"] - b["t = 100, τ = 0.4"]) / 750
            rows.append({"clock": clock, "tree": name, "generated_stepper": generated[name],
                         **{label: b[label] for label, _, _ in CONFIGS},
                         "per_step": per_step})
    ratio = {}
    for r in rows:
        print(f"{r['clock']:4s} {r['tree']:5s} generated={r['generated_stepper']!s:5s} "
              + ", ".join(f"{label}: {r[label] * 1e3:.3f} ms" for label, _, _ in CONFIGS)
              + f"; per step {r['per_step'] * 1e6:.2f} µs")
    for base, this in (rows[0:2], rows[2:4]):
        ratio[base["clock"]] = {label: base[label] / this[label]
                                for label, _, _ in CONFIGS + (("per_step", 0, 0),)}
        print(f"{base['clock']}: base / this: " + ", ".join(
            f"{k} {v:.2f}×" for k, v in ratio[base["clock"]].items()))
    # X1 and the energy error of each tree's runs at t = 100: the same
    # numbers, or (another stepper) the same to round-off.
    agreement = {}
    for case, (x1_base, e_base) in values["base"].items():
        x1_this, e_this = values["this"][case]
        agreement[case] = {"x1_base": x1_base, "x1_this": x1_this,
                           "x1_relative": abs(float(x1_this) / float(x1_base) - 1.0),
                           "energy_error_base": e_base, "energy_error_this": e_this}
        print(f"{case}: X1 {x1_base} / {x1_this} (relative "
              f"{agreement[case]['x1_relative']:.1e}), energy error {e_base:.2e} / {e_this:.2e}")
    Path(args.out).mkdir(parents=True, exist_ok=True)
    save_csv(args.out, "bar_call_cost", rows, list(rows[0]))
    save_json(args.out, "bar_call_cost", {"rows": rows, "base_over_this": ratio,
                                          "base": str(trees["base"]), "rounds": args.rounds,
                                          "repeats": args.repeats, "agreement": agreement,
                                          "load": start,
                                          "load_end": load()})


if __name__ == "__main__":
    main()

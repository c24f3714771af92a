"""The cost model of a generated step (:mod:`varint.step_cost`): its weights,
and whether the LH/constant ratio it predicts tracks the measured one
(issue 29, issue 27 item 4b: ``chaos_map``'s ``time_transform="auto"``).

Part ``weights``: the cost of one operation of each kind of
:data:`varint.step_cost.KINDS`, in scalar additions, in the two contexts the
emitted steppers run in. ``"scalar"``: one orbit's straight-line code (the
LH stepper), four independent chains of the operation in a loop; ``"lanes"``:
a loop over :data:`~varint.codegen.interval.LANE_WIDTH` lanes whose body is
a chain of the operation per lane, as the TM stepper's SIMD lanes (the
lanes' logarithm is :func:`varint.kernels.logarithm.vlog`, as in the
lanes' accumulators). Each is timed with chains of 1 and 9 operations,
compiled first, interleaved, the minimum of the repeats, CPU time, one
thread: (t₉ − t₁) / 8 per operation leaves out the loop and the loads.
The logarithm's chain is log(v + w) and the load's v + m[j]: one addition
is taken off each. The table
is stored (``step_cost.json``); the "scalar" one is copied into
:data:`varint.step_cost.WEIGHTS`, rounded to two significant figures (it
priced both steppers until the tables fitted to the maps' runs by
``studies/switch_check.py``: neither per-operation table prices the
emitted steppers as they run, part ``track``).

Part ``track``: for the FLI maps of ``studies/lh_defaults.py`` (Hénon–Heiles,
cored logarithmic R_c = 0.3, 0.1, 0.03, the Sun–Jupiter three-body
problem at C = 3.05; quick grids, t_end = 100), the predicted cost of one
force evaluation of each stepper (:func:`varint.step_cost.log_gradient_cost`,
:func:`~varint.step_cost.constant_gradient_cost` with SRKN14a, the
defaults' constant scheme) and the measured seconds per force evaluation
of each map's run at a fixed step (``time_transform="log", tau=H`` and
``time_transform=None, tau=TAU, scheme="SRKN14a"``: no pilot), one
thread, interleaved, the minimum of the repeats; the table: predicted and
measured LH/constant ratio per map, the predicted and measured seconds
per force evaluation of each (one addition: the "scalar" table's), and
the constant step's cost by the "lanes" table (both from part
``weights``: of this call, or the stored one, kept in the file).

Usage: ``python studies/step_cost.py [--quick] [--part weights,track]``;
results ``step_cost.json`` (``quick/step_cost.json``). State the machine
load (recorded) with every figure.
"""

from __future__ import annotations

import json
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
from studies.common import interleaved, parse_args, save_json
from studies.lh_defaults import maps
from varint import step_cost
from varint.codegen.interval import LANE_WIDTH
from varint.codegen.tm import step_counts
from varint.maps import MAP_SCHEME
from varint.schemes import get_scheme, stage_arrays
from varint.time_transform import LogHamiltonian

PARTS = ("weights", "track")
#: One chain step per kind: v the chain's value, w an operand per lane.
#: The operands keep every chain bounded (w = 0.5 for fma and 3 for log:
#: fixed points; 1.5 / v oscillates; sqrt, sin, cos, exp(−v) and v^0.9
#: converge).
CHAINS = {"add": ("v + w", 1e-3), "mul": ("v * w", 1.0000001), "fma": ("fma(v, w, w)", 0.5),
          "div": ("w / v", 1.5), "sqrt": ("math.sqrt(v)", 0.0), "log": ("LOG(v + w)", 3.0),
          "exp": ("math.exp(-v)", 0.0), "sin": ("math.sin(v)", 0.0),
          "cos": ("math.cos(v)", 0.0), "pow": ("v ** w", 0.9),
          "compare": ("max(v, w)", 0.7), "memory": ("v + m[J]", 0.0)}
LONG, SHORT_CHAIN = 9, 1
#: The fixed steps of part "track" (LH: fictitious h; constant: τ).
H, TAU, T_END = 0.05, 1.0 / 32.0, 100.0


def _kernel(kind, length, context):
    """The numba kernel timing ``length`` operations of ``kind``."""
    expr, _ = CHAINS[kind]
    expr = expr.replace("LOG", "math.log" if context == "scalar" else "vlog")
    if context == "lanes":
        chain = "\n".join(f"            v = {expr.replace('J', f'{i % 8}, b')}"
                          for i in range(length))
        src = f"""
def run(x, u, m, out, reps):
    for r in range(reps):
        for b in range(x.shape[0]):
            v = x[b]
            w = u[b]
{chain}
            out[b] = v
"""
    else:
        # The scalar loads index with the loop counter: a constant index
        # would be hoisted out of the loop.
        chain = "\n".join(
            f"        v{c} = {expr.replace('v', f'v{c}').replace('J', f'(r + {i}) & 7')}"
            for i in range(length) for c in range(4))
        src = f"""
def run(x, u, m, out, reps):
    v0, v1, v2, v3 = x[0], x[1], x[2], x[3]
    w = u[0]
    for r in range(reps):
{chain}
    out[0] = v0 + v1 + v2 + v3
"""
    from varint.kernels.fma import fma
    from varint.kernels.logarithm import vlog

    scope = {"math": __import__("math"), "fma": fma, "vlog": vlog}
    exec(compile(src, f"<{kind} {context} {length}>", "exec"), scope)
    return numba.njit(error_model="numpy")(scope["run"])


def weights(repeats, reps):
    """Seconds per operation of each kind and context (module docstring),
    and the table in scalar additions."""
    tasks, per = {}, {}
    for context in ("scalar", "lanes"):
        width = LANE_WIDTH if context == "lanes" else 4
        for kind, (_, w) in CHAINS.items():
            x = np.full(width, 0.7)
            u = np.full(width, w)
            m = np.full((8, width) if context == "lanes" else 8, 1e-3)
            out = np.zeros(width)
            for length in (SHORT_CHAIN, LONG):
                f = _kernel(kind, length, context)
                f(x, u, m, out, 1)   # compiles, untimed
                tasks[(context, kind, length)] = (
                    lambda f=f, x=x, u=u, m=m, out=out: f(x, u, m, out, reps))
            per[(context, kind)] = width * reps * (LONG - SHORT_CHAIN)
    labels = {f"{c} {k} {n}": t for (c, k, n), t in tasks.items()}
    best, _ = interleaved(labels, repeats, clock=time.process_time)
    seconds = {}
    for (context, kind), count in per.items():
        seconds[(context, kind)] = (best[f"{context} {kind} {LONG}"]
                                    - best[f"{context} {kind} {SHORT_CHAIN}"]) / count
    # The logarithm's and the load's chains add once per step.
    for context in ("scalar", "lanes"):
        for kind in ("log", "memory"):
            seconds[(context, kind)] -= seconds[(context, "add")]
    unit = seconds[("scalar", "add")]
    table = {c: {k: seconds[(c, k)] / unit for k in CHAINS} for c in ("scalar", "lanes")}
    return {"ns_per_operation": {c: {k: 1e9 * seconds[(c, k)] for k in CHAINS}
                                 for c in ("scalar", "lanes")},
            "weights": table, "repeats": repeats, "reps": reps}


def _gradients(result):
    c = result.provenance.counts
    return c["gradient"] if "gradient" in c else c["gradient_evaluations"]


def track(repeats):
    """Predicted and measured LH/constant cost per force evaluation, per map."""
    rows = []
    numba.set_num_threads(1)
    for name, model, grid in maps(True):
        lh = LogHamiltonian(model, "ABA864")
        log_cost, log_counts = step_cost.log_gradient_cost(lh)
        acc = varint.INDICATORS["fli"].accumulator_for({})
        constant_cost, constant_counts = step_cost.constant_gradient_cost(model, MAP_SCHEME, 1,
                                                                          acc)
        kinds, _, _ = stage_arrays(get_scheme(MAP_SCHEME), 1.0)
        per_step, _ = step_counts(kinds, [False] * len(kinds), 1)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")

            def go(model=model, grid=grid, **kw):
                return varint.chaos_map(model, grid, "fli", t_end=T_END, progress=False, **kw)
            tasks = {"log": lambda: go(time_transform="log", tau=H),
                     "constant": lambda: go(time_transform=None, tau=TAU, scheme=MAP_SCHEME)}
            for task in tasks.values():
                task()   # compiles, untimed
            best, outs = interleaved(tasks, repeats, clock=time.process_time)
        per = {key: best[key] / _gradients(outs[key]) for key in tasks}
        row = {"map": name, "orbits": len(grid.states),
               "predicted": {"log": log_cost, "constant": constant_cost,
                             "ratio": log_cost / constant_cost,
                             "gradients_per_step": int(per_step[0]),
                             "kicks": int(sum(1 for v in lh.kinds if int(v) == 1)),
                             "log_operations": dict(log_counts),
                             "constant_operations": dict(constant_counts)},
               "measured": {"us_per_gradient": {k: 1e6 * v for k, v in per.items()},
                            "gradients": {k: _gradients(outs[k]) for k in tasks},
                            "seconds": best, "ratio": per["log"] / per["constant"]}}
        rows.append(row)
        print(f"{name}: predicted LH/constant {row['predicted']['ratio']:.3g} "
              f"({log_cost:.3g} / {constant_cost:.3g} adds per force evaluation), measured "
              f"{row['measured']['ratio']:.3g} ({1e6 * per['log']:.3g} / "
              f"{1e6 * per['constant']:.3g} us)", flush=True)
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    return rows


def main(argv=None):
    def extra(parser):
        parser.add_argument("--part", default=",".join(PARTS))

    args = parse_args(__doc__.split("\n\n")[0], argv, extra)
    parts = [p for p in args.part.split(",") if p]
    if set(parts) - set(PARTS):
        raise SystemExit(f"parts are {', '.join(PARTS)}")
    result = {"quick": args.quick, "load": list(os.getloadavg())}
    stored = args.out / "step_cost.json"
    if "weights" not in parts and stored.exists():
        # The table this run prices by was measured by an earlier run: kept.
        result["weights"] = json.loads(stored.read_text())["weights"]
        result["weights_load"] = json.loads(stored.read_text())["load"]
    if "weights" in parts:
        result["weights"] = weights(3 if args.quick else 5, 2_000 if args.quick else 10_000)
        for context, table in result["weights"]["weights"].items():
            print(context + ": " + ", ".join(f"{k} {v:.2g}" for k, v in table.items()),
                  flush=True)
    if "track" in parts:
        result["track"] = track(2 if args.quick else 3)
        if "weights" in result:
            # The module prices in nanoseconds (its fitted tables); the
            # per-operation tables of part "weights" price in additions.
            add_ns = result["weights"]["ns_per_operation"]["scalar"]["add"]
            tables = result["weights"]["weights"]
            for row in result["track"]:
                p, m = row["predicted"], row["measured"]
                p["measured_over_predicted"] = {
                    k: 1e3 * m["us_per_gradient"][k] / p[k] for k in ("log", "constant")}
                by = {c: add_ns * sum(tables[c].get(k, 0.0) * n for k, n in ops.items()) / per
                      for c, ops, per in (("scalar", p["log_operations"], p["kicks"]),
                                          ("lanes", p["constant_operations"],
                                           p["gradients_per_step"]))}
                p["ns_by_operation_tables"] = by
                print(f"{row['map']}: measured / predicted ns per force evaluation "
                      f"LH {p['measured_over_predicted']['log']:.2g}, constant "
                      f"{p['measured_over_predicted']['constant']:.2g}; by the operation "
                      f"tables LH/constant {by['scalar'] / by['lanes']:.3g}", flush=True)
    result["load_end"] = list(os.getloadavg())
    save_json(args.out, "step_cost", result)
    return result


if __name__ == "__main__":
    main()

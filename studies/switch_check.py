"""Whether ``chaos_map``'s ``time_transform="auto"`` prices the two steppers
as the maps run them (issue 29, issue 27 item 4b): the weights of the
constant step's SIMD lanes (:data:`varint.step_cost.LANE_WEIGHTS`), fitted
on training models, and a check of the predicted LH/constant cost per
force evaluation on held-out models, with the prediction stated before
the held-out run.

Each model's two maps run at fixed steps (no pilot), FLI, one thread,
interleaved, the minimum of the repeats, CPU time: the LH map
(``time_transform="log", tau=H``, ABA864, one orbit at a time in scalar
code) and the constant-step map (``time_transform=None, tau=TAU,
scheme="SRKN14a"``, the generated stepper's lanes). Each map's seconds over
its force evaluations is the measured cost of one; the operations of each
stepper's step are counted from its emitted source
(:func:`varint.step_cost.operations`).

Part ``fit`` (training models: Hénon–Heiles, the cored logarithmic
potential R_c = 0.03, a quartic oscillator, the isochrone potential, the
Toda lattice of three particles, a pendulum pair): the lanes' nanoseconds
per force evaluation fitted by non-negative least squares to the lanes'
operations per force evaluation in four classes
(:data:`varint.step_cost.CLASSES`: arithmetic, division and square root,
library calls, checks and loads), and the LH's likewise: the tables
:data:`varint.step_cost.LANE_WEIGHTS` and :data:`~varint.step_cost.LH_WEIGHTS`
(copied by hand, two significant figures). Leave-one-out over the six
(ratio predicted by the other five against the one's measured ratio):
0.66–1.8, the largest where a class rests on one model (the isochrone's
square roots, the pendulums' sines).

Part ``heldout`` (held-out models: the restricted three-body problem,
Sun–Jupiter, C = 3.05; a softened point mass, ε = 1e-3, the orbits of
``tests/test_step_agreement.py``; a cored logarithmic potential in a
rotating frame, Ω = 0.3, a bar-like model of the rotating form): the same
measurement, against the module's prediction. :data:`PREDICTED` holds
the predicted LH/constant ratios written into this file before the
held-out run (commit 1 of the change); the check: every measured ratio
within a factor :data:`TOLERANCE` of the prediction, and the stepper the
prediction calls cheaper per force evaluation the measured cheaper one
wherever the two differ by more than that factor.

Usage: ``python studies/switch_check.py [--quick] [--part fit,heldout]``;
results ``switch_check.json`` (``quick/``). State the machine load
(recorded) with every figure.
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
import sympy as sp

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import varint
from studies.common import interleaved, parse_args, save_json
from studies.lh_defaults import cored
from varint import step_cost
from varint.codegen.tm import step_counts
from varint.maps import MAP_SCHEME
from varint.models import from_hamiltonian, from_potential
from varint.models.cr3bp import CR3BP, SUN_JUPITER_MU
from varint.schemes import get_scheme, stage_arrays
from varint.time_transform import LogHamiltonian

PARTS = ("fit", "heldout")
#: The fixed steps (LH: fictitious h; constant: τ) and the horizon.
H, TAU, T_END = 0.05, 1.0 / 32.0, 100.0
#: The operation classes of the fit.
CLASSES = step_cost.CLASSES
#: The predicted LH/constant cost per force evaluation of the held-out
#: models, by the module's tables, written here before their run.
PREDICTED: dict[str, float] = {
    "cr3bp": 2.4,                  # LH 127 ns, lanes 53 ns per force evaluation
    "softened point mass": 2.66,   # LH 89.8 ns, lanes 33.8 ns
    "rotating cored": 4.93,        # LH 119 ns, lanes 24.2 ns
}
#: How far a held-out measured ratio may lie from its prediction.
TOLERANCE = 1.5


def _xy():
    return sp.symbols("x y")


def _grid(rng, m, q, p):
    """``m`` states with positions uniform in the box ``q`` and momenta in
    ``p`` ((lo, hi) per coordinate)."""
    cols = [rng.uniform(lo, hi, m) for lo, hi in (*q, *p)]
    return np.column_stack(cols)


def training(m):
    """(name, model, states) of the fit's models."""
    rng = np.random.default_rng(1)
    x, y = _xy()
    hh = varint.models.HenonHeiles()
    yield "henon-heiles", hh, varint.section_grid(
        hh, 0.125, np.linspace(-0.4, 0.65, 8), np.linspace(-0.4, 0.4, 6)).states[:m]
    c = cored(0.03)
    yield "cored R_c=0.03", c, varint.section_grid(
        c, 0.0, np.linspace(-0.9, 0.9, 8), np.linspace(-0.9, 0.9, 6), plane=1).states[:m]
    quartic = from_potential((x**2 + y**2) / 2 + (x**4 + y**4) / 4 - sp.Float(0.3) * x**2 * y**2,
                             [x, y], name="quartic oscillator")
    yield "quartic", quartic, _grid(rng, m, ((-0.8, 0.8), (-0.8, 0.8)), ((-0.4, 0.4),) * 2)
    iso = from_potential(-1 / (1 + sp.sqrt(1 + x**2 + y**2)), [x, y], name="isochrone")
    yield "isochrone", iso, _grid(rng, m, ((0.3, 1.0), (-0.1, 0.1)), ((-0.05, 0.05), (0.1, 0.3)))
    s3 = sp.Float(3) ** sp.Float(0.5)
    toda = from_potential((sp.exp(2 * y + 2 * s3 * x) + sp.exp(2 * y - 2 * s3 * x)
                           + sp.exp(-4 * y)) / 24 - sp.Rational(1, 8), [x, y],
                          name="Toda (three particles)")
    yield "toda", toda, _grid(rng, m, ((-0.3, 0.3), (-0.3, 0.3)), ((-0.3, 0.3),) * 2)
    pend = from_potential(-sp.cos(x) - sp.cos(y) - sp.Float(0.3) * sp.cos(x - y), [x, y],
                          name="pendulum pair")
    yield "pendulums", pend, _grid(rng, m, ((-1.0, 1.0), (-1.0, 1.0)), ((-0.5, 0.5),) * 2)


def heldout(m):
    """(name, model, states) of the held-out models."""
    rng = np.random.default_rng(2)
    x, y = _xy()
    c = CR3BP(SUN_JUPITER_MU)
    yield "cr3bp", c, c.section_grid(3.05, np.linspace(0.3, 0.85, 8),
                                     np.linspace(-0.3, 0.3, 6)).states[:m]
    pm = from_potential(-1 / sp.sqrt(x**2 + y**2 + sp.Float(1e-3)**2), [x, y],
                        name="softened point mass")
    yield "softened point mass", pm, np.column_stack(
        [rng.uniform(0.5, 1.0, m), np.zeros(m), np.zeros(m), rng.uniform(0.05, 0.5, m)])
    px, py = sp.symbols("p_x p_y")
    rot = from_hamiltonian((px**2 + py**2) / 2 - sp.Float(0.3) * (x * py - y * px)
                           + sp.log(sp.Float(0.03)**2 + x**2 + y**2 / sp.Float(0.8)**2) / 2,
                           [x, y], [px, py], name="rotating cored logarithmic")
    yield "rotating cored", rot, _grid(rng, m, ((-0.9, 0.9), (-0.05, 0.05)),
                                       ((-0.3, 0.3), (-0.3, 0.3)))


def _gradients(result):
    c = result.provenance.counts
    return c["gradient"] if "gradient" in c else c["gradient_evaluations"]


def _classes(counts, per):
    return {cls: sum(counts.get(k, 0) for k in kinds) / per for cls, kinds in CLASSES.items()}


def measure(name, model, X, repeats):
    """One model's row: operations and measured nanoseconds per force
    evaluation of each stepper, and the module's prediction."""
    lh = LogHamiltonian(model, "ABA864")
    log_cost, log_counts = step_cost.log_gradient_cost(lh)
    acc = varint.INDICATORS["fli"].accumulator_for({})
    constant_cost, constant_counts = step_cost.constant_gradient_cost(model, MAP_SCHEME, 1, acc)
    kicks = int(sum(1 for v in lh.kinds if int(v) == 1))
    kinds, _, _ = stage_arrays(get_scheme(MAP_SCHEME), 1.0)
    lanes_per = int(step_counts(kinds, [False] * len(kinds), 1)[0][0])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")

        def go(**kw):
            return varint.chaos_map(model, X, "fli", t_end=T_END, progress=False, **kw)
        tasks = {"log": lambda: go(time_transform="log", tau=H),
                 "constant": lambda: go(time_transform=None, tau=TAU, scheme=MAP_SCHEME)}
        t0 = time.process_time()
        for task in tasks.values():
            task()   # compiles, untimed
        compile_s = time.process_time() - t0
        best, outs = interleaved(tasks, repeats, clock=time.process_time)
    ns = {k: 1e9 * best[k] / _gradients(outs[k]) for k in tasks}
    stopped = {k: int(np.sum(np.asarray(outs[k].status) != 0)) for k in tasks}
    row = {"model": name, "orbits": len(X), "compile_s": compile_s,
           "predicted": {"log": log_cost, "constant": constant_cost,
                         "ratio": log_cost / constant_cost},
           "log_operations": dict(log_counts), "log_kicks": kicks,
           "constant_operations": dict(constant_counts), "constant_gradients_per_step": lanes_per,
           "lanes_classes": _classes(constant_counts, lanes_per),
           "log_weighted": step_cost.weighted(log_counts) / kicks,
           "measured": {"ns_per_gradient": ns, "ratio": ns["log"] / ns["constant"],
                        "seconds": best, "gradients": {k: _gradients(outs[k]) for k in tasks},
                        "stopped": stopped}}
    print(f"{name}: measured LH {ns['log']:.3g} ns, constant {ns['constant']:.3g} ns per force "
          f"evaluation (ratio {row['measured']['ratio']:.3g}); predicted ratio "
          f"{row['predicted']['ratio']:.3g}; stopped {stopped}; compile {compile_s:.0f} s",
          flush=True)
    return row


def _design(rows, key, per):
    return np.array([list(_classes(r[key], r[per]).values()) for r in rows])


def fit(rows):
    """Each stepper's nanoseconds per operation of each class (non-negative
    least squares on the measured nanoseconds per force evaluation), the
    fitted costs, and each model's ratio predicted by a fit on the other
    models (leave one out)."""
    from scipy.optimize import nnls

    A = _design(rows, "constant_operations", "constant_gradients_per_step")
    L = _design(rows, "log_operations", "log_kicks")
    a = np.array([r["measured"]["ns_per_gradient"]["constant"] for r in rows])
    b = np.array([r["measured"]["ns_per_gradient"]["log"] for r in rows])
    lanes, _ = nnls(A, a)
    lh, _ = nnls(L, b)
    names = [r["model"] for r in rows]
    loo = {}
    for i, name in enumerate(names):
        keep = [j for j in range(len(rows)) if j != i]
        wa, _ = nnls(A[keep], a[keep])
        wb, _ = nnls(L[keep], b[keep])
        loo[name] = float((L[i] @ wb) / (A[i] @ wa) / (b[i] / a[i]))
    return {"lanes_ns": dict(zip(CLASSES, lanes.tolist(), strict=True)),
            "lh_ns": dict(zip(CLASSES, lh.tolist(), strict=True)),
            "fitted_lanes_ns": dict(zip(names, (A @ lanes).tolist(), strict=True)),
            "fitted_lh_ns": dict(zip(names, (L @ lh).tolist(), strict=True)),
            "leave_one_out_predicted_over_measured": loo}


def main(argv=None):
    def extra(parser):
        parser.add_argument("--part", default=",".join(PARTS))

    args = parse_args(__doc__.split("\n\n")[0], argv, extra)
    parts = [p for p in args.part.split(",") if p]
    if set(parts) - set(PARTS):
        raise SystemExit(f"parts are {', '.join(PARTS)}")
    m = 16 if args.quick else 40
    repeats = 2 if args.quick else 3
    result = {"quick": args.quick, "load": list(os.getloadavg()), "h": H, "tau": TAU,
              "t_end": T_END}
    numba.set_num_threads(1)
    stored = args.out / "switch_check.json"
    if "fit" in parts:
        rows = [measure(name, model, X, repeats) for name, model, X in training(m)]
    elif stored.exists():
        # The training rows of an earlier run: fitted again (deterministic).
        rows = json.loads(stored.read_text())["fit"]["rows"]
    else:
        rows = None
    if rows is not None:
        result["fit"] = {"rows": rows, **fit(rows)}
        for side in ("lanes", "lh"):
            print(f"{side} ns per operation: " + ", ".join(
                f"{k} {v:.2g}" for k, v in result["fit"][f"{side}_ns"].items()), flush=True)
        print("leave one out, predicted / measured ratio: " + ", ".join(
            f"{k} {v:.2g}" for k, v in
            result["fit"]["leave_one_out_predicted_over_measured"].items()), flush=True)
    if "heldout" in parts:
        rows = []
        for name, model, X in heldout(m):
            row = measure(name, model, X, repeats)
            predicted = PREDICTED.get(name, row["predicted"]["ratio"])
            measured = row["measured"]["ratio"]
            row["stated_prediction"] = PREDICTED.get(name)
            row["within"] = bool(max(predicted / measured, measured / predicted) <= TOLERANCE)
            row["same_order"] = bool((predicted > 1) == (measured > 1)
                                     or max(predicted, 1 / predicted) <= TOLERANCE
                                     and max(measured, 1 / measured) <= TOLERANCE)
            rows.append(row)
        result["heldout"] = {"rows": rows, "tolerance": TOLERANCE,
                             "passed": all(r["within"] and r["same_order"] for r in rows)}
        print(f"held-out check (within {TOLERANCE}x, same order): "
              f"{'passed' if result['heldout']['passed'] else 'FAILED'}", flush=True)
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    result["load_end"] = list(os.getloadavg())
    save_json(args.out, "switch_check", result)
    return result


if __name__ == "__main__":
    main()

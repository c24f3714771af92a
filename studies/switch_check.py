"""Whether ``chaos_map``'s ``time_transform="auto"`` prices the two steppers
as the maps run them (issue 29, issue 27 item 4b): the tables of
:mod:`varint.step_cost` fitted on training models, and a check of the predicted LH/constant cost per
force evaluation on held-out models, with the prediction stated before
the held-out run.

Each model's maps run at fixed steps (no pilot), FLI, one thread,
interleaved, the minimum of the repeats, CPU time: the LH map
(``time_transform="log", tau=H``, ABA864, one orbit at a time in scalar
code), the same LH map over SIMD lanes (``log_lanes``, lhprice18:
:mod:`varint.codegen.lh_lanes`, taken whatever the work,
:data:`varint.time_transform.LANES_WORK` = 0; its FLIs checked equal to
one orbit's bit for bit) and the constant-step map
(``time_transform=None, tau=TAU, scheme="SRKN14a"``, the generated
stepper's lanes). Each map's seconds over
its force evaluations is the measured cost of one; the operations of each
stepper's step are counted from its emitted source
(:func:`varint.step_cost.operations`).

Part ``fit``: the training models' rows, and per stepper the nanoseconds
per operation of each class (:data:`varint.step_cost.CLASSES`: arithmetic,
division and square root, library calls, checks and loads) fitted by
non-negative least squares to the measured nanoseconds per force
evaluation: the LH's on all, the lanes' separately where their loop
vectorises and where it does not (:func:`varint.step_cost.vectorises`: a
library call in the step keeps it scalar; a negative integer power did,
until the steppers printed it as a division, :mod:`varint.codegen.printer`).
The LH over lanes is fitted alike on the LH's operations (the lanes run
the one-orbit step's statements): :data:`varint.step_cost.LH_LANES_WEIGHTS`.
They are :data:`varint.step_cost.LH_WEIGHTS`,
:data:`~varint.step_cost.VECTOR_LANE_WEIGHTS` and
:data:`~varint.step_cost.SCALAR_LANE_WEIGHTS` (copied by hand, two
significant figures). Training models: Hénon–Heiles, the cored logarithmic
potential R_c = 0.03, a quartic oscillator, the isochrone, the Toda
lattice of three particles, a pendulum pair (:func:`training`), and
(:func:`seen`) the restricted three-body problem (Sun–Jupiter, C = 3.05),
a softened point mass (ε = 1e-3, eccentric orbits), a cored logarithmic
potential in a rotating frame and a Miyamoto–Nagai disc in its meridional
plane. ``--reuse`` takes earlier measured rows instead of measuring again
(their operations counted again from the current source). Leave one out
(each model's ratio predicted by a fit on the others, over its measured
ratio): 0.38–2.3 (0.62–1.4 before the third check, below; the two
scalar-lane models, Toda and the pendulums, are the extremes).

Part ``heldout``: models the tables were not fitted on (:func:`heldout`:
two fixed softened centres, masses 1 and 0.5; a softened point mass in a
rotating frame, Ω = 0.5; a logarithmic halo with a softened central mass),
measured alike, against :data:`PREDICTED`, the ratios the tables predict,
written into this file before the held-out run. The check: every
measured ratio within a factor :data:`TOLERANCE` of its prediction and on
the same side of 1 (the stepper predicted cheaper per force evaluation
is the measured cheaper one). The second check passed
(``switch_check_second_quick.json``, load 6–9): two centres 3.83 measured
against 4.63 predicted, the rotating point mass 8.94 against 7.17, the
halo with a central mass 2.48 against 2.55.

The third check, after negative integer powers were printed as divisions
(the lanes of both cored potentials, the isochrone and the halo with a
central mass then vectorise): the three training rows whose source
changed measured again, the others reused (``--reuse``;
``switch_check_refit_quick.json``, load 4.9 → 6.9: the cored lanes 32.3 →
14.0 ns per force evaluation, the rotating cored 30.4 → 13.8, the
isochrone 36.5 → 16.4), the tables fitted again and copied into
:mod:`varint.step_cost`, :data:`PREDICTED` written, then the held-out run
(``switch_check_quick.json``, load 7.6 → 9.1): passed, two centres 4.33
measured against 4.87 predicted, the rotating point mass 5.66 against
7.13, the halo with a central mass 4.57 against 5.19 (its lanes 44.3 →
25.1 ns).

The fourth check: every training row measured again in one run at
load 1–2 (``switch_check.json``, the full grids, not ``--quick``; load
1.7 → 1.7), since the tables fitted at load 5–9 priced the LH's force
evaluation on the cored potential at 5.9 lanes' against 8.5 measured
here (Hénon–Heiles 6.3 against 8.1): under load the LH's divisions had
cost 2.0 ns, now 0.57. Leave one out: 0.87–1.1 except the two
scalar-lane models (Toda 0.39, the pendulums 2.6). The tables copied
into :mod:`varint.step_cost`, :data:`PREDICTED` written, then the held-out
run (load 0.7 → 1.3): passed, two centres 5.60 measured against 5.12
predicted, the rotating point mass 7.70 against 8.81, the halo with a
central mass 5.98 against 5.90.

The fifth check (map25, on an AMD EPYC with AVX-512, where the studies
now run; load 8–13, CPU time): every training row measured again, the
tables fitted again and copied into :mod:`varint.step_cost` (the LH over
lanes with a table of its own, column ``log_lanes``), :data:`PREDICTED`
written, then the held-out run (``switch_check.json``). The Xeon's tables
priced this machine's vectorised lanes 2–3 times too dear (the
three-body problem's LH over lanes at 2.2 times a lane's force
evaluation against 4.0 measured on the full map of
``studies/hamiltonians.py``, which made the defaults run the LH there).
Leave one out 0.37–2.7 (the LH over lanes 0.43–2.2). The held-out run
(load 9.8 → 10.1) passed: two centres 6.05 measured against 8.72
predicted, the rotating point mass 11.0 against 13.3, the halo with a
central mass 9.63 against 9.17.

The first check (one table for the lanes, fitted on the first six
training models; ``switch_check_first_quick.json``) failed: predicted
2.4, 2.66, 4.93 against measured 6.43, 4.27, 3.33 on the three-body
problem, the softened point mass and the rotating cored potential. The
three-body lanes cost 18 ns per force evaluation, not the 53 predicted:
their loop vectorises, the cored potential's does not (its Hessian's
``(R² + r²)**(-2)``), which one table could not tell apart. Those models
joined the training set, and new ones are held out.

Usage: ``python studies/switch_check.py [--quick] [--part fit,heldout]``;
results ``switch_check.json`` (``quick/``). State the machine load
(recorded) with every figure.
"""

from __future__ import annotations

import json
import math
import os
import sys
import time
import warnings
from pathlib import Path
from unittest import mock

import numba
import numpy as np
import sympy as sp

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import varint
from studies.common import interleaved, parse_args, save_json
from studies.lh_defaults import cored
from varint import step_cost, time_transform
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
#: The fifth check's (tables fitted again on an AMD EPYC, znver4, map25):
#: the fourth's (Intel Xeon) were 5.12, 8.81 and 5.90, the third's 4.63,
#: 7.17 and 2.55 (the halo's lanes scalar).
PREDICTED: dict[str, float] = {
    "two centres": 8.72,            # LH 57.7 ns, lanes 6.61 ns (vectorised)
    "rotating point mass": 13.3,    # LH 71.5 ns, lanes 5.37 ns (vectorised)
    "halo and mass": 9.17,          # LH 54.7 ns, lanes 5.96 ns (vectorised)
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


def seen(m):
    """(name, model, states) of the first held-out set, whose check failed
    (the three-body problem; module docstring): training models since."""
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
    z = sp.Symbol("z")
    mn = from_potential(-1 / sp.sqrt(x**2 + (1 + sp.sqrt(z**2 + sp.Float(0.1)**2))**2), [x, z],
                        name="Miyamoto-Nagai meridional")
    yield "miyamoto-nagai", mn, _grid(rng, m, ((0.3, 1.5), (-0.2, 0.2)), ((-0.1, 0.1),) * 2)


def heldout(m):
    """(name, model, states) of the held-out models."""
    rng = np.random.default_rng(3)
    x, y = _xy()
    eps2 = sp.Float(1e-3)**2
    two = from_potential(-1 / sp.sqrt((x - sp.Float(0.5))**2 + y**2 + eps2)
                         - sp.Float(0.5) / sp.sqrt((x + sp.Float(0.5))**2 + y**2 + eps2), [x, y],
                         name="two fixed centres")
    yield "two centres", two, _grid(rng, m, ((-1.2, 1.2), (0.2, 0.8)), ((-0.2, 0.2),) * 2)
    px, py = sp.symbols("p_x p_y")
    rot = from_hamiltonian((px**2 + py**2) / 2 - sp.Float(0.5) * (x * py - y * px)
                           - 1 / sp.sqrt(x**2 + y**2 + eps2), [x, y], [px, py],
                           name="rotating softened point mass")
    r = rng.uniform(0.5, 1.0, m)
    yield "rotating point mass", rot, np.column_stack(
        [r, np.zeros(m), np.zeros(m), rng.uniform(0.05, 0.5, m) + 0.5 * r])
    halo = from_potential(sp.log(1 + x**2 + y**2 / sp.Float(0.8)**2) / 2
                          - sp.Float(0.3) / sp.sqrt(x**2 + y**2 + sp.Float(0.01)**2), [x, y],
                          name="halo with a central mass")
    yield "halo and mass", halo, _grid(rng, m, ((-0.9, 0.9), (-0.05, 0.05)), ((-0.3, 0.3),) * 2)


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
        tasks = {"log": lambda: _lanes(math.inf, go, time_transform="log", tau=H),
                 "log_lanes": lambda: _lanes(0.0, go, time_transform="log", tau=H),
                 "constant": lambda: go(time_transform=None, tau=TAU, scheme=MAP_SCHEME)}
        t0 = time.process_time()
        for task in tasks.values():
            task()   # compiles, untimed
        compile_s = time.process_time() - t0
        best, outs = interleaved(tasks, repeats, clock=time.process_time)
    ns = {k: 1e9 * best[k] / _gradients(outs[k]) for k in tasks}
    if not np.array_equal(outs["log"].values, outs["log_lanes"].values, equal_nan=True):
        raise AssertionError(f"{name}: the LH map over lanes differs from one orbit at a time")
    stopped = {k: int(np.sum(np.asarray(outs[k].status) != 0)) for k in tasks}
    row = {"model": name, "orbits": len(X), "compile_s": compile_s,
           "predicted": {"log": log_cost, "constant": constant_cost,
                         "ratio": log_cost / constant_cost if constant_cost else math.nan},
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


def _lanes(work, go, **kw):
    """``go(**kw)`` with :data:`varint.time_transform.LANES_WORK` at
    ``work``: 0 runs every LH map of at least
    :data:`~varint.time_transform.MIN_LANES` orbits over SIMD lanes, inf one
    orbit at a time (the same bits)."""
    with mock.patch.object(time_transform, "LANES_WORK", work):
        return go(**kw)


def _design(rows, key, per):
    return np.array([list(_classes(r[key], r[per]).values()) for r in rows])


def _nnls(A, b):
    from scipy.optimize import nnls

    return nnls(A, b)[0] if len(b) else np.zeros(A.shape[1])


def _tables(rows):
    """The fitted nanoseconds per operation of each class: the LH's, and
    the lanes' where they vectorise and where they do not."""
    L = _design(rows, "log_operations", "log_kicks")
    b = np.array([r["measured"]["ns_per_gradient"]["log"] for r in rows])
    tables = {"lh": _nnls(L, b)}
    if all("log_lanes" in r["measured"]["ns_per_gradient"] for r in rows):
        tables["lh_lanes"] = _nnls(L, np.array([r["measured"]["ns_per_gradient"]["log_lanes"]
                                                for r in rows]))
    for side, flag in (("vector", True), ("scalar", False)):
        sub = [r for r in rows if step_cost.vectorises(r["constant_operations"]) == flag]
        A = _design(sub, "constant_operations", "constant_gradients_per_step")
        tables[side] = _nnls(A, np.array([r["measured"]["ns_per_gradient"]["constant"]
                                          for r in sub]))
    return tables


def _predict(tables, row):
    """(LH, lanes) nanoseconds per force evaluation of ``row`` by ``tables``."""
    lh = _design([row], "log_operations", "log_kicks")[0] @ tables["lh"]
    side = "vector" if step_cost.vectorises(row["constant_operations"]) else "scalar"
    lanes = _design([row], "constant_operations", "constant_gradients_per_step")[0] \
        @ tables[side]
    return float(lh), float(lanes)


def fit(rows):
    """The tables (:func:`_tables`), the fitted costs, and each model's
    ratio predicted by a fit on the other models over its measured ratio
    (leave one out)."""
    tables = _tables(rows)
    names = [r["model"] for r in rows]
    loo = {}
    for i, row in enumerate(rows):
        lh, lanes = _predict(_tables(rows[:i] + rows[i + 1:]), row)
        m = row["measured"]["ns_per_gradient"]
        loo[names[i]] = lh / lanes / (m["log"] / m["constant"]) if lanes > 0 else math.inf
    loo_lanes = {}
    if "lh_lanes" in tables:
        # The LH over lanes against the constant step's lanes, alike.
        for i, row in enumerate(rows):
            others = _tables(rows[:i] + rows[i + 1:])
            lh = float(_design([row], "log_operations", "log_kicks")[0] @ others["lh_lanes"])
            lanes = _predict(others, row)[1]
            m = row["measured"]["ns_per_gradient"]
            loo_lanes[names[i]] = (lh / lanes / (m["log_lanes"] / m["constant"])
                                   if lanes > 0 else math.inf)
    return {"leave_one_out_lanes_predicted_over_measured": loo_lanes,
            **{f"{side}_ns": dict(zip(CLASSES, t.tolist(), strict=True))
               for side, t in tables.items()},
            "fitted_ns": {name: _predict(tables, r) for name, r in zip(names, rows, strict=True)},
            "vectorises": {r["model"]: step_cost.vectorises(r["constant_operations"])
                           for r in rows},
            "leave_one_out_predicted_over_measured": loo}


def _earlier(paths):
    """Measured rows by model from earlier results of this study."""
    rows = {}
    for path in (p for p in paths.split(",") if p):
        data = json.loads(Path(path).read_text())
        for part in ("fit", "heldout"):
            for row in data.get(part, {}).get("rows", []):
                rows[row["model"]] = row
    return rows


def _recounted(row, model):
    """An earlier measured ``row`` with its operations counted again from
    the current emitted source (the counter may have learnt a kind)."""
    lh = LogHamiltonian(model, "ABA864")
    acc = varint.INDICATORS["fli"].accumulator_for({})
    log_cost, log_counts = step_cost.log_gradient_cost(lh)
    constant_cost, constant_counts = step_cost.constant_gradient_cost(model, MAP_SCHEME, 1, acc)
    print(f"{row['model']}: measured row reused (operations counted again)", flush=True)
    return {**row, "reused": True, "log_operations": dict(log_counts),
            "constant_operations": dict(constant_counts),
            "lanes_classes": _classes(constant_counts, row["constant_gradients_per_step"]),
            "predicted": {"log": log_cost, "constant": constant_cost,
                          "ratio": log_cost / constant_cost if constant_cost else math.nan}}


def main(argv=None):
    def extra(parser):
        parser.add_argument("--part", default=",".join(PARTS))
        parser.add_argument("--models", default="",
                            help="the training models to measure (comma-separated names; "
                                 "default: all)")
        parser.add_argument("--reuse", default="",
                            help="earlier results of this study (comma-separated) whose "
                                 "measured rows part fit takes instead of measuring again")

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
        earlier = _earlier(args.reuse)
        chosen = [name for name in args.models.split(",") if name]
        rows = [_recounted(earlier[name], model) if name in earlier
                else measure(name, model, X, repeats)
                for models in (training(m), seen(m)) for name, model, X in models
                if not chosen or name in chosen]
    elif stored.exists():
        # The training rows of an earlier run: fitted again (deterministic).
        rows = json.loads(stored.read_text())["fit"]["rows"]
    else:
        rows = None
    if rows is not None:
        result["fit"] = {"rows": rows, **fit(rows)}
        for side in ("lh", "lh_lanes", "vector", "scalar"):
            if f"{side}_ns" not in result["fit"]:
                continue
            print(f"{side} ns per operation: " + ", ".join(
                f"{k} {v:.2g}" for k, v in result["fit"][f"{side}_ns"].items()), flush=True)
        print("leave one out, predicted / measured ratio: " + ", ".join(
            f"{k} {v:.2g}" for k, v in
            result["fit"]["leave_one_out_predicted_over_measured"].items()), flush=True)
        print("leave one out, LH over lanes: " + ", ".join(
            f"{k} {v:.2g}" for k, v in
            result["fit"]["leave_one_out_lanes_predicted_over_measured"].items()), flush=True)
    if "heldout" in parts:
        rows = []
        for name, model, X in heldout(m):
            row = measure(name, model, X, repeats)
            predicted = PREDICTED.get(name, row["predicted"]["ratio"])
            measured = row["measured"]["ratio"]
            row["stated_prediction"] = PREDICTED.get(name)
            row["within"] = bool(max(predicted / measured, measured / predicted) <= TOLERANCE)
            row["same_order"] = bool((predicted > 1) == (measured > 1))
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

"""When a chaos map's defaults should take the logarithmic-Hamiltonian step
(issue 27 item 4b, issue 29): for FLI maps of models whose force varies
more or less along the orbits, the spread of U = C − V over the map's
initial conditions (:func:`u_spread`), and, one thread each, the minimum of
the repeats, interleaved: constant steps at the energy pilot's step
(``chaos_map`` with ``time_transform=None``: pilot and run), the LH at its
automatic h (``time_transform="log"``, no tau: the step at which the pilot
orbits' FLI agrees with that at h/2, :mod:`varint.step_agreement`; pilot
and run), the defaults (``time_transform="auto"``: the cheaper of the two
steppers each at its agreeing step, ``varint.maps._cheaper_steps``), and
the seconds per force evaluation of the two runs at fixed steps (no pilot:
``cost_ratio``, the LH's over the constant step's, which set the single
cost constant the defaults used before ``varint.step_cost``; the
constant run at a given τ takes the default scheme of a given step, not
the defaults' SRKN14a: ``studies/step_cost.py`` measures that ratio with
SRKN14a). Each contender keeps its step, rule,
force evaluations (run and pilots), the largest energy error over its
orbits and how often its FLI classifications (antimode of the
constant-step map's values) agree with the constant-step map's.

Before the generated LH stepper and the indicator pilot (load 12–15,
2 cores): the LH map at its energy-tolerance h was 0.13× (Hénon–Heiles) to
0.70× (R_c = 0.03) the speed of constant steps, so the defaults took it
only where no constant step met the tolerance. The stored run
(``lh_defaults_quick.json``) is quoted in the guide page "Steps that follow
the orbit".

Maps (section grids, t_end = 200, ``--quick``: smaller grids, 2 repeats):
Hénon–Heiles (E = 1/8), the cored logarithmic potential of
``studies/map_steps.py`` with core radius R_c = 0.3, 0.1 and 0.03, the
restricted three-body problem of ``studies/map_steps.py`` (Sun–Jupiter,
C = 3.05).

Usage: ``python studies/lh_defaults.py [--quick]``; results
``lh_defaults.json`` (``lh_defaults_quick.json``). State the machine load
(recorded) with every figure.
"""

from __future__ import annotations

import os
import sys
import warnings
from pathlib import Path

import numba
import numpy as np
import sympy as sp

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import varint
from studies.common import interleaved, parse_args, save_json
from varint.models.cr3bp import CR3BP, SUN_JUPITER_MU

T_END = 200.0


def u_spread(model, X):
    """max U / min U over the orbits ``X`` at their starts, U = C − V(q)
    with each orbit's C of :class:`varint.time_transform.LogHamiltonian`
    (δ = 1): how strongly the logarithmic Hamiltonian would vary the
    physical step over the region the map's initial conditions cover. NaN
    where U ≤ 0 at a start."""
    n = X.shape[1] // 2
    with np.errstate(all="ignore"):
        E = np.asarray(model.conserved(X)["energy"], dtype=float)
        U = E + np.maximum(-E, 1.0) - np.asarray(model.potential(X[:, :n]), dtype=float)
    return float(U.max() / U.min()) if np.all(np.isfinite(U)) and np.all(U > 0) else float("nan")


def cored(rc):
    x, y = sp.symbols("x y")
    return varint.models.from_potential(
        sp.log(sp.Float(rc)**2 + x**2 + y**2 / sp.Float(0.8)**2) / 2, [x, y],
        name=f"cored logarithmic, R_c = {rc}")


def maps(quick):
    n = (8, 6) if quick else (12, 10)
    hh = varint.models.HenonHeiles()
    yield "henon-heiles", hh, varint.section_grid(hh, 0.125, np.linspace(-0.4, 0.65, n[0]),
                                                  np.linspace(-0.4, 0.4, n[1]))
    for rc in (0.3, 0.1, 0.03):
        m = cored(rc)
        yield f"cored R_c={rc}", m, varint.section_grid(
            m, 0.0, np.linspace(-0.9, 0.9, n[0]), np.linspace(-0.9, 0.9, n[1]), plane=1)
    c = CR3BP(SUN_JUPITER_MU)
    yield "cr3bp", c, c.section_grid(3.05, np.linspace(0.3, 0.85, n[0]),
                                     np.linspace(-0.3, 0.3, n[1]))


def classify(values, threshold):
    return np.where(np.isfinite(values), values > threshold, False)


def antimode(values):
    v = np.log10(np.maximum(values[np.isfinite(values)], 1e-300))
    hist, edges = np.histogram(v, bins=20)
    inner = hist[1:-1]
    k = 1 + int(np.argmin(inner)) if len(inner) else 0
    return 10 ** (0.5 * (edges[k] + edges[k + 1]))


def _gradients(result):
    """Force evaluations of a map's run and of its pilot(s)."""
    c, choice = result.provenance.counts, result.provenance.tau_choice
    run = c["gradient"] if "gradient" in c else c["gradient_evaluations"]
    pilot = 0
    for part in (choice, choice.get("energy_choice", {})):
        counts = part.get("counts", {})
        pilot += counts.get("gradient", counts.get("gradient_evaluations", 0))
    return run, pilot


def measure(name, model, grid, repeats):
    """One map's row: constant steps (energy pilot), the LH at its
    automatic h (indicator pilot), the defaults, and the seconds per force
    evaluation of the two steppers' runs at fixed steps (no pilot)."""
    X = grid.states
    numba.set_num_threads(1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        def go(**kw):
            return varint.chaos_map(model, grid, "fli", t_end=T_END, progress=False, **kw)
        first = {"constant": go(time_transform=None), "log": go(time_transform="log")}
        tau, h = first["constant"].provenance.tau, first["log"].provenance.tau
        tasks = {"constant": lambda: go(time_transform=None),
                 "log": lambda: go(time_transform="log"),
                 "defaults": lambda: go(),
                 "constant run": lambda: go(time_transform=None, tau=tau),
                 "log run": lambda: go(time_transform="log", tau=h)}
        for run in tasks.values():
            run()   # compiles, untimed
        best, outs = interleaved(tasks, repeats)
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    c, lg, d = outs["constant"], outs["log"], outs["defaults"]
    thr = antimode(c.values)
    per_gradient = {key: best[key] / _gradients(outs[key])[0] for key in ("constant run", "log run")}
    row = {"map": name, "orbits": len(X), "t_end": T_END, "u_spread": u_spread(model, X),
           "cost_ratio": per_gradient["log run"] / per_gradient["constant run"],
           "us_per_gradient": {k: 1e6 * v for k, v in per_gradient.items()}}
    for key, out in (("constant", c), ("log", lg), ("defaults", d)):
        run, pilot = _gradients(out)
        row[key] = {"method": out.provenance.method, "step": out.provenance.tau,
                    "rule": out.provenance.tau_choice.get("rule"),
                    "seconds": best[key], "gradients": run, "pilot_gradients": pilot,
                    "max_energy_error": float(np.nanmax(out.accuracy.energy_error)),
                    "failed": int(np.sum(out.status != 0)),
                    "agreement_with_constant": float(np.mean(
                        classify(c.values, thr) == classify(out.values, thr)))}
    row["defaults"]["prices"] = d.provenance.tau_choice.get("prices")
    row["log_over_constant_seconds"] = best["log"] / best["constant"]
    row["defaults_over_constant_seconds"] = best["defaults"] / best["constant"]
    return row


def main(argv=None):
    args = parse_args(__doc__.split("\n\n")[0], argv)
    start = list(os.getloadavg())
    rows = []
    for name, model, grid in maps(args.quick):
        row = measure(name, model, grid, 2 if args.quick else 3)
        rows.append(row)
        print(f"{name}: u_spread {row['u_spread']:.3g}, cost ratio {row['cost_ratio']:.3g}; "
              + "; ".join(f"{key} {row[key]['method']} step {row[key]['step']:.3g} "
                          f"({row[key]['rule']}) {row[key]['seconds']:.3g} s, agreement "
                          f"{row[key]['agreement_with_constant']:.3f}"
                          for key in ("constant", "log", "defaults")),
              flush=True)
    save_json(args.out, "lh_defaults_quick" if args.quick else "lh_defaults",
              {"quick": args.quick, "rows": rows, "load": start,
               "load_end": list(os.getloadavg())})


if __name__ == "__main__":
    main()

"""When a chaos map's defaults should take the logarithmic-Hamiltonian step
(issue 27 item 4b): for FLI maps of models whose force varies more or less
along the orbits, the spread of U = C − V over the map's initial conditions
(:func:`u_spread`) against the work of the two automatic choices at
the same energy tolerance (the FLI map's pilot tolerance, 1e-7): constant
steps (``chaos_map`` with ``time_transform=None``: its pilot and its run)
and the LH at its automatic h (``time_transform="log"``, no tau: its pilot
and its run), in force evaluations, and seconds one thread each, the
minimum of the repeats, interleaved. Each map also keeps the energy errors
both reach (the largest over the orbits) and how often their FLI
classifications (antimode of the constant-step map's values) agree.

Quick run (load 12–15 on 2 cores, ``lh_defaults_quick.json``): the LH map
was slower on every map, 0.13× (Hénon–Heiles) to 0.70× (R_c = 0.03, 4.5 times
fewer force evaluations, each 6.5 times the cost), CR3BP 0.28×: so the
defaults take the LH only where no constant step meets the tolerance
(``varint.maps._log_candidate``).

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


def measure(name, model, grid, repeats):
    X = grid.states
    numba.set_num_threads(1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        tasks = {"constant": lambda: varint.chaos_map(model, grid, "fli", t_end=T_END,
                                                      progress=False, time_transform=None),
                 "log": lambda: varint.chaos_map(model, grid, "fli", t_end=T_END,
                                                 progress=False, time_transform="log")}
        for go in tasks.values():
            go()   # compiles, untimed
        best, outs = interleaved(tasks, repeats)
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    c, lg = outs["constant"], outs["log"]
    cc = c.provenance.tau_choice.get("counts", {})
    grad_c = c.provenance.counts.get("gradient", 0)
    pilot_c = cc.get("gradient", 0)
    lc = lg.provenance.tau_choice.get("counts", {})
    grad_l = lg.provenance.counts["gradient_evaluations"]
    pilot_l = lc.get("gradient_evaluations", 0)
    thr = antimode(c.values)
    row = {"map": name, "orbits": len(X), "t_end": T_END, "u_spread": u_spread(model, X),
           "constant_tau": c.provenance.tau, "constant_seconds": best["constant"],
           "constant_gradients": grad_c, "constant_pilot_gradients": pilot_c,
           "constant_max_energy_error": float(np.nanmax(c.accuracy.energy_error)),
           "log_h": lg.provenance.tau, "log_seconds": best["log"],
           "log_gradients": grad_l, "log_pilot_gradients": pilot_l,
           "log_max_energy_error": float(np.nanmax(lg.accuracy.energy_error)),
           "log_failed": int(np.sum(lg.status != 0)),
           "agreement": float(np.mean(classify(c.values, thr) == classify(lg.values, thr))),
           "time_ratio": best["constant"] / best["log"],
           "gradient_ratio": (grad_c + pilot_c) / max(1, grad_l + pilot_l)}
    return row


def main(argv=None):
    args = parse_args(__doc__.split("\n\n")[0], argv)
    start = list(os.getloadavg())
    rows = []
    for name, model, grid in maps(args.quick):
        row = measure(name, model, grid, 2 if args.quick else 3)
        rows.append(row)
        print(f"{name}: u_spread {row['u_spread']:.3g}, constant {row['constant_seconds']:.3g} s"
              f" ({row['constant_gradients'] + row['constant_pilot_gradients']} gradients), "
              f"log h {row['log_h']:.3g} {row['log_seconds']:.3g} s "
              f"({row['log_gradients'] + row['log_pilot_gradients']}); time ratio "
              f"{row['time_ratio']:.3g}, agreement {row['agreement']:.3f}, errors "
              f"{row['constant_max_energy_error']:.2g} / {row['log_max_energy_error']:.2g}",
              flush=True)
    save_json(args.out, "lh_defaults_quick" if args.quick else "lh_defaults",
              {"quick": args.quick, "rows": rows, "load": start,
               "load_end": list(os.getloadavg())})


if __name__ == "__main__":
    main()

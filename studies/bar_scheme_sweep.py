"""Which two-part scheme and step reach each error of the bar race's X1
in the fewest kicks (issue 29): the choice of ``studies/hamiltonians.py
--part bar``'s varint contenders.

Case
----
The named orbits :data:`varint.models.bar.BAR_ORBITS` (regular, chaotic),
``lyapunov_spectrum`` with one deviation vector (equal components, the
race's), X1 at t = 100 against the race's reference (ABA864, τ = 0.005).

Method
------
Every two-part scheme of :data:`varint.SCHEMES` without corrector or
processor that runs on the bar's generated stepper (ABA864, ABA1064,
ABAH864, FR4, S9ODR6, S11ODR6, SRKN14a, S15ODR8), at steps τ = 100/n for
n = 100 … 1000 (whole numbers of steps: a τ that does not divide t_end
ends the run away from it, measured here as ``off_grid``: τ = 0.45 and
0.15). Kept per run: the kicks (the stepper's gradient count: the cost
of a step is its kicks, ~55 ns each inside the bar) and the error of X1.
No times: the race measures them.

Stored as ``bar_scheme_sweep.json`` under ``--out``
(``studies/results/bar25`` by default), with the cheapest run per decade
of error.

Usage: ``python studies/bar_scheme_sweep.py [--quick]``.
"""

from __future__ import annotations

import os
import sys
import warnings

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import varint
from studies.common import RESULTS, parse_args, save_json
from varint.models.bar import BAR_ORBITS, bar_orbit

SCHEMES = ("ABA864", "ABA1064", "ABAH864", "FR4", "S9ODR6", "S11ODR6", "SRKN14a", "S15ODR8")
STEPS = (100, 125, 200, 250, 400, 500, 800, 1000)
#: Steps that do not divide t = 100 (the race's ABA864 τ = 0.45, FR4 0.15).
OFF_GRID = (0.45, 0.15)


def _x1(model, x0, t_end, tau, scheme):
    w0 = np.full((6, 1), 1 / np.sqrt(6))
    out = varint.lyapunov_spectrum(model, x0, t_end, tau=tau, scheme=scheme, deviations=w0,
                                   t_out=[t_end])
    return float(out.exponents[-1, 0]), int(out.provenance.counts["gradient"])


def measure(quick):
    """Per orbit: rows (scheme, τ, kicks, error) and the cheapest per decade."""
    t_end = 20.0 if quick else 100.0
    schemes = SCHEMES[:2] if quick else SCHEMES
    out = {}
    for name in BAR_ORBITS:
        model, x0 = bar_orbit(name)
        ref, _ = _x1(model, x0, t_end, 0.005, "ABA864")
        rows = []
        for scheme in schemes:
            for n in STEPS:
                tau = t_end / round(n * t_end / 100.0)
                x1, kicks = _x1(model, x0, t_end, tau, scheme)
                rows.append({"scheme": scheme, "tau": tau, "kicks": kicks,
                             "error": abs(x1 - ref), "whole_steps": True})
            for tau in OFF_GRID:
                x1, kicks = _x1(model, x0, t_end, tau, scheme)
                rows.append({"scheme": scheme, "tau": tau, "kicks": kicks,
                             "error": abs(x1 - ref), "whole_steps": False})
        best = {}
        for decade in range(-4, -12, -1):
            fits = [r for r in rows if r["whole_steps"] and r["error"] <= 10.0 ** decade]
            if fits:
                r = min(fits, key=lambda r: r["kicks"])
                best[f"1e{decade}"] = r
                print(f"{name}: error ≤ 1e{decade}: {r['scheme']} τ = {r['tau']:.4g}, "
                      f"{r['kicks']} kicks (error {r['error']:.1e})", flush=True)
        for r in rows:
            if not r["whole_steps"]:
                print(f"{name}: {r['scheme']} τ = {r['tau']} (off the grid): error "
                      f"{r['error']:.1e}", flush=True)
        out[name] = {"reference_x1": ref, "rows": rows, "cheapest_per_decade": best}
    return out


def main(argv=None):
    args = parse_args(__doc__.splitlines()[0], argv)
    if args.out in (RESULTS, RESULTS / "quick"):
        args.out = args.out / "bar25"
        args.out.mkdir(parents=True, exist_ok=True)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = measure(args.quick)
    save_json(args.out, "bar_scheme_sweep", {"orbits": result, "load": os.getloadavg()})
    return result


if __name__ == "__main__":
    main()

"""Where the bar race's time goes (issue 29): per named bar orbit, the
share of its positions outside the Ferrers bar, the bar's force + Hessian
there and inside, and a ``lyapunov_spectrum`` call's fixed cost against
its steps.

Case
----
The race's configuration that met AGAMA's accuracy at stop 57
(``studies/hamiltonians.py --part bar``): the named orbits
:data:`varint.models.bar.BAR_ORBITS`, ABA864 at τ = 0.4, one deviation
vector (galpy's default, equal components), t = 100.

Method
------
* ``outside``: the orbit's positions every 0.01 up to t = 100 (ABA864,
  τ = 0.01): the fraction with λ > 0, and λ's range there. The kicks of a
  step sample the orbit at its stages, so the fraction of time outside is
  the fraction of the bar's evaluations outside.
* ``kick_ns``: ``ferrers_kick`` (force + Hessian, what a kick adds) in a
  compiled loop over those positions inside and outside, this code and,
  with ``--baseline DIR``, the code in DIR (its module loaded beside this
  one, :func:`studies.bar_force_cost._baseline_kick`), interleaved; the
  minimum over ``--repeats`` turns of the process's CPU time.
* ``call_ms``: the race's call at t = 100 and the same call at t = τ (one
  step: the call's fixed cost, its checks, accuracy verdict and results),
  CPU time, minimum over ``--repeats`` interleaved turns; ``steps_ms`` is
  their difference.

Stored as ``bar_time_split.json`` under ``--out``
(``studies/results/bar24`` by default), with the load.

Usage: ``python studies/bar_time_split.py [--quick] [--repeats N]
[--baseline DIR]``.
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import varint
from studies.bar_force_cost import _baseline_kick, _kick_loop
from studies.common import RESULTS, interleaved, parse_args, save_json
from varint.models.bar import BAR_ORBITS, bar_orbit
from varint.models.ferrers import ferrers_lambda

SCHEME, TAU, T_END = "ABA864", 0.4, 100.0


def _positions(model, x0, t_end):
    """The orbit's positions every 0.01 up to ``t_end`` and their λ."""
    times = np.arange(1, int(round(t_end / 0.01)) + 1) * 0.01
    run = varint.integrate(model, x0, t_end, tau=0.01, scheme=SCHEME, t_out=times)
    Q = np.ascontiguousarray(np.asarray(run.states)[:, :3])
    lam = np.array([ferrers_lambda(q * q, model._axes2) for q in Q])
    return Q, lam


def measure(quick, repeats, baseline=None):
    """Per named orbit: the share outside, the kick's cost there and inside,
    the call's fixed cost and steps (module docstring)."""
    t_end = 20.0 if quick else T_END
    w0 = np.full((6, 1), 1 / np.sqrt(6))
    out = {}
    for name in BAR_ORBITS:
        model, x0 = bar_orbit(name)
        axes2, gm = model._axes2, model.values["bar_mass"]
        Q, lam = _positions(model, x0, t_end)
        outside = lam > 0
        row = {"positions": len(Q), "fraction_outside": float(outside.mean()),
               "lambda_outside": ([float(lam[outside].min()), float(np.median(lam[outside])),
                                   float(lam[outside].max())] if outside.any() else None)}
        tasks = {}
        loops = {"this code": (_kick_loop(), model._inside)}
        old = _baseline_kick(baseline, axes2, gm)
        if old is not None:
            loops["baseline"] = old
        for where, mask in (("inside", ~outside), ("outside", outside)):
            P = np.ascontiguousarray(Q[mask])
            if not len(P):
                continue
            for code, (loop, table) in loops.items():
                loop(P, axes2, gm, table)
                tasks[f"kick {where} {code}"] = (
                    lambda P=P, loop=loop, table=table, axes2=axes2, gm=gm:
                    loop(P, axes2, gm, table))
        for label, end in (("call", t_end), ("one step", TAU)):
            tasks[label] = (lambda end=end, model=model, x0=x0: varint.lyapunov_spectrum(
                model, x0, end, tau=TAU, scheme=SCHEME, deviations=w0, t_out=[end]))
            tasks[label]()
        best, _ = interleaved(tasks, repeats, clock=time.process_time)
        row["kick_ns"] = {}
        for label, seconds in best.items():
            if label.startswith("kick"):
                _, where, code = label.split(" ", 2)
                count = int((outside if where == "outside" else ~outside).sum())
                row["kick_ns"].setdefault(where, {})[code] = 1e9 * seconds / count
        row["call_ms"] = {"t_end": 1e3 * best["call"], "one_step": 1e3 * best["one step"],
                          "steps": 1e3 * (best["call"] - best["one step"])}
        out[name] = row
        print(f"{name}: {100 * row['fraction_outside']:.1f} % outside; kick ns "
              + "; ".join(f"{w} " + ", ".join(f"{c} {v:.0f}" for c, v in d.items())
                          for w, d in row["kick_ns"].items())
              + f"; call {row['call_ms']['t_end']:.3f} ms = fixed "
              f"{row['call_ms']['one_step']:.3f} + steps {row['call_ms']['steps']:.3f}",
              flush=True)
    return out


def main(argv=None):
    def extra(parser):
        parser.add_argument("--repeats", type=int, default=7)
        parser.add_argument("--baseline", type=Path, default=None,
                            help="a code directory whose ferrers_kick is timed beside this one")

    args = parse_args(__doc__.splitlines()[0], argv, extra)
    if args.out in (RESULTS, RESULTS / "quick"):
        args.out = args.out / "bar24"
        args.out.mkdir(parents=True, exist_ok=True)
    start = os.getloadavg()
    result = measure(args.quick, 1 if args.quick else args.repeats, args.baseline)
    save_json(args.out, "bar_time_split", {"orbits": result, "scheme": SCHEME, "tau": TAU,
                                           "load": start, "load_end": os.getloadavg(),
                                           "baseline": str(args.baseline)})
    print(f"load {start[0]:.2f} → {os.getloadavg()[0]:.2f}")
    return result


if __name__ == "__main__":
    main()

"""Whether the defaults' two ladders may be judged by one rule (issue 29,
pilot19): the constant-step ladder of the switch
(:func:`varint.maps._cheaper_steps`, :class:`varint.step_agreement.ConstantLadder`)
by the logarithmic Hamiltonian's rule,
:func:`varint.step_agreement.map_verdict` (the FLI values to the map's
t_end), instead of the verdict at the pilot's t
(:func:`~varint.step_agreement.same_verdict`, the rule before pilot19).

Why one rule: a rung of either ladder is judged by how its FLI at the
pilot's t moves when the step is halved, and the argument that made the
LH's rule look to the map's t_end — a regular orbit's phase error, and with
it its FLI's, grows linearly in time under a symplectic scheme (Hairer,
Lubich & Wanner, *Geometric Numerical Integration*, 2nd ed., Thm. X.3.1) —
holds for a constant step as for the LH's. Judged by different rules, the
switch priced a constant step that only had to keep the verdict at t = 100
against an LH step that had to keep the values to t_end: the weaker rule
favoured constant steps.

For each map and each rule of the constant ladder (the LH's is
:func:`~varint.step_agreement.map_verdict` in both), the defaults
(``chaos_map(model, X, "fli", t_end=...)``) and the constant ladder alone,
descended to its end (``agreeing_tau``, no price stops it), against a
tight reference (heyoka at tol 1e-15, normalising every time unit, the
races' driver of ``studies/map_steps.py``) classified at FLI = 2 ln t.
Recorded: the stepper and step the defaults chose, the agreement with the
reference, the pilots' force evaluations and rungs (counts, no timings:
the load does not enter), the constant ladder's own choice and rungs.

Maps: ``cr3bp`` and ``core``, the races' maps of ``studies/map_steps.py``
(quick grids); ``two centres``, the held-out model of
``studies/switch_check.py`` (two fixed softened centres, masses 1 and 0.5;
40 orbits, t = 500).

Stored run (``studies/results/pilot19/ladder_rule.json``, pilot19, load
15.8 → 17.1; counts only): by either rule the defaults chose the same
stepper and step, with the same pilot force evaluations and the same
values bit for bit: the three-body map constant SRKN14a τ = 0.25 (98.7 %;
pilots 336 000 constant and 80 066 LH force evaluations), the two
centres the LH at h = 0.0318 (100 %; 11.4e6 and 2.82e6), the cored map
the LH at h = 0.0247 (100 %; 1.41e6 and 1.35e6). The constant ladder
alone: τ = 0.25 on the three-body map by both rules, none on the two
centres (every rung above the energy ceiling), and on the cored map
τ = 1/128 by the maps' rule against 1/64 by the verdict (at 1/64 all 16
verdicts agree at t = 100, 7 of 16 values to t_end = 2000).

Usage: ``python studies/ladder_rule.py [--maps cr3bp,core,two]``; result
``ladder_rule.json``.
"""

from __future__ import annotations

import hashlib
import os
import sys
import warnings
from pathlib import Path
from unittest import mock

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import varint
from studies.common import parse_args, save_json
from studies.map_steps import (BATCH, INDICATOR, REF_EVERY, REF_TOL, HeyokaMap, fli_threshold,
                               race_map, seeded_vectors)
from studies.switch_check import heldout
from varint import maps, step_agreement, time_transform_step
from varint.accuracy import DEFAULT_ENERGY_TOL
from varint.stepsize_orbits import indicator_judge

#: The LH's rule, imported before any patch below: the switch imports
#: :mod:`varint.time_transform_step` on its first call, and a patched
#: ``step_agreement.map_verdict`` would then become the LH's rule too (its
#: functions bind it as a default argument).
LH_RULE = time_transform_step.map_verdict
MAPS = ("cr3bp", "core", "two")
RULES = {"verdict": step_agreement.same_verdict, "map_verdict": step_agreement.map_verdict}
#: The held-out map's orbits and t_end (as ``studies/switch_check.py``).
HELDOUT_ORBITS, HELDOUT_T = 40, 500.0


def case(name):
    """(model, states, t_end) of map ``name`` (module docstring)."""
    if name in ("cr3bp", "core"):
        model, grid, t_end = race_map(name, True)
        return model, grid.states, t_end
    _, model, X = next(iter(heldout(HELDOUT_ORBITS)))
    return model, X, HELDOUT_T


def ladder(model, X, t_end, agree):
    """The constant ladder alone, to its end: (τ, its choice)."""
    ind = varint.INDICATORS[INDICATOR]
    judge = indicator_judge(ind, model, {}, maps.pilot_tolerance(ind), DEFAULT_ENERGY_TOL)
    return step_agreement.agreeing_tau(
        model, X, t_end, scheme=maps.MAP_SCHEME, seed=0, k=1, renorm=ind.renorm,
        accumulator=ind.accumulator_for({}), value=judge.value, quantile=maps.MAP_QUANTILE,
        ceiling=DEFAULT_ENERGY_TOL, agree=agree)


def measure(name):
    """One map's reference and its defaults and constant ladder under each rule."""
    import heyoka as hy

    model, X, t_end = case(name)
    hy.set_nthreads(1)
    W0 = seeded_vectors(model.dim, 1, len(X))
    values = HeyokaMap(model, INDICATOR, "var_ode_sys", BATCH, REF_TOL, every=REF_EVERY).run(
        X, W0, t_end)
    threshold, _ = fli_threshold(t_end)
    truth = values > threshold
    row = {"map": name, "orbits": len(X), "t_end": t_end, "threshold": threshold,
           "reference_chaotic": float(np.mean(truth)), "rules": {}}
    for label, agree in RULES.items():
        with warnings.catch_warnings(), mock.patch.object(step_agreement, "map_verdict", agree):
            warnings.simplefilter("ignore")
            out = varint.chaos_map(model, X, INDICATOR, t_end=t_end, progress=False)
            tau, alone = ladder(model, X, t_end, agree)
        assert time_transform_step.agreeing_h.__kwdefaults__["agree"] is LH_RULE
        v = np.asarray(out.values)
        choice = out.provenance.tau_choice
        log = choice if out.provenance.method == "tm+log" else choice.get("log", {})
        constant = choice if out.provenance.method == "tm" else choice.get("constant", {})
        r = row["rules"][label] = {
            "method": out.provenance.method,
            "step": choice.get("h") if out.provenance.method == "tm+log" else out.provenance.tau,
            "agreement": float(np.mean(np.isfinite(v) & ((v > threshold) == truth))),
            "constant_tried": constant.get("tried"),
            "constant_pilot_gradients": (constant.get("counts") or {}).get("gradient"),
            "log_tried": log.get("tried"),
            "log_pilot_gradients": (log.get("counts") or {}).get("gradient_evaluations"),
            "prices": choice.get("prices"),
            "ladder_alone_tau": tau, "ladder_alone_tried": alone["tried"],
            "values_sha256": hashlib.sha256(np.ascontiguousarray(v).tobytes()).hexdigest()}
        print(f"{name} {label}: {r['method']} step {r['step']:.4g} agreement "
              f"{r['agreement']:.3f}; constant ladder alone τ {tau}; pilot force evaluations "
              f"constant {r['constant_pilot_gradients']} LH {r['log_pilot_gradients']}",
              flush=True)
    return row


def main(argv=None):
    def extra(parser):
        parser.add_argument("--maps", default=",".join(MAPS))

    args = parse_args(__doc__.split("\n\n")[0], argv, extra)
    names = [m for m in args.maps.split(",") if m]
    if set(names) - set(MAPS):
        raise SystemExit(f"maps are {', '.join(MAPS)}")
    result = {"load": list(os.getloadavg()), "rows": [measure(name) for name in names]}
    result["load_end"] = list(os.getloadavg())
    save_json(args.out, "ladder_rule", result)
    return result


if __name__ == "__main__":
    main()

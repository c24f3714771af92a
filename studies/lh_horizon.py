"""Whether the LH pilot's automatic h keeps an FLI map's verdicts to the
map's own t_end, not only to the pilot's (issue 27).

The LH map's h (:func:`varint.time_transform_step.agreeing_offset`,
:func:`~varint.time_transform_step.agreeing_h`) is judged on 16 pilot
orbits to t = min(t_end, 100) by whether their FLI at h agrees with that at
h/2. Two rules of "agrees" (:mod:`varint.step_agreement`):

``verdict``
    :func:`~varint.step_agreement.same_verdict`, the same side of the
    chaotic level at the pilot's t, whatever the map's t_end (the rule
    before lhprice18).
``horizon``
    :func:`~varint.step_agreement.agreeing`: the FLI values within
    0.05 dex times t_pilot/t_end, or both chaotic. A regular orbit's phase
    error, and with it its FLI's, grows linearly in time under a
    symplectic scheme (Hairer, Lubich & Wanner, *Geometric Numerical
    Integration*, 2nd ed., Thm. X.3.1), so a map 20 times longer than its
    pilot needs agreement 20 times closer at the pilot's t (the rule now,
    :func:`varint.time_transform_step.map_verdict`, which is this one on
    every map here: each runs longer than its pilot).

Stored run (``studies/results/lhprice18/lh_horizon.json``, load 9–20):
the cored map, verdict rule h = 0.099 (δ = 0.25) 92.5 % (9 regular
orbits called chaotic), horizon rule h = 0.025 100 %, 60 400 LH steps per
orbit against 45 100, pilot force evaluations 2.43e6 against 0.66e6; the
three-body map 96.1 % → 100 % (h 0.82 → 0.21, 3 700 → 7 100 steps per
orbit); the halo with a central mass 91.7 % → 95.8 % (h 0.39 → 0.083,
fewer steps: 23 800 → 16 800, the coarse h retried most orbits); the
softened point mass 60.4 % with both rules (its FLIs of regular orbits
lie about 2 ln t: the shear of eccentric orbits, not the step).

Each map runs as ``chaos_map(..., time_transform="log")`` does (the pilot,
the δ it prices, each orbit retried to the map's energy tolerance), with
the rule substituted, against a tight reference (heyoka at tol 1e-15,
normalising every time unit, the races' driver of
``studies/map_steps.py``) classified at FLI = 2 ln t. Recorded per map and
rule: h, δ, the agreement with the reference and its errors both ways, the
map's LH steps per orbit, the pilot's force evaluations (counts, no
timings: the load does not enter).

Maps: ``core`` and ``cr3bp``, the races' maps of ``studies/map_steps.py``
(:func:`~studies.map_steps.race_map`, quick grids: 120 orbits to t = 2000,
76 to t = 1000); ``plummer``, a softened point mass (ε = 1e-3), 48
eccentric orbits from (x, 0), x ∈ [0.5, 1], p_y ∈ [0.05, 0.5] (pericentres
~0.01), to t = 2000: integrable, so every chaotic verdict is false;
``halo``, a cored logarithmic halo with a softened central mass (V = ½ ln(1
+ x² + y²/0.8²) − 0.3/√(x² + y² + 0.01²), the held-out model of
``studies/switch_check.py``), the section y = 0, p_y ≥ 0 at E = 0 over
(x, p_x) ∈ [−0.5, 0.5]², 8 × 6 points, to t = 2000.

Usage: ``python studies/lh_horizon.py [--maps core,cr3bp,plummer,halo]``;
result ``lh_horizon.json``.
"""

from __future__ import annotations

import functools
import os
import sys
import warnings
from pathlib import Path
from unittest import mock

import numpy as np
import sympy as sp

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import varint
from studies.common import parse_args, save_json
from studies.map_steps import (BATCH, INDICATOR, REF_EVERY, REF_TOL, HeyokaMap, fli_threshold,
                               race_map, seeded_vectors)
from varint import step_agreement, time_transform_step
from varint.models import from_potential

MAPS = ("core", "cr3bp", "plummer", "halo")
RULES = {"verdict": step_agreement.same_verdict, "horizon": step_agreement.agreeing}
#: The softened point mass's and the halo's t_end.
T_END = 2000.0


def case(name):
    """(model, states, t_end) of map ``name`` (module docstring)."""
    if name in ("core", "cr3bp"):
        model, grid, t_end = race_map(name, True)
        return model, grid.states, t_end
    x, y = sp.symbols("x y")
    if name == "plummer":
        model = from_potential(-1 / sp.sqrt(x**2 + y**2 + sp.Float(1e-3)**2), [x, y],
                               name="softened point mass")
        rng = np.random.default_rng(4)
        m = 48
        return model, np.column_stack([rng.uniform(0.5, 1.0, m), np.zeros(m), np.zeros(m),
                                       rng.uniform(0.05, 0.5, m)]), T_END
    model = from_potential(sp.log(1 + x**2 + y**2 / sp.Float(0.8)**2) / 2
                           - sp.Float(0.3) / sp.sqrt(x**2 + y**2 + sp.Float(0.01)**2), [x, y],
                           name="halo with a central mass")
    grid = varint.section_grid(model, 0.0, np.linspace(-0.5, 0.5, 8), np.linspace(-0.5, 0.5, 6),
                               plane=1)
    return model, grid.states, T_END


def measure(name):
    """One map's reference and its LH map under each rule."""
    import heyoka as hy

    model, X, t_end = case(name)
    hy.set_nthreads(1)
    W0 = seeded_vectors(model.dim, 1, len(X))
    ref = HeyokaMap(model, INDICATOR, "var_ode_sys", BATCH, REF_TOL, every=REF_EVERY)
    values = ref.run(X, W0, t_end)
    threshold, rule = fli_threshold(t_end)
    truth = values > threshold
    row = {"map": name, "orbits": len(X), "t_end": t_end, "threshold": threshold,
           "rule": rule, "reference_chaotic": float(np.mean(truth)),
           "reference_finite": bool(np.isfinite(values).all()), "rules": {}}
    original = time_transform_step.agreeing_offset
    for label, agree in RULES.items():
        with warnings.catch_warnings(), mock.patch.object(
                time_transform_step, "agreeing_offset",
                functools.partial(original, agree=agree)):
            warnings.simplefilter("ignore")
            out = varint.chaos_map(model, X, INDICATOR, t_end=t_end, progress=False,
                                   time_transform="log")
        v = np.asarray(out.values)
        called = v > threshold
        choice = out.provenance.tau_choice
        c = out.provenance.counts
        pilot = choice["counts"]["gradient_evaluations"] + choice.get("offset_pricing", 0)
        row["rules"][label] = {
            "agreement": float(np.mean(np.isfinite(v) & (called == truth))),
            "regular_called_chaotic": int(np.sum(called & ~truth)),
            "chaotic_called_regular": int(np.sum(~called & truth)),
            "not_finite": int(np.sum(~np.isfinite(v))),
            "h": choice.get("h"), "offset": choice.get("offset"),
            "tried": choice.get("tried"), "offsets": choice.get("offsets"),
            "levels": np.bincount(np.asarray(choice.get("levels", [0]))).tolist(),
            "lh_steps_per_orbit": float(c["lh_steps"]) / len(X),
            "gradients_per_orbit": float(c["gradient_evaluations"]) / len(X),
            "pilot_gradients": int(pilot)}
        r = row["rules"][label]
        print(f"{name} {label}: h {r['h']:.4g} δ {r['offset']} agreement {r['agreement']:.3f} "
              f"(regular called chaotic {r['regular_called_chaotic']}, chaotic called regular "
              f"{r['chaotic_called_regular']}), LH steps/orbit {r['lh_steps_per_orbit']:.0f}, "
              f"retry levels {r['levels']}, pilot force evaluations {pilot}", flush=True)
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
    save_json(args.out, "lh_horizon", result)
    return result


if __name__ == "__main__":
    main()

"""Held-out check of the refined constant step of chaos maps (issue 29):
:meth:`varint.step_agreement.ConstantLadder.refine` takes a step between
two rungs of the defaults' pilot where the coarser rung's FLI verdicts
agreed and only its energy error exceeded the ceiling. Does the refined
map still classify orbits the pilot never saw as a tight reference does?

Criterion, written before the run (stop 48): on each held-out map the
defaults of :func:`varint.chaos_map` with the refinement agree with the
reference on ≥ 99 % of the orbits. Maps (FLI, one thread):

``cr3bp C=3.1``
    Sun–Jupiter, section y = 0, ẏ > 0 at C = 3.1 (the race's map of
    ``studies/map_steps.py`` is at C = 3.05), (x, p_x) ∈ [0.3, 0.85] ×
    [−0.3, 0.3], 10 × 8 points, t = 1000.
``softened point mass``
    V = −1/√(r² + ε²), ε = 10⁻³ (the set of ``tests/test_step_agreement.py``):
    64 eccentric orbits, pericentres ~0.01, t = 200.
``rotating bar``
    The Ferrers bar of Skokos, Patsis & Athanassoula (2002)
    (:class:`varint.models.RotatingBar`), orbits started on the x axis at
    z = 0.1 with x ∈ [0.3, 3], E_J ∈ {−0.40, −0.28} (the named regular and
    chaotic orbits' energies), 2 × 24 orbits, t = 1000.
``henon-heiles``
    E = 1/8, section x = 0, (y, p_y) ∈ [−0.4, 0.6] × [−0.4, 0.4], 12 × 12
    points, t = 1000.

Reference: the same map with constant steps of :data:`varint.maps.MAP_SCHEME`
at 1/16 of the step the refined defaults chose (at least 16 times finer
than any step compared). Verdict: chaotic above FLI = 2 ln t (the race's
threshold, ``studies/map_steps.py``). Rows: the defaults with and without
the refinement (:meth:`~varint.step_agreement.ConstantLadder.refine`
patched out), their step, agreement and median |ΔFLI| on the orbits the
reference calls regular.

Usage: ``python studies/refined_step.py [--quick]``; result
``refined_step.json``.
"""

from __future__ import annotations

import sys
import warnings
from pathlib import Path
from unittest import mock

import numba
import numpy as np
import sympy as sp

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import varint
from studies.common import parse_args, save_json
from varint.maps import MAP_SCHEME
from varint.models.cr3bp import CR3BP, SUN_JUPITER_MU
from varint.step_agreement import ConstantLadder

CRITERION = 0.99
DIVISOR = 16


def maps():
    """name → (model, states, t_end) of the held-out maps (module docstring)."""
    cr3bp = CR3BP(SUN_JUPITER_MU)
    x, y = sp.symbols("x y")
    plummer = varint.models.from_potential(-1 / sp.sqrt(x**2 + y**2 + sp.Float(1e-3)**2), [x, y])
    rng = np.random.default_rng(1)
    eccentric = np.column_stack([rng.uniform(0.5, 1.0, 64), np.zeros(64), np.zeros(64),
                                 rng.uniform(0.05, 0.5, 64)])
    bar = varint.models.RotatingBar()
    bar_x = np.concatenate([[bar.state_on_x_axis(x0, e, 0.1) for x0 in np.linspace(0.3, 3.0, 24)]
                            for e in (-0.40, -0.28)])
    hh = varint.models.HenonHeiles()
    return {
        "cr3bp C=3.1": (cr3bp, cr3bp.section_grid(3.1, np.linspace(0.3, 0.85, 10),
                                                  np.linspace(-0.3, 0.3, 8)).states, 1000.0),
        "softened point mass": (plummer, eccentric, 200.0),
        "rotating bar": (bar, bar_x[np.isfinite(bar_x).all(axis=1)], 1000.0),
        "henon-heiles": (hh, varint.section_grid(hh, 0.125, np.linspace(-0.4, 0.6, 12),
                                                 np.linspace(-0.4, 0.4, 12)).states, 1000.0),
    }


def measure(name, model, X, t_end):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        refined = varint.chaos_map(model, X, "fli", t_end=t_end, progress=False)
        with mock.patch.object(ConstantLadder, "refine", lambda self: None):
            before = varint.chaos_map(model, X, "fli", t_end=t_end, progress=False)
        tau = refined.provenance.tau
        reference = varint.chaos_map(model, X, "fli", t_end=t_end, progress=False,
                                     tau=tau / DIVISOR, scheme=MAP_SCHEME, time_transform=None)
    threshold = 2 * np.log(t_end)
    truth = reference.values > threshold
    rows = []
    for label, r in (("defaults, refined", refined), ("defaults, before", before)):
        gap = np.abs(r.values - reference.values)
        rows.append({"map": name, "contender": label, "method": r.provenance.method,
                     "tau": r.provenance.tau,
                     "refined": bool((r.provenance.tau_choice or {}).get("refined", False)),
                     "steps": int(r.provenance.counts.get("steps", 0)),
                     "agreement": float(np.mean(np.isfinite(r.values)
                                                & ((r.values > threshold) == truth))),
                     "dfli_median": float(np.nanmedian(gap[~truth])) if (~truth).any() else None,
                     "orbits": len(X), "t_end": t_end,
                     "reference_chaotic": float(truth.mean()),
                     "reference_tau": tau / DIVISOR})
    return rows


def main(argv=None):
    args = parse_args(__doc__.split("\n\n")[0], argv)
    numba.set_num_threads(1)
    rows = []
    for name, (model, X, t_end) in maps().items():
        for row in measure(name, model, X, t_end):
            rows.append(row)
            print(f"{name}: {row['contender']}: method {row['method']}, tau {row['tau']}, "
                  f"refined {row['refined']}, steps {row['steps']}, agreement "
                  f"{row['agreement']:.4f}, median |dFLI| {row['dfli_median']}, reference "
                  f"chaotic {row['reference_chaotic']:.2f}", flush=True)
    supported = all(r["agreement"] >= CRITERION for r in rows
                    if r["contender"] == "defaults, refined")
    print(f"criterion (>= {CRITERION:.0%} on every held-out map): "
          f"{'met' if supported else 'NOT met'}")
    save_json(args.out, "refined_step", {"rows": rows, "criterion": CRITERION,
                                         "supported": supported})
    return rows


if __name__ == "__main__":
    main()

"""What the offset δ of the logarithmic Hamiltonian (LH) does to the step
its pilot accepts and to the price of an FLI map (issues 27 item 4b, 29).

The LH map steps uniformly in a fictitious time s with dt/ds = 1/U,
U = C − V(q) and C = E + δ (:mod:`varint.time_transform`). On an orbit
of energy E = A + V, U = A + δ: for a kinetic A = ½|p|², the physical
step is h/(T + δ) (Preto & Tremaine 1999, eq. 14 with f = g = ln;
Mikkola & Tanikawa 1999, sect. 2). Where the orbit is slow (T → 0, an
apocentre) the step is h/δ; where it is fast (a passage through a core of
depth |V_min|) about h/|V_min|: the ratio of the largest to the smallest
physical step along an orbit is (T_max + δ)/δ. A small δ concentrates the
steps at the core; δ → ∞ gives constant steps h/δ. On a potential without
a deep centre (Hénon–Heiles) adaptivity only costs: the step the pilot
accepts should be about the same physical step for every δ, so the map
with the largest δ (least variation) is expected to be cheapest, or all
equal. For the rotating frame of the three-body problem A = ½|p|² − Ω·L
takes both signs: below C = 0 the kick can find U ≤ 0 and the orbit stops.

Part ``ladder`` (task 1 of delta12): the cored map (R_c = 0.03) and the
three-body map of ``studies/map_steps.py`` (``--quick`` sizes) and a
Hénon–Heiles section map (E = 1/8, the non-singular check), at δ ∈
``OFFSETS`` (None: today's rule δ = max(−E, 1)), each with the h its pilot
chooses (:func:`varint.time_transform_step.agreeing_h`, the maps' rule:
the verdicts at h and h/2 agree, energy ceiling 10 × energy_tol, each
orbit then retried to energy_tol, :func:`~varint.time_transform_step.retried`).
Per δ: h, h/h₀, the pilot's force evaluations, the price it predicts
(force evaluations per orbit and unit of time, retries counted), the
map's own force evaluations per orbit, the CPU seconds of pilot + map
(interleaved over δ, one thread, min of the repeats) and the agreement of
the map's verdicts with a reference: the same orbits at δ = today's rule
and h/16 of today's h, classified by the antimode of its log10 FLI (as
``studies/map_steps.py``).

Usage: ``python studies/lh_offset.py [--quick] [--part ladder]
[--repeats N]``; results ``lh_offset_ladder.json`` (``quick/``). State the
machine load (recorded) with every figure.
"""

from __future__ import annotations

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
from studies.bench_peers import agreement, antimode, chaotic
from studies.common import interleaved, parse_args, save_json
from studies.map_steps import case
from varint.accuracy import DEFAULT_ENERGY_TOL, Reference
from varint.maps import LOG_MAP_OPTIONS, MAP_QUANTILE
from varint.state import initial_deviations
from varint.time_transform import LogHamiltonian
from varint.time_transform_step import RETRY_CEILING, agreeing_h, orbit_errors, retried

#: The offsets of part ``ladder`` (None: today's rule δ = max(−E, 1)).
OFFSETS = (None, 1.0, 0.5, 0.25, 0.1, 0.05)
REFERENCE_DIVISOR = 16
T_END = 200.0


def sets():
    """name -> (model, X, t_end): the two race maps and Hénon–Heiles."""
    out = {}
    for name in ("core", "cr3bp"):
        model, grid, t_end = case(name, True)
        out[name] = (model, grid.states, t_end)
    hh = varint.models.HenonHeiles()
    grid = varint.section_grid(hh, 0.125, np.linspace(-0.4, 0.65, 10),
                               np.linspace(-0.4, 0.4, 8))
    out["henon_heiles"] = (hh, grid.states, T_END)
    return out


def pilot_and_map(lh, X, W0, t_end, seed=0):
    """The LH map at δ = ``lh.offset`` as the defaults run it: the pilot's h
    (retry ceiling), then every orbit retried to energy_tol."""
    tol = DEFAULT_ENERGY_TOL
    h, choice = agreeing_h(lh, X, t_end, quantile=MAP_QUANTILE, ceiling=RETRY_CEILING * tol,
                           seed=seed, every=LOG_MAP_OPTIONS["every"], retry=tol)
    if h is None:
        return None, choice, None, None
    out, level = retried(lh, X, W0, t_end, h, tol, Reference(lh.model, X),
                         every=LOG_MAP_OPTIONS["every"])
    return h, choice, out, level


def ladder(name, model, X, t_end, repeats):
    lh = LogHamiltonian(model, LOG_MAP_OPTIONS["scheme"])
    W0 = initial_deviations(model.dim, 1, len(X), 0, np.arange(len(X)))[:, :, 0]
    numba.set_num_threads(1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        h_today, _, _, _ = pilot_and_map(lh, X, W0, t_end)
        ref = lh.outputs(X, W0, t_end, h_today / REFERENCE_DIVISOR,
                         every=LOG_MAP_OPTIONS["every"])
        threshold, how = antimode(ref.fli)
        truth = chaotic("fli", ref.fli, threshold)
        tasks = {f"offset {d}": (lambda d=d: pilot_and_map(lh.with_offset(d), X, W0, t_end))
                 for d in OFFSETS}
        best, outs = interleaved(tasks, repeats, clock=time.process_time)
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    rows = []
    reference = Reference(model, X)
    for d in OFFSETS:
        label = f"offset {d}"
        h, choice, out, level = outs[label]
        row = {"map": name, "offset": d, "h": h, "h0": choice["h0"],
               "tried": choice["tried"], "pilot_gradients": choice["counts"]["gradient_evaluations"],
               "cpu_seconds": best[label], "orbits": len(X)}
        if h is not None:
            errors = orbit_errors(reference, out)
            row.update(h_over_h0=h / choice["h0"], predicted_rate=choice["gradient_rate"],
                       retried_share_pilot=choice.get("retried_share"),
                       map_gradients_per_orbit=float(out.counts[:, 2].sum() / len(X)),
                       map_rate=float(out.counts[:, 2].sum() / (len(X) * t_end)),
                       retried=float(np.mean(level > 0)),
                       stopped=int(np.sum(out.status != 0)),
                       largest_energy_error=float(np.max(errors)),
                       agreement=agreement("fli", out.fli, truth, threshold),
                       threshold=threshold, threshold_rule=how)
        rows.append(row)
        print(f"{name}: δ {d}: h {h}, h/h0 {row.get('h_over_h0')}, predicted rate "
              f"{row.get('predicted_rate')}, map rate {row.get('map_rate')}, pilot grads "
              f"{row['pilot_gradients']}, cpu {best[label]:.3f} s, agreement "
              f"{row.get('agreement')}, retried {row.get('retried')}, stopped "
              f"{row.get('stopped')}", flush=True)
    return rows


def main(argv=None):
    args = parse_args(__doc__.split("\n\n")[0], argv, extra=lambda p: (
        p.add_argument("--part", choices=("ladder",), default="ladder"),
        p.add_argument("--repeats", type=int, default=2),
        p.add_argument("--case", default="core,cr3bp,henon_heiles")))
    start = list(os.getloadavg())
    chosen = [c for c in args.case.split(",") if c]
    rows = [row for name, s in sets().items() if name in chosen
            for row in ladder(name, *s, args.repeats)]
    save_json(args.out, f"lh_offset_{args.part}",
              {"rows": rows, "offsets": list(OFFSETS), "load": start,
               "load_end": list(os.getloadavg())})


if __name__ == "__main__":
    main()

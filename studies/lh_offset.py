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

Part ``held`` (task 3 of delta12; the check and its criterion fixed
here before its run): the δ the pilot chooses
(:func:`varint.time_transform_step.agreeing_offset`) against today's rule
on orbits the pilot did not see, on the held-out sets of the tests: the
softened point mass ε = 1e-3 of ``tests/test_step_agreement.py`` (pilot
seed 0, held-out seed 1, 16 orbits each), the softened point mass
ε = 1e-2 of ``tests/test_time_transform_maps.py`` (the same draws with
p_y ∈ [0.1, 0.6]) and the three-body problem (pilot at C = 3.05,
held-out at C = 3.1, 16 × 16 draws; unpriced: the rule by construction),
to t = 200. Each held-out set runs as the map runs it (each orbit retried
to energy_tol) at today's (rule, h) and at the chosen (δ, h); reference:
the held-out orbits at the rule and h/16. Criterion: on every set the
chosen δ does not lose, i.e. its held-out force evaluations are at most
today's and its agreement with the reference at the chaotic level
ln(1000 t_end) (the same side) is at least today's. Also recorded: the
pilots' force evaluations (today's pilot; the pricing pilots plus the
pilot at δ), the CPU seconds of pilot + held-out run (interleaved, one
thread, min of the repeats) and the antimode agreement.

Usage: ``python studies/lh_offset.py [--quick] [--part ladder|held]
[--repeats N]``; results ``lh_offset_{ladder,held}.json`` (``quick/``).
State the machine load (recorded) with every figure.
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
from varint.time_transform_step import (RETRY_CEILING, agreeing_h, agreeing_offset, orbit_errors,
                                        retried)

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


def pilot_and_map(lh, X, W0, t_end, seed=0, choose=False):
    """The LH map at δ = ``lh.offset`` as the defaults run it: the pilot's h
    (retry ceiling), then every orbit retried to energy_tol; ``choose``:
    δ chosen by the pilot (:func:`~varint.time_transform_step.agreeing_offset`)."""
    tol = DEFAULT_ENERGY_TOL
    kwargs = {"quantile": MAP_QUANTILE, "ceiling": RETRY_CEILING * tol, "seed": seed,
              "every": LOG_MAP_OPTIONS["every"], "retry": tol}
    if choose:
        lh, h, choice = agreeing_offset(lh, X, t_end, **kwargs)
    else:
        h, choice = agreeing_h(lh, X, t_end, **kwargs)
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
        tasks["offset chosen by the pilot"] = lambda: pilot_and_map(lh, X, W0, t_end,
                                                                     choose=True)
        best, outs = interleaved(tasks, repeats, clock=time.process_time)
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    rows = []
    reference = Reference(model, X)
    for d in (*OFFSETS, "chosen"):
        label = "offset chosen by the pilot" if d == "chosen" else f"offset {d}"
        h, choice, out, level = outs[label]
        if d == "chosen":
            d = choice["offset"]
        row = {"map": name, "contender": label, "offset": d, "h": h, "h0": choice["h0"],
               "offsets_priced": choice.get("offsets"),
               "pricing_gradients": choice.get("offset_pricing", 0),
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
        print(f"{name}: {label} (δ {d}): h {h}, h/h0 {row.get('h_over_h0')}, predicted rate "
              f"{row.get('predicted_rate')}, map rate {row.get('map_rate')}, pilot grads "
              f"{row['pilot_gradients']}, cpu {best[label]:.3f} s, agreement "
              f"{row.get('agreement')}, retried {row.get('retried')}, stopped "
              f"{row.get('stopped')}", flush=True)
    return rows


def held_sets():
    """name -> (model, pilot orbits, held-out orbits, t_end) of part ``held``."""
    import sympy as sp

    from varint.models import from_potential
    from varint.models.cr3bp import CR3BP, SUN_JUPITER_MU

    def point_mass(eps):
        x, y = sp.symbols("x y")
        return from_potential(-1 / sp.sqrt(x**2 + y**2 + sp.Float(eps)**2), [x, y])

    def eccentric(seed, lo, hi, m=16):
        rng = np.random.default_rng(seed)
        return np.column_stack([rng.uniform(0.5, 1.0, m), np.zeros(m), np.zeros(m),
                                rng.uniform(lo, hi, m)])

    def three_body(seed, m, jacobi):
        rng = np.random.default_rng(seed)
        return CR3BP(SUN_JUPITER_MU).section_grid(
            jacobi, np.sort(rng.uniform(0.3, 0.85, m)), np.sort(rng.uniform(-0.3, 0.3, m))).states

    return {"point mass eps 1e-3": (point_mass(1e-3), eccentric(0, 0.05, 0.5),
                                    eccentric(1, 0.05, 0.5), T_END),
            "point mass eps 1e-2": (point_mass(1e-2), eccentric(0, 0.1, 0.6),
                                    eccentric(1, 0.1, 0.6), T_END),
            "cr3bp C=3.1": (CR3BP(SUN_JUPITER_MU), three_body(0, 16, 3.05),
                            three_body(1, 16, 3.1), T_END)}


def held(name, model, pilot, X, t_end, repeats):
    """Part ``held`` on one set (module docstring)."""
    from varint.step_agreement import chaotic_level
    from varint.time_transform_step import agreeing_offset

    tol = DEFAULT_ENERGY_TOL
    kwargs = {"quantile": MAP_QUANTILE, "ceiling": RETRY_CEILING * tol, "seed": 0,
              "every": LOG_MAP_OPTIONS["every"], "retry": tol}
    lh = LogHamiltonian(model, LOG_MAP_OPTIONS["scheme"])
    W0 = initial_deviations(model.dim, 1, len(X), 0)[:, :, 0]
    reference = Reference(model, X)

    def today():
        h, choice = agreeing_h(lh, pilot, t_end, **kwargs)
        return (lh, h, choice) + retried(lh, X, W0, t_end, h, tol, reference)

    def chosen():
        at, h, choice = agreeing_offset(lh, pilot, t_end, **kwargs)
        return (at, h, choice) + retried(at, X, W0, t_end, h, tol, reference)

    numba.set_num_threads(1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        best, outs = interleaved({"today": today, "chosen": chosen}, repeats,
                                 clock=time.process_time)
        h_rule = outs["today"][1]
        ref = lh.outputs(X, W0, t_end, h_rule / REFERENCE_DIVISOR, every=LOG_MAP_OPTIONS["every"])
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    threshold, how = antimode(ref.fli)
    truth = chaotic("fli", ref.fli, threshold)
    level_line = chaotic_level(t_end)
    rows = []
    for label in ("today", "chosen"):
        at, h, choice, out, level = outs[label]
        with np.errstate(invalid="ignore"):
            same_side = np.isfinite(out.fli) & ((out.fli > level_line) == (ref.fli > level_line))
        pilot_work = choice["counts"]["gradient_evaluations"] + choice.get("offset_pricing", 0)
        rows.append({"set": name, "contender": label, "offset": at.offset, "h": h,
                     "offsets": choice.get("offsets"), "held_out": len(X),
                     "held_out_gradients": int(out.counts[:, 2].sum()),
                     "pilot_gradients": int(pilot_work), "cpu_seconds": best[label],
                     "level_agreement": float(np.mean(same_side)),
                     "agreement": agreement("fli", out.fli, truth, threshold),
                     "threshold_rule": how, "retried": float(np.mean(level > 0)),
                     "largest_energy_error": float(np.max(orbit_errors(reference, out)))})
        r = rows[-1]
        print(f"{name}: {label}: δ {r['offset']}, h {h:.4g}, held-out gradients "
              f"{r['held_out_gradients']}, pilot {r['pilot_gradients']}, cpu "
              f"{r['cpu_seconds']:.3f} s, level agreement {r['level_agreement']:.3f}, "
              f"agreement {r['agreement']:.3f}", flush=True)
    a, b = rows
    verdict = {"set": name, "not_lost": bool(b["held_out_gradients"] <= a["held_out_gradients"]
                                             and b["level_agreement"] >= a["level_agreement"]),
               "gradients_ratio": b["held_out_gradients"] / a["held_out_gradients"],
               "cpu_ratio": b["cpu_seconds"] / a["cpu_seconds"]}
    print(f"  {verdict}", flush=True)
    return rows, verdict


def main(argv=None):
    args = parse_args(__doc__.split("\n\n")[0], argv, extra=lambda p: (
        p.add_argument("--part", choices=("ladder", "held"), default="ladder"),
        p.add_argument("--repeats", type=int, default=2),
        p.add_argument("--case", default="core,cr3bp,henon_heiles")))
    start = list(os.getloadavg())
    if args.part == "held":
        rows, verdicts = [], []
        for name, s in held_sets().items():
            r, v = held(name, *s, args.repeats)
            rows += r
            verdicts.append(v)
        save_json(args.out, "lh_offset_held",
                  {"rows": rows, "verdicts": verdicts, "load": start,
                   "load_end": list(os.getloadavg())})
        return
    chosen = [c for c in args.case.split(",") if c]
    rows = [row for name, s in sets().items() if name in chosen
            for row in ladder(name, *s, args.repeats)]
    # A run of some cases only is stored beside the full one.
    suffix = "" if chosen == ["core", "cr3bp", "henon_heiles"] else "_" + "_".join(chosen)
    save_json(args.out, f"lh_offset_{args.part}{suffix}",
              {"rows": rows, "offsets": list(OFFSETS), "load": start,
               "load_end": list(os.getloadavg())})


if __name__ == "__main__":
    main()

"""Where a planetary MEGNO map's time goes, per grid point and per step of
dt, and REBOUND's per point on the same machine (issue 30: measure before
changing the stepper).

The system and grid are those of studies/bench_planetary.py (the Sun,
Jupiter and a Saturn-mass planet on (a, e) ∈ [7, 10] × [0, 0.5], dt = 1,
ten WH steps per renormalisation interval τ = 10, Jacobi coordinates, one
deviation vector). Every figure is CPU time of this process (one thread),
the minimum over interleaved repeats (:func:`common.interleaved`), so that
the load of the shared machine does not enter it; the load is recorded.

The pieces, each a compiled loop over steps of one orbit:

* ``kepler solve``: the planets' r₀, β, η₀, ζ₀ and Kepler's equation
  (``prepare`` and ``solve_fast`` of :mod:`varint.kernels.kepler`) for
  every planet, the state not moved (the same equation every time);
* ``drift``, ``drift + tangent``: the generated Kepler drift of both
  planets (:func:`varint.kernels.nbody_unrolled.drift_kernel`) with no
  and with one deviation vector; the tangent is their difference, the
  f, g update the drift less the solve;
* ``kick``, ``kick + tangent``: the interaction kick likewise;
* ``parts stepper``: ``parts_steps``, the part stepper's loop (the word of
  flows, no renormalisation and no indicator) with one vector;
* ``map, FLI`` and ``map, MEGNO``: ``chaos_map`` on a block of 64 grid
  points over 1e3 intervals, per point and step: the stepper with the
  end of every interval (checks, renormalisation) and the indicator's
  update (MEGNO's also evaluates the vector field), and the Python of a
  map call spread over its points;
* ``map call overhead``: ``chaos_map`` over one interval on the same block,
  per point (what a call costs besides its steps).

REBOUND: ``WHFast`` (``safe_mode`` 1, as MEGNO needs) with ``init_megno()``
on one grid point, per step, and WHFast without variational particles.

Run: ``python studies/planetary_profile.py [--quick]``.
"""

from __future__ import annotations

import os
import sys
import time
import warnings

import numba
import numpy as np
from numba import njit

import varint
from varint.kernels import kepler as kep
from varint.kernels.nbody_unrolled import drift_kernel, kick_kernel
from varint.methods.parts import _tables, parts_steps
from varint.models import Planetary

try:
    from bench_planetary import DT, MASSES, SUBSTEPS, grid, rebound_megno, varint_map
    from common import interleaved, parse_args, save_json
except ImportError:  # imported as studies.planetary_profile
    from .bench_planetary import DT, MASSES, SUBSTEPS, grid, rebound_megno, varint_map
    from .common import interleaved, parse_args, save_json


def _solve_loop(n_planets):
    """Kepler's equation of every planet, ``n`` times on the same state."""
    omu, okm = 5 + 2 * n_planets, 5 + 3 * n_planets

    @njit(error_model="numpy")
    def loop(x, h, par, n):
        acc = 0.0
        for _ in range(n):
            for i in range(n_planets):
                ok, rx, ry, rz, vx, vy, vz, r0, beta, eta0, zeta0, h2 = kep.prepare(
                    x, 3 * i, 3 * n_planets + 3 * i, par[omu + i], 1.0 / par[okm + i])
                st, X, G0, G1, G2, G3, G4, G5 = kep.solve_fast(r0, eta0, zeta0, beta, h)
                acc += X + G5
        return acc

    return loop


def _flow_loop(flow):
    """``n`` calls of a generated flow (drift or kick) on one orbit."""

    @njit(error_model="numpy")
    def loop(x, V, k, h, par, n):
        s = 0
        for _ in range(n):
            s += flow(x, V, k, h, par)
        return s

    return loop


def pieces(model, x0, steps, repeats):
    """CPU ns per step of dt of each compiled piece (module docstring)."""
    scheme = varint.get_scheme("SABA1").repeated(SUBSTEPS)
    _, _, par, _ = _tables(model, scheme, DT * SUBSTEPS)
    n = model.n_planets
    solve, drift, kick = _solve_loop(n), _flow_loop(drift_kernel(n)), _flow_loop(
        kick_kernel(n, True))
    w = np.zeros((1, 6 * n))
    w[0, 0] = 1.0
    # The drifts move the orbit forward, the kicks with h = dt/1e6 barely:
    # each loop starts again from x0, so every repeat times the same work.
    tasks = {
        "kepler solve": lambda: solve(x0.copy(), DT, par, steps),
        "drift": lambda: drift(x0.copy(), w.copy(), 0, DT, par, steps),
        "drift + tangent": lambda: drift(x0.copy(), w.copy(), 1, DT, par, steps),
        "kick": lambda: kick(x0.copy(), w.copy(), 0, 1e-6 * DT, par, steps),
        "kick + tangent": lambda: kick(x0.copy(), w.copy(), 1, 1e-6 * DT, par, steps),
        "parts stepper": lambda: parts_steps(model, x0, w[0][:, None], DT * SUBSTEPS,
                                             steps // SUBSTEPS, scheme),
    }
    for task in tasks.values():
        task()                                   # compile
    best, _ = interleaved(tasks, repeats, clock=time.process_time)
    return {k: 1e9 * v / steps for k, v in best.items()}


def map_costs(model, X, intervals, repeats):
    """CPU ns per point and step of dt of chaos_map (FLI, MEGNO) on the
    block ``X``, and the per-point cost of a call of one interval."""
    t_end = intervals * DT * SUBSTEPS
    scheme = varint.get_scheme("SABA1").repeated(SUBSTEPS)

    def chaos(indicator, t):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            varint.chaos_map(model, X, indicator, t_end=t, tau=DT * SUBSTEPS, threshold=None,
                             scheme=scheme, progress=False, chunk_size=len(X))

    tasks = {"map, FLI": lambda: chaos("fli", t_end),
             "map, MEGNO": lambda: chaos("megno", t_end),
             "map call, one interval": lambda: chaos("megno", DT * SUBSTEPS)}
    for task in tasks.values():
        task()
    best, _ = interleaved(tasks, repeats, clock=time.process_time)
    steps = intervals * SUBSTEPS
    return {"map, FLI": 1e9 * best["map, FLI"] / (len(X) * steps),
            "map, MEGNO": 1e9 * best["map, MEGNO"] / (len(X) * steps),
            "map call overhead per point (us)": 1e6 * best["map call, one interval"] / len(X)}


def rebound_costs(model, x0, t_end, repeats):
    """CPU ns per step of REBOUND WHFast with and without MEGNO."""
    def plain():
        sim = model.to_rebound(x0)
        sim.integrator = "whfast"
        sim.dt = DT
        sim.integrate(t_end, exact_finish_time=0)

    tasks = {"REBOUND WHFast + MEGNO": lambda: rebound_megno(model, x0, t_end, 0),
             "REBOUND WHFast": plain}
    best, _ = interleaved(tasks, repeats, clock=time.process_time)
    return {k: 1e9 * v / (t_end / DT) for k, v in best.items()}


def main(argv=None):
    args = parse_args(__doc__.split("\n\n")[0], argv)
    steps, intervals, repeats = (2_000, 20, 2) if args.quick else (100_000, 1_000, 5)
    numba.set_num_threads(1)
    model = Planetary(MASSES)
    X = grid(model, 8).states                    # 64 points, one block
    x0 = X[len(X) // 2 + 3]
    load_start = os.getloadavg()[0]
    varint_map(model, X[:2], 2 * DT * SUBSTEPS, None)
    ns = pieces(model, x0, steps, repeats)
    ns.update(map_costs(model, X, intervals, repeats))
    ns.update(rebound_costs(model, x0, steps * DT, repeats))
    load_end = os.getloadavg()[0]
    derived = {
        "tangent of the drift": ns["drift + tangent"] - ns["drift"],
        "f, g update of the orbit": ns["drift"] - ns["kepler solve"],
        "tangent of the kick": ns["kick + tangent"] - ns["kick"],
        "end of interval, FLI (map, FLI - parts stepper)": ns["map, FLI"] - ns["parts stepper"],
        "MEGNO update beyond FLI's": ns["map, MEGNO"] - ns["map, FLI"],
        "REBOUND variational + MEGNO": ns["REBOUND WHFast + MEGNO"] - ns["REBOUND WHFast"],
    }
    share = {k: v / ns["map, MEGNO"] for k, v in
             {"kepler solve": ns["kepler solve"],
              "f, g update of the orbit": derived["f, g update of the orbit"],
              "tangent of the drift": derived["tangent of the drift"],
              "kick (orbit)": ns["kick"],
              "tangent of the kick": derived["tangent of the kick"],
              "end of interval and FLI": derived["end of interval, FLI (map, FLI - parts stepper)"],
              "MEGNO beyond FLI": derived["MEGNO update beyond FLI's"]}.items()}
    print(f"CPU ns per step of dt (one orbit, one thread); load {load_start:.1f} → {load_end:.1f}")
    for k, v in {**ns, **derived}.items():
        print(f"  {k:52} {v:9.1f}")
    print("  shares of the MEGNO map's step: " + ", ".join(f"{k} {v:.0%}" for k, v in share.items()))
    result = {"ns_per_step": ns, "derived_ns_per_step": derived, "share_of_map_step": share,
              "rebound_over_varint_per_step": ns["REBOUND WHFast + MEGNO"] / ns["map, MEGNO"],
              "steps": steps, "intervals": intervals, "repeats": repeats, "block": len(X),
              "dt": DT, "substeps": SUBSTEPS, "load_average": [load_start, load_end],
              "cores": os.cpu_count(),
              "versions": varint.results.package_versions("rebound")}
    save_json(args.out, "planetary_profile", result,
              times="measured: CPU time of this process, min of interleaved repeats; "
                    "derived_ns_per_step and share_of_map_step are differences and ratios "
                    "of the measured ns_per_step")
    return result


if __name__ == "__main__":
    main()
    sys.exit(0)

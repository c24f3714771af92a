"""What compensated summation would buy the TM method: the round-off floor
of orbit + one tangent vector with and without it (issue 27, item 3; a
measurement ahead of the kernel work, not a varint feature).

The TM steppers add every drift, kick and tangent update to the state in
plain floating point, so the round-off of those additions accumulates
like the number of steps (∝ t) and sets varint's floor (issue 27: 8e-13 at
t = 1e3, 2.8e-10 at t = 1e4 on R1). Kahan's compensated summation keeps
the low-order bits each addition loses in a second array and feeds them
back into the next addition (Kahan 1965; Møller 1965; for long symplectic
runs Hairer, McLachlan & Razakarivony, BIT 48, 231 (2008), who show the
error then grows like a random walk).

To measure this before it is put into the kernels, this study runs a
minimal stepper of Hénon–Heiles — the exact drift and kick flows and
their tangent maps, the stages of :func:`varint.schemes.stage_arrays` —
twice, with plain and with compensated additions to the orbit and the
tangent vector (the increments themselves are computed alike), from R1
with the seeded unit tangent vector of :mod:`studies.frontier`, to
t = 1e3 and 1e4, with SRKN14a and s35odr10 at steps down to where the
truncation error is below round-off. The global error is as in
:mod:`studies.frontier`, against the extended-precision Taylor reference.
Cost: the minimum over repeats of the two variants called in turn (wall
and CPU time, one thread, load stored).

Usage: ``python studies/compensated_floor.py [--quick] [--out DIR]``
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import numba  # noqa: E402
from numba import njit  # noqa: E402

import varint  # noqa: E402
from studies.bench_peers import seeded_vectors  # noqa: E402
from studies.common import parse_args, save_csv, save_json  # noqa: E402
from studies.frontier import interleaved, relative  # noqa: E402
from varint.cache import reference  # noqa: E402
from varint.schemes import stage_arrays  # noqa: E402

LADDERS = {"SRKN14a": (0.0625, 0.03125, 0.015625), "s35odr10": (0.2, 0.16, 0.125, 0.1)}
QUICK_LADDERS = {"SRKN14a": (0.125, 0.03125), "s35odr10": (0.4, 0.125)}


@njit
def _add(a, c, i, inc, compensated):
    """a[i] += inc; compensated: Kahan's summation with the lost bits in c[i]."""
    if compensated:
        y = inc - c[i]
        t = a[i] + y
        c[i] = (t - a[i]) - y
        a[i] = t
    else:
        a[i] += inc


@njit
def henon_heiles_tm(x, w, kinds, h, n_steps, compensated):
    """n_steps of the scheme (stage kinds and lengths) on the orbit x and the
    tangent vector w of H = (px² + py²)/2 + (x² + y²)/2 + x²y − y³/3, in
    place; drifts and kicks are the exact flows and their tangent maps."""
    cx = np.zeros(4)
    cw = np.zeros(4)
    for _ in range(n_steps):
        for st in range(kinds.shape[0]):
            a = h[st]
            if kinds[st] == 0:
                dx, dy, dwx, dwy = a * x[2], a * x[3], a * w[2], a * w[3]
                _add(x, cx, 0, dx, compensated)
                _add(x, cx, 1, dy, compensated)
                _add(w, cw, 0, dwx, compensated)
                _add(w, cw, 1, dwy, compensated)
            else:
                q0, q1 = x[0], x[1]
                gx = q0 + 2.0 * q0 * q1
                gy = q1 + q0 * q0 - q1 * q1
                hxx, hxy, hyy = 1.0 + 2.0 * q1, 2.0 * q0, 1.0 - 2.0 * q1
                dwx = -a * (hxx * w[0] + hxy * w[1])
                dwy = -a * (hxy * w[0] + hyy * w[1])
                _add(x, cx, 2, -a * gx, compensated)
                _add(x, cx, 3, -a * gy, compensated)
                _add(w, cw, 2, dwx, compensated)
                _add(w, cw, 3, dwy, compensated)


def run(x0, w0, scheme, tau, t_end, compensated):
    kinds, h, hc = stage_arrays(varint.get_scheme(scheme), tau)
    if np.any(hc != 0.0):
        raise ValueError(f"scheme {scheme!r} has a corrector; this stepper has none")
    x, w = np.array(x0, dtype=float), np.array(w0, dtype=float)
    henon_heiles_tm(x, w, kinds, h, int(round(t_end / tau)), compensated)
    return x, w


def main(argv=None):
    args = parse_args(__doc__.splitlines()[0], argv)
    numba.set_num_threads(1)
    horizons = (100.0,) if args.quick else (1e3, 1e4)
    ladders = QUICK_LADDERS if args.quick else LADDERS
    repeats = 1 if args.quick else 7
    model, x0 = varint.paper_orbit("R1")
    w0 = seeded_vectors(model.dim, 1, 1, seed=0)[0][:, 0]
    load_before = os.getloadavg()
    rows = []
    for t_end in horizons:
        ref = reference(model, x0, t_end, tau=0.1, deviations=w0[:, None])
        x_ref, w_ref = ref.state, ref.deviations[:, 0]
        for scheme, taus in ladders.items():
            for tau in taus:
                run(x0, w0, scheme, tau, 1.0, True)   # compile both variants first
                run(x0, w0, scheme, tau, 1.0, False)
                tasks = {c: (lambda c=c, s=scheme, t=tau, te=t_end: run(x0, w0, s, t, te, c))
                         for c in (False, True)}
                for comp, (wall, cpu, (x, w)) in interleaved(tasks, repeats).items():
                    rows.append({"t_end": t_end, "scheme": scheme, "tau": tau,
                                 "compensated": comp, "seconds": wall, "cpu_seconds": cpu,
                                 "error": max(relative(x, x_ref), relative(w, w_ref))})
    load = {"before": load_before, "after": os.getloadavg(), "cpus": os.cpu_count()}
    floors = []
    for t_end in horizons:
        for comp in (False, True):
            mine = [r for r in rows if r["t_end"] == t_end and r["compensated"] == comp]
            best = min(mine, key=lambda r: r["error"])
            floors.append({"t_end": t_end, "compensated": comp, "floor": best["error"],
                           "at": f"{best['scheme']} tau={best['tau']:g}"})
    save_csv(args.out, "compensated_floor", rows,
             ["t_end", "scheme", "tau", "compensated", "error", "seconds", "cpu_seconds"])
    result = {"rows": rows, "floors": floors, "load": load, "repeats": repeats,
              "quick": args.quick, "versions": {"varint": varint.__version__,
                                                "numba": numba.__version__}}
    save_json(args.out, "compensated_floor", result)
    print(f"compensated_floor: load {load['before']} -> {load['after']} on {load['cpus']} "
          f"CPUs, {repeats} repeat(s)")
    for r in rows:
        print(f"t={r['t_end']:g} {r['scheme']:9} tau={r['tau']:<8g} "
              f"{'compensated' if r['compensated'] else 'plain      '} error {r['error']:.2e} "
              f"cpu {r['cpu_seconds'] * 1e3:.2f} ms")
    for f in floors:
        print(f"floor t={f['t_end']:g} {'compensated' if f['compensated'] else 'plain'}: "
              f"{f['floor']:.2e} ({f['at']})")
    return result


if __name__ == "__main__":
    main()

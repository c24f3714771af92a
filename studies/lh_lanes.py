"""Study: where an LH step's time goes on the cored map, and the LH map's
``outputs`` over SIMD lanes against one orbit at a time (issue 27).

The cored race's orbits (``studies/map_steps.py``, :func:`race_map`, the
quick grid: 120 orbits) with the hand-tuned LH contender ABA864, h = 0.025,
δ = 0.25, one vector each.

``--part profile``: one orbit, the emitted kernels called from a compiled
loop (µs per call, the minimum of repeats, interleaved):

* ``lh_step``, ``tm_step``: the module's ``step`` with ``log`` on (an LH
  step) and off (the ordinary TM step of the same scheme, the landing
  tail's step), with the vector and without (``_k0``). Their difference
  is the time transformation; the difference of the differences (with the
  vector minus without) is its rank-one tangent terms.
* ``log``: libm's ``log`` on the arguments a kick takes it of, times the
  kicks per step: what V (needed by every kick, U = C − V) costs.
* ``outputs_per_step``: the one-orbit ``outputs`` over the whole map
  (t_end = ``T_PROFILE``) per step taken (LH and tail steps): the step
  plus its loop (the saved state, the undone step, the tails, projections
  and outputs).

``--part lanes``: ``LogHamiltonian.outputs`` over lanes and one orbit at a
time on the same orbits and h, µs per orbit-step (LH + tail steps), each
bitwise checked against the other, interleaved, the minimum of repeats.

``--part compile``: the first ``outputs`` calls (a vector, then none) of a
process with empty caches, with lanes and one orbit at a time, and the
vector instructions in the lanes kernel's machine code.

Run: ``python studies/lh_lanes.py [--part profile|lanes|compile] [--repeats N]``;
writes ``lh_lanes_profile.json``, ``lh_lanes.json``, ``lh_lanes_compile.json``
under ``--out``.
"""

from __future__ import annotations

import copy
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from numba import njit

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from studies.common import interleaved, parse_args, save_json  # noqa: E402
from studies.map_steps import race_map  # noqa: E402
from varint import step_cost  # noqa: E402
from varint.time_transform import LogHamiltonian  # noqa: E402

SCHEME, H, OFFSET, EVERY = "ABA864", 0.025, 0.25, 10.0
#: The profile's horizon (the race's is 2000): every orbit's core passages
#: and output landings in proportion, a shorter run.
T_PROFILE = 200.0
#: Steps per timed call of a kernel.
CALLS = 20_000


def _setup():
    model, grid, _ = race_map("core", True)
    X = grid.states
    W0 = np.random.default_rng(0).standard_normal(X.shape)
    W0 /= np.linalg.norm(W0, axis=1)[:, None]
    return LogHamiltonian(model, SCHEME, offset=OFFSET), X, W0


def _step_loop(step):
    """A compiled loop of ``CALLS`` steps of the emitted ``step`` from one
    state (each call restarts from it: the same work every call)."""
    @njit
    def loop(x0, V0, dpt, clock0, kinds, coef, h, par, log, C, calls):
        x, V, dt, clock = x0.copy(), V0.copy(), np.zeros(V0.shape[0]), clock0.copy()
        counts = np.zeros(3, np.int64)
        gA, gV, HV = np.empty(4), np.empty(2), np.empty((2, 2))
        dtau = np.empty(V0.shape[0])
        s = 0.0
        for _ in range(calls):
            x[:] = x0
            V[:, :] = V0
            clock[:] = clock0
            s += step(x, V, dt, dpt, clock, kinds, coef, h, par, log, C, counts, gA, gV,
                      HV, dtau)
            s += x[0]
        return s
    return loop


@njit
def _logs(args, calls):
    s = 0.0
    for i in range(calls):
        s += math.log(args[i % args.shape[0]])
    return s


def profile(out, repeats):
    lh, X, W0 = _setup()
    loop = _step_loop(lh.step_kernel)
    E = lh.energy(X)
    C = E + OFFSET
    m = 0
    x0 = X[m].copy()
    clock = np.array([0.0, -E[m] + C[m]])
    kicks = int((lh.kinds != 0).sum())
    q = X[:, :2]
    args = 0.03**2 + q[:, 0]**2 + q[:, 1]**2 / 0.8**2
    tasks, per = {}, {}
    for k in (1, 0):
        V0 = W0[m:m + 1].copy()[:k]
        dpt = np.zeros(k)
        for log in (True, False):
            name = ("lh_step" if log else "tm_step") + ("" if k else "_k0")
            loop(x0, V0, dpt, clock, lh.kinds, lh.coef, H, lh.par, log, C[m], 2)
            tasks[name] = (lambda V0=V0, dpt=dpt, log=log: loop(
                x0, V0, dpt, clock, lh.kinds, lh.coef, H, lh.par, log, C[m], CALLS))
            per[name] = CALLS
    _logs(args, 2)
    tasks["log"] = lambda: _logs(args, CALLS * kicks)
    per["log"] = CALLS

    one = copy.copy(lh)
    one.lanes_kernels = (None, None)
    one.outputs(X[:2], W0[:2], 1.0, H, every=EVERY)   # compiles
    counts = one.outputs(X, W0, T_PROFILE, H, every=EVERY).counts
    tasks["outputs_per_step"] = lambda: one.outputs(X, W0, T_PROFILE, H, every=EVERY)
    per["outputs_per_step"] = int(counts[:, 0].sum() + counts[:, 1].sum())
    load = os.getloadavg()
    best, _ = interleaved(tasks, repeats)
    us = {name: 1e6 * best[name] / per[name] for name in tasks}
    res = {"us_per_call": us, "load": load, "load_end": os.getloadavg(),
           "kicks_per_step": kicks, "scheme": SCHEME, "h": H, "offset": OFFSET,
           "t_profile": T_PROFILE, "orbits": len(X),
           "lh_steps": int(counts[:, 0].sum()), "tail_steps": int(counts[:, 1].sum()),
           "shares_of_lh_step": {
               "log": us["log"] / us["lh_step"],
               "time_transform": (us["lh_step"] - us["tm_step"]) / us["lh_step"],
               "rank_one_terms": ((us["lh_step"] - us["tm_step"])
                                  - (us["lh_step_k0"] - us["tm_step_k0"])) / us["lh_step"],
               "vector": (us["lh_step"] - us["lh_step_k0"]) / us["lh_step"],
               "loop_around_step": (us["outputs_per_step"] - us["lh_step"])
               / us["outputs_per_step"]}}
    for name, v in us.items():
        print(f"{name:20s} {v:8.3f} µs per call")
    for name, v in res["shares_of_lh_step"].items():
        print(f"{name:20s} {v:8.1%}")
    print(f"load {load} -> {res['load_end']}")
    save_json(out, "lh_lanes_profile", res)


def lanes(out, repeats):
    lh, X, W0 = _setup()
    one = copy.copy(lh)
    one.lanes_kernels = (None, None)
    res = {"load": os.getloadavg(), "scheme": SCHEME, "h": H, "offset": OFFSET,
           "orbits": len(X), "cases": {}}
    for t_end in (T_PROFILE, 2000.0):
        for vector in (True, False):
            W = W0 if vector else None
            a = lh.outputs(X, W, t_end, H, every=EVERY)   # compiles
            b = one.outputs(X, W, t_end, H, every=EVERY)
            same = all(np.array_equal(getattr(a, f), getattr(b, f), equal_nan=True)
                       for f in ("fli", "status", "x", "t", "x_worst", "t_worst", "counts"))
            steps = int(a.counts[:, 0].sum() + a.counts[:, 1].sum())
            gradients = int(a.counts[:, 2].sum())
            t0 = time.perf_counter()
            best, _ = interleaved({"lanes": lambda W=W, t=t_end: lh.outputs(X, W, t, H,
                                                                             every=EVERY),
                                   "one": lambda W=W, t=t_end: one.outputs(X, W, t, H,
                                                                           every=EVERY)},
                                  repeats if t_end < 1000 else max(1, repeats // 3))
            label = f"t_end {t_end:g}, {'one vector' if vector else 'no vector'}"
            row = {"bitwise": same, "steps": steps, "tail_steps": int(a.counts[:, 1].sum()),
                   "seconds": best, "us_per_orbit_step": {k: 1e6 * v / steps
                                                          for k, v in best.items()},
                   "ns_per_gradient": {k: 1e9 * v / gradients for k, v in best.items()},
                   "lanes_speedup": best["one"] / best["lanes"],
                   "wall": time.perf_counter() - t0}
            res["cases"][label] = row
            print(f"{label:28s} bitwise {same}  steps {steps}  one "
                  f"{row['us_per_orbit_step']['one']:.3f} µs  lanes "
                  f"{row['us_per_orbit_step']['lanes']:.3f} µs  ×{row['lanes_speedup']:.2f}")
    # What the defaults' choice prices an LH force evaluation at
    # (varint.step_cost: the one-orbit step's operations), against the
    # measured ones of the race's horizon with a vector (as the map runs).
    priced = step_cost.log_gradient_cost(lh)[0]
    measured = res["cases"]["t_end 2000, one vector"]["ns_per_gradient"]
    res["price"] = {"lh_ns_per_gradient": priced,
                    "measured_over_priced": {k: v / priced for k, v in measured.items()}}
    print(f"priced LH {priced:.1f} ns per force evaluation; measured one orbit "
          f"{measured['one']:.1f}, lanes {measured['lanes']:.1f}")
    res["load_end"] = os.getloadavg()
    print(f"load {res['load']} -> {res['load_end']}")
    save_json(out, "lh_lanes", res)


#: Instructions counted in the compiled lanes kernel (AVX2: 4 doubles in a
#: ymm register; the scalar forms are the events' and the remainders').
_INSTRUCTIONS = ("vmulpd\t%ymm", "vaddpd\t%ymm", "vsubpd\t%ymm", "vdivpd\t%ymm", "vmulsd",
                 "vdivsd", "vfmadd")


def _first_calls(which):
    """Seconds of the first ``outputs`` calls (one vector, then none) of a
    process with empty caches (``which``: "lanes" or "one"), and for
    "lanes" the counts of :data:`_INSTRUCTIONS` in ``lanes1``'s machine
    code: the loop over the lanes vectorised, without fused multiply–adds."""
    with tempfile.TemporaryDirectory() as tmp:
        env = {**os.environ, "NUMBA_CACHE_DIR": f"{tmp}/nc", "VARINT_CACHE_DIR": f"{tmp}/vc"}
        code = ("import copy, json, time, sys; sys.path.insert(0, '.');"
                "from studies.lh_lanes import _setup, H, _INSTRUCTIONS;"
                "lh, X, W0 = _setup(); one = copy.copy(lh); one.lanes_kernels = (None, None);"
                f"run = lh if {which!r} == 'lanes' else one;"
                "t = time.perf_counter(); run.outputs(X[:8], W0[:8], 1.0, H);"
                "run.outputs(X[:8], None, 1.0, H); s = time.perf_counter() - t;"
                "asm = ''.join(lh.lanes_kernels[1].inspect_asm().values()) "
                f"if {which!r} == 'lanes' else '';"
                "print(json.dumps({'seconds': s, 'asm': {i: asm.count(i) for i in _INSTRUCTIONS}}))")
        done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                              text=True, check=True)
        return json.loads(done.stdout.splitlines()[-1])


def compile_cost(out):
    """The first calls of ``outputs`` in a cold process, with lanes and one
    orbit at a time (what the lanes' larger module adds to compiling), and
    the lanes kernel's vector instructions."""
    load = os.getloadavg()
    res = {which: _first_calls(which) for which in ("one", "lanes")}
    res["load"], res["load_end"] = load, os.getloadavg()
    print(f"first calls, cold caches: one orbit {res['one']['seconds']:.1f} s, lanes "
          f"{res['lanes']['seconds']:.1f} s; lanes1: {res['lanes']['asm']}"
          f"  (load {load} -> {res['load_end']})")
    save_json(out, "lh_lanes_compile", res)


def main(argv=None):
    def extra(parser):
        parser.add_argument("--part", choices=("profile", "lanes", "compile"), default=None)
        parser.add_argument("--repeats", type=int, default=7)

    cli = parse_args(__doc__.split("\n\n")[0], argv, extra)
    if cli.part in (None, "profile"):
        profile(cli.out, cli.repeats)
    if cli.part in (None, "lanes"):
        lanes(cli.out, cli.repeats)
    if cli.part in (None, "compile"):
        compile_cost(cli.out)


if __name__ == "__main__":
    main()

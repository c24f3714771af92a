"""Where the defaults' switch spends its time, run by run (issue 29,
pilot19): every pilot run the switch (:func:`varint.maps._cheaper_steps`)
makes on a map, in order, with its stepper, step, force evaluations, rate
(force evaluations per orbit and unit of time) and CPU seconds, and the
switch's own CPU seconds.

Each pilot run is recorded by hook: the constant ladder's
(:func:`varint.stepsize.pilot_errors` as :mod:`varint.step_agreement`
calls it) and the logarithmic Hamiltonian's
(:meth:`varint.time_transform.LogHamiltonian.outputs`), CPU time around
each call, the minimum over the repeats of the map with every default
(``chaos_map(model, X, "fli", t_end=...)``, one thread, caches warm).
The counts are the same on any machine and load; the seconds are not
(state the load, recorded). Then the switch under :mod:`cProfile` (which
slows Python more than the kernels: read shares), the functions with the
most own time.

Maps: ``cr3bp`` and ``core``, the races' maps of ``studies/map_steps.py``
(quick grids); ``two``, the held-out two centres of
``studies/switch_check.py`` (``studies/ladder_rule.py``).

Stored run (``studies/results/pilot19/pilot_runs.json``, pilot19, 3
repeats, load 15.2 → 15.2: read the counts, and the seconds as shares).
The three-body map: the switch 27.5 ms CPU, its pilot runs 19.1 ms: four
LH runs (h = 3.30, 1.65, 0.82 and 0.41, the fine run of the rung 0.82,
which fails by 7 of 16 orbits: 80 066 force evaluations, 11.3 ms, about
141 ns each: the one-orbit kernel, as a map of 76 orbits at these h runs)
and four constant runs (τ = 1 and 0.5 failing on their energy errors, 0.25
passing against 0.125: 336 000, 7.8 ms, 23 ns each, lanes). Every one of
them is needed by the rules: the LH rung 0.82 is priced (13.25 force
evaluations per orbit and unit of time at the lanes' 30.3 units, 402)
below the constant step that wins (760), so it must be judged, and its
fine run is then the next rung's coarse run, whose rate (25.6: 775)
stops the descent. The cored map: the switch 145 ms CPU, its pilot runs
89 ms: 37 LH runs of the offset pricing to t = 25 (1.08e6 force
evaluations, 40 ms, most of them rungs above the energy ceiling, each
~0.5 ms whatever its size), 10 LH runs of the map's descent at δ = 0.25
to t = 100 (1.35e6), the constant ladder's 6 runs (1.41e6, all above the
energy ceiling, down to τ = 1/32, whose rate stops it).

lh20 (``studies/results/lh20/pilot_runs_before.json`` on 4f2bb83, load
3.5 → 13.0, and ``pilot_runs_after.json``, load 15.1 → 12.6; 3 repeats):
the cored map's pilots make the same 53 runs, step for step, with the
same force evaluations (LH 2 427 219, constant 1 411 200); the energies
at the orbits' starts, computed per run and per descent before (the
profile's two list comprehensions of ``time_transform.py``, its largest
own times after the lanes kernel), are computed once per switch
(:class:`varint.time_transform.Starts`). The seconds of the two runs
are at different loads (switch 73.9 vs 119.5 ms): the before/after
figure is ``studies/lh_switch_cost.py``'s, interleaved.

Usage: ``python studies/pilot_runs.py [--maps cr3bp,core] [--repeats N]``;
result ``pilot_runs.json``.
"""

from __future__ import annotations

import cProfile
import os
import pstats
import sys
import time
import warnings
from pathlib import Path
from unittest import mock

import numba

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import varint
from studies.common import parse_args, save_json
from studies.ladder_rule import case
from varint import maps, step_agreement
from varint.time_transform import LogHamiltonian


def _hooked(runs):
    """Patches that append each pilot run to ``runs``: (stepper, step,
    orbits, force evaluations, CPU seconds)."""
    constant_run, lh_run = step_agreement.pilot_errors, LogHamiltonian.outputs

    def constant(model, X, tau, t_pilot, *args, **kwargs):
        counts = args[2]
        before, start = counts.get("gradient", 0), time.process_time()
        out = constant_run(model, X, tau, t_pilot, *args, **kwargs)
        runs.append(("constant", float(tau), len(X), float(t_pilot),
                     int(counts["gradient"] - before), time.process_time() - start))
        return out

    def log(self, X, W0, t_end, h, *args, **kwargs):
        start = time.process_time()
        out = lh_run(self, X, W0, t_end, h, *args, **kwargs)
        runs.append(("log", float(h), len(X), float(t_end), int(out.counts[:, 2].sum()),
                     time.process_time() - start))
        return out

    return (mock.patch.object(step_agreement, "pilot_errors", constant),
            mock.patch.object(LogHamiltonian, "outputs", log))


def measure(name, repeats):
    """One map's pilot runs, switch seconds and profile."""
    model, X, t_end = case(name)
    switch = maps._cheaper_steps
    per_repeat, switch_seconds = [], []

    def timed(*args):
        start = time.process_time()
        try:
            return switch(*args)
        finally:
            switch_seconds.append(time.process_time() - start)

    numba.set_num_threads(1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = varint.chaos_map(model, X, "fli", t_end=t_end, progress=False)   # compiles
        for _ in range(repeats):
            runs: list = []
            first, second = _hooked(runs)
            with first, second, mock.patch.object(maps, "_cheaper_steps", timed):
                varint.chaos_map(model, X, "fli", t_end=t_end, progress=False)
            # The map's own LH run (a map the LH wins) is not a pilot run.
            per_repeat.append([r for r in runs if not (r[0] == "log" and r[2] == len(X))])
        profile = cProfile.Profile(time.process_time)

        def profiled(*args):
            profile.enable()
            try:
                return switch(*args)
            finally:
                profile.disable()

        with mock.patch.object(maps, "_cheaper_steps", profiled):
            for _ in range(repeats):
                varint.chaos_map(model, X, "fli", t_end=t_end, progress=False)
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    stats = pstats.Stats(profile)
    total = stats.total_tt  # type: ignore[attr-defined]
    top = sorted(stats.stats.items(), key=lambda kv: -kv[1][2])[:12]  # type: ignore[attr-defined]
    rows = []
    for i, (kind, step, orbits, t_pilot, gradients, _) in enumerate(per_repeat[0]):
        rows.append({"stepper": kind, "step": step, "orbits": orbits, "pilot_t": t_pilot,
                     "gradient_evaluations": gradients,
                     "rate": gradients / (orbits * t_pilot),
                     "cpu_seconds": min(rep[i][5] for rep in per_repeat)})
    choice = out.provenance.tau_choice
    result = {"map": name, "orbits": len(X), "t_end": t_end, "method": out.provenance.method,
              "step": choice.get("h") if out.provenance.method == "tm+log" else out.provenance.tau,
              "runs": rows, "switch_cpu_seconds": min(switch_seconds),
              "runs_cpu_seconds": sum(r["cpu_seconds"] for r in rows),
              "gradient_evaluations": {k: sum(r["gradient_evaluations"] for r in rows
                                              if r["stepper"] == k) for k in ("constant", "log")},
              "profile_own_seconds_per_map": [
                  {"function": f"{Path(f).name}:{line}({fn})", "seconds": tt / repeats,
                   "share": tt / total} for (f, line, fn), (_, _, tt, _, _) in top]}
    print(f"{name}: {out.provenance.method} step {result['step']:.4g}; switch "
          f"{1e3 * result['switch_cpu_seconds']:.2f} ms CPU, of it the pilot runs "
          f"{1e3 * result['runs_cpu_seconds']:.2f} ms", flush=True)
    for r in rows:
        print(f"  {r['stepper']:<8} step {r['step']:<10.4g} {r['orbits']:>3} orbits to "
              f"{r['pilot_t']:g}: {r['gradient_evaluations']:>9} force evaluations "
              f"(rate {r['rate']:.4g}), {1e3 * r['cpu_seconds']:.2f} ms", flush=True)
    return result


def main(argv=None):
    def extra(parser):
        parser.add_argument("--maps", default="cr3bp,core")
        parser.add_argument("--repeats", type=int, default=5)

    args = parse_args(__doc__.split("\n\n")[0], argv, extra)
    result = {"load": list(os.getloadavg()), "repeats": args.repeats,
              "maps": [measure(name, args.repeats) for name in args.maps.split(",") if name]}
    result["load_end"] = list(os.getloadavg())
    save_json(args.out, "pilot_runs", result)
    return result


if __name__ == "__main__":
    main()

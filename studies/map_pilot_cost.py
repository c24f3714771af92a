"""What the defaults' pilot costs on the three-body map (issue 29: the
CR3BP map's defaults ≥ 3× heyoka batch 8).

Case: the race map of :mod:`studies.map_steps` (Sun–Jupiter, C = 3.05,
76 orbits with ``--quick``, t = 1000, FLI, one thread). Two contenders,
interleaved, the minimum of the repeats, CPU time: the map with every
default (``chaos_map(model, X, "fli", t_end=...)``: the pilots, then the
run at the step they choose) and the same run at that step with no pilot
(``tau=``, ``scheme=``, ``time_transform=None``: the bits of the defaults'
run). Their difference is the pilots' share.

Where the pilots' time goes: the defaults' map under :mod:`cProfile`
(which slows Python more than the kernels: read shares, not seconds), by
cumulative time of the functions in :data:`PARTS` per map. They nest: the
switch holds the LH's pilot, whose descent runs the constant-step
ladder's pilot runs between its rungs (:class:`varint.step_agreement.ConstantLadder`),
and both build propagators. The pilots' force evaluations and the rungs
each judged (counts, not timings) come from the defaults' ``tau_choice``.

The switch itself (``maps._cheaper_steps``: both pilots, the prices
and the choice), timed around each of its calls in the defaults' repeats
(CPU, the minimum), is the pilots' time measured directly rather than as
a difference of two noisy minima.

Their arithmetic: the pilots alone (``maps._cheaper_steps``, the switch)
under cProfile, the CPU seconds of their compiled kernels (the generated
steppers' and LH's functions, which cProfile times as one call each, so
it does not slow them) against the pilots' own seconds without the
profiler: what no cut of Python or NumPy can take from them.

Measured (quick map, this AMD EPYC without AVX-512): on main 8c4a645
(``map_pilot_cost_before_pilot17.json``, load 0.38 → 0.43) the switch
took 18.0 ms CPU a map, 7.3 of it in kernels; with the pilots' fixed
costs cut (pilot17, ``map_pilot_cost.json``, load 0.43 → 0.47) 13.8 ms,
7.2 in kernels, the same 7 runs, choice and bits. In a scratch profile
the rest (6.6 ms) was mostly the TM advance's and the LH outputs' own
Python per run (:mod:`varint.methods.tm`, :mod:`varint.time_transform`);
of the kernels, the LH's third run, its finest and dearest, is made only
to learn that its rate stops the descent. pilot18 cut the constant
pilots' Python (step counts once per scheme, propagators kept across
maps, outputs scattered from the lanes in one compiled pass, the pilot's
vectors drawn once, one error quantile per judged rung): on a machine
loaded 19–22 (no quiet period that session) the switch went 20.2 → 19.6
ms CPU (21 interleaved repeats, ``pilot18/map_pilot_cost_*_loaded2.json``),
its cProfile share 473 → 385 ms, the constant pilot runs' 212 → 175 ms
(the profiler inflates Python, not the kernels); same 7 runs, choice
and bits.

Usage: ``python studies/map_pilot_cost.py [--quick] [--repeats N] [--out DIR]``;
results ``map_pilot_cost.json``.
"""

from __future__ import annotations

import cProfile
import os
import pstats
import sys
import time
import warnings
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import numba  # noqa: E402
import numpy as np  # noqa: E402

import varint  # noqa: E402
from varint import maps as varint_maps  # noqa: E402
from studies.common import interleaved, parse_args, save_json  # noqa: E402
from studies.map_steps import race_map  # noqa: E402

#: The pilots' parts, each by the function whose cumulative time is its
#: cost: (label, file suffix, function name).
PARTS = (("LH pilot, the ladder within (agreeing_offset)", "time_transform_step.py", "agreeing_offset"),
         ("constant ladder's pilot runs (pilot_errors)", "stepsize.py", "pilot_errors"),
         ("propagators built (make_propagator)", "methods/__init__.py", "make_propagator"),
         ("the switch (_cheaper_steps)", "maps.py", "_cheaper_steps"),
         ("the run (run_chunk)", "maps.py", "run_chunk"),
         ("whole map (chaos_map)", "maps.py", "chaos_map"))


def _map(model, X, t_end, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return varint.chaos_map(model, X, "fli", t_end=t_end, progress=False, **kwargs)


def _profile(model, X, t_end, maps):
    """Cumulative seconds per map of each of :data:`PARTS` under cProfile."""
    profile = cProfile.Profile()
    profile.enable()
    for _ in range(maps):
        _map(model, X, t_end)
    profile.disable()
    stats = pstats.Stats(profile).stats  # type: ignore[attr-defined]
    shares = {}
    for label, suffix, name in PARTS:
        shares[label] = sum(row[3] for (file, _, func), row in stats.items()
                            if func == name and file.endswith(suffix)) / maps
    return shares


def _kernel_seconds(model, X, t_end, maps):
    """CPU seconds per map of the pilots' compiled kernels: the functions
    of the generated modules (the kernel cache's ``varint_*`` files) under
    cProfile, which is on only inside the switch
    (:func:`varint.maps._cheaper_steps`)."""
    # CPU time, as the contenders are timed (a loaded machine's wall
    # time counts other processes' turns).
    profile, switch = cProfile.Profile(time.process_time), varint_maps._cheaper_steps

    def profiled(*args):
        profile.enable()
        try:
            return switch(*args)
        finally:
            profile.disable()

    varint_maps._cheaper_steps = profiled
    try:
        for _ in range(maps):
            _map(model, X, t_end)
    finally:
        varint_maps._cheaper_steps = switch
    stats = pstats.Stats(profile).stats  # type: ignore[attr-defined]
    return sum(row[2] for (file, _, _), row in stats.items()
               if Path(file).name.startswith("varint_")) / maps


def _timed_switch(record):
    """Install a wrapper of the switch (:func:`varint.maps._cheaper_steps`)
    that appends each call's CPU seconds to ``record``; returns a function
    that removes it."""
    switch = varint_maps._cheaper_steps

    def timed(*args):
        start = time.process_time()
        try:
            return switch(*args)
        finally:
            record.append(time.process_time() - start)

    varint_maps._cheaper_steps = timed

    def remove():
        varint_maps._cheaper_steps = switch

    return remove


def main(argv=None):
    def extra(parser):
        parser.add_argument("--repeats", type=int, default=7)

    args = parse_args(__doc__.split("\n\n")[0], argv, extra)
    numba.set_num_threads(1)
    model, X, t_end = race_map("cr3bp", args.quick)
    load = list(os.getloadavg())
    defaults = _map(model, X, t_end)
    choice = defaults.provenance.tau_choice
    tau, method = choice["tau"], defaults.provenance.method
    if method != "tm":
        raise SystemExit(f"the defaults chose {method!r}, not constant steps: this study "
                         "splits the constant-step choice only")
    scheme = defaults.provenance.method_options.get("scheme")
    scheme = scheme.get("name") if isinstance(scheme, dict) else scheme
    bare = _map(model, X, t_end, tau=tau, scheme=scheme, time_transform=None)
    tasks = {"defaults": lambda: _map(model, X, t_end),
             "run alone": lambda: _map(model, X, t_end, tau=tau, scheme=scheme,
                                       time_transform=None)}
    switch_seconds: list = []
    remove = _timed_switch(switch_seconds)
    try:
        best, _ = interleaved(tasks, args.repeats, clock=time.process_time)
    finally:
        remove()
    parts = _profile(model, X, t_end, maps=max(3, args.repeats // 2))
    kernels = _kernel_seconds(model, X, t_end, maps=max(3, args.repeats // 2))
    result = {"quick": args.quick, "orbits": len(X), "t_end": t_end, "tau": tau,
              "scheme": scheme, "bitwise_run": bool(np.array_equal(bare.values, defaults.values, equal_nan=True)),
              "seconds": best, "pilot_seconds": best["defaults"] - best["run alone"],
              "pilot_share": 1.0 - best["run alone"] / best["defaults"],
              "switch_seconds": min(switch_seconds),
              "profile_seconds_per_map": parts,
              "pilot_kernel_seconds": kernels,
              # Counts, not timings: the same on any machine and load.
              "pilot_runs": {"constant": len(choice["tried"]),
                             "log": len(choice["log"]["tried"])},
              "pilot_gradients": {"constant": choice["counts"]["gradient"],
                                  "log": choice["log"]["counts"]["gradient_evaluations"]},
              "load": load,
              "load_end": list(os.getloadavg())}
    print(f"CR3BP map, {len(X)} orbits, t = {t_end:g}, defaults τ = {tau:g} ({scheme}), "
          f"CPU, min of {args.repeats} interleaved, load {load[0]:.1f}")
    for k, v in best.items():
        print(f"  {k:<12} {1e3 * v:8.2f} ms")
    print(f"  pilots       {1e3 * result['pilot_seconds']:8.2f} ms "
          f"({100 * result['pilot_share']:.0f} % of the defaults)"
          f"; the run alone gives the defaults' bits: {result['bitwise_run']}")
    print(f"  the switch alone (both pilots, timed inside the defaults) "
          f"{1e3 * result['switch_seconds']:8.2f} ms")
    print(f"  of which the pilots' compiled kernels {1e3 * kernels:8.2f} ms (under cProfile)")
    print(f"  pilot force evaluations: constant ladder {result['pilot_gradients']['constant']}"
          f" ({result['pilot_runs']['constant']} rungs judged), LH "
          f"{result['pilot_gradients']['log']} ({result['pilot_runs']['log']} rungs judged)")
    print("under cProfile, per map (shares, not seconds):")
    for k, v in parts.items():
        print(f"  {k:<45} {1e3 * v:8.2f} ms")
    save_json(args.out, "map_pilot_cost", result)
    return result


if __name__ == "__main__":
    main()

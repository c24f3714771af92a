"""Where a GPU chaos map's time goes, stage by stage (issue 33).

``staged()`` is a context manager around one call of ``varint.chaos_map``:
inside it, the host functions of the map's path are wrapped with timers
(CPU seconds of the process summed over their calls, :data:`CLOCK`), and
the GPU calls' own stages (wall clock) come from
:data:`varint.gpu.resident.STAGES` (packing, copies each way, compaction,
the kernel, writing back, failed orbits). The wrappers are put on the
names the map's code looks up at call time (module globals and class
attributes) and removed on leaving. Nested stages are not subtracted:
``records`` includes ``energy errors``; ``read snapshots`` includes
``records``; ``assembly`` includes ``map order``. A stage whose function
a source tree lacks (``chunk reads`` and ``map order`` before gpu23's
change, which read the records and put the chunks' arrays in order
inline) is left out: run this script in both trees (``--against`` runs
the other tree's own copy; copy this one there to time the same stages).

Run on its own (numba's CUDA simulator without a GPU, the kernel's launch
replaced by one that takes no step and the energy kernel's by one that
computes nothing, so only the host's work is timed)::

    NUMBA_ENABLE_CUDASIM=1 python studies/gpu_stages.py --orbits 20000 \
        [--compare 3] [--out studies/results/gpu_stages_simulator]

(``--out NAME``: writes ``NAME.json`` and ``NAME.md``; ``--compare R``:
main a875246's GPU call, whose host computed the snapshots' energies, and
today's, interleaved, R runs each, the fastest of each reported; with
``--before host`` main 7b2b6c8's host functions of the map instead;
``--against TREE --repeats R``: this script of another source tree, e.g.
``git archive <commit> | tar -x -C TREE``, and of this one, each in a fresh
process, alternating, R runs each, the fastest of each reported, for
changes outside the GPU call.) On the simulator
the copies to and from the "device" are NumPy copies and the kernel's
place is taken by copies of the state into the snapshots: the figures are
the host's share of the work, not a GPU's.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
import time
import warnings
from pathlib import Path

HERE = Path(__file__).resolve().parent
if str(HERE.parent) not in sys.path:
    sys.path.insert(0, str(HERE.parent))

#: (stage, module, attribute path) of the host functions timed.
WRAPPED = (
    ("validation", "varint._validate", "kernels"),
    ("full-rank check", "varint._validate", "full_rank"),
    ("seeded vectors", "varint.maps", "initial_deviations"),
    ("initial energies", "varint.accuracy", "Reference.__init__"),
    ("snapshot arrays", "varint.methods.tm", "TangentMapPropagator._snapshots"),
    ("propagator calls", "varint.methods.tm", "TangentMapPropagator.advance"),
    ("read snapshots", "varint.driver", "_read_snapshots"),
    ("records", "varint.run", "Run.record"),
    ("energy errors", "varint.accuracy", "Reference.errors"),
    ("records joined", "varint.records", "Records.stacked"),
    ("chunk reads", "varint.maps", "_read_at"),
    ("assembly", "varint.maps", "_assemble"),
    ("map order", "varint.maps", "_in_map_order"),
)


#: The clock of the wrapped host stages: the process's CPU seconds, which
#: a loaded machine does not inflate as it does the wall clock (the
#: stages' NumPy work runs in this thread; the ``gpu:`` stages are the
#: library's own wall-clock figures).
CLOCK = time.process_time


def _timed(fn, seconds, stage):
    def wrapper(*args, **kwargs):
        t = CLOCK()
        try:
            return fn(*args, **kwargs)
        finally:
            seconds[stage] += CLOCK() - t

    wrapper.__wrapped__ = fn
    return wrapper


@contextlib.contextmanager
def staged():
    """Times the stages of the map run inside; yields the dict that is
    filled on leaving: {stage: seconds} of :data:`WRAPPED`, ``gpu: <stage>``
    of the GPU calls, their counts and ``total``."""
    import importlib

    from varint.gpu.resident import STAGES

    seconds = {}
    undo = []
    for stage, module, path in WRAPPED:
        owner = importlib.import_module(module)
        *outer, name = path.split(".")
        for part in outer:
            owner = getattr(owner, part)
        if name not in owner.__dict__:   # not in this source tree
            continue
        seconds[stage] = 0.0
        original = owner.__dict__[name]
        setattr(owner, name, _timed(original, seconds, stage))
        undo.append((owner, name, original))
    before = dict(STAGES)
    out: dict = {}
    t, cpu = time.perf_counter(), time.process_time()
    try:
        yield out
    finally:
        total = time.perf_counter() - t
        cpu = time.process_time() - cpu
        for owner, name, original in reversed(undo):
            setattr(owner, name, original)
        out.update(seconds)
        for key, value in STAGES.items():
            out[f"gpu: {key}"] = value - before[key]
        # The process's CPU seconds (all its threads) beside the wall
        # clock's: on a loaded machine the wall clock counts waiting too.
        out["cpu total"] = cpu
        out["total"] = total


def describe(stages):
    """One line per stage: seconds and share of the total."""
    total = stages["total"]
    lines = []
    for key, value in stages.items():
        if key in ("total", "cpu total"):
            continue
        if isinstance(value, float):
            lines.append(f"  {key:<22} {value:9.4f} s  {value / total:6.1%}")
        else:
            lines.append(f"  {key:<22} {value:9d}")
    return "\n".join(lines + [f"  {'cpu total':<22} {stages['cpu total']:9.4f} s",
                              f"  {'total':<22} {total:9.4f} s"])


def _no_steps(self, n_threads, X, W, am, ae, st, fs, nxt, itv, n_steps, step0, tau, h, hc,
              escape_r2, mode, every, aux, outs, snap_x, snap_W, snap_m, snap_e, snap_aux):
    """The kernel's launch on the simulator, doing no step: the snapshots
    get the state as it is, the status is OK."""
    st[:] = 0
    for j in range(snap_x.shape[0]):
        snap_x[j], snap_W[j], snap_m[j], snap_e[j] = X, W, am, ae
        snap_aux[j] = aux


def _no_energy(self, n_threads, snap_x, count, out):
    """The energy kernel's launch on the simulator (:mod:`varint.gpu.energy`),
    doing no arithmetic: each output gets the orbit's first coordinate
    (the energy errors are then meaningless, and their warnings are
    silenced; only the host's share of the work is timed)."""
    out[:count] = snap_x[:count, 0]


def _fake_launch(self, n_threads, *args):
    """The launches on the simulator: the stepper's by :func:`_no_steps`,
    the energy kernel's by :func:`_no_energy`, the initial energies' by
    copies of two numbers per state, the transpositions into the
    host's layout by NumPy's (the simulator would run them thread by
    thread in Python); the gathers of a compaction as they are."""
    name = self.dispatcher.py_func.__name__
    if name == "energy":
        return _no_energy(self, n_threads, *args)
    if name == "parts":   # the initial energies' T and V: the first two numbers
        x, kinetic, potential = args
        kinetic[:], potential[:] = x[:, 0], x[:, 1]
        return None
    if name == "thread":
        return _no_steps(self, n_threads, *args)
    if name == "_to_rows":   # a transposition on the device, in NumPy
        src, dst, c0 = args
        dst[:, c0:c0 + src.shape[0]] = src.T
        return None
    return _REAL_LAUNCH[0](self, n_threads, *args)


_REAL_LAUNCH: list = []


@contextlib.contextmanager
def call_of(contender):
    """``"main"``: the GPU call of main a875246 (the snapshots' energies on
    the host, ``studies/gpu_advance_main.py``) in the place of today's
    (the TM propagator looks ``advance_cuda`` up at each call);
    ``"host_main"``: main 7b2b6c8's host functions of the map
    (``studies/gpu_host_main.py``); ``"now"``: today's. Entered outside
    :func:`staged` (which wraps the functions in place when it starts)."""
    if contender == "now":
        yield
        return
    if contender == "host_main":
        from studies.gpu_host_main import host_of_main

        with host_of_main():
            yield
        return
    from studies import gpu_advance_main
    from varint.gpu import advance

    today = advance.advance_cuda
    advance.advance_cuda = gpu_advance_main.advance_cuda
    try:
        yield
    finally:
        advance.advance_cuda = today


def compare_table(best, other="main", label="main a875246"):
    """Markdown: each stage's seconds for ``best[other]`` (``label``) and
    today, and their ratio."""
    lines = [f"| stage | {label} s | now s | before / now |", "|---|---|---|---|"]
    for key, before in best[other].items():
        now = best["now"].get(key, 0.0)
        if isinstance(before, float) or isinstance(now, float):
            ratio = f"{before / now:.2f}" if now > 0 else "—"
            lines.append(f"| {key} | {before:.4f} | {now:.4f} | {ratio} |")
        else:
            lines.append(f"| {key} | {before} | {now} | |")
    for key in best["now"].keys() - best[other].keys():
        lines.append(f"| {key} | — | {best['now'][key]:.4f} | |")
    return "\n".join(lines)


def _fresh_run(tree, orbits, t_end, warm=0):
    """This script of source tree ``tree`` run once in a new process on the
    simulator: its stages (the JSON of its last line)."""
    import os
    import subprocess

    env = {**os.environ, "NUMBA_ENABLE_CUDASIM": "1"}
    if tree.resolve() != HERE.parent:
        # The other tree's kernels in a cache of their own.
        env["VARINT_CACHE_DIR"] = env.get("VARINT_CACHE_DIR", "/tmp/varint-cache") + "-against"
    out = subprocess.run([sys.executable, str(tree / "studies" / "gpu_stages.py"), "--orbits",
                          str(orbits), "--t-end", repr(t_end), "--warm", str(warm)], cwd=tree, env=env,
                         capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])["now"]


def against(tree, orbits, t_end, repeats, warm=0):
    """``({"before": stages, "now": stages}, fastest, runs)``: the fastest
    (by CPU seconds) of ``repeats`` fresh runs of ``tree``'s script and of
    this tree's, alternating; each stage's fastest over the runs; every
    run's stages."""
    best: dict = {}
    fastest: dict = {}
    runs: dict = {"before": [], "now": []}
    for _ in range(repeats):
        for name, where in (("before", tree), ("now", HERE.parent)):
            stages = _fresh_run(where, orbits, t_end, warm)
            runs[name].append(stages)
            key = "cpu total" if "cpu total" in stages else "total"
            if name not in best or stages[key] < best[name][key]:
                best[name] = stages
            fastest.setdefault(name, {})
            for stage, value in stages.items():
                fastest[name][stage] = min(fastest[name].get(stage, value), value)
    return best, fastest, runs


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--orbits", type=int, default=20000)
    p.add_argument("--t-end", type=float, default=1000.0)
    p.add_argument("--warm", type=int, default=0,
                   help="full-size maps run (untimed) before the timed one in the same "
                        "process: a process that runs several maps (its buffers and "
                        "freed memory reused)")
    p.add_argument("--threshold", type=float, default=None,
                   help="early stopping's threshold (default: chaos_map's)")
    p.add_argument("--compare", type=int, default=0, metavar="REPEATS",
                   help="time main a875246's GPU call and today's, interleaved, REPEATS "
                        "times each; the fastest run of each is reported")
    p.add_argument("--against", type=Path, default=None, metavar="TREE",
                   help="another source tree's run of this script against this tree's, "
                        "each in fresh processes, alternating (--repeats each)")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--label", default="before",
                   help="the other tree's name in the table (e.g. main 7b2b6c8)")
    p.add_argument("--before", choices=("a875246", "host"), default="a875246",
                   help="--compare's other contender: main a875246's GPU call, or main "
                        "7b2b6c8's host functions of the map")
    p.add_argument("--out", type=Path, default=None,
                   help="write the breakdown to OUT.json and OUT.md")
    args = p.parse_args(argv)
    import os
    import platform

    import numpy as np

    import varint
    from varint.gpu import device
    from varint.models import HenonHeiles

    if args.against is not None:
        load = os.getloadavg()
        best, fastest, runs = against(args.against, args.orbits, args.t_end, args.repeats,
                                      args.warm)
        text = (f"# A GPU map's host work by stage, on numba's CUDA simulator: "
                f"{args.label} against this tree\n\n"
                f"Hénon–Heiles FLI map (chaos_map defaults), {args.orbits} orbits, "
                f"t = {args.t_end:g}, one chunk; the kernel's launch replaced by one that "
                f"takes no step, the energy kernel's by one that computes nothing. Each run "
                f"a fresh process, the two trees alternating, the fastest (by the process's "
                f"CPU seconds) of "
                f"{args.repeats} each. {os.cpu_count()} CPU cores, load {load[0]:.1f} at "
                f"the start, {os.getloadavg()[0]:.1f} at the end; Python "
                f"{platform.python_version()}.\n`NUMBA_ENABLE_CUDASIM=1 python "
                f"studies/gpu_stages.py --orbits {args.orbits} --against TREE --repeats "
                f"{args.repeats} --warm {args.warm}` (TREE: {args.label}; with --warm W, W "
                f"maps of as many orbits ran before the timed one in its process)\n\nNested: records include energy "
                "errors, propagator calls the gpu: stages, assembly map order. Host stages "
                "in CPU seconds, gpu: stages in wall-clock seconds; `gpu: "
                "kernel`, `gpu: energy` and the copies stand in for the device's work "
                "(NumPy on the simulator). The fastest run of each:\n\n"
                + compare_table(best, "before", args.label)
                + "\n\nEach stage's fastest of its runs:\n\n"
                + compare_table(fastest, "before", args.label) + "\n")
        print(text)
        if args.out is not None:
            from studies.common import save_json

            args.out.parent.mkdir(parents=True, exist_ok=True)
            save_json(args.out.parent, args.out.name, {
                "orbits": args.orbits, "t_end": args.t_end, "load": load,
                "load_end": os.getloadavg(), "against": args.label, "warm": args.warm,
                "repeats": args.repeats, "by_contender": best,
                "fastest_by_stage": fastest, "runs": runs})
            args.out.with_suffix(".md").write_text(text)
        return
    if not device.simulated():
        raise SystemExit("run with NUMBA_ENABLE_CUDASIM=1 (the device script times a GPU)")
    _REAL_LAUNCH.append(device._Kernel.launch)
    device._Kernel.launch = _fake_launch
    hh = HenonHeiles()
    side = int(np.ceil(np.sqrt(args.orbits * 1.6)))   # ~60 % of the square is allowed
    X = varint.section_grid(hh, 0.125, np.linspace(-0.45, 0.7, side),
                            np.linspace(-0.45, 0.45, side)).states[:args.orbits]
    kw = dict(t_end=args.t_end, progress=False, chunk_size=args.orbits, backend="cuda")
    if args.threshold is not None:
        kw["threshold"] = args.threshold
    before = {"a875246": "main", "host": "host_main"}[args.before]
    label = {"main": "main a875246", "host_main": "main 7b2b6c8's host"}[before]
    contenders = (before, "now") if args.compare else ("now",)
    for c in contenders:
        with call_of(c), warnings.catch_warnings():
            warnings.simplefilter("ignore")
            varint.chaos_map(hh, X[:256], "fli", **{**kw, "t_end": 2.0})
            for _ in range(args.warm):
                varint.chaos_map(hh, X, "fli", **kw)
    load = os.getloadavg()
    best: dict = {}
    fastest: dict = {}   # each stage's fastest run (a load's noise is per stage)
    values: dict = {}
    for _ in range(max(args.compare, 1)):
        for c in contenders:
            with call_of(c), staged() as stages, warnings.catch_warnings():
                warnings.simplefilter("ignore")   # the fake energies' accuracy warnings
                values[c] = varint.chaos_map(hh, X, "fli", **kw).values
            if c not in best or stages["total"] < best[c]["total"]:
                best[c] = stages
            fastest.setdefault(c, {})
            for key, value in stages.items():
                fastest[c][key] = min(fastest[c].get(key, value), value)
    stages = best["now"]
    command = (f"`NUMBA_ENABLE_CUDASIM=1 python studies/gpu_stages.py --orbits {args.orbits}"
               + (f" --compare {args.compare} --before {args.before}`" if args.compare
                  else "`"))
    text = (f"# A GPU map's host work by stage, on numba's CUDA simulator\n\n"
            f"Hénon–Heiles FLI map (chaos_map defaults), {args.orbits} orbits, "
            f"t = {args.t_end:g}, one chunk; the kernel's launch replaced by one that takes "
            f"no step, the energy kernel's by one that computes nothing. {os.cpu_count()} "
            f"CPU cores, load {load[0]:.1f} at the start, {os.getloadavg()[0]:.1f} at the "
            f"end; Python {platform.python_version()}.\n{command}\n\n")
    if args.compare:
        same = bool(np.array_equal(values[before], values["now"], equal_nan=True))
        what = ("Main a875246's GPU call (energies on the host)" if before == "main" else
                "Main 7b2b6c8's host functions (studies/gpu_host_main.py)")
        text += (f"{what} and today's, interleaved, "
                 f"the fastest of {args.compare} runs each; the same values: {same}. "
                 "Nested: records include energy errors, propagator calls the gpu: "
                 "stages; `gpu: kernel` and `gpu: energy` stand in for the device's "
                 "work. The fastest run of each (by total):\n\n"
                 + compare_table(best, before, label)
                 + "\n\nEach stage's fastest of its runs (the total: the fastest run's):\n\n"
                 + compare_table(fastest, before, label) + "\n")
    else:
        text += f"```\n{describe(stages)}\n```\n"
    print(text)
    print(json.dumps(best))
    if args.out is not None:
        args.out.with_suffix(".json").write_text(json.dumps(
            {"orbits": args.orbits, "t_end": args.t_end, "load": load,
             "stages": stages, "by_contender": best, "fastest_by_stage": fastest},
            indent=1))
        args.out.with_suffix(".md").write_text(text)


if __name__ == "__main__":
    main()

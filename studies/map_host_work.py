"""Study: the host work of a chaos map per orbit, before and after (issue 33,
step 1), and the CPU map's orbits per second.

A GPU map of 1e5 orbits spent 17.8 µs per orbit on the host against the
kernel's 0.18 µs (``bench_gpu_h100.md``): validation, seeded vectors,
repacking at the launches, records. This study times each part for the
same Hénon–Heiles FLI map (random points of the section at H = 0.125,
chaos_map defaults; ``--indicator`` for another) in two source trees,
``--before`` (a git revision) and this one's HEAD, both exported with ``git
archive``, each part in fresh processes, alternating before/after, the
minimum of repeats:

* ``kernels``: the derivative kernels checked at every state
  (``_validate.kernels``), the first time (a fresh model);
* ``seeds``: the seeded orthonormal vectors (``state.initial_deviations``);
* ``full_rank``: the check of given vectors (``_validate.full_rank``);
* ``gpu_host``: a whole map with ``backend="cuda"`` on numba's CUDA
  simulator with the kernel's launch replaced by one that takes no step
  (the snapshots get the state as it is): everything the host does for a
  GPU map (validation, seeds, repacking and copies at every launch,
  records), per orbit;
* ``cpu_map``: the map on the CPU (all cores of this machine), orbits/s.

Run: ``python studies/map_host_work.py [--orbits 100000] [--t-end 1000]
[--repeats 3] [--before REV] [--parts kernels,...] [--indicator fli]
[--name map_host_work] [--quick]``; writes ``results/<name>.json`` and
``.md``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
PARTS = ("kernels", "seeds", "full_rank", "gpu_host", "cpu_map")


def worker(part, m, t_end, indicator="fli"):
    """Time ``part`` once in this process (its compilation first, on a
    small batch) and print {"s": seconds}."""
    import numpy as np

    import varint
    from varint import _validate as check
    from varint.models import HenonHeiles
    from varint.state import initial_deviations

    sys.path.insert(0, str(HERE))
    from bench_gpu import section_points

    X = section_points(HenonHeiles(), m)
    idx = np.arange(m)
    if part == "kernels":
        check.kernels(HenonHeiles(), X[:64])
        hh = HenonHeiles()     # a fresh model: nothing remembered
        t = time.perf_counter()
        check.kernels(hh, X)
    elif part == "seeds":
        initial_deviations(4, 1, 64, 3, idx[:64])
        t = time.perf_counter()
        initial_deviations(4, 1, m, 3, idx)
    elif part == "full_rank":
        W = initial_deviations(4, 1, m, 3, idx)
        check.full_rank(W[:64])
        t = time.perf_counter()
        check.full_rank(W)
    elif part in ("gpu_host", "cpu_map"):
        kw = dict(t_end=t_end, progress=False, chunk_size=m)
        if part == "gpu_host":
            from varint.gpu import device

            device._Kernel.launch = _no_steps
            kw["backend"] = "cuda"
        # The same kernels (the parallel one for many orbits), compiled or
        # loaded, on a short map of the same orbits.
        varint.chaos_map(HenonHeiles(), X, indicator, **{**kw, "t_end": min(t_end, 2.0)})
        t = time.perf_counter()
        varint.chaos_map(HenonHeiles(), X, indicator, **kw)
    print(json.dumps({"s": time.perf_counter() - t}))


def _no_steps(self, n_threads, X, W, am, ae, st, fs, nxt, itv, n_steps, step0, tau, h, hc,
              escape_r2, mode, every, aux, outs, snap_x, snap_W, snap_m, snap_e, snap_aux):
    """The kernel's launch, doing no step: the snapshots get the state as it
    is (so that the records are of finite values, as after real steps);
    every orbit's status OK, as the kernel writes it."""
    st[:] = 0
    for j in range(snap_x.shape[0]):
        snap_x[j], snap_W[j], snap_m[j], snap_e[j] = X, W, am, ae
        snap_aux[j] = aux


def run_part(tree, part, m, t_end, indicator):
    env = dict(os.environ, PYTHONPATH=str(tree))
    if part == "gpu_host":
        env["NUMBA_ENABLE_CUDASIM"] = "1"
    out = subprocess.run([sys.executable, str(tree / "studies" / "map_host_work.py"),
                          "--worker", part, "--orbits", str(m), "--t-end", str(t_end),
                          "--indicator", indicator],
                         env=env, capture_output=True, text=True, cwd=tree, check=False)
    if out.returncode:
        raise RuntimeError(f"{part} in {tree}: {out.stderr[-2000:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])["s"]


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--orbits", type=int, default=100_000)
    p.add_argument("--t-end", type=float, default=1000.0)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--before", default="8042720")
    p.add_argument("--parts", default=",".join(PARTS))
    p.add_argument("--quick", action="store_true")
    p.add_argument("--indicator", default="fli", help="the map's indicator (fli, megno, sali)")
    p.add_argument("--name", default="map_host_work", help="the result files' name")
    p.add_argument("--worker", default=None, help=argparse.SUPPRESS)
    p.add_argument("--out", type=Path, default=HERE / "results")
    args = p.parse_args(argv)
    if args.worker:
        worker(args.worker, args.orbits, args.t_end, args.indicator)
        return None
    m, t_end, reps = ((2000, 20.0, 1) if args.quick else (args.orbits, args.t_end, args.repeats))
    parts = args.parts.split(",")
    after = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"],
                           capture_output=True, text=True, check=True).stdout.strip()
    with tempfile.TemporaryDirectory(prefix="varint-trees-") as tmp:
        # Both trees exported from git: what was committed, whatever the
        # working tree holds meanwhile.
        trees = {"before": Path(tmp) / "before", "after": Path(tmp) / "after"}
        for name, rev in (("before", args.before), ("after", after)):
            trees[name].mkdir()
            archive = subprocess.run(["git", "-C", str(ROOT), "archive", rev],
                                     capture_output=True, check=True).stdout
            subprocess.run(["tar", "-x", "-C", str(trees[name])], input=archive, check=True)
            # This script in the old tree too (it may not have it).
            (trees[name] / "studies" / "map_host_work.py").write_bytes(
                Path(__file__).read_bytes())
        res = {"orbits": m, "t_end": t_end, "indicator": args.indicator, "repeats": reps,
               "before": args.before,
               "after": after,
               "load_start": os.getloadavg(), "cpus": os.cpu_count(), "s": {}}
        for part in parts:
            times = {"before": [], "after": []}
            for _ in range(reps):
                for name, tree in trees.items():   # alternating
                    times[name].append(run_part(tree, part, m, t_end, args.indicator))
            res["s"][part] = {name: min(v) for name, v in times.items()}
            print(part, json.dumps(res["s"][part]), flush=True)
            # After every part: a study stopped early keeps what it measured.
            args.out.mkdir(parents=True, exist_ok=True)
            (args.out / f"{args.name}.json").write_text(json.dumps(res, indent=1))
        res["load_end"] = os.getloadavg()
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / f"{args.name}.json").write_text(json.dumps(res, indent=1))
    lines = [f"# Host work of a Hénon–Heiles {args.indicator.upper()} map: {m} orbits, "
             f"t = {t_end:g}", "",
             f"Before {res['before']}, after {res['after']}; {res['cpus']} CPU cores, load "
             f"{res['load_start'][0]:.1f} at the start, {res['load_end'][0]:.1f} at the end; "
             f"minimum of {reps} alternating runs, each in a fresh process.", "",
             "| part | before µs/orbit | after µs/orbit | before/after |", "|---|---|---|---|"]
    for part, v in res["s"].items():
        if part == "cpu_map":
            continue
        lines.append(f"| {part} | {v['before'] / m * 1e6:.3g} | {v['after'] / m * 1e6:.3g} | "
                     f"{v['before'] / v['after']:.1f} |")
    if "cpu_map" in res["s"]:
        v = res["s"]["cpu_map"]
        lines += ["", f"CPU map ({res['cpus']} cores): {m / v['before']:.4g} orbits/s before, "
                      f"{m / v['after']:.4g} after ({v['before'] / v['after']:.2f}×)."]
    text = "\n".join(lines) + "\n"
    (args.out / f"{args.name}.md").write_text(text)
    print(text)
    return res


if __name__ == "__main__":
    main()

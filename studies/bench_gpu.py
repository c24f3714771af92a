"""Benchmark: Hénon–Heiles chaos maps on a CUDA GPU against the CPU path.

One command on a machine with a GPU (``pip install "varint[cuda]"``)::

    python studies/bench_gpu.py [--quick] [--out DIR] [--sizes 1000000,100000]
                                [--deadline SECONDS]

The parts run in this order, each written to ``bench_gpu.json`` as soon as
it is measured (a run stopped at its time limit keeps what it measured):

1. **Speed, the target's size first.** The FLI map (chaos_map defaults,
   t = 1e3) of random points of the section at 1e6, then 1e5 orbits
   (``--sizes``): orbits per second on the GPU (one chunk per map, with the
   kernel's own seconds and the map's time by stage,
   ``studies/gpu_stages.py``), on the GPU with main 7b2b6c8's host
   functions of the map (``gpu_host_main``, ``studies/gpu_host_main.py``:
   the initial energies on the host and again per chunk, the seeds' hash
   vectorised, every length of the full-rank check, the initial states'
   finiteness with temporaries), with ``--with-a875246`` the GPU call of main a875246
   (``gpu_main``: the snapshots' energies computed on the host,
   ``studies/gpu_advance_main.py``), with ``--with-93ccc3a`` also that of
   main 93ccc3a, ``gpu_before``: the state packed and copied at every call,
   ``studies/gpu_advance_before.py``), on all CPU cores and (up to ``--cpu1-max``
   orbits, its rate being flat in the size) on one, interleaved, one run
   each at 1e6 and the minimum of two below.
2. **Agreement.** The FLI map of a 16 × 16 grid on the section x = 0,
   p_x ≥ 0 at H = 0.125 (t = 100, chaos_map defaults) with
   ``backend="cuda"`` and on the CPU: bitwise equal or the largest relative
   difference, and both against a tight reference (the same map at τ/4 on
   the CPU: the defaults' error, the same for both); then where the two
   first differ (``studies/gpu_difference.py``: the device's primitives
   against the host's, and the first step of the propagation at which
   any orbit differs); then SALI and MEGNO (SBAB2C, τ = 0.05), SALI with
   early stopping to t = 500 (the decided orbits dropped on the device:
   uploads, compactions and launches counted) and the FLI map of a Toda
   lattice from ``from_potential`` (exp: libdevice against the C library),
   while ``--deadline`` allows.
3. **Fraction of peak.** The floating-point operations of one step of the
   generated kernel, counted in its source (an fma counts 2, a √ or log 1,
   varint's ``vlog`` too; comparisons and integer work 0), times the steps,
   over the GPU's time, against the peak FP64 rate of its FP64 units (SMs ×
   64 FMA × 2 × clock; not the tensor cores, which a step cannot use).

heyoka's batch mode is not installed on GPU machines here; its ratio to
varint's CPU path is that of ``studies/bench_peers.py``.

Writes ``bench_gpu.json`` and ``bench_gpu.md`` to ``--out`` and prints the table.
"""

from __future__ import annotations

import argparse
import ast
import contextlib
import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
if str(HERE.parent) not in sys.path:
    sys.path.insert(0, str(HERE.parent))

import varint  # noqa: E402
from studies import gpu_difference  # noqa: E402
from studies.gpu_difference import ENERGY  # noqa: E402
from studies.gpu_stages import describe, staged  # noqa: E402
from varint.models import HenonHeiles  # noqa: E402


def section_points(model, m, seed=0):
    """``m`` random allowed points of the section x = 0, p_x ≥ 0 at H = ENERGY."""
    rng = np.random.default_rng(seed)
    out = np.empty((0, 4))
    while len(out) < m:
        y = rng.uniform(-0.45, 0.7, 2 * m)
        py = rng.uniform(-0.45, 0.45, 2 * m)
        v = y * y / 2 - y ** 3 / 3
        px2 = 2 * (ENERGY - v) - py * py
        ok = px2 >= 0
        pts = np.column_stack([np.zeros(ok.sum()), y[ok], np.sqrt(px2[ok]), py[ok]])
        out = np.vstack([out, pts])
    return out[:m]


def toda():
    import sympy as sp

    q0, q1 = sp.symbols("q0 q1")
    r3 = sp.sqrt(3)
    V = (sp.exp(q1 + 2 * r3 * q0) + sp.exp(q1 - 2 * r3 * q0) + sp.exp(-2 * q1)) / 24 \
        - sp.Rational(1, 8)
    return varint.models.from_potential(V, [q0, q1], name="toda")


def compare(a, b):
    """'bitwise' or the largest relative difference of the finite values."""
    same = all(np.array_equal(getattr(a, f), getattr(b, f), equal_nan=True)
               for f in ("values", "t_stop", "status"))
    if same:
        return "bitwise", 0.0
    ok = np.isfinite(a.values) & np.isfinite(b.values)
    rel = np.abs(a.values[ok] - b.values[ok]) / np.maximum(np.abs(a.values[ok]), 1e-300)
    return "differs", float(rel.max()) if rel.size else float("nan")


def step_flops(model, indicator="fli", scheme=None):
    """(flops, sqrt+log count) of one step of the generated CUDA kernel,
    counted in its source: the body of the loop over steps, less the
    branches a chaos map of this indicator does not take every step (the
    copies at output steps, the sparse schedule, the overflow check of
    unrenormalised vectors)."""
    from varint.gpu.emit import cuda_source
    from varint.indicators import resolve
    from varint.methods import make_propagator
    from varint.schemes import DRIFT, stage_arrays

    ind, _ = resolve(indicator)
    prop = make_propagator("tm", model, 0.05, "normalize", getattr(ind, "accumulator", None),
                           **({"scheme": scheme} if scheme else {}))
    kinds, _, hc = stage_arrays(prop.scheme, 0.05)
    src = cuda_source(model, kinds, (hc != 0) & (kinds != DRIFT), 1, prop.accumulator)
    tree = ast.parse(src)
    loop = next(n for n in ast.walk(tree) if isinstance(n, ast.For)
                and isinstance(n.target, ast.Name) and n.target.id == "s")
    skipped = ("jo <", "every != 0", "chk")

    def counted(node):
        if isinstance(node, ast.If) and any(ast.unparse(node.test).startswith(s)
                                            for s in skipped):
            return sum(counted(x) for x in node.orelse)
        flops = special = 0
        for sub in ast.walk(node):
            if isinstance(sub, ast.BinOp) and isinstance(sub.op, (ast.Add, ast.Sub, ast.Mult,
                                                                  ast.Div)):
                flops += 1
            elif isinstance(sub, ast.Call):
                name = ast.unparse(sub.func)
                if name in ("cuda.fma", "fma"):
                    flops += 2
                elif name in ("math.sqrt", "math.log", "vlog", "math.exp"):
                    special += 1
        return flops + special

    total = sum(counted(n) for n in loop.body)
    return total, src


def gpu_info():
    from numba import cuda

    dev = cuda.get_current_device()
    sms = dev.MULTIPROCESSOR_COUNT
    clock_hz = dev.CLOCK_RATE * 1e3
    name = dev.name.decode() if isinstance(dev.name, bytes) else str(dev.name)
    # Hopper: 64 FP64 FMA units per SM (128 flops per clock).
    fp64 = 64 if dev.compute_capability >= (9, 0) else 32
    return {"name": name, "sms": sms, "clock_ghz": clock_hz / 1e9,
            "compute_capability": list(dev.compute_capability),
            "peak_fp64_tflops": sms * fp64 * 2 * clock_hz / 1e12}


@contextlib.contextmanager
def call_of(contender):
    """For ``gpu_before``, the GPU call of main 93ccc3a in the place of
    today's, for ``gpu_main`` that of main a875246 (the snapshots' energies
    on the host; the TM propagator looks ``advance_cuda`` up at each
    call); for ``gpu_host_main`` main 7b2b6c8's host functions of the map
    (``studies/gpu_host_main.py``). Entered outside ``staged()``, which
    wraps the functions it finds when it starts."""
    if contender == "gpu_host_main":
        from studies.gpu_host_main import host_of_main

        with host_of_main():
            yield
        return
    if contender not in ("gpu_before", "gpu_main"):
        yield
        return
    from studies import gpu_advance_before, gpu_advance_main
    from varint.gpu import advance

    today = advance.advance_cuda
    advance.advance_cuda = (gpu_advance_before if contender == "gpu_before"
                            else gpu_advance_main).advance_cuda
    try:
        yield
    finally:
        advance.advance_cuda = today


def timed(fn):
    t = time.perf_counter()
    r = fn()
    return time.perf_counter() - t, r


def table(res):
    """The Markdown table of a result of :func:`main` (also of one that was
    stopped before its end: ``python studies/bench_gpu.py --table FILE``)."""
    from varint.maps import MAP_SCHEME

    flops = res["flops_per_step_fli"]
    gpu = res["gpu"]
    name = gpu["name"] if isinstance(gpu, dict) else (gpu or "no GPU")
    lines = [f"# bench_gpu: {name}, "
             f"{res['machine']['cpus']} CPU cores, load {res['machine']['load']}", "",
             f"FLI step of Hénon–Heiles ({MAP_SCHEME}): {flops} flops (fma = 2)", "",
             "| orbits | GPU orbits/s | all cores orbits/s | 1 core orbits/s | GPU/all | GPU/1 "
             "| GPU TFLOP/s (map) | of peak | kernel s / map s | TFLOP/s (kernel) | of peak |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]

    def f(v, fmt):
        return format(v, fmt) if isinstance(v, float) else "—"

    for r in res["speed"]:
        lines.append(f"| {r['orbits']} | {f(r.get('gpu_orbits_per_s'), '.4g')} | "
                     f"{f(r.get('cpu_all_orbits_per_s'), '.4g')} | "
                     f"{f(r.get('cpu_1_orbits_per_s'), '.4g')} | "
                     f"{f(r.get('gpu_over_cpu_all'), '.1f')} | "
                     f"{f(r.get('gpu_over_cpu_1', r.get('gpu_over_cpu_1_rate')), '.1f')} | "
                     f"{f(r.get('gpu_tflops'), '.2f')} | {f(r.get('gpu_fraction_of_peak'), '.1%')} | "
                     f"{f(r.get('gpu_kernel_s'), '.3g')} / {f(r.get('gpu_s'), '.3g')} | "
                     f"{f(r.get('kernel_tflops'), '.2f')} | "
                     f"{f(r.get('kernel_fraction_of_peak'), '.1%')} |")
    for r in res["speed"]:
        if "gpu_main_s" in r:
            lines += ["", f"{r['orbits']} orbits: the GPU map {r['gpu_s']:.4g} s, with the GPU "
                      f"call of main a875246 (energies on the host) {r['gpu_main_s']:.4g} s "
                      f"({r.get('gpu_over_main', float('nan')):.2f}×; host part in the calls "
                      f"{r['gpu_host_s']:.3g} s against {r['gpu_main_host_s']:.3g} s); "
                      f"same values: {r.get('gpu_same_as_main')}"]
        if "gpu_host_main_s" in r:
            lines += ["", f"{r['orbits']} orbits: the GPU map {r['gpu_s']:.4g} s, with main "
                      f"7b2b6c8's host functions {r['gpu_host_main_s']:.4g} s "
                      f"({r.get('gpu_over_host_main', float('nan')):.2f}×); same values: "
                      f"{r.get('gpu_same_as_host_main')}"]
        if "projected_device_only_over_cpu_all" in r:
            lines += ["", f"{r['orbits']} orbits, a projection (not measured): with no host "
                      f"work the GPU map would be "
                      f"{r['projected_device_only_over_cpu_all']:.0f}× all cores (kernel and "
                      f"energies alone); measured {r['gpu_over_cpu_all']:.1f}×"]
        if "gpu_before_s" in r:
            lines += ["", f"{r['orbits']} orbits: the GPU map {r['gpu_s']:.4g} s, with the GPU "
                      f"call of main 93ccc3a {r['gpu_before_s']:.4g} s "
                      f"({r.get('gpu_over_before', float('nan')):.2f}×; host part in the calls "
                      f"{r['gpu_host_s']:.3g} s against {r['gpu_before_host_s']:.3g} s); "
                      f"same values: {r.get('gpu_same_as_before')}"]
        if r.get("gpu_stages"):
            lines += ["", f"GPU map of {r['orbits']} orbits by stage (s; nested: records "
                      "include energy errors, propagator calls the gpu: stages):", "",
                      "| stage | s | of map |", "|---|---|---|"]
            total = r["gpu_stages"]["total"]
            lines += [f"| {k} | {v:.4g} | {v / total:.1%} |" if isinstance(v, float)
                      else f"| {k} | {v} | |" for k, v in r["gpu_stages"].items()]
        if r.get("gpu_host_main_stages") and r.get("gpu_stages"):
            lines += ["", "The same by stage, main 7b2b6c8's host functions against "
                      "today's (s):", "", "| stage | main 7b2b6c8 | now |", "|---|---|---|"]
            lines += [f"| {k} | {v:.4g} | {r['gpu_stages'].get(k, 0.0):.4g} |"
                      if isinstance(v, float) else f"| {k} | {v} | {r['gpu_stages'].get(k)} |"
                      for k, v in r["gpu_host_main_stages"].items()]
        if r.get("gpu_main_stages") and r.get("gpu_stages"):
            lines += ["", "The same by stage, main a875246's GPU call against today's (s):",
                      "", "| stage | main a875246 | now |", "|---|---|---|"]
            lines += [f"| {k} | {v:.4g} | {r['gpu_stages'].get(k, 0.0):.4g} |"
                      if isinstance(v, float) else f"| {k} | {v} | {r['gpu_stages'].get(k)} |"
                      for k, v in r["gpu_main_stages"].items()]
    lines += ["", "Agreement: " + json.dumps(res["agreement"])]
    diff = res.get("difference", {})
    for way, ops in diff.get("primitives", {}).items():
        lines.append(f"Primitives whose bits differ on the device, kernel compiled as {way} "
                     "(of each): " + json.dumps({k: v["differ"] for k, v in ops.items()}))
    if "first_step" in diff:
        first = {k: v for k, v in diff["first_step"].items() if k != "examples"}
        lines.append("First differing step of the FLI propagation: " + json.dumps(first))
    lines.append("Errors: " + json.dumps(res["errors"]))
    return "\n".join(lines) + "\n"


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="small sizes (seconds)")
    p.add_argument("--out", type=Path, default=HERE / "results")
    p.add_argument("--t-end", type=float, default=1000.0)
    p.add_argument("--sizes", default="1000000,100000",
                   help="orbits of the speed part, comma-separated, measured in this order")
    p.add_argument("--cpu1-max", type=int, default=100_000,
                   help="the largest size timed on one CPU core (its rate is flat in the size)")
    p.add_argument("--deadline", type=float, default=float("inf"),
                   help="seconds from the start after which no further part or size is begun")
    p.add_argument("--with-a875246", action="store_true",
                   help="also the GPU call of main a875246 (gpu_main: energies on the host)")
    p.add_argument("--with-93ccc3a", action="store_true",
                   help="also time the GPU call of main 93ccc3a (gpu_before)")
    p.add_argument("--table", type=Path, default=None,
                   help="only print the table of this bench_gpu.json")
    args = p.parse_args(argv)
    if args.table is not None:
        text = table(json.loads(args.table.read_text()))
        print(text)
        return text
    args.out.mkdir(parents=True, exist_ok=True)
    from varint.gpu import device

    start = time.perf_counter()

    def log(*what):
        print(f"[{time.perf_counter() - start:6.1f} s]", *what, flush=True)

    def late():
        return time.perf_counter() - start > args.deadline

    hh = HenonHeiles()
    # The simulator stands in for a GPU only in a dry run (--quick): it runs
    # the kernels as Python, thread by thread.
    real = device.available() and not device.simulated()
    gpu = real or (args.quick and device.available())
    res = {"machine": {"platform": platform.platform(), "cpus": os.cpu_count(),
                       "load": os.getloadavg(), "python": platform.python_version(),
                       "numba": __import__("numba").__version__,
                       "varint": varint.__version__},
           "gpu": gpu_info() if real else ("simulator" if gpu else None), "agreement": {},
           "speed": [], "errors": [], "seconds": {}}

    def save(part=None):
        # After every part: a run stopped at its time limit keeps what it measured.
        if part:
            res["seconds"][part] = time.perf_counter() - start
        (args.out / "bench_gpu.json").write_text(json.dumps(res, indent=1, default=str))

    log(json.dumps(res["machine"]), res["gpu"])
    from varint.maps import MAP_SCHEME

    flops, _ = step_flops(hh, "fli", MAP_SCHEME)
    res["flops_per_step_fli"] = flops
    log(f"flops per step (Hénon–Heiles, FLI, {MAP_SCHEME}): {flops}")

    # 1. Speed first (the target's size first): interleaved contenders.
    import numba

    sizes = [400, 200] if args.quick else [int(float(v)) for v in args.sizes.split(",")]
    t_end = 20.0 if args.quick else args.t_end
    # gpu_before: the same kernel with the GPU call as at main 93ccc3a
    # (studies/gpu_advance_before.py: the state packed, copied and
    # allocated at every call), for the before/after ratio of the host work.
    contenders = (["gpu", "gpu_host_main"] + (["gpu_main"] if args.with_a875246 else [])
                  + (["gpu_before"] if args.with_93ccc3a else [])
                  if gpu else []) + ["cpu_all", "cpu_1"]
    all_threads = numba.config.NUMBA_NUM_THREADS
    # Compile every contender's kernels first (numba compiles the parallel
    # CPU kernel once per process, and the GPU kernel once per process).
    W = section_points(hh, 512, seed=1)
    res["compile_s"] = {}
    for c in list(contenders):
        numba.set_num_threads(1 if c == "cpu_1" else all_threads)
        kw = dict(t_end=t_end, progress=False,
                  **({"backend": "cuda"} if c.startswith("gpu") else {}))
        try:
            with call_of(c):
                res["compile_s"][c] = timed(lambda kw=kw: varint.chaos_map(hh, W, "fli",
                                                                           **kw))[0]
        except Exception as exc:   # this contender cannot run; the others still do
            res["errors"].append(f"{c} warm-up: {exc!r}")
            contenders.remove(c)
    numba.set_num_threads(all_threads)
    save("compiled")
    log("warm-up (compilation) seconds", res["compile_s"])
    from varint.gpu.advance import STATS

    for m in sizes:
        if late():
            res["errors"].append(f"speed at {m}: not run (deadline)")
            continue
        X = section_points(hh, m)
        row = {"orbits": m, "t_end": t_end}
        values = {}
        res["speed"].append(row)
        for c in contenders:
            if (c == "cpu_1" and m > args.cpu1_max and not args.quick) or late():
                continue
            kw = dict(t_end=t_end, progress=False, chunk_size=m)
            if c.startswith("gpu"):
                kw["backend"] = "cuda"
            numba.set_num_threads(1 if c == "cpu_1" else all_threads)
            best = np.inf
            try:
                # One run at the largest sizes (seconds each), else the
                # minimum of two.
                for _ in range(1 if m >= 1_000_000 else 2):
                    STATS.update(launches=0, kernel_s=0.0, host_s=0.0)
                    # The GPU map's stages (timers around the host's
                    # functions and in the GPU calls: gpu_stages.py).
                    with call_of(c), (staged() if c in ("gpu", "gpu_main", "gpu_host_main")
                                      else contextlib.nullcontext({})) as stages:
                        dt, r = timed(lambda kw=kw, X=X: varint.chaos_map(hh, X, "fli", **kw))
                    if dt < best:
                        best, stats, best_stages = dt, dict(STATS), stages
                    values[c] = r.values
            except Exception as exc:
                res["errors"].append(f"{c} at {m}: {exc!r}")
                continue
            finally:
                numba.set_num_threads(all_threads)
            row[f"{c}_s"] = best
            row[f"{c}_orbits_per_s"] = m / best
            if c == "gpu_main":
                row["gpu_main_host_s"] = stats["host_s"]
                row["gpu_main_stages"] = best_stages
                log(f"GPU map of {m} orbits with main a875246's GPU call, by stage:\n"
                    + describe(best_stages))
                if "gpu_s" in row:
                    row["gpu_over_main"] = best / row["gpu_s"]
                if "gpu" in values:
                    row["gpu_same_as_main"] = bool(np.array_equal(
                        values["gpu"], values["gpu_main"], equal_nan=True))
            if c == "gpu_host_main":
                row["gpu_host_main_stages"] = best_stages
                log(f"GPU map of {m} orbits with main 7b2b6c8's host functions, by stage:\n"
                    + describe(best_stages))
                if "gpu_s" in row:
                    row["gpu_over_host_main"] = best / row["gpu_s"]
                if "gpu" in values:
                    row["gpu_same_as_host_main"] = bool(np.array_equal(
                        values["gpu"], values["gpu_host_main"], equal_nan=True))
            if c == "gpu_before":
                row["gpu_before_launches"] = stats["launches"]
                row["gpu_before_host_s"] = stats["host_s"]
                if "gpu_s" in row:
                    row["gpu_over_before"] = best / row["gpu_s"]
                if "gpu" in values:
                    row["gpu_same_as_before"] = bool(np.array_equal(
                        values["gpu"], values["gpu_before"], equal_nan=True))
            if c == "gpu":
                steps = float(np.round(r.t_stop / r.accuracy.tau).sum())
                row["gpu_steps"], row["tau"] = steps, r.accuracy.tau
                row["gpu_launches"] = stats["launches"]
                row["gpu_kernel_s"], row["gpu_host_s"] = stats["kernel_s"], stats["host_s"]
                row["gpu_stages"] = best_stages
                log(f"GPU map of {m} orbits, by stage:\n" + describe(best_stages))
                if isinstance(res["gpu"], dict):
                    rate = flops * steps / best / 1e12
                    row["gpu_tflops"] = rate
                    row["gpu_fraction_of_peak"] = rate / res["gpu"]["peak_fp64_tflops"]
                    kernel = flops * steps / max(stats["kernel_s"], 1e-9) / 1e12
                    row["kernel_tflops"] = kernel
                    row["kernel_fraction_of_peak"] = kernel / res["gpu"]["peak_fp64_tflops"]
            if "gpu_s" in row and "cpu_all_s" in row:
                row["gpu_over_cpu_all"] = row["cpu_all_s"] / row["gpu_s"]
                # A projection, not a measurement: the ratio if the host's
                # work took no time (the device's kernel and energies only).
                device_s = row["gpu_kernel_s"] + row["gpu_stages"].get("gpu: energy", 0.0)
                row["projected_device_only_over_cpu_all"] = row["cpu_all_s"] / device_s
            if "gpu_s" in row and "cpu_1_s" in row:
                row["gpu_over_cpu_1"] = row["cpu_1_s"] / row["gpu_s"]
            save(f"speed {m} {c}")
            log(json.dumps(row))
    # Ratios from orbits per second: against all cores at each size, against
    # one core from its rate at the largest size it ran (flat in the size).
    one = [r["cpu_1_orbits_per_s"] for r in res["speed"] if "cpu_1_orbits_per_s" in r]
    for r in res["speed"]:
        if "gpu_orbits_per_s" in r and one and "gpu_over_cpu_1" not in r:
            r["gpu_over_cpu_1_rate"] = r["gpu_orbits_per_s"] / one[0]
    save("speed")

    # 2. Agreement: Hénon–Heiles FLI (the speed test's kernel), its first
    # differing step, then SALI, MEGNO and Toda, while the deadline allows.
    n_grid, t_agree = (4, 5.0) if args.quick else (16, 100.0)
    grid = varint.section_grid(hh, ENERGY, np.linspace(-0.45, 0.7, n_grid),
                               np.linspace(-0.45, 0.45, n_grid)).states
    backends = ["cuda"] if gpu else []
    taus = {}

    def agree(ind):
        # FLI with the map defaults (its kernel is the speed test's); SALI
        # and MEGNO with the paper's SBAB2C at τ = 0.05.
        kw = dict(t_end=t_agree, progress=False)
        if ind != "fli":
            kw.update(tau=0.05, scheme="SBAB2C")
        cpu = varint.chaos_map(hh, grid, ind, **kw)
        taus[ind] = cpu.accuracy.tau
        for b in backends:
            got = varint.chaos_map(hh, grid, ind, backend=b, **kw)
            res["agreement"][f"hh_{ind}"] = compare(cpu, got)
            if ind == "fli":
                try:
                    tight = varint.chaos_map(hh, grid, ind, tau=cpu.accuracy.tau / 4, **kw)
                    ok = np.isfinite(tight.values) & np.isfinite(got.values)
                    res["agreement"]["hh_fli_vs_tau/4_max_abs"] = float(
                        np.max(np.abs(tight.values[ok] - got.values[ok])))
                    ok = ok & np.isfinite(cpu.values)
                    res["agreement"]["hh_fli_cpu_vs_tau/4_max_abs"] = float(
                        np.max(np.abs(tight.values[ok] - cpu.values[ok])))
                except Exception as exc:
                    res["errors"].append(f"tight reference: {exc!r}")

    def agree_early():
        # Early stopping (SALI's default threshold, t = 500 so that chaotic
        # orbits decide): the decided orbits are dropped on the device
        # (varint.gpu.resident); the same bits as the CPU's map.
        from varint.gpu.resident import STAGES

        # (55 of the grid's 180 orbits decide by t = 500; the dry run's few
        # with a looser threshold.)
        kw = dict(t_end=500.0, tau=0.05, scheme="SBAB2C", progress=False)
        if args.quick:
            kw.update(t_end=100.0, threshold=1e-2)
        cpu = varint.chaos_map(hh, grid, "sali", **kw)
        before = dict(STAGES)
        got = varint.chaos_map(hh, grid, "sali", backend="cuda", **kw)
        res["agreement"]["hh_sali_early_stopping"] = compare(cpu, got)
        res["agreement"]["hh_sali_early_stopping_decided"] = int((cpu.status == -1).sum())
        res["agreement"]["hh_sali_early_stopping_calls"] = {
            key: STAGES[key] - before[key] for key in ("uploads", "compactions", "launches")}

    def agree_toda():
        T = np.array([[0.0, 0.0, 0.35, 0.25], [0.1, -0.1, 0.3, 0.3], [0.0, 0.2, 0.4, 0.1],
                      [0.05, 0.05, 0.2, 0.4]])
        kw = dict(t_end=100.0, tau=0.05, threshold=None, progress=False)
        res["agreement"]["toda_fli_t100"] = compare(varint.chaos_map(toda(), T, "fli", **kw),
                                                    varint.chaos_map(toda(), T, "fli",
                                                                     backend="cuda", **kw))

    def difference():
        res["difference"] = {"primitives": gpu_difference.primitives(
            300 if args.quick else 1_000_000)}
        save()
        tau = taus.get("fli") or varint.chaos_map(hh, grid, "fli", t_end=t_agree,
                                                  progress=False).accuracy.tau
        res["difference"]["first_step"] = gpu_difference.first_step(
            hh, grid, tau, int(round(t_agree / tau)))

    for name, check in (("fli", lambda: agree("fli")), ("difference", difference),
                        ("sali", lambda: agree("sali")), ("megno", lambda: agree("megno")),
                        ("early stopping", agree_early), ("toda", agree_toda)):
        if not gpu or late():
            res["errors"].append(f"agreement {name}: not run (deadline or no GPU)")
            continue
        try:
            check()
        except Exception as exc:   # e.g. the kernel does not compile: the rest still runs
            res["errors"].append(f"agreement {name}: {exc!r}")
        save(f"agreement {name}")
        log(name, json.dumps(res["difference"] if name == "difference" else res["agreement"],
                             default=str)[:3000])
    res["machine"]["load_after"] = os.getloadavg()
    save("end")
    text = table(res)
    (args.out / "bench_gpu.md").write_text(text)
    log(text)
    return res


if __name__ == "__main__":
    main()

"""One device run of the GPU study: ``studies/bench_gpu.py``, then the PTX of
every kernel it launched and a profile of one GPU map, all under one clock.

Run on a machine with a CUDA GPU, from a copy of the repository::

    OUT=dir python studies/gpu_device_run.py [--budget S] [--deadline S] [--sizes M,...]
                                            [--quick]

(the defaults fit ~300 s on an H100 host: agreement of the FLI map, speed at
1e4, 1e5 and 1e6 orbits, the other agreement checks, then the profile;
``--quick`` with ``NUMBA_ENABLE_CUDASIM=1`` is a dry run on the simulator)

Writes to ``$OUT``: ``bench_gpu.json``/``.md`` (the benchmark), ``ptx.json``
(per kernel: counts of the FP64 instructions whose rounding decides bitwise
agreement with the CPU — ``fma.rn``, ``mul``, ``add``, ``div.rn`` against
``div.approx``/``div.full``, ``sqrt.rn`` against ``sqrt.approx``), one
kernel's ``kernel.ptx``, and ``profile.txt`` (cProfile of the FLI map of
1e5 orbits on the GPU, by cumulative time: where the map's time goes
besides the kernel).
"""

from __future__ import annotations

import argparse
import cProfile
import io
import json
import os
import pstats
import re
import sys
import time
from pathlib import Path

import numpy as np

START = time.perf_counter()
HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

# numba-cuda 0.30 registers numpy functions that numpy 2.5 removed; it
# only needs the names to exist.
for _old, _new in (("row_stack", "vstack"), ("trapz", "trapezoid"), ("in1d", "isin")):
    if not hasattr(np, _old):
        setattr(np, _old, getattr(np, _new))

from studies import bench_gpu  # noqa: E402
from varint.gpu import device  # noqa: E402

PATTERNS = {"fma.rn.f64": r"\bfma\.rn\.f64", "mul.f64": r"\bmul(\.rn)?\.f64",
            "add.f64": r"\badd(\.rn)?\.f64", "sub.f64": r"\bsub(\.rn)?\.f64",
            "div.rn.f64": r"\bdiv\.rn\.f64", "div.approx/full": r"\bdiv\.(approx|full)",
            "sqrt.rn.f64": r"\bsqrt\.rn\.f64", "sqrt.approx": r"\bsqrt\.approx",
            "rcp.approx": r"\brcp\.approx", "ex2/lg2.approx": r"\b(ex2|lg2)\.approx"}


def main(argv=None):
    p = argparse.ArgumentParser()
    p.add_argument("--budget", type=float, default=150.0,
                   help="seconds for the benchmark's speed part")
    p.add_argument("--deadline", type=float, default=240.0,
                   help="seconds from the start after which no optional part begins")
    p.add_argument("--sizes", default="10000,100000,1000000")
    p.add_argument("--quick", action="store_true")
    p.add_argument("--skip-bench", action="store_true",
                   help="only the profile and the PTX (the benchmark measured before)")
    args = p.parse_args(argv)
    out = Path(os.environ.get("OUT", "gpu_device_out"))
    out.mkdir(parents=True, exist_ok=True)

    launched = {}
    original = device._Kernel.launch

    def launch(self, n_threads, *a):
        launched[id(self)] = self
        return original(self, n_threads, *a)

    device._Kernel.launch = launch
    argv = ["--out", str(out), "--budget", str(args.budget), "--sizes", args.sizes,
            "--deadline", str(args.deadline - (time.perf_counter() - START))] + (
        ["--quick"] if args.quick else [])
    try:
        if not args.skip_bench:
            bench_gpu.main(argv)
    except Exception as exc:   # keep going: the PTX and profile still tell something
        print("bench_gpu failed:", repr(exc), flush=True)

    if time.perf_counter() - START > args.deadline or not device.available() \
            or device.simulated():
        print("no time (or no GPU) for the profile", flush=True)
        return
    import varint
    from varint.gpu.advance import STATS
    from varint.models import HenonHeiles

    hh = HenonHeiles()
    m = 2000 if args.quick else 100_000
    X = bench_gpu.section_points(hh, m)
    # Compilation (the kernel, the pilot's CPU stepper) is not the map's time.
    varint.chaos_map(hh, X[:512], "fli", t_end=1000.0, progress=False, backend="cuda")
    STATS.update(launches=0, kernel_s=0.0, host_s=0.0)
    prof = cProfile.Profile()
    t = time.perf_counter()
    prof.enable()
    varint.chaos_map(hh, X, "fli", t_end=1000.0, progress=False, chunk_size=m,
                     backend="cuda")
    prof.disable()
    total = time.perf_counter() - t
    s = io.StringIO()
    s.write(f"FLI map of {m} orbits on the GPU, t = 1e3: {total:.3f} s; "
            f"launches/kernel/host-in-advance: {json.dumps(STATS)}\n\n")
    pstats.Stats(prof, stream=s).sort_stats("cumulative").print_stats(45)
    pstats.Stats(prof, stream=s).sort_stats("tottime").print_stats(25)
    (out / "profile.txt").write_text(s.getvalue())
    print(s.getvalue()[:6000], flush=True)
    summary = []
    for k in launched.values():
        for sig, ptx in k.dispatcher.inspect_asm().items():
            counts = {name: len(re.findall(rx, ptx)) for name, rx in PATTERNS.items()}
            summary.append({"signature": str(sig), "ptx_lines": ptx.count("\n"), **counts})
            if not (out / "kernel.ptx").exists():
                (out / "kernel.ptx").write_text(ptx)
    (out / "ptx.json").write_text(json.dumps(summary, indent=1))
    print("PTX:", json.dumps(summary), flush=True)

    print(f"total {time.perf_counter() - START:.1f} s", flush=True)


if __name__ == "__main__":
    main()

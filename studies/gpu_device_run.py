"""One device run of the GPU study: ``studies/bench_gpu.py`` (speed at 1e6
orbits first, then 1e5, then agreement and where the GPU first departs from
the CPU), then the PTX of every kernel it launched and, while time is left,
a profile of one GPU map, all under one clock.

Run on a machine with a CUDA GPU and numba-cuda, from a copy of the
repository. The device lacks ``platformdirs`` (which ``varint.cachedir``
imports): carry its wheel in an ignored folder (``.gpurun/whl``) and put
the unpacked wheel on ``PYTHONPATH``::

    python -m zipfile -e .gpurun/whl/platformdirs-*.whl /tmp/pd && \
    PYTHONPATH=/tmp/pd:. VARINT_CACHE_DIR=/tmp/varint-cache timeout 330 \
    python studies/gpu_device_run.py --deadline 270

(``--deadline``: seconds from the start after which no further part
begins; ``--sizes`` the speed part's orbits, measured in that order;
``--quick`` with ``NUMBA_ENABLE_CUDASIM=1`` is a dry run on the simulator)

Writes to ``$OUT`` as it goes: ``bench_gpu.json`` (after every measurement:
per size the GPU map's time by stage — validation, seeds, snapshot arrays,
records, energy errors, assembly and, inside the GPU calls, buffer
allocation, packing, copies each way, compaction, kernel, the snapshots'
energies, writing back — and the same map with main 7b2b6c8's host
functions of the map, ``studies/gpu_host_main.py``, for the before/after
ratio;
and, stated as a projection, the ratio to all CPU cores if the host's work
took no time) and ``bench_gpu.md`` (the benchmark), ``ptx.json`` (per kernel: counts of
the FP64 instructions whose rounding decides bitwise agreement with the
CPU — ``fma.rn``; ``mul``, ``add``, ``sub`` with ``.rn``, which ptxas
never fuses, and without it, which it may; ``div.rn`` against
``div.approx``/``div.full``, ``rcp.rn`` against ``rcp.approx``,
``sqrt.rn`` against ``sqrt.approx``), one kernel's ``kernel.ptx``,
``ptx_lto.json`` (the FLI kernel's counts as NVVM writes it and as
nvJitLink rewrites it under link-time optimisation), ``gpu_energy.json``
(the device's energies against the host's, ``studies/gpu_energy.py``), and
``profile.txt`` (cProfile of the FLI map of 1e5 orbits on the GPU, by
cumulative time: where the map's time goes besides the kernel).
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

PATTERNS = {"fma.rn.f64": r"\bfma\.rn\.f64", "mul.rn.f64": r"\bmul\.rn\.f64",
            "add.rn.f64": r"\badd\.rn\.f64", "sub.rn.f64": r"\bsub\.rn\.f64",
            "mul/add/sub.f64 (fusable)": r"\b(mul|add|sub)\.f64",
            "div.rn.f64": r"\bdiv\.rn\.f64", "div.approx/full": r"\bdiv\.(approx|full)",
            "rcp.rn.f64": r"\brcp\.rn\.f64", "sqrt.rn.f64": r"\bsqrt\.rn\.f64",
            "sqrt.approx": r"\bsqrt\.approx", "rcp.approx": r"\brcp\.approx",
            "ex2/lg2.approx": r"\b(ex2|lg2)\.approx"}


def device_cc():
    from numba import cuda

    return cuda.get_current_device().compute_capability


def main(argv=None):
    p = argparse.ArgumentParser()
    p.add_argument("--deadline", type=float, default=270.0,
                   help="seconds from the start after which no further part begins")
    p.add_argument("--sizes", default="1000000,100000")
    p.add_argument("--quick", action="store_true")
    p.add_argument("--skip-bench", action="store_true",
                   help="only the PTX and the profile (the benchmark measured before)")
    args = p.parse_args(argv)
    out = Path(os.environ.get("OUT", "gpu_device_out"))
    out.mkdir(parents=True, exist_ok=True)

    launched = {}
    original = device._Kernel.launch

    def launch(self, n_threads, *a):
        launched[id(self)] = self
        return original(self, n_threads, *a)

    device._Kernel.launch = launch
    argv = ["--out", str(out), "--sizes", args.sizes,
            "--deadline", str(args.deadline - (time.perf_counter() - START))] + (
        ["--quick"] if args.quick else [])
    try:
        if not args.skip_bench:
            bench_gpu.main(argv)
    except Exception as exc:   # keep going: the PTX and profile still tell something
        print("bench_gpu failed:", repr(exc), flush=True)

    if not device.available() or device.simulated():
        print("no GPU: no PTX or profile", flush=True)
        return
    try:   # the device's energies against the host's (issue 33): seconds
        from studies import gpu_energy

        gpu_energy.main(["--out", str(out / "gpu_energy")])
    except Exception as exc:
        print("gpu_energy failed:", repr(exc), flush=True)
    # The PTX of what ran (seconds: compiled already).
    summary = []
    for k in launched.values():
        for sig, ptx in k.dispatcher.inspect_asm().items():
            counts = {name: len(re.findall(rx, ptx)) for name, rx in PATTERNS.items()}
            summary.append({"signature": str(sig), "ptx_lines": ptx.count("\n"), **counts})
            if not (out / "kernel.ptx").exists():
                (out / "kernel.ptx").write_text(ptx)
    (out / "ptx.json").write_text(json.dumps(summary, indent=1))
    print("PTX:", json.dumps(summary), flush=True)
    try:   # the FLI kernel's PTX before and after nvJitLink's link-time optimisation
        from studies import gpu_difference

        lto = gpu_difference.linked_ptx(tuple(device_cc()))
        (out / "ptx_lto.json").write_text(json.dumps(lto, indent=1))
        print("PTX with and without LTO:", json.dumps(lto), flush=True)
    except Exception as exc:
        print("PTX with LTO failed:", repr(exc), flush=True)
    if time.perf_counter() - START > args.deadline:
        print("no time for the profile", flush=True)
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
    print(f"total {time.perf_counter() - START:.1f} s", flush=True)


if __name__ == "__main__":
    main()

"""Study: where the GPU's chaos map first departs from the CPU's (issue 33).

On an H100 the Hénon–Heiles FLI map differed from the CPU's by 1.03e-11
relative at t = 100 (``results/bench_gpu_h100.md``), with libdevice's log
and with varint's own logarithm alike, while on numba's CUDA simulator (the
same generated source run as Python) the two are bitwise. The kernel's PTX
(compiled here without a GPU) rounds every operation: ``mul.rn``,
``add.rn``, ``sub.rn`` (ptxas does not fuse those), ``fma.rn`` only where
the source writes ``fma``, ``div.rn``, ``rcp.rn``, ``sqrt.rn``. So the
difference must be found on the device, in two parts:

1. :func:`primitives`: every operation the FLI kernel uses, on the device
   and on the host, over a million operands of all magnitudes (a product
   and a sum rounded apart, ``fma``, division, reciprocal, √, the sum of
   squares of a norm, varint's ``vlog``, int → float): the count of
   operands whose bits differ, and the first few, for the kernel compiled
   as varint compiles its kernels and as numba-cuda does by default
   (linked with link-time optimisation where nvJitLink is installed, which
   fuses products and sums on its own: ``results/gpu_lto_ptx.json``, the
   cause found, :mod:`varint.gpu.device`). Zero everywhere means the
   device computes what the source says.
2. :func:`first_step`: the map's orbits (x0 and seeded vectors as
   ``chaos_map`` draws them, its scheme, τ and renormalisation) advanced by
   the TM propagator on the CPU and on the GPU in one call each, with the
   state copied at every step: the first step at which any orbit differs,
   which quantities differ there (the orbit, the vectors, the growth, the
   FLI accumulator), both values in hex for the first orbits, and the
   count of orbits that differ at the end. A difference first in the
   orbit's coordinates is the drift/kick arithmetic; first in the growth
   or the accumulator, the renormalisation.

Run alone: ``python studies/gpu_difference.py [--quick] [--out DIR]``
(``--quick`` with ``NUMBA_ENABLE_CUDASIM=1`` is a dry run); writes
``gpu_difference.json``. ``--ptx`` (NVVM and nvJitLink needed, not a GPU)
writes ``gpu_lto_ptx.json``: the FLI kernel's operation counts as NVVM
writes it and as nvJitLink rewrites it (:func:`linked_ptx`). ``studies/bench_gpu.py`` runs it after its speed
and agreement parts.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
if str(HERE.parent) not in sys.path:
    sys.path.insert(0, str(HERE.parent))

#: The Hénon–Heiles energy of the maps compared (the paper's, H = 1/8);
#: ``bench_gpu`` maps the same section.
ENERGY = 0.125

#: The primitives' kernel: one operand triple per thread, one row of
#: ``out`` per operation (the names of :data:`OPS`, in order).
_PRIMITIVES = '''
def primitives(a, b, c, n, out):
    i = cuda.grid(1)
    if i >= a.shape[0]:
        return
    x = a[i]
    y = b[i]
    z = c[i]
    out[0, i] = x * y + z
    out[1, i] = fma(x, y, z)
    out[2, i] = x / y
    out[3, i] = 1.0 / y
    out[4, i] = math.sqrt(abs(x))
    out[5, i] = math.sqrt(x * x + y * y + z * z + x * z)
    out[6, i] = vlog(abs(x))
    out[7, i] = float(n[i]) * 0.6931471805599453
    out[8, i] = 2 * x * y + x
'''
OPS = ("x*y+z", "fma", "x/y", "1/y", "sqrt|x|", "sqrt(norm2)", "vlog|x|", "float(n)*ln2",
       "2*x*y+x")


def _hex(v):
    return float(v).hex()


def operands(m, seed=0):
    """``m`` operand triples of every magnitude (2**-60 … 2**60, both signs)
    and integers for the conversion."""
    rng = np.random.default_rng(seed)

    def wide():
        return rng.choice([-1.0, 1.0], m) * np.exp2(rng.uniform(-60, 60, m)) * \
            rng.uniform(1, 2, m)

    a, b, c = wide(), wide(), wide()
    # A third of them of one scale, where sums cancel (a step's arithmetic).
    third = m // 3
    a[:third], b[:third], c[:third] = (rng.uniform(-1, 1, (3, third)))
    n = rng.integers(-2000, 2000, m).astype(np.int64)
    return a, b, c, n


def _host(a, b, c, n):
    """The same operations on the CPU (numpy, and numba for fma and vlog)."""
    from numba import njit

    from varint.kernels.fma import fma
    from varint.kernels.logarithm import vlog

    @njit
    def fused(a, b, c):
        out = np.empty((2, a.shape[0]))
        for i in range(a.shape[0]):
            out[0, i] = fma(a[i], b[i], c[i])
            out[1, i] = vlog(abs(a[i]))
        return out

    f = fused(a, b, c)
    return np.stack([a * b + c, f[0], a / b, 1.0 / b, np.sqrt(np.abs(a)),
                     np.sqrt(a * a + b * b + c * c + a * c), f[1], n * 0.6931471805599453,
                     2 * a * b + a])


def primitives(m=1_000_000, seed=0):
    """Each operation of :data:`OPS` on the device and on the host: per way
    of compiling the kernel, the count of operands whose bits differ and
    the first three of them. ``varint``: as varint compiles its kernels
    (:func:`varint.gpu.device.kernel`: NVVM without contraction, no
    link-time optimisation); ``lto``: the same with numba-cuda's default
    linking (link-time optimisation by nvJitLink where it is installed,
    which contracts a·b + c on its own)."""
    from numba import cuda

    from varint.gpu import device, emit
    from varint.kernels.logarithm import SOURCE as LOG_SOURCE

    source = "import math\n\n@cuda.jit(device=True)\n" + LOG_SOURCE + _PRIMITIVES
    if not device.simulated():
        source = emit._FMA.sub("cuda.fma(", source)
    a, b, c, n = operands(m, seed)
    want = _host(a, b, c, n)
    res = {}
    for way in ("varint", "lto"):
        scope = dict(device.kernel_globals(), math=math)
        exec(compile(source, f"<gpu_difference.primitives.{way}>", "exec"), scope)
        if way == "varint":
            kernel = device.kernel(scope["primitives"])
        else:
            kernel = device._Kernel(cuda.jit(scope["primitives"]))
        out = cuda.device_array((len(OPS), m))
        kernel.launch(m, cuda.to_device(a), cuda.to_device(b), cuda.to_device(c),
                      cuda.to_device(n), out)
        got = out.copy_to_host()
        res[way] = {}
        for j, name in enumerate(OPS):
            bad = np.flatnonzero(got[j].view(np.int64) != want[j].view(np.int64))
            res[way][name] = {"differ": int(bad.size), "of": m,
                              "first": [{"a": _hex(a[i]), "b": _hex(b[i]), "c": _hex(c[i]),
                                         "device": _hex(got[j, i]), "host": _hex(want[j, i])}
                                        for i in bad[:3]]}
    return res


def first_step(model, X, tau, n_steps, seed=0):
    """The FLI map's propagation of orbits ``X`` on the CPU and on the GPU,
    copied at every step: the first step where they differ and what
    differs there (see the module docstring)."""
    from varint.indicators.megno import FLI_ACCUMULATOR
    from varint.maps import MAP_SCHEME
    from varint.methods import make_propagator
    from varint.state import RunState, initial_deviations

    acc = FLI_ACCUMULATOR
    X = np.asarray(X, dtype=float)
    W0 = initial_deviations(X.shape[1], 1, len(X), seed)
    runs = {}
    for backend in ("cpu", "cuda"):
        prop = make_propagator("tm", model, tau, "normalize", acc, scheme=MAP_SCHEME,
                               backend=backend)
        state = RunState.start(X, W0)
        state.extra[acc.key] = np.tile(np.array(acc.initial, dtype=np.float64),
                                       (state.n_orbits, state.k, 1))
        snaps = prop.advance(state, n_steps, outputs=np.arange(1, n_steps + 1))
        runs[backend] = {"x": snaps.x, "W": snaps.W, "acc_m": snaps.acc_m,
                         "acc_e": snaps.acc_e, "aux": snaps.extra[acc.key]}
    cpu, gpu = runs["cpu"], runs["cuda"]
    differs = {}
    for key in cpu:
        a, b = cpu[key], gpu[key]
        ne = ~((a == b) | (np.isnan(a) & np.isnan(b))) if a.dtype.kind == "f" else a != b
        differs[key] = ne.reshape(ne.shape[0], ne.shape[1], -1).any(axis=2)   # (steps, M)
    any_step = np.any(np.stack([d for d in differs.values()]), axis=(0, 2))
    res = {"orbits": len(X), "steps": n_steps, "tau": tau,
           "orbits_differing_at_end": int(np.stack([d[-1] for d in differs.values()])
                                          .any(axis=0).sum())}
    if not any_step.any():
        res["first_step"] = None
        return res
    s = int(np.argmax(any_step))
    res["first_step"] = s + 1
    res["at_first_step"] = {key: int(d[s].sum()) for key, d in differs.items()}
    rows = np.flatnonzero(np.stack([d[s] for d in differs.values()]).any(axis=0))[:3]
    res["examples"] = []
    for m in rows:
        ex = {"orbit": int(m)}
        for key in cpu:
            if differs[key][s, m]:
                ex[key] = {"cpu": [_hex(v) for v in np.ravel(cpu[key][s, m])],
                           "gpu": [_hex(v) for v in np.ravel(gpu[key][s, m])],
                           "cpu_before": [_hex(v) for v in np.ravel(cpu[key][s - 1, m])]
                           if s else None}
        res["examples"].append(ex)
    return res


def linked_ptx(cc=(9, 0)):
    """Counts of the FP64 operations in the Hénon–Heiles FLI kernel's PTX
    as NVVM writes it (``-fma=0``) and as nvJitLink rewrites it when the
    kernel is linked with link-time optimisation (numba-cuda's default
    where nvJitLink is installed). Needs NVVM and nvJitLink, not a GPU:
    without one, numba-cuda's questions to the driver (the device's compute
    capability, binding the linked kernel) are answered for ``cc``."""
    import re
    import types as pytypes

    import numba.cuda.codegen as codegen
    import numba.cuda.dispatcher as dispatcher
    from numba import cuda
    from numba import types as T

    from varint.gpu import device, emit
    from varint.indicators.megno import FLI_ACCUMULATOR
    from varint.maps import MAP_SCHEME
    from varint.models import HenonHeiles
    from varint.schemes import DRIFT, get_scheme, stage_arrays

    if not device.available():
        fake = pytypes.SimpleNamespace(device=pytypes.SimpleNamespace(compute_capability=cc))
        codegen.devices.get_context = lambda *a: fake
        dispatcher.get_current_device = lambda: fake.device
        dispatcher._Kernel.bind = lambda self: None
    kinds, _, hc = stage_arrays(get_scheme(MAP_SCHEME), 0.05)
    kern = emit.cuda_stepper(HenonHeiles(), kinds, (hc != 0) & (kinds != DRIFT), 1,
                             FLI_ACCUMULATOR)
    f2, f3, f4 = T.float64[:, ::1], T.float64[:, :, ::1], T.float64[:, :, :, ::1]
    i1, i2, i3 = T.int64[::1], T.int64[:, ::1], T.int64[:, :, ::1]
    sig = (f2, f3, f2, i2, i1, i1, i1, i1, T.int64, T.int64, T.float64, T.float64[::1],
           T.float64[::1], T.float64, T.int64, T.int64, f3, i1, f3, f4, f3, i3, f4)

    def counts(ptx):
        return {op: len(re.findall(rx, ptx)) for op, rx in (
            ("fma.rn.f64", r"\bfma\.rn\.f64"), ("mul.rn.f64", r"\bmul\.rn\.f64"),
            ("add.rn.f64", r"\badd\.rn\.f64"), ("sub.rn.f64", r"\bsub\.rn\.f64"),
            ("mul/add/sub.f64 (fusable)", r"\b(mul|add|sub)\.f64"))}

    lto = cuda.jit(kern.dispatcher.py_func, lto=True)
    with device._no_contraction():
        kern.dispatcher.compile(sig)
        lto.compile(sig)
        from importlib.metadata import version

        from numba.cuda.cudadrv import nvvm

        return {"kernel": f"Hénon–Heiles FLI, {MAP_SCHEME}", "cc": list(cc),
                "numba_cuda": version("numba-cuda"), "nvvm": list(nvvm.NVVM().get_version()),
                "varint (NVVM -fma=0, no LTO)": counts(kern.dispatcher.inspect_asm(sig)),
                "LTO: NVVM's PTX": counts(lto.inspect_asm(sig)),
                "LTO: nvJitLink's PTX (what runs)": counts(lto.inspect_lto_ptx(sig))}


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="small sizes (the simulator)")
    p.add_argument("--out", type=Path, default=HERE / "results")
    p.add_argument("--ptx", action="store_true",
                   help="only the FLI kernel's PTX before and after nvJitLink's link-time "
                        "optimisation (no GPU needed): gpu_lto_ptx.json")
    args = p.parse_args(argv)
    if args.ptx:
        res = linked_ptx()
        print(json.dumps(res, indent=1))
        args.out.mkdir(parents=True, exist_ok=True)
        (args.out / "gpu_lto_ptx.json").write_text(json.dumps(res, indent=1) + "\n")
        return res
    import varint
    from varint.models import HenonHeiles

    hh = HenonHeiles()
    n_grid, t_end = (4, 5.0) if args.quick else (16, 100.0)
    grid = varint.section_grid(hh, ENERGY, np.linspace(-0.45, 0.7, n_grid),
                               np.linspace(-0.45, 0.45, n_grid)).states
    res = {"primitives": primitives(300 if args.quick else 1_000_000)}
    print(json.dumps(res["primitives"]), flush=True)
    # The map's τ (its pilot's choice at this horizon, on the CPU).
    tau = varint.chaos_map(hh, grid, "fli", t_end=t_end, progress=False).accuracy.tau
    res["first_step"] = first_step(hh, grid, tau, int(round(t_end / tau)))
    print(json.dumps(res["first_step"]), flush=True)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "gpu_difference.json").write_text(json.dumps(res, indent=1))
    return res


if __name__ == "__main__":
    main()

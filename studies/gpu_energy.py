"""The energies computed on the device (``varint.gpu.energy``) against the
host's: how far the energy errors of a GPU map are from the CPU's, and
whether the accuracy verdicts agree (issue 33).

    NUMBA_ENABLE_CUDASIM=1 python studies/gpu_energy.py \
        [--out studies/results/gpu_energy_simulator]

On numba's CUDA simulator without a GPU (the kernel's source run as
Python), or on a GPU. Two parts:

1. the energy kernel alone, at states drawn uniformly from [−0.6, 0.6]⁴ (a
   polynomial potential, Hénon–Heiles; one with ``exp``, a Toda lattice;
   one with unequal masses): max |H_gpu − H_cpu| / (|T| + |V|);
2. FLI maps of random Hénon–Heiles orbits at H ≈ 0.1 (t = 100, τ = 0.05,
   with a tolerance that splits the orbits' verdicts): the largest
   difference of the energy errors (already relative to the energy scale),
   of the largest errors behind the verdicts, and whether the verdicts are
   the same; the values bitwise the CPU's.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
if str(HERE.parent) not in sys.path:
    sys.path.insert(0, str(HERE.parent))


def kernel_gaps(rng, n=2000):
    import sympy as sp
    from numba import cuda

    import varint
    from varint.gpu import energy

    q0, q1 = sp.symbols("q0 q1")
    models = {
        "henon_heiles": varint.models.HenonHeiles(),
        "toda_exp": varint.models.from_potential(
            sp.exp(q1 + 2 * sp.sqrt(3) * q0) / 24 + sp.exp(q1 - 2 * sp.sqrt(3) * q0) / 24
            + sp.exp(-2 * q1) / 24 - sp.Rational(1, 8), [q0, q1], name="toda"),
        "unequal_masses": varint.models.from_potential(
            q0 ** 4 / 4 + q0 ** 2 * q1 - q1 ** 3 / 5 + q1 ** 2 / 2, [q0, q1],
            inverse_mass=[2.0, sp.Rational(1, 3)], name="masses")}
    out = {}
    for name, model in models.items():
        S = rng.uniform(-0.6, 0.6, (2, 4, n))
        dev = cuda.device_array((2, n))
        energy.energy_kernel(model).launch(n, cuda.to_device(S), 2, dev)
        states = np.moveaxis(S, 1, 2)
        gap = np.abs(dev.copy_to_host() - model.energy(states)) / model.energy_scale(states)
        out[name] = {"states": 2 * n, "max_gap_of_scale": float(gap.max()),
                     "bitwise_share": float(np.mean(gap == 0.0))}
    return out


def map_gaps(rng, n):
    import varint

    hh = varint.models.HenonHeiles()
    X = np.zeros((n, 4))
    X[:, 1] = rng.uniform(-0.25, 0.35, n)
    X[:, 2] = rng.uniform(0.05, 0.35, n)
    X[:, 3] = rng.uniform(0.05, 0.3, n)
    kw = dict(t_end=100.0, tau=0.05, threshold=None, progress=False)
    cpu = varint.chaos_map(hh, X, "fli", **kw)
    # A tolerance at the median of the largest errors: half the orbits trusted.
    tol = float(np.median(cpu.accuracy.energy_error))
    cpu = varint.chaos_map(hh, X, "fli", energy_tol=tol, **kw)
    gpu = varint.chaos_map(hh, X, "fli", backend="cuda", energy_tol=tol, **kw)
    return {"orbits": n, "energy_tol": tol,
            "values_bitwise": bool(np.array_equal(cpu.values, gpu.values, equal_nan=True)),
            "max_gap_energy_error": float(np.nanmax(np.abs(cpu.energy_error
                                                           - gpu.energy_error))),
            "max_gap_largest_error": float(np.nanmax(np.abs(cpu.accuracy.energy_error
                                                            - gpu.accuracy.energy_error))),
            "largest_error_range": [float(cpu.accuracy.energy_error.min()),
                                    float(cpu.accuracy.energy_error.max())],
            "trusted_cpu": int(cpu.accuracy.accurate.sum()),
            "same_verdicts": bool(np.array_equal(cpu.accuracy.accurate,
                                                 gpu.accuracy.accurate))}


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--orbits", type=int, default=40)
    p.add_argument("--out", type=Path, default=None,
                   help="write OUT.json")
    args = p.parse_args(argv)
    from varint.gpu import device

    if not device.available():
        raise SystemExit("needs a CUDA GPU or NUMBA_ENABLE_CUDASIM=1")
    rng = np.random.default_rng(33)
    res = {"device": "simulator" if device.simulated() else "gpu",
           "python": platform.python_version(), "load": os.getloadavg(),
           "kernel": kernel_gaps(rng), "map": map_gaps(rng, args.orbits)}
    print(json.dumps(res, indent=1))
    if args.out is not None:
        args.out.with_suffix(".json").write_text(json.dumps(res, indent=1))


if __name__ == "__main__":
    main()

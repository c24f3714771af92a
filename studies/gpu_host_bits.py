"""Digests of every field of small GPU maps on numba's CUDA simulator (the
real kernels), to compare two source trees bit for bit (issue 33's host
part: a change to how the host reads the device's results must not change
a bit of them).

Run in each tree with fresh caches and compare the printed JSON::

    NUMBA_ENABLE_CUDASIM=1 python studies/gpu_host_bits.py > bits.json

Cases: Hénon–Heiles FLI, MEGNO and SALI maps without early stopping, a
SALI map with early stopping (orbits decided, compacted on the device,
read at their decision), and an FLI map with escapes (failed orbits
recomputed on the CPU); each on the CPU and on the (simulated) GPU.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import warnings
from pathlib import Path

HERE = Path(__file__).resolve().parent
if str(HERE.parent) not in sys.path:
    sys.path.insert(0, str(HERE.parent))

FIELDS = ("values", "t_stop", "status", "state", "energy_error")


def digests(result):
    """sha256 (16 hex digits) of each field and of the accuracy verdict's
    arrays."""
    import numpy as np

    arrays = {name: getattr(result, name) for name in FIELDS}
    arrays["accuracy.energy_error"] = result.accuracy.energy_error
    arrays["accuracy.accurate"] = result.accuracy.accurate
    for key, value in result.accuracy.conserved.items():
        arrays[f"accuracy.conserved.{key}"] = value
    return {name: hashlib.sha256(np.ascontiguousarray(a).tobytes()).hexdigest()[:16]
            for name, a in arrays.items()}


def main(argv=None):
    argparse.ArgumentParser(description=__doc__.splitlines()[0]).parse_args(argv)
    import numpy as np

    import varint
    from varint.models import HenonHeiles

    hh = HenonHeiles()
    rng = np.random.default_rng(5)
    m = 12   # above the CPU's 8 SIMD lanes
    X = np.zeros((m, 4))
    X[:, 1] = rng.uniform(-0.25, 0.35, m)
    X[:, 2] = rng.uniform(0.05, 0.35, m)
    X[:, 3] = rng.uniform(0.05, 0.3, m)
    fast = X.copy()
    fast[::3, 2:] *= 6.0   # above the escape energy
    # At H = 0.16 a chaotic orbit's SALI falls below 0.1 by t ≈ 10
    # (tests/test_gpu.py): decided orbits, read at their decision.
    y, py = rng.uniform(-0.3, 0.5, m), rng.uniform(-0.2, 0.2, m)
    px = np.sqrt(np.maximum(2 * (0.16 - (y * y / 2 - y ** 3 / 3)) - py * py, 0.0))
    C = np.column_stack([np.zeros(m), y, px, py])
    cases = {
        "fli": (X, "fli", dict(threshold=None)),
        "megno": (X, "megno", dict(threshold=None)),
        "sali": (X, "sali", dict(threshold=None)),
        "sali_early": (C, "sali", dict(threshold=0.1)),
        "fli_escape": (fast, "fli", dict(threshold=None, escape_radius=3.0)),
    }
    out = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for name, (x0, ind, kw) in cases.items():
            for backend in ("cpu", "cuda"):
                r = varint.chaos_map(hh, x0, ind, t_end=12.0, tau=0.05, progress=False,
                                     backend=backend, **kw)
                out[f"{name}/{backend}"] = digests(r)
                out[f"{name}/{backend}/failed"] = int((r.status > 0).sum())
                out[f"{name}/{backend}/decided"] = int((r.status < 0).sum())
    print(json.dumps(out, indent=1, sort_keys=True))


if __name__ == "__main__":
    main()

"""Long runs of the kernels kern18 made shareable (TDHcc and TDHeps on one
kernel, the planetary lane block shared by the serial and parallel batch,
the general Gauss–Legendre step compiled for a run-time k), on this tree
and on another (``--base``, e.g. a worktree of the commit before): the
seconds of each run, warm (its kernels compiled first), in child processes
taken in turn (base, this, base, this, …, so that the load of the shared
machine falls on both alike), the minimum of the repeats. The results'
bits are compared too (a hash of each run's numbers).

Usage: ``python studies/shared_kernels.py --base TREE [--repeats R] [--out DIR]``
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

try:
    from common import parse_args, save_json
except ImportError:  # imported as studies.shared_kernels
    from .common import parse_args, save_json

ROOT = Path(__file__).resolve().parent.parent

#: The runs, by label: the code a child runs (``model``, ``x0`` and the
#: call), timed after one call that compiles.
CASES = {
    "tdhcc HH lyapunov k=4": (
        "import varint, numpy as np; m = varint.models.HenonHeiles(); "
        "x0 = np.array([0.0, 0.1, 0.45, 0.0]); "
        "run = lambda T: varint.lyapunov_spectrum(m, x0, T, tau=0.05, method='tdhcc', "
        "n_exponents=4, progress=False)", 2e4),
    "tdheps HH lyapunov k=4": (
        "import varint, numpy as np; m = varint.models.HenonHeiles(); "
        "x0 = np.array([0.0, 0.1, 0.45, 0.0]); "
        "run = lambda T: varint.lyapunov_spectrum(m, x0, T, tau=0.05, method='tdheps', "
        "n_exponents=4, progress=False)", 1e4),
    "planetary megno map 30 orbits serial": (
        "import varint, numpy as np; from varint.models import Planetary; "
        "m = Planetary([1.0, 0.000954, 0.000285]); "
        "g = varint.element_grid(m, [dict(a=5.204, M=0.6, omega=0.257, e=0.048), "
        "dict(a=9.0, e=0.0, M=0.871, omega=1.616)], 2, np.linspace(6.5, 10.0, 6), "
        "np.linspace(0.0, 0.6, 5)); "
        "run = lambda T: varint.megno(m, g.states, T, tau=1.0, parallel=False, progress=False)",
        3e3),
    "general GL6 lyapunov k=2": (
        "import sys, varint, numpy as np; sys.path.insert(0, '.'); "
        "from tests.flows.steppers import coupled_general; m = coupled_general(); "
        "x0 = np.array([0.1, 0.05, 0.2, 0.25]); "
        "run = lambda T: varint.lyapunov_spectrum(m, x0, T, tau=0.1, scheme='GL6', "
        "n_exponents=2, progress=False)", 2e3),
    "general GL4 lyapunov k=4": (
        "import sys, varint, numpy as np; sys.path.insert(0, '.'); "
        "from tests.flows.steppers import coupled_general; m = coupled_general(); "
        "x0 = np.array([0.1, 0.05, 0.2, 0.25]); "
        "run = lambda T: varint.lyapunov_spectrum(m, x0, T, tau=0.1, scheme='GL4', "
        "n_exponents=4, progress=False)", 2e3),
}

_CHILD = """
import hashlib, json, time
import numpy as np
{setup}
run(1.0)
t0 = time.perf_counter()
r = run({t_end!r})
s = time.perf_counter() - t0
h = hashlib.sha256()
for name in ("exponents", "megno", "state", "status"):
    if hasattr(r, name):
        h.update(np.ascontiguousarray(np.asarray(getattr(r, name), dtype=float)).tobytes())
print(json.dumps({{"s": s, "hash": h.hexdigest()[:16]}}))
"""


def _child(tree, label, cache):
    """One timed run of case ``label`` in a child process on ``tree``."""
    setup, t_end = CASES[label]
    env = {**os.environ, "PYTHONPATH": str(tree), "NUMBA_CACHE_DIR": str(cache / "nc"),
           "VARINT_CACHE_DIR": str(cache / "vc")}
    out = subprocess.run([sys.executable, "-c", _CHILD.format(setup=setup, t_end=t_end)],
                         cwd=tree, env=env, capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def _extra(parser):
    parser.add_argument("--base", type=Path, required=True,
                        help="the tree to compare with (a worktree of the commit before)")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--cache", type=Path, default=Path("/tmp") / "shared_kernels_cache",
                        help="numba's and varint's caches, one folder per tree")


def main(argv=None):
    args = parse_args(__doc__.splitlines()[0], argv, extra=_extra)
    trees = {"base": args.base.resolve(), "this": ROOT}
    load_start = [round(x, 2) for x in os.getloadavg()]
    table = {}
    for label in CASES:
        seconds = {name: [] for name in trees}
        hashes = {}
        for _ in range(args.repeats):
            for name, tree in trees.items():
                r = _child(tree, label, args.cache / name)
                seconds[name].append(round(r["s"], 4))
                hashes[name] = r["hash"]
        best = {name: min(v) for name, v in seconds.items()}
        table[label] = {"seconds": seconds, "best_s": best,
                        "this_over_base": round(best["this"] / best["base"], 3),
                        "hash": hashes, "bitwise": hashes["base"] == hashes["this"]}
        print(f"{label:40s} base {best['base']:8.3f} s  this {best['this']:8.3f} s  "
              f"ratio {table[label]['this_over_base']:5.3f}  bitwise {table[label]['bitwise']}")
    load_end = [round(x, 2) for x in os.getloadavg()]
    save_json(args.out, "shared_kernels", {"cases": table, "repeats": args.repeats,
                                           "load_start": load_start, "load_end": load_end,
                                           "base": args.base.name})
    return table


if __name__ == "__main__":
    main()

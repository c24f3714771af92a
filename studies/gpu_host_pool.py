"""The snapshot buffers of :mod:`varint.gpu.host` against fresh NumPy
arrays, a process's maps one after another (issue 33's host part).

Each contender runs in fresh processes, alternating (``rounds`` each): a
256-orbit warm-up map, then ``maps`` Hénon–Heiles FLI maps of ``orbits``
orbits on numba's CUDA simulator (the kernel's launch replaced by one that
takes no step, as in ``studies/gpu_stages.py``), each map's stages in CPU
seconds. ``fresh``: ``varint.gpu.host.empty`` replaced by ``numpy.empty``
(fresh pages at every call; still no NaN fill). Stores
``studies/results/gpu23/host_pool_<orbits><tag>.json``::

    python studies/gpu_host_pool.py --orbits 100000 --rounds 2
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
if str(HERE.parent) not in sys.path:
    sys.path.insert(0, str(HERE.parent))

_CHILD = r'''
import json, sys, warnings
import numpy as np, varint
from varint.gpu import device, host
from studies import gpu_stages as gs
from varint.models import HenonHeiles
gs._REAL_LAUNCH.append(device._Kernel.launch)
device._Kernel.launch = gs._fake_launch
n, mode, maps = int(sys.argv[1]), sys.argv[2], int(sys.argv[3])
if mode == "fresh":
    host.empty = lambda shape, dtype=float: np.empty(shape, dtype)
hh = HenonHeiles()
side = int(np.ceil(np.sqrt(n * 1.6)))
X = varint.section_grid(hh, 0.125, np.linspace(-0.45, 0.7, side),
                        np.linspace(-0.45, 0.45, side)).states[:n]
warnings.simplefilter("ignore")
kw = dict(t_end=1000.0, progress=False, chunk_size=n, backend="cuda")
varint.chaos_map(hh, X[:256], "fli", **{**kw, "t_end": 2.0})
out = []
for _ in range(maps):
    with gs.staged() as st:
        varint.chaos_map(hh, X, "fli", **kw)
    out.append(st)
print(json.dumps(out))
'''


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--orbits", type=int, default=100000)
    p.add_argument("--rounds", type=int, default=2)
    p.add_argument("--maps", type=int, default=4)
    p.add_argument("--tag", default="", help="appended to the result's name")
    args = p.parse_args(argv)
    from studies.common import save_json

    env = {**os.environ, "NUMBA_ENABLE_CUDASIM": "1"}
    load = os.getloadavg()
    runs: dict = {"pool": [], "fresh": []}
    for _ in range(args.rounds):
        for mode in runs:
            out = subprocess.run([sys.executable, "-c", _CHILD, str(args.orbits), mode,
                                  str(args.maps)], cwd=HERE.parent, env=env,
                                 capture_output=True, text=True, check=True)
            runs[mode].append(json.loads(out.stdout.strip().splitlines()[-1]))
    keys = ("cpu total", "snapshot arrays", "records", "energy errors", "gpu: unpack")
    # The first map of a process allocates the buffers: the later ones.
    best = {mode: {key: min(st[key] for run in rs for st in run[1:]) for key in keys}
            for mode, rs in runs.items()}
    print(f"{args.orbits} orbits, load {load[0]:.1f} -> {os.getloadavg()[0]:.1f}; fastest "
          f"of maps 2..{args.maps} of {args.rounds} processes each (CPU s; unpack wall):")
    for key in keys:
        print(f"  {key:<16} pool {best['pool'][key]:.4f}  fresh {best['fresh'][key]:.4f}")
    save_json(HERE / "results" / "gpu23", f"host_pool_{args.orbits}{args.tag}",
              {"orbits": args.orbits, "rounds": args.rounds, "maps": args.maps, "load": load,
               "load_end": os.getloadavg(), "best_after_first_map": best, "runs": runs})


if __name__ == "__main__":
    main()

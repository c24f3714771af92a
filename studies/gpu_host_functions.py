"""The host functions of a GPU map that this round changed, timed one by
one against main 7b2b6c8's (``studies/gpu_host_main.py``), interleaved in
one process, the fastest of ``--repeats`` each (issue 33).

A map's stages (``studies/gpu_stages.py``) on a loaded machine vary by
more than these functions' gains; timed alone, each is measured where it
changed::

    python studies/gpu_host_functions.py [--orbits 100000,1000000] [--repeats 5] \
        [--out studies/results/gpu_host_functions]

Stages, each at M Hénon–Heiles states of the map's section (HH FLI map:
one deviation vector per orbit):

* ``seeded vectors``: ``initial_deviations(4, 1, M, seed, indices)``;
* ``initial energies``: what a one-chunk map computes: before, the
  reference of the map's states and again the chunk's; now, the map's and
  the chunk's rows of it (``Reference.rows``);
* ``full-rank check``: ``check.full_rank`` of the seeded vectors;
* ``validation``: ``check.kernels`` (∇V, D²V, third derivatives finite).

Every stage's results are compared bit for bit between the two.
"""

from __future__ import annotations

import argparse
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


def stages(hh, X):
    """{stage: function of no argument returning its result's bytes}."""
    from varint import _validate as check
    from varint.accuracy import Reference
    from varint.state import initial_deviations

    m = len(X)
    idx = np.arange(m)
    W = initial_deviations(hh.dim, 1, m, 11, idx)

    def energies_now():
        whole = Reference(hh, X)
        part = whole.rows(idx)
        return whole.values["energy"].tobytes() + part.scales["energy"].tobytes()

    def energies_before():
        whole = Reference(hh, X)
        part = Reference(hh, X[idx])
        return whole.values["energy"].tobytes() + part.scales["energy"].tobytes()

    return {
        "seeded vectors": (lambda: initial_deviations(hh.dim, 1, m, 11, idx).tobytes(),) * 2,
        "initial energies": (energies_before, energies_now),
        "full-rank check": (lambda: check.full_rank(W),) * 2,
        "validation": (lambda: check.kernels(hh, X),) * 2,
    }


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--orbits", default="100000,1000000")
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument("--out", type=Path, default=None)
    args = p.parse_args(argv)
    import varint
    from studies.gpu_host_main import host_of_main
    from varint.models import HenonHeiles

    hh = HenonHeiles()
    load = os.getloadavg()
    rows = []
    for m in [int(float(v)) for v in args.orbits.split(",")]:
        side = int(np.ceil(np.sqrt(m * 1.6)))
        X = varint.section_grid(hh, 0.125, np.linspace(-0.45, 0.7, side),
                                np.linspace(-0.45, 0.45, side)).states[:m]
        X = np.ascontiguousarray(X)
        for name, (before, now) in stages(hh, X).items():
            best = {"before": np.inf, "now": np.inf}
            out = {}
            for _ in range(args.repeats):
                for who, fn in (("before", before), ("now", now)):
                    with host_of_main() if who == "before" else contextlib.nullcontext():
                        t = time.perf_counter()
                        out[who] = fn()
                        best[who] = min(best[who], time.perf_counter() - t)
            rows.append({"orbits": m, "stage": name, "before_s": best["before"],
                         "now_s": best["now"], "ratio": best["before"] / best["now"],
                         "same": out["before"] == out["now"]})
            print(json.dumps(rows[-1]), flush=True)
    end = os.getloadavg()
    text = ["# A GPU map's changed host functions: main 7b2b6c8 against now", "",
            f"Each the fastest of {args.repeats}, the two interleaved in one process; "
            f"{os.cpu_count()} CPU cores, load {load[0]:.1f} at the start, {end[0]:.1f} at "
            f"the end; Python {platform.python_version()}, NumPy {np.__version__}.",
            f"`python studies/gpu_host_functions.py --orbits {args.orbits} --repeats "
            f"{args.repeats}`", "",
            "| orbits | stage | main 7b2b6c8 s | now s | before / now | same bits |",
            "|---|---|---|---|---|---|"]
    text += [f"| {r['orbits']} | {r['stage']} | {r['before_s']:.4f} | {r['now_s']:.4f} | "
             f"{r['ratio']:.2f} | {r['same']} |" for r in rows]
    print("\n".join(text))
    if args.out is not None:
        args.out.with_suffix(".json").write_text(json.dumps(
            {"load": [load, end], "repeats": args.repeats, "rows": rows}, indent=1))
        args.out.with_suffix(".md").write_text("\n".join(text) + "\n")


if __name__ == "__main__":
    main()

"""Study: the cost of varint's logarithm (``varint.kernels.logarithm.vlog``)
against the C library's ``log`` that numba calls for ``math.log``, per call
in a compiled loop (10⁶ arguments in [0.5, 3], and 10⁶ within 2 % of 1, as
the stretching factors a renormalisation takes the logarithm of),
interleaved, the minimum of repeats, in one process; and how often the two
differ (in the last place) on uniform arguments of a few ranges.

Run: ``python studies/log_cost.py [--out DIR]``; writes ``log_cost.json``
there (default ``studies/results``).
"""

from __future__ import annotations

import json
import math
import os
import sys
import time
from pathlib import Path

import numpy as np
from numba import njit

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from studies.common import parse_args, save_json  # noqa: E402
from varint.kernels.logarithm import vlog  # noqa: E402


@njit
def _libm(x):
    s = 0.0
    for v in x:
        s += math.log(v)
    return s


@njit
def _vlog(x):
    s = 0.0
    for v in x:
        s += vlog(v)
    return s


@njit
def _differ(x):
    n = 0
    for v in x:
        if vlog(v) != math.log(v):
            n += 1
    return n


def main(argv=None):
    cli = parse_args(__doc__.split("\n\n")[0], argv)
    rng = np.random.default_rng(0)
    # Wide arguments, and ones within 2 % of 1 (a renormalisation's stretching
    # over one short step: vlog's branches are then predictable).
    args = {"[0.5, 3]": rng.uniform(0.5, 3.0, 1_000_000),
            "[0.98, 1.02]": rng.uniform(0.98, 1.02, 1_000_000)}
    _libm(args["[0.5, 3]"][:8]), _vlog(args["[0.5, 3]"][:8])
    best = {(r, name): math.inf for r in args for name in ("libm", "vlog")}
    load = os.getloadavg()
    for _ in range(15):
        for r, x in args.items():
            for name, f in (("libm", _libm), ("vlog", _vlog)):
                t = time.perf_counter()
                f(x)
                best[r, name] = min(best[r, name], time.perf_counter() - t)
    res = {"ns_per_call": {r: {name: best[r, name] / len(x) * 1e9 for name in ("libm", "vlog")}
                           for r, x in args.items()},
           "vlog_over_libm": {r: best[r, "vlog"] / best[r, "libm"] for r in args}, "load": load,
           "load_end": os.getloadavg(), "cpus": os.cpu_count(), "differ_from_libm": {}}
    rng = np.random.default_rng(1)
    for lo, hi in ((0.999, 1.001), (0.9, 1.1), (0.5, 2.0), (1.0, 100.0)):
        y = rng.uniform(lo, hi, 1_000_000)
        res["differ_from_libm"][f"[{lo}, {hi}]"] = _differ(y) / len(y)
    save_json(cli.out, "log_cost", res)
    print(json.dumps(res))
    return res


if __name__ == "__main__":
    main()

"""How promptly an interrupted Dask chaos map returns, and its cluster closes.

A chaos map on a Dask cluster is interrupted (SIGINT, as Ctrl-C sends it)
a few seconds into a long map; measured from the signal: when
``varint.chaos_map`` returns its partial result, and when the ``with
LocalCluster(...), Client(...)`` block that made the cluster ends. Chunks
already running on the workers stop at their next sub-chunk (~0.2 s) once
their tasks are cancelled (``varint.maps._cancel_check``); before, they ran
to their end (seconds to minutes) and closing the cluster waited for them
(the nanny kills a busy worker after 4 s).

Two clusters: worker threads in the map's process (``processes=False``,
where the compiled chunks also release the GIL) and worker processes. The
figure of each is the median of ``REPEATS`` interleaved runs; the machine's
load average is stored with them (ratios across machines mean nothing).

Usage: ``python studies/interrupt_latency.py [--quick] [--out DIR]``
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from studies.common import parse_args, save_json  # noqa: E402

REPEATS = (5, 1)
#: Seconds the map runs before the signal.
AFTER = 3.0

_CHILD = """
import sys, time, warnings
import numpy as np
import varint
from distributed import Client, LocalCluster
warnings.simplefilter("ignore")
if __name__ == "__main__":
    hh = varint.models.HenonHeiles()
    grid = varint.section_grid(hh, 0.125, np.linspace(-0.4, 0.6, 60), np.linspace(-0.4, 0.4, 60))
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=sys.argv[1] == "processes",
                      dashboard_address=None) as cluster, Client(cluster) as client:
        varint.chaos_map(hh, grid, "sali", t_end=10.0, tau=0.05, client=client, progress=False)
        print("ready", flush=True)
        r = varint.chaos_map(hh, grid, "sali", t_end=2e4, tau=0.05, client=client,
                             progress=False, threshold=None)
        print("returned", time.monotonic(), r.interrupted, flush=True)
    print("closed", time.monotonic(), flush=True)
"""


def _once(kind):
    """Seconds from SIGINT to the map's return and to the cluster's close."""
    child = subprocess.Popen([sys.executable, "-c", _CHILD, kind], stdout=subprocess.PIPE,
                             stderr=subprocess.DEVNULL, text=True, start_new_session=True)
    for line in child.stdout:
        if line.startswith("ready"):
            break
    time.sleep(AFTER)
    sent = time.monotonic()
    child.send_signal(signal.SIGINT)
    times = {}
    for line in child.stdout:
        word, when, *rest = line.split()
        times[word] = float(when) - sent
        if word == "returned":
            times["interrupted"] = rest == ["True"]
    child.wait(timeout=120)
    return times


def main(argv=None):
    args = parse_args(__doc__.splitlines()[0], argv)
    repeats = REPEATS[1] if args.quick else REPEATS[0]
    runs = {"threads": [], "processes": []}
    load = os.getloadavg()
    for _ in range(repeats):        # interleaved
        for kind in runs:
            runs[kind].append(_once(kind))
    out = {"after_s": AFTER, "repeats": repeats, "load_average_at_start": load,
           "load_average_at_end": os.getloadavg(), "cpus": os.cpu_count(), "runs": runs}
    for kind, rows in runs.items():
        for key in ("returned", "closed"):
            values = sorted(r[key] for r in rows if key in r)
            out[f"{kind}_{key}_median_s"] = values[len(values) // 2] if values else None
        out[f"{kind}_all_interrupted"] = all(r.get("interrupted") for r in rows)
    save_json(args.out, "interrupt_latency", out)
    return out


if __name__ == "__main__":
    result = main()
    print({k: v for k, v in result.items() if k != "runs"})

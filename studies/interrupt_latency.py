"""How promptly an interrupted Dask chaos map returns, and its cluster closes.

A chaos map on a Dask cluster is interrupted (SIGINT, as Ctrl-C sends it)
a few seconds into a long map; measured from the signal: when
``varint.chaos_map`` returns its partial result, and when the ``with
LocalCluster(...), Client(...)`` block that made the cluster ends. Chunks
already running on the workers stop at their next sub-chunk (~0.2 s) once
their tasks are cancelled (``varint.fanout._cancel_check``); before, they ran
to their end (seconds to minutes) and closing the cluster waited for them
(the nanny kills a busy worker after 4 s).

Two clusters: worker threads in the map's process (``processes=False``,
where the compiled chunks also release the GIL) and worker processes; on
each, two contenders: ``polling`` (varint as it is) and ``no polling``
(the workers' ``_cancel_check`` replaced by one that never reports a
cancellation, i.e. chunks run to their end as before the fix); and, as
the floor of the close, a short map that finishes without a signal
(``finished``: only ``close_after_return``, the seconds from the map's
return to the cluster's close, means something there). The figure
of each is the median of ``REPEATS`` interleaved runs; the machine's load
average is stored with them (compare the contenders of one run, never
times across machines or runs).

The child restores Python's default SIGINT handler: a process started in
the background by a non-interactive shell inherits SIGINT ignored, and
would not be interrupted at all (the map then runs to its end; every run
records whether the map reported ``interrupted``, and the study fails if
one did not).

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

REPEATS = (3, 1)
CONTENDERS = ("polling", "no polling", "finished")
#: Seconds the map runs before the signal.
AFTER = 3.0

_CHILD = """
import signal, sys, time, warnings
import numpy as np
import varint
from distributed import Client, LocalCluster
warnings.simplefilter("ignore")


def never_cancelled():
    import varint.fanout
    varint.fanout._cancel_check = lambda worker: (lambda: False)


if __name__ == "__main__":
    signal.signal(signal.SIGINT, signal.default_int_handler)
    hh = varint.models.HenonHeiles()
    grid = varint.section_grid(hh, 0.125, np.linspace(-0.4, 0.6, 60), np.linspace(-0.4, 0.4, 60))
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=sys.argv[1] == "processes",
                      dashboard_address=None) as cluster, Client(cluster) as client:
        if sys.argv[2] == "no polling":
            client.run(never_cancelled)
        varint.chaos_map(hh, grid, "sali", t_end=10.0, tau=0.05, client=client, progress=False)
        print("ready", flush=True)
        r = varint.chaos_map(hh, grid, "sali", t_end=10.0 if sys.argv[2] == "finished" else 2e4,
                             tau=0.05, client=client, progress=False, threshold=None)
        print("returned", time.monotonic(), r.interrupted, flush=True)
    print("closed", time.monotonic(), flush=True)
"""


def _once(kind, contender):
    """Seconds from SIGINT to the map's return and to the cluster's close."""
    child = subprocess.Popen([sys.executable, "-c", _CHILD, kind, contender], stdout=subprocess.PIPE,
                             stderr=subprocess.DEVNULL, text=True, start_new_session=True)
    for line in child.stdout:
        if line.startswith("ready"):
            break
    sent = time.monotonic()
    if contender != "finished":
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
    if contender == "finished":  # no signal: only the close is measured
        times["interrupted"] = not times["interrupted"]
    times["close_after_return"] = times["closed"] - times["returned"]
    return times


def main(argv=None):
    args = parse_args(__doc__.splitlines()[0], argv)
    repeats = REPEATS[1] if args.quick else REPEATS[0]
    runs = {f"{kind}, {contender}": [] for kind in ("threads", "processes")
            for contender in CONTENDERS}
    load = os.getloadavg()
    for _ in range(repeats):        # interleaved
        for name in runs:
            runs[name].append(_once(*name.split(", ")))
    out = {"after_s": AFTER, "repeats": repeats, "load_average_at_start": load,
           "load_average_at_end": os.getloadavg(), "cpus": os.cpu_count(), "runs": runs,
           "table": {}}
    for name, rows in runs.items():
        row = {f"{key}_median_s": _median([r[key] for r in rows if key in r])
               for key in ("returned", "closed", "close_after_return")}
        # "finished" rows hold True when the short map was not interrupted.
        row["all_interrupted"] = all(r.get("interrupted") for r in rows)
        out["table"][name] = row
    save_json(args.out, "interrupt_latency", out)
    if not all(row["all_interrupted"] for row in out["table"].values()):
        raise SystemExit("a map was not interrupted: its figures measure nothing")
    return out


def _median(values):
    values = sorted(values)
    return values[len(values) // 2] if values else None


if __name__ == "__main__":
    result = main()
    print(f"load average {result['load_average_at_start']} .. {result['load_average_at_end']}")
    for name, row in result["table"].items():
        print(f"{name:24s} returned {row['returned_median_s']:7.2f} s  "
              f"closed {row['closed_median_s']:7.2f} s  "
              f"close after return {row['close_after_return_median_s']:7.2f} s  "
              f"as expected {row['all_interrupted']}")

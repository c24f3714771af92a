"""What each row of Table I costs to t = 1e8, and how far its run has got.

A full Table I row takes up to about two hours of CPU here, too long to
run all 17 in one sitting on a shared machine, so the rows run as separate
resumable jobs (``python studies/table1.py --row N``). To plan them, this
study measures each row's CPU time per unit of time with short runs of the
same method and settings (the paper's R1, seeded vectors and outputs of
:mod:`paper_runs`, kernels compiled first), at two horizons so that any
fixed per-run overhead shows, takes the minimum over repeats (the machine
is shared: the minimum is the least disturbed), and projects the CPU time
to t = 1e8 from the slope between them (:func:`project`). It then says, per row, whether its
1e8 run is stored (and compares the projection with that run's measured
CPU time), how far a checkpoint of an unfinished run has got, and the CPU
time still to go.

The projection is a CPU time: a job gets about that wall time on a core of
its own, longer when the 2 cores are shared (a checkpoint's wall time is
shown beside the CPU estimate of the part done).

Writes ``table1_cost.csv``, ``table1_cost.json`` and ``table1_cost.md``
into the results directory. The short runs go to a temporary directory;
nothing in ``runs/`` is touched.

Usage: ``python studies/table1_cost.py [--quick] [--out DIR] [--t-end T ...]
[--repeats R]``
"""

from __future__ import annotations

import json
import sys
import tempfile
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from studies.common import parse_args, save_csv, save_json  # noqa: E402
from studies.paper_runs import METHOD_LABELS, run, stored_key  # noqa: E402
from studies.table1 import PAPER_TABLE, T_END  # noqa: E402
from varint.checkpoint import read as read_checkpoint  # noqa: E402

#: Horizons of the short runs (full, quick) and repeats of each.
HORIZONS = ((1e4, 1e5), (1e3, 1e4))
REPEATS = (3, 1)

COLUMNS = ["row", "integrator", "method", "tau", "delta", "cpu_short_s", "cpu_long_s",
           "cpu_per_time", "wall_per_cpu", "projected_cpu_1e8_s", "projected_cpu_1e8_h",
           "projected_wall_1e8_h",
           "stored_t_end", "stored_cpu_s", "projected_over_stored", "checkpoint_t",
           "checkpoint_wall_s", "remaining_cpu_h", "remaining_wall_h", "status"]


def measure(spec, horizons, repeats, scratch):
    """CPU seconds of the row ``spec`` to each of the two ``horizons`` (the
    minimum over ``repeats`` fresh runs), and wall over CPU time of the
    longer run."""
    _, method, tau, delta, *_ = spec
    cpu, wall_per_cpu = [], None
    for t_end in horizons:
        best = None
        for _ in range(repeats):
            s = run(scratch, "lyapunov", "R1", method, tau, t_end, delta=delta, fresh=True,
                    progress=False)
            if best is None or s.cpu < best.cpu:
                best = s
        cpu.append(best.cpu)
        wall_per_cpu = best.wall / best.cpu
    return cpu, wall_per_cpu


def project(horizons, cpu, t_end=T_END):
    """CPU seconds to ``t_end`` from those to two shorter ``horizons``: a
    run costs a fixed part (setting up, outputs, the checkpoint) plus a
    part proportional to t, so the marginal cost per unit of time is the
    slope between the two runs and the fixed part is not scaled up. Returns
    (projected CPU seconds, marginal seconds per unit of time)."""
    (t1, t2), (c1, c2) = horizons, cpu
    marginal = (c2 - c1) / (t2 - t1)
    if marginal <= 0:
        # Noise larger than the work between the two horizons: the longer
        # run's average, an upper bound, is all that can be said.
        marginal = c2 / t2
    return c2 + marginal * (t_end - t2), marginal


def progress_of(out, spec):
    """(stored horizon or None, its CPU seconds or None, checkpoint t or
    None, checkpoint wall seconds or None) of the row's runs in ``out``."""
    _, method, tau, delta, *_ = spec
    key = stored_key("lyapunov", "R1", method, tau, T_END, delta=delta)
    runs = Path(out) / "runs"
    stored_t = stored_cpu = ckpt_t = ckpt_wall = None
    meta = runs / f"{key}.json"
    if meta.exists() and meta.with_suffix(".npz").exists():
        stored_t, stored_cpu = T_END, float(json.loads(meta.read_text())["cpu"])
    ckpt = runs / "checkpoints" / f"{key}.ckpt"
    if ckpt.exists():
        snap = read_checkpoint(ckpt)
        ckpt_t, ckpt_wall = snap.state.step * tau, float(snap.wall_time)
    return stored_t, stored_cpu, ckpt_t, ckpt_wall


def cost_table(out, quick=False, horizons=None, repeats=None):
    """One dict per row of Table I, in the paper's order (columns
    :data:`COLUMNS`)."""
    horizons = horizons or HORIZONS[quick]
    repeats = repeats or REPEATS[quick]
    rows = []
    with tempfile.TemporaryDirectory(prefix="table1_cost_") as scratch:
        for n, spec in enumerate(PAPER_TABLE, 1):
            integrator, method, tau, delta, *_ = spec
            cpu, wall_per_cpu = measure(spec, horizons, repeats, scratch)
            projected, marginal = project(horizons, cpu)
            stored_t, stored_cpu, ckpt_t, ckpt_wall = progress_of(out, spec)
            reached = stored_t or ckpt_t or 0.0
            if stored_t:
                status = "stored to 1e8"
            elif ckpt_t:
                status = f"checkpoint at t = {ckpt_t:.3g}"
            else:
                status = "not run"
            row = {"row": n, "integrator": integrator, "method": METHOD_LABELS[method],
                   "tau": tau, "delta": delta, "cpu_short_s": cpu[0], "cpu_long_s": cpu[1],
                   "cpu_per_time": marginal, "wall_per_cpu": wall_per_cpu,
                   "projected_cpu_1e8_s": projected, "projected_cpu_1e8_h": projected / 3600,
                   "projected_wall_1e8_h": projected * wall_per_cpu / 3600,
                   "stored_t_end": stored_t, "stored_cpu_s": stored_cpu,
                   "projected_over_stored": projected / stored_cpu if stored_cpu else None,
                   "checkpoint_t": ckpt_t, "checkpoint_wall_s": ckpt_wall,
                   "remaining_cpu_h": marginal * (T_END - reached) / 3600,
                   "remaining_wall_h": marginal * wall_per_cpu * (T_END - reached) / 3600,
                   "status": status}
            rows.append(row)
            print(f"{n:2d} {row['method']:7s} tau={tau:<5g} delta={delta or '':<6} "
                  f"{marginal:.3g} s/unit -> {projected / 3600:.3g} h to 1e8; {status}",
                  flush=True)
    return rows


def _cell(value, fmt):
    return "—" if value is None else format(value, fmt)


def markdown(rows, horizons, repeats):
    """The cost table as markdown, with how it was measured."""
    lines = [f"# Table I: cost per row to t = {T_END:.0e}", "",
             f"CPU seconds of each row (`time.process_time()`, minimum of {repeats} fresh "
             f"runs to t = {horizons[0]:g} and to t = {horizons[1]:g}, kernels compiled "
             "first); the marginal cost per unit of time is the slope between the two, and "
             f"the CPU time to 1e8 that of the run to {horizons[1]:g} plus the slope times "
             "the rest (a run's fixed cost is not scaled up). Written by "
             "`studies/table1_cost.py`. Run a row with "
             "`nohup nice -n 15 python studies/table1.py --row N &` (it resumes from its "
             "checkpoint if killed), then `python studies/table1.py` to write the table.", "",
             f"| row | method | τ | δ | CPU s to t = {horizons[0]:g} | to {horizons[1]:g} | "
             "marginal s per unit time | wall/CPU | projected CPU to 1e8 | wall at that "
             "wall/CPU | stored 1e8 run: CPU | projected/stored | checkpoint t (wall so far) | "
             "CPU still to go | wall still to go | status |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        ckpt = "—" if r["checkpoint_t"] is None else \
            f"{r['checkpoint_t']:.3g} ({r['checkpoint_wall_s'] / 3600:.2f} h)"
        lines.append("| " + " | ".join((
            str(r["row"]), r["method"], f"{r['tau']:g}", _cell(r["delta"], "g"),
            f"{r['cpu_short_s']:.3g}", f"{r['cpu_long_s']:.3g}", f"{r['cpu_per_time']:.3g}",
            f"{r['wall_per_cpu']:.2f}",
            f"{r['projected_cpu_1e8_h']:.2f} h ({r['projected_cpu_1e8_s']:.0f} s)",
            f"{r['projected_wall_1e8_h']:.2f} h",
            _cell(r["stored_cpu_s"], ".0f") + (" s" if r["stored_cpu_s"] else ""),
            _cell(r["projected_over_stored"], ".2f"), ckpt,
            f"{r['remaining_cpu_h']:.2f} h", f"{r['remaining_wall_h']:.2f} h",
            r["status"])) + " |")
    todo = [r for r in rows if r["stored_t_end"] is None]
    lines += ["", f"{len(rows) - len(todo)} of {len(rows)} rows are stored to 1e8; the other "
              f"{len(todo)} need {sum(r['remaining_cpu_h'] for r in todo):.1f} h of CPU in "
              f"all ({max((r['remaining_cpu_h'] for r in todo), default=0.0):.1f} h the "
              "longest), one core per row: on an idle core the wall time is about the CPU "
              "time; at the load of this measurement (wall/CPU above) it is "
              f"{sum(r['remaining_wall_h'] for r in todo):.1f} h in all."]
    check = [r["projected_over_stored"] for r in rows if r["projected_over_stored"]]
    if check:
        lines += ["", f"Check: where a 1e8 run is stored, the projection is "
                  f"{min(check):.2f}–{max(check):.2f}× its measured CPU time. CPU time "
                  "measured while the cores are shared is inflated (caches, memory "
                  "bandwidth), so a projection made at a higher load than the stored runs' "
                  "is high by about that factor; compare rows within one session."]
    return "\n".join(lines + [""])


def main(argv=None):
    def extra(parser):
        parser.add_argument("--t-end", type=float, action="append", default=None,
                            help="the two horizons of the short runs, given twice "
                                 "(default 1e4 and 1e5)")
        parser.add_argument("--repeats", type=int, default=None,
                            help="fresh runs per horizon; the minimum counts (default 3)")

    args = parse_args(__doc__.split("\n\n")[0], argv, extra=extra)
    horizons = tuple(sorted(args.t_end)) if args.t_end else HORIZONS[args.quick]
    if len(horizons) != 2 or horizons[0] == horizons[1]:
        raise ValueError(f"--t-end must be given twice, two different horizons, got "
                         f"{horizons!r}")
    repeats = REPEATS[args.quick] if args.repeats is None else args.repeats
    for t in horizons:
        if not 0 < t <= T_END:
            raise ValueError(f"--t-end must be in (0, {T_END:g}], got {t!r}")
    if repeats < 1:
        raise ValueError(f"--repeats must be a positive integer, got {repeats!r}")
    rows = cost_table(args.out, args.quick, horizons, repeats)
    save_csv(args.out, "table1_cost", rows, COLUMNS)
    save_json(args.out, "table1_cost", {"horizons": horizons, "repeats": repeats,
                                        "rows": rows, "columns": COLUMNS},
              times={"cpu_short_s, cpu_long_s, stored_cpu_s": "measured (CPU)",
                     "cpu_per_time, projected_*, remaining_*": "derived from the measured "
                                                              "ones (the slope between the two "
                                                              "horizons, see project())"})
    path = Path(args.out) / "table1_cost.md"
    path.write_text(markdown(rows, horizons, repeats))
    return {"rows": rows, "markdown": path}


if __name__ == "__main__":
    main()

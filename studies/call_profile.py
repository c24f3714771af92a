"""Where one short call's fixed cost goes: µs per stage of a one-step
``varint.integrate`` of R1 (issue 27; issue 28's "fixed cost of one call",
target ≤ 50 µs).

Case
----
The frontier study's call (:mod:`studies.frontier`): orbit R1 and one given
unit tangent vector, ``varint.integrate(model, x0, t_end, tau=τ,
scheme="s15odr8", deviations=w)`` with ``t_end = τ = 0.05`` (one step), every
cache warm (the call made first). Almost all of it is the call's fixed
cost: checks, set-up, recording, the result and its provenance.

Method
------
Each stage (:data:`STAGES`: a function of varint the call goes through) is
wrapped with ``time.perf_counter`` around it; the time of each stage is its
inclusive time within one call (a stage inside another counts in both, the
tree shows which). Over ``--calls`` wrapped calls the median per stage is
kept (the wrapper adds ~0.3 µs a stage). The whole call, unwrapped, is
timed over the same number of calls in turns with the wrapped ones, and its
minimum and median are kept, in wall and CPU time (``time.process_time``).
The load of the shared machine (``os.getloadavg``) is stored with them: only
the shares and the call's own minimum mean much.

Stored as ``call_profile_<label>.json``/``.csv``: ``before`` is the code
as the fixed-cost work started (main a885a59, its ``varint`` exported with
``git archive`` and imported first, then this script run with
:func:`runpy.run_path`), ``after`` this code, run right after it in the
same load window (only figures of one window compare).

Usage: ``python studies/call_profile.py [--quick] [--out DIR] [--calls N] [--label L]``
"""

from __future__ import annotations

import functools
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import varint  # noqa: E402
from studies.common import parse_args, save_csv, save_json  # noqa: E402

#: (depth, label, owner, attribute): the stages, in call order; ``owner``
#: is a dotted module path, optionally ``:Class``. A name imported into
#: another module is wrapped where it is called from.
STAGES = (
    (0, "integrate (whole call)", "varint.api", "run"),
    (1, "specify: check every argument", "varint.run", "specify"),
    (2, "model check", "varint.runspec:check", "model"),
    (2, "states check", "varint.runspec:check", "states"),
    (2, "kernels finite at x0", "varint.runspec:check", "kernels"),
    (2, "reference energy and scales", "varint.runspec:accuracy", "Reference"),
    (2, "energy tolerance", "varint.runspec:accuracy", "energy_tolerance"),
    (2, "output times check", "varint.runspec:check", "output_times"),
    (2, "indicator configure", "varint.indicators:Indicator", "configure"),
    (1, "Run: set up", "varint.run:Run", "__init__"),
    (2, "machine identity", "varint.run:identity", "machine"),
    (2, "code identity", "varint.run:identity", "code_identity"),
    (2, "initial vectors check", "varint.run:Run", "_initial_vectors"),
    (2, "fix tau, output steps", "varint.runspec:RunSpec", "with_step"),
    (2, "size check", "varint.run:Run", "_check_size"),
    (2, "propagator (kernel lookup)", "varint.run", "make_propagator"),
    (2, "start state", "varint.run:Run", "_start_state"),
    (1, "execute", "varint.run:Run", "execute"),
    (2, "drive", "varint.run", "drive"),
    (3, "record (indicator, energy error)", "varint.run:Run", "record"),
    (2, "result", "varint.run:Run", "_result"),
    (3, "accuracy verdict", "varint.run:accuracy", "assess"),
    (3, "accuracy annotate", "varint.run:accuracy", "annotate"),
    (3, "provenance", "varint.run:Run", "provenance"),
    (2, "accuracy warning", "varint.run:accuracy", "warn"),
)


def _owner(path):
    """The object a dotted ``module[:attr]`` path names."""
    import importlib

    module, _, attr = path.partition(":")
    obj = importlib.import_module(module)
    return getattr(obj, attr) if attr else obj


def wrap_stages(spent):
    """Wrap every stage with a timer adding to ``spent[label]``; returns a
    function that restores the originals."""
    undo = []
    for _, label, path, name in STAGES:
        owner = _owner(path)
        original = getattr(owner, name)

        def timed(*args, _f=original, _label=label, **kwargs):
            t0 = time.perf_counter()
            try:
                return _f(*args, **kwargs)
            finally:
                spent[_label] = spent.get(_label, 0.0) + time.perf_counter() - t0

        if isinstance(original, type):
            # A class (Reference): time its construction.
            wrapped = functools.wraps(original, updated=())(timed)
        else:
            wrapped = functools.wraps(original)(timed)
        setattr(owner, name, wrapped)
        undo.append((owner, name, original))

    def restore():
        for owner, name, original in reversed(undo):
            setattr(owner, name, original)

    return restore


def main(argv=None):
    def extra(parser):
        parser.add_argument("--calls", type=int, default=2000)
        parser.add_argument("--label", default="now",
                            help="suffix of the stored files (e.g. before/after a change)")

    args = parse_args(__doc__.splitlines()[0], argv, extra)
    calls = 100 if args.quick else args.calls
    model, x0 = varint.paper_orbit("R1")
    w0 = np.random.default_rng(1).standard_normal(len(x0))
    w0 /= np.linalg.norm(w0)

    def call():
        return varint.integrate(model, x0, 0.05, tau=0.05, scheme="s15odr8",
                                deviations=w0[:, None])

    for _ in range(20):
        call()
    load_before = os.getloadavg()
    per_stage = {label: [] for _, label, _, _ in STAGES}
    wall, cpu = [], []
    for _ in range(calls):
        c0, t0 = time.process_time(), time.perf_counter()
        call()
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
        spent = {}
        restore = wrap_stages(spent)
        try:
            call()
        finally:
            restore()
        for label in per_stage:
            per_stage[label].append(spent.get(label, 0.0))
    total = statistics.median(per_stage[STAGES[0][1]])
    rows = [{"depth": depth, "stage": label, "median_us": statistics.median(per_stage[label]) * 1e6,
             "share": statistics.median(per_stage[label]) / total}
            for depth, label, _, _ in STAGES]
    whole = {"wall_min_us": min(wall) * 1e6, "wall_median_us": statistics.median(wall) * 1e6,
             "cpu_min_us": min(cpu) * 1e6, "cpu_median_us": statistics.median(cpu) * 1e6}
    load = {"before": load_before, "after": os.getloadavg(), "cpus": os.cpu_count()}
    name = f"call_profile_{args.label}"
    save_csv(args.out, name, rows, ["depth", "stage", "median_us", "share"])
    save_json(args.out, name, {"stages": rows, "whole_call": whole, "calls": calls,
                               "load": load, "quick": args.quick, "label": args.label})
    print(f"one-step call, R1, s15odr8: {calls} calls, load {load['before']} -> "
          f"{load['after']} on {load['cpus']} CPUs")
    print(f"unwrapped: wall min {whole['wall_min_us']:.0f} µs, median "
          f"{whole['wall_median_us']:.0f}; CPU min {whole['cpu_min_us']:.0f}, median "
          f"{whole['cpu_median_us']:.0f}")
    for r in rows:
        print(f"{'  ' * r['depth']}{r['stage']:<{44 - 2 * r['depth']}} "
              f"{r['median_us']:8.1f} µs {r['share']:6.1%}")
    return {"stages": rows, "whole_call": whole}


if __name__ == "__main__":
    main()

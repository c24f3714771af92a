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

The prepared path (``varint.prepare(model, "integrate", t_end, tau=τ,
scheme=…, deviations=w)`` once, then ``run(x0)``; :mod:`varint.prepared`)
is profiled in the same run, its calls interleaved with the one-shot
call's (:data:`SHORT_STAGES`), and so is the same prepared call by the
general path (:data:`PREPARED_STAGES`; ``--path`` picks some).

Stored as ``call_profile_<label>.json``/``.csv``: ``before`` is the code
as the fixed-cost work started (main a885a59, its ``varint`` exported with
``git archive`` and imported first, then this script run with
:func:`runpy.run_path`), ``after`` this code, run right after it in the
same load window (only figures of one window compare). Issue 28's second
round: ``round2_before`` (main 93ccc3a, one-shot only) and
``round2_after`` (both paths); its third (the prepared call's fixed cost):
``round3_before`` (main a875246, both paths) and ``round3_after``, run
one after the other in one load window; its fourth (the prepared call's
kernel check and the TM propagator's per-call set-up): ``round4_before``
(main fc6a4bb) and ``round4_after``, likewise; its fifth (the prepared
call's short path, :class:`varint.prepared._ShortCall`, now :class:`varint.rerun.ShortCall`): ``round5``, the
three paths of :data:`PATHS` interleaved (``prepared_general`` is the
previous path of the same code), and ``round5_before`` (main 7b2b6c8, where
``prepared`` is the general path), run one after the other in one load
window; its sixth (the short call's buffers kept per thread, its energy
errors and verdict compiled, its provenance's fixed part left pickled
until read): ``round6_before`` (main 5d760dc) and ``round6_after``, the
prepared path alone, likewise (quick, ``results/quick``); its seventh
(T compiled with the energy errors where it rounds as NumPy's, the
errors returned as one array, the load average read once a second):
``round7_before`` (main a56fbcd) and ``round7_after``, likewise; its
eighth (the states checked without a new specification, the state and its
kernels tested finite in one pass, the start states kept before the
outputs, NumPy's error handling set without rebuilding it):
``round8_before`` (main 2aef9d2) and ``round8_after``, likewise. Its
ninth (Hénon–Heiles' V of the short call's rows compiled,
``HenonHeiles.potential_rows``, then a hand-written twin of its NumPy V,
since vgen17 compiled from that V's own expression,
:mod:`varint.models.potential_rows`; the kernels' values tested finite in
one compiled pass; the counts made in one dict) is stored in ``results/``
as ``round6`` (the issue's sixth stored profile, after ``round5``; not the
quick ``round6_before``/``round6_after`` above): this code alone, every
path, the figures against main (63e9f7c) in ``call_overhead.json``. Its
tenth (call18: the prepared call as on a CPU with AVX-512, ``--avx512``,
where NumPy's power is SVML's and Hénon–Heiles' V is now compiled but for
its cube, :class:`varint.models.potential_rows.NumPyPowers`; the
verdict's notes made once per prepared run): ``call18/`` holds
``call_profile_avx512_before`` (main a37e246, which has no compiled V
there) and ``call_profile_avx512_after``, run one after the other in one
load window, the figures against main in ``call_overhead.json``. Its
eleventh (fix25: a model's key token kept while its walk's checks hold,
``varint.remembered.model_token``; a HamiltonianModel's verdict compiled;
the compact stepper's shape asked once) is stored under ``fix25/``:
``call_profile_fix25_before`` (main a1228da's own script and code) and
``call_profile_fix25``, run one after the other in one load window.

Usage: ``python studies/call_profile.py [--quick] [--out DIR] [--calls N] [--label L]
[--path oneshot prepared prepared_general] [--avx512]``
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
import varint.prepared  # noqa: E402
from studies.common import parse_args, save_csv, save_json  # noqa: E402

#: The calls profiled: the one-shot call, a prepared run's call (its short
#: path where the code has one) and the same prepared call by the general
#: path (:meth:`varint.run.Run.with_orbits`, the short path switched off).
PATHS = ("oneshot", "prepared", "prepared_general")

#: (depth, label, owner, attribute): the stages, in call order; ``owner``
#: is a dotted module path, optionally ``:Class``. A name imported into
#: another module is wrapped where it is called from.
STAGES = (
    (0, "integrate (whole call)", "varint.api", "run"),
    (1, "key of a remembered call", "varint.remembered", "call_key"),
    (2, "model's token (its checks)", "varint.remembered", "model_token"),
    (1, "remembered call (varint.remembered)", "varint.rerun:Rerun", "__call__"),
    (2, "x0 and its kernels finite, one pass", "varint._validate:KernelCheck", "states"),
    (2, "given vectors checked", "varint.rerun:ShortCall", "vectors"),
    (2, "short call (varint.rerun)", "varint.rerun:ShortCall", "__call__"),
    (3, "energy errors and verdict", "varint.rerun:ShortCall", "_energy_verdict"),
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

#: The stages of a prepared run's call through the general path
#: (:class:`varint.prepared.PreparedRun` without its short calls: each call
#: a :meth:`varint.run.Run.with_orbits` run), as :data:`STAGES`.
PREPARED_STAGES = (
    (0, "prepared run (whole call)", "varint.prepared:PreparedRun", "__call__"),
    (1, "check x0", "varint.runspec:RunSpec", "with_states"),
    (2, "states check", "varint.runspec:check", "states"),
    (2, "kernels finite at x0", "varint.runspec:check", "kernels"),
    (2, "kernels finite at x0, kept buffers", "varint._validate:KernelCheck", "__call__"),
    (2, "reference energy and scales", "varint.runspec:accuracy", "Reference"),
    (1, "Run: over new orbits", "varint.run:Run", "with_orbits"),
    (2, "machine identity", "varint.run:identity", "machine"),
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

#: The stages of a prepared run's short call (:class:`varint.prepared._ShortCall`),
#: as :data:`STAGES`; each code has some of them (those only older code
#: passes: :data:`SHORT_STAGES_BEFORE_ROUND6`, :data:`SHORT_STAGES_BEFORE_ROUND8`,
#: :data:`SHORT_STAGES_BEFORE_ROUND9`).
SHORT_STAGES = (
    (0, "prepared run (whole call)", "varint.prepared:PreparedRun", "__call__"),
    (1, "check x0, a new specification", "varint.runspec:RunSpec", "with_states"),
    (1, "check x0", "varint.runspec:RunSpec", "checked_states"),
    (2, "states check", "varint.runspec:check", "states"),
    (2, "kernels finite at x0, kept buffers", "varint._validate:KernelCheck", "__call__"),
    (2, "x0 and its kernels finite, one pass", "varint._validate:KernelCheck", "states"),
    (1, "short call", "varint.prepared:_ShortCall", "__call__"),
    (1, "rerun of the first run", "varint.rerun:Rerun", "__call__"),
    (2, "short call (varint.rerun)", "varint.rerun:ShortCall", "__call__"),
    (2, "stepper from fresh arrays", "varint.methods.tm:TangentMapPropagator", "advance_fresh"),
    (2, "snapshot rows", "varint.state:Snapshots", "rows"),
    (2, "reference and energy errors", "varint.accuracy", "reference_and_errors"),
    (2, "accuracy verdict", "varint.accuracy", "assess"),
    (2, "provenance", "varint.results:Provenance", "__init__"),
    (2, "stepper, kept buffers", "varint.methods.fresh_run:FreshRun", "__call__"),
    (2, "snapshot rows, kept views", "varint.methods.fresh_run:FreshRun", "rows"),
    (2, "energy errors and verdict", "varint.prepared:_ShortCall", "_energy_verdict"),
    (3, "energy errors and verdict", "varint.rerun:ShortCall", "_energy_verdict"),
    (4, "V compiled, its powers NumPy's", "varint.models.potential_rows:NumPyPowers",
     "__call__"),
    (2, "provenance, fixed part pickled", "varint.results:Provenance", "with_pickled"),
    (2, "machine identity", "varint.identity", "machine"),
    (2, "accuracy warning", "varint.accuracy", "warn"),
)

#: The labels of :data:`SHORT_STAGES` that only the code of rounds 5 and
#: before passes (round 6's short call runs from kept buffers, computes the
#: energy errors and verdict in one compiled pass and warns from there).
SHORT_STAGES_BEFORE_ROUND6 = frozenset({
    "stepper from fresh arrays", "reference and energy errors", "accuracy verdict",
    "provenance", "accuracy warning",
})

#: The labels of :data:`SHORT_STAGES` that only the code of rounds 8 and
#: before passes (round 9's prepared run and remembered one-shot calls share
#: one short path, :class:`varint.rerun.ShortCall`).
SHORT_STAGES_BEFORE_ROUND9 = frozenset({"short call"})

#: The labels of :data:`SHORT_STAGES` that only the code of rounds 7 and
#: before passes (round 8's short call checks the states without making a
#: specification over them, ``RunSpec.checked_states``, and tests the state
#: and its kernels finite in one pass, ``KernelCheck.states``).
SHORT_STAGES_BEFORE_ROUND8 = frozenset({
    "check x0, a new specification", "states check", "kernels finite at x0, kept buffers",
})


#: The labels of :data:`SHORT_STAGES` that only a model whose V is
#: compiled but for its powers passes (Hénon–Heiles where NumPy's power is
#: not libm's: a CPU with AVX-512, or ``--avx512``).
SHORT_STAGES_NUMPY_POWERS = frozenset({"V compiled, its powers NumPy's"})


def as_on_avx512():
    """Make the models' compiled V from now on as on a CPU with AVX-512,
    where NumPy's power is SVML's, not libm's
    (:data:`varint.models.potential_rows.NUMPY_POWER_IS_LIBM` false; code
    before call18 then makes no compiled V of a cube, call18's leaves the
    cube to NumPy)."""
    from varint.models import potential_rows

    potential_rows.NUMPY_POWER_IS_LIBM = False
    potential_rows.rows_from.cache_clear()


def _owner(path):
    """The object a dotted ``module[:attr]`` path names."""
    import importlib

    module, _, attr = path.partition(":")
    obj = importlib.import_module(module)
    return getattr(obj, attr) if attr else obj


def wrap_stages(spent, stages=STAGES):
    """Wrap every stage with a timer adding to ``spent[label]``; returns a
    function that restores the originals."""
    undo = []
    for _, label, path, name in stages:
        try:
            owner = _owner(path)
            original = getattr(owner, name)
        except (AttributeError, ModuleNotFoundError):
            continue    # a stage the profiled code has not (other code): 0 µs

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


def profile(call, stages, calls):
    """Stage medians (µs, share of the whole) and the unwrapped call's wall
    and CPU times over ``calls`` calls, wrapped and unwrapped in turns."""
    per_stage = {label: [] for _, label, _, _ in stages}
    wall, cpu = [], []
    for _ in range(calls):
        c0, t0 = time.process_time(), time.perf_counter()
        call()
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
        spent = {}
        restore = wrap_stages(spent, stages)
        try:
            call()
        finally:
            restore()
        for label in per_stage:
            per_stage[label].append(spent.get(label, 0.0))
    total = statistics.median(per_stage[stages[0][1]])
    rows = [{"depth": depth, "stage": label, "median_us": statistics.median(per_stage[label]) * 1e6,
             "share": statistics.median(per_stage[label]) / total}
            for depth, label, _, _ in stages]
    whole = {"wall_min_us": min(wall) * 1e6, "wall_median_us": statistics.median(wall) * 1e6,
             "cpu_min_us": min(cpu) * 1e6, "cpu_median_us": statistics.median(cpu) * 1e6}
    return rows, whole


def main(argv=None):
    def extra(parser):
        parser.add_argument("--calls", type=int, default=2000)
        parser.add_argument("--label", default="now",
                            help="suffix of the stored files (e.g. before/after a change)")
        parser.add_argument("--path", nargs="+", choices=PATHS, default=list(PATHS),
                            help="which calls to profile (default all, interleaved)")
        parser.add_argument("--avx512", action="store_true",
                            help="the models' compiled V as on a CPU with AVX-512 "
                                 "(as_on_avx512)")

    args = parse_args(__doc__.splitlines()[0], argv, extra)
    calls = 100 if args.quick else args.calls
    if args.avx512:
        as_on_avx512()
    model, x0 = varint.paper_orbit("R1")
    w0 = np.random.default_rng(1).standard_normal(len(x0))
    w0 /= np.linalg.norm(w0)

    def oneshot():
        return varint.integrate(model, x0, 0.05, tau=0.05, scheme="s15odr8",
                                deviations=w0[:, None])

    def prepared(short=True):
        run = varint.prepare(model, "integrate", 0.05, tau=0.05, scheme="s15odr8",
                             deviations=w0[:, None])
        run(x0)
        if not short:
            # Every call by the general path (older code has none).
            if hasattr(run, "_again"):
                run._again.short = None
            else:
                run._short = None
        return functools.partial(run, x0)

    paths = {"oneshot": (oneshot, STAGES)}
    if "prepared" in args.path:
        paths["prepared"] = (prepared(), SHORT_STAGES if hasattr(
            varint.prepared, "_ShortCall") or hasattr(varint.prepared, "Rerun")
            else PREPARED_STAGES)
    if "prepared_general" in args.path:
        paths["prepared_general"] = (prepared(short=False), PREPARED_STAGES)
    paths = {k: v for k, v in paths.items() if k in args.path}
    for call, _ in paths.values():
        for _ in range(20):
            call()
    load_before = os.getloadavg()
    # Interleaved in rounds of 50 calls, so that the load falls on both.
    found = {k: ([], []) for k in paths}
    for _ in range(max(1, calls // 50)):
        for key, (call, stages) in paths.items():
            rows, whole = profile(call, stages, min(calls, 50))
            found[key][0].append(rows)
            found[key][1].append(whole)
    load = {"before": load_before, "after": os.getloadavg(), "cpus": os.cpu_count()}
    out = {"calls": calls, "load": load, "quick": args.quick, "label": args.label,
           "avx512": args.avx512}
    csv_rows = []
    print(f"one-step call, R1, s15odr8: {calls} calls a path, load {load['before']} -> "
          f"{load['after']} on {load['cpus']} CPUs")
    for key, (rounds, wholes) in found.items():
        # The median of the rounds' medians per stage; the whole call's
        # minimum over all rounds and its median of medians.
        rows = [{**r, "median_us": statistics.median(rr[i]["median_us"] for rr in rounds)}
                for i, r in enumerate(rounds[0])]
        total = rows[0]["median_us"]
        for r in rows:
            r["share"] = r["median_us"] / total
        whole = {"wall_min_us": min(w["wall_min_us"] for w in wholes),
                 "wall_median_us": statistics.median(w["wall_median_us"] for w in wholes),
                 "cpu_min_us": min(w["cpu_min_us"] for w in wholes),
                 "cpu_median_us": statistics.median(w["cpu_median_us"] for w in wholes)}
        if key == "oneshot":
            out.update(stages=rows, whole_call=whole)     # as stored before
        else:
            out[key] = {"stages": rows, "whole_call": whole}
        csv_rows += [{"path": key, **r} for r in rows]
        print(f"{key}: unwrapped wall min {whole['wall_min_us']:.0f} µs, median "
              f"{whole['wall_median_us']:.0f}; CPU min {whole['cpu_min_us']:.0f}, median "
              f"{whole['cpu_median_us']:.0f}")
        for r in rows:
            print(f"{'  ' * r['depth']}{r['stage']:<{44 - 2 * r['depth']}} "
                  f"{r['median_us']:8.1f} µs {r['share']:6.1%}")
    for key, over in (("prepared", "oneshot"), ("prepared", "prepared_general"),
                      ("prepared_general", "oneshot")):
        if key not in found or over not in found:
            continue
        a, b = (out[k]["whole_call"] if k != "oneshot" else out["whole_call"]
                for k in (key, over))
        ratio = out[f"{key}_over_{over}"] = {
            "wall_min": a["wall_min_us"] / b["wall_min_us"],
            "wall_median": a["wall_median_us"] / b["wall_median_us"],
            "cpu_min": a["cpu_min_us"] / b["cpu_min_us"]}
        print(f"{key} / {over}: wall min {ratio['wall_min']:.2f}, median "
              f"{ratio['wall_median']:.2f}; CPU min {ratio['cpu_min']:.2f}")
    name = f"call_profile_{args.label}"
    save_csv(args.out, name, csv_rows, ["path", "depth", "stage", "median_us", "share"])
    save_json(args.out, name, out)
    return out


if __name__ == "__main__":
    main()

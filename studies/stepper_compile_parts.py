"""What one generated stepper's compile time is made of (issue 26 item 5:
the suite's 113 ``batch_serial`` compiles, ≈ 10.7 CPU s each at stop 43).

The one-orbit kernel of a generated module (``orbit``,
:mod:`varint.codegen.interval` around :class:`varint.codegen.tm.TMBody`)
is emitted again with parts of it left out, in the study only (the
product is unchanged; the variants compute other things and are never
run), and each variant's ``orbit`` is compiled in memory for the
signature the real run compiled, CPU seconds of
``Dispatcher.compile`` (numba's front end: bytecode, type inference, SSA,
rewrites, lowering; and LLVM):

* ``today``: the module as emitted;
* ``rule's log inlined``: the accumulator rule's logarithm (MEGNO's,
  FLI's) inlined by numba at each use, as the one-orbit kernel had it
  before gen10 (today it is called, as the schedule's is);
* ``no kick checks``: without the finiteness branch after each group of
  derivatives of every kick (``fin = g0 + g1``, ``if fin - fin != 0.0:
  status = …; break``);
* ``no end of step``: the step and the orbit's escape/finiteness check
  only — no renormalisation, schedule, accumulator, overflow check;
* ``no snapshots``: without the copies at the output steps;
* ``step and loop``: the loop and the step alone (none of the above but
  the kick checks);
* ``step and loop, no kick checks``: the straight-line arithmetic and the
  loop alone.

The differences say what each part costs the front end; ``step and loop``
against ``today`` is what a step compiled once and shared by every
indicator's and level's loop module could save at most per extra module
(idea (a) of the brief; it needs the step to stay inlined at run time).

Every shared kernel (the logarithm, the schedule, the multiply–add) is
compiled by a warm-up run first, as in a test process after its first
stepper; the variants are compiled in turn, ``--repeats`` times, minimum
kept (the machine is shared: each figure's spread is stored too).

Cases: Hénon–Heiles SBAB2C, Lyapunov with one vector (R1); the paper's
C2, MEGNO, ABA864; the three-dof model of Contopoulos et al., MEGNO,
SBAB2C. Usage: ``python studies/stepper_compile_parts.py [--quick]
[--repeats N] [--cases ...]``.
"""

from __future__ import annotations

import os
import shutil
import sys
import tempfile
import time
import types
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import numpy as np  # noqa: E402

import varint  # noqa: E402
from studies.common import parse_args, save_json  # noqa: E402
from varint.codegen import stepper  # noqa: E402
from varint.codegen.interval import Interval  # noqa: E402
from varint.codegen.tm import TMBody  # noqa: E402

R1 = np.array([0.0, 0.558, 0.23337397, 0.0])
THREE_DOF = np.array([0.1, 0.1, 0.1, 0.2, 0.1, 0.15])

#: case -> (model, x0, indicator, options)
CASES = {
    "hh_sbab2c_lyapunov1": (varint.models.HenonHeiles, R1, "lyapunov",
                            {"n_exponents": 1, "scheme": "SBAB2C"}),
    "c2_aba864_megno": (lambda: varint.paper_orbit("C2")[0], varint.paper_orbit("C2")[1],
                        "megno", {"scheme": "ABA864"}),
    "three_dof_sbab2c_megno": (varint.models.ThreeDof, THREE_DOF, "megno",
                               {"scheme": "SBAB2C"}),
}

#: variant -> what it leaves out ("log inlined": what it emits as before gen10)
VARIANTS = {
    "today": (),
    "rule's log inlined": ("log inlined",),
    "no kick checks": ("kick checks",),
    "no end of step": ("end",),
    "no snapshots": ("snapshots",),
    "step and loop": ("end", "snapshots", "check"),
    "step and loop, no kick checks": ("end", "snapshots", "check", "kick checks"),
}


class _Unchecked:
    """A target whose failures are not written (the kick checks left out)."""

    def __init__(self, target):
        self.target = target

    def fail(self, src, condition, value):
        pass

    def __getattr__(self, name):
        return getattr(self.target, name)


class _Body(TMBody):
    def derivatives(self, src, target, label, what):
        super().derivatives(src, _Unchecked(target), label, what)


def emitted(E, plan, acc, left_out):
    """The module's source with the parts ``left_out`` not written."""

    class Cut(Interval):
        def loop(self):
            if not {"end", "check"} & set(left_out):
                return super().loop()
            src = self.src
            src("jo = 0", "while jo < outs.shape[0] and outs[jo] <= step0:", "    jo += 1")
            with src.block("for s in range(n_steps):"):
                src("step = step0 + s + 1")
                self.step()
                if "check" not in left_out:
                    self.check()
                if "snapshots" not in left_out:
                    self.snapshot()
            return None

        def snapshot(self):
            if "snapshots" not in left_out:
                super().snapshot()

        def accumulate_rule(self):
            self._log()
            super().accumulate_rule()

        def columns_out(self, j, target):
            self._log()
            super().columns_out(j, target)

        def _log(self):
            # Before gen10, one orbit's rule inlined the logarithm's IR as
            # the lanes do.
            if "log inlined" in left_out:
                self.t.log = "vlog"

    body_type = _Body if "kick checks" in left_out else TMBody
    body = body_type(E, plan.kinds, plan.corrected, plan.k, plan.compensated)
    return Cut(body, plan.k, acc).module(plan.accumulator)


def measure(case, repeats):
    make, x0, indicator, options = CASES[case]
    captured = []
    original = stepper.generated_source

    def capture(E, plan, accumulator=None):
        captured.append((E, plan, accumulator))
        return original(E, plan, accumulator)

    # Warm-up: the shared kernels, compiled once per process in the suite.
    varint.run(make(), x0, indicator, 10.0, 0.05, progress=False,
               **{**options, "scheme": "SABA1"})
    stepper.generated_source = capture
    try:
        varint.run(make(), x0, indicator, 10.0, 0.05, progress=False, **options)
    finally:
        stepper.generated_source = original
    E, plan, acc = captured[-1]
    module = stepper._LOADED[stepper._digest(stepper.model_key(make()), plan)]
    signature = module.orbit.signatures[0]
    sources = {name: emitted(E, plan, acc, cut) for name, cut in VARIANTS.items()}
    seconds: dict = {name: [] for name in VARIANTS}
    for turn in range(repeats):
        for name, text in sources.items():
            fresh = types.ModuleType(f"varint_stepper_parts_{turn}_{len(seconds[name])}")
            exec(compile(text.replace("cache=True", "cache=False"), fresh.__name__, "exec"),
                 fresh.__dict__)
            start = time.process_time()
            fresh.orbit.compile(signature)
            seconds[name].append(time.process_time() - start)
    best = {name: min(s) for name, s in seconds.items()}
    rows = {name: {"CPU s": round(best[name], 3),
                   "of today": round(best[name] / best["today"], 3),
                   "turns": [round(s, 3) for s in seconds[name]],
                   "source lines": len(sources[name].splitlines())} for name in VARIANTS}
    return {"plan": {"stages": len(plan.kinds), "k": plan.k,
                     "accumulator": plan.accumulator[:40]}, "rows": rows}


def main(argv=None):
    def extra(parser):
        parser.add_argument("--repeats", type=int, default=3)
        parser.add_argument("--cases", nargs="*", default=list(CASES), choices=list(CASES))

    args = parse_args(__doc__.splitlines()[0], argv, extra)
    # A cache of its own: every stepper's source is emitted in this process.
    os.environ["VARINT_CACHE_DIR"] = tempfile.mkdtemp(prefix="varint-compile-parts-")
    load_start = os.getloadavg()
    result = {}
    for case in args.cases:
        result[case] = measure(case, 1 if args.quick else args.repeats)
        print(case, result[case]["plan"])
        print(f"  {'variant':32s} {'CPU s':>7s} {'of today':>9s}  turns")
        for name, row in result[case]["rows"].items():
            print(f"  {name:32s} {row['CPU s']:7.2f} {row['of today']:9.2f}  {row['turns']}")
    save_json(args.out, "stepper_compile_parts",
              {"cases": result, "load_start": load_start, "load_end": os.getloadavg(),
               "repeats": args.repeats})
    shutil.rmtree(os.environ["VARINT_CACHE_DIR"], ignore_errors=True)


if __name__ == "__main__":
    main()

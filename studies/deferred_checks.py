"""Whether checking a generated step's derivatives once per step instead of
at every kick makes the step cheaper (issue 27: C2 at 1e-10 against
heyoka). Answer on this machine: no, it makes it slower.

The generated TM step (:class:`varint.codegen.tm.TMBody`) checks the
derivatives of every kick where it evaluates them (``fin = g0 + g1``,
``if fin - fin != 0.0: fail``): ≈ 7 of ≈ 31 floating-point operations of a
Hénon–Heiles stage with one vector (c2front8), so checking once per step
looked like the next 10–20 %. Two variants are emitted here, in the study
only (the product is unchanged), and timed against the step as it is
(``checked``):

* ``deferred``: no check at the kicks; at the step's end one check of the
  orbit's squares and the vectors' components (a derivative that was not
  finite leaves a non-finite component: p_i ← p_i − h g_i and
  δp_i ← δp_i − h H_il δq_l make it non-finite, and every later update
  adds to it), and on failure the step is redone from copies of the
  step's start with the checks at every kick, so that the status, step,
  state and counters are today's (the design the issue asked for);
* ``marked``: the same end-of-step check without the copies and the
  redo (a lower bound on what deferring can save; it would need the caller
  to recompute a failed orbit, as after SIMD lanes).

Case: the paper's C2 with one unit tangent vector, renormalised every
step, τ = 0.2 to t = 1e3 (``--quick``: t = 200), s35odr10 (the 1e-10
race's scheme), SRKN14a and SBAB2C at each compensation level; the
one-orbit stepper (``batch_serial``, compiled in memory), CPU time of one
call on one thread, the minimum over the repeats of all contenders called
in turn (:func:`studies.common.interleaved`), each ratio's spread over
the turns; every variant must give the ``checked`` bits (checked here).
The compile time of each module is stored too.

Usage: ``python studies/deferred_checks.py [--quick] [--repeats N]
[--schemes S ...] [--out DIR]``
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import numba  # noqa: E402
import numpy as np  # noqa: E402

import varint  # noqa: E402
from studies.bench_peers import seeded_vectors  # noqa: E402
from studies.common import interleaved, parse_args, ratio_spread, save_json  # noqa: E402
from varint import codecache  # noqa: E402
from varint.codegen.expressions import ensure_form, expressions, model_key  # noqa: E402
from varint.codegen.interval import (CompensatedOrbit, Interval, Outputs,  # noqa: E402
                                     StepperOrbit, StepperSetup)
from varint.codegen.tm import TMBody  # noqa: E402
from varint.kernels.interval import Call  # noqa: E402
from varint.protocol import Renorm  # noqa: E402
from varint.schemes import DRIFT, get_scheme, stage_arrays  # noqa: E402

SCHEMES = ("s35odr10", "SRKN14a", "SBAB2C")
LEVELS = (False, "orbit", True)
TAU = 0.2


class _Quiet:
    """A target whose failures are not emitted: the kicks' checks of
    :meth:`TMBody.derivatives` are dropped (their sums, unused, are removed
    by the compiler); everything else is the target's."""

    def __init__(self, target):
        self.target = target

    def __getattr__(self, name):
        return getattr(self.target, name)

    def fail(self, src, condition, value):
        pass


class Marked(TMBody):
    """No check at the kicks; one at the step's end, which only marks the
    orbit (module docstring)."""

    def end_check(self, src):
        squares = [f"{v} * {v}" for v in self.q + self.p]
        vectors = [self.component(i, j) for j in range(self.k) for i in range(2 * self.n)]
        src(f"fin = {' + '.join(squares + vectors)}")
        return "fin - fin != 0.0"

    def step(self, src, target):
        super().step(src, _Quiet(target))
        target.fail(src, self.end_check(src), 1)


class Deferred(Marked):
    """No check at the kicks; one at the step's end, and on failure the
    step redone from its start with the checks at every kick (module
    docstring)."""

    def restartable(self):
        """The locals a step changes before it reads them again: the orbit,
        the vectors, the compensations, the values a BAB step's first kick
        reuses, the counters."""
        names = [self.coordinate(i) for i in range(2 * self.n)]
        names += [self.component(i, j) for j in range(self.k) for i in range(2 * self.n)]
        names += [self.compensation(name) for name in names if self.compensates(name)]
        return names + self.carried() + list(self.counters())

    def step(self, src, target):
        names = self.restartable()
        src(*(f"was_{name} = {name}" for name in names))
        TMBody.step(self, src, _Quiet(target))
        with src.block(f"if {self.end_check(src)}:"):
            src(*(f"{name} = was_{name}" for name in names))
            TMBody.step(self, src, target)


VARIANTS = {"checked": TMBody, "marked": Marked, "deferred": Deferred}


def stepper(E, scheme, k, level, body_type):
    """The one-orbit ``batch_serial`` of ``body_type`` (a
    :data:`VARIANTS` body) for expressions ``E`` (compiled in memory on
    first call) and its stage arrays at :data:`TAU`."""
    kinds, h, hc = stage_arrays(get_scheme(scheme), TAU)
    body = body_type(E, kinds, (hc != 0.0) & (kinds != DRIFT), k, level)
    source = Interval(body, k, None).module("")
    name = f"varint_study_deferred_{body_type.__name__}_{scheme}_{level}".lower()
    module = codecache.load_module(name, "kernels", lambda: source, on_disk=False)
    return module.batch_serial, StepperSetup(h, hc, 0)


def runner(kernel, setup, level, x0, w0, n):
    """``run() -> (x, W)``: ``n`` steps of one orbit with the vector
    renormalised every step, from (x0, w0)."""
    d, k = len(x0), 1
    outputs = Outputs(np.zeros(0, dtype=np.int64), np.empty((0, 1, d)), np.empty((0, 1, d, k)),
                      np.ones((0, 1, k)), np.zeros((0, 1, k), dtype=np.int64),
                      np.empty((0, 1, k, 0)))
    call = Call(n, 0, TAU, int(Renorm.QR), np.inf)

    def run():
        x, W = x0[None].copy(), w0[None, :, None].copy()
        record = (x, W, np.ones((1, k)), np.zeros((1, k), dtype=np.int64),
                  np.empty((1, k, 0)), np.zeros((1, 4), dtype=np.int64),
                  np.ones((1, 2), dtype=np.int64))
        record = CompensatedOrbit(*record, np.zeros((1, d, 1 + k))) if level \
            else StepperOrbit(*record)
        status, done = np.zeros(1, dtype=np.int64), np.zeros(1, dtype=np.int64)
        kernel(record, setup, call, outputs, status, done)
        assert status[0] == 0
        return x[0], W[0, :, 0]
    return run


def main(argv=None):
    def extra(parser):
        parser.add_argument("--repeats", type=int, default=9,
                            help="turns of the interleaved timing")
        parser.add_argument("--schemes", nargs="*", default=list(SCHEMES))

    args = parse_args(__doc__.splitlines()[0], argv, extra=extra)
    numba.set_num_threads(1)
    load = {"before": list(os.getloadavg()), "cpus": os.cpu_count()}
    model, x0 = varint.paper_orbit("C2")
    x0 = np.asarray(x0, dtype=float)
    w0 = seeded_vectors(model.dim, 1, 1, seed=0)[0][:, 0]
    key = model_key(model)
    ensure_form(model, key)
    E = expressions(key)
    n = round((200.0 if args.quick else 1e3) / TAU)
    tasks, compile_seconds = {}, {}
    for scheme in args.schemes:
        for level in LEVELS:
            for tag, body_type in VARIANTS.items():
                kernel, setup = stepper(E, scheme, 1, level, body_type)
                label = f"{scheme} {level} {tag}"
                tasks[label] = runner(kernel, setup, level, x0, w0, n)
                c0 = time.process_time()
                tasks[label]()                                # compiles
                compile_seconds[label] = time.process_time() - c0
    repeats = 2 if args.quick else args.repeats
    turns: dict = {}
    best, out = interleaved(tasks, repeats, clock=time.process_time, turns=turns)
    load["after"] = list(os.getloadavg())
    rows = []
    for scheme in args.schemes:
        for level in LEVELS:
            base = f"{scheme} {level} checked"
            for tag in VARIANTS:
                label = f"{scheme} {level} {tag}"
                if not all(u.tobytes() == v.tobytes()
                           for u, v in zip(out[label], out[base], strict=True)):
                    raise AssertionError(f"{label}: not the bits of the checked step")
                rows.append({"scheme": scheme, "level": str(level), "variant": tag, "steps": n,
                             "ms": best[label] * 1e3,
                             "speedup_vs_checked": best[base] / best[label],
                             "spread": ratio_spread(turns, label, base),
                             "compile_s": compile_seconds[label]})
    result = {"rows": rows, "load": load, "repeats": repeats, "quick": args.quick,
              "orbit": "C2", "tau": TAU, "clock": "process CPU time, 1 thread"}
    save_json(args.out, "deferred_checks", result)
    print(f"load {load}")
    print(f"{'scheme':9s} {'level':6s} {'variant':9s} {'ms':>8s} {'vs checked':>11s} "
          f"{'spread':>13s} {'compile s':>10s}")
    for r in rows:
        lo, hi = r["spread"] or (np.nan, np.nan)
        print(f"{r['scheme']:9s} {r['level']:6s} {r['variant']:9s} {r['ms']:8.3f} "
              f"{r['speedup_vs_checked']:11.3f} {lo:6.3f}–{hi:6.3f} {r['compile_s']:10.2f}")
    return result


if __name__ == "__main__":
    main()

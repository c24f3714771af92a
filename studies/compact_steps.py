"""The compact TM stepper against the stepper with its stages written out
(issue 26: compile seconds, run speed, bits).

A generated TM stepper writes every stage of its scheme out as straight-line
code (:meth:`varint.codegen.tm.TMBody.stages`), so a 29-stage SRKN14a kernel
holds 14 copies of the force, Hessian and tangent-kick code, and numba's
compile time follows the size of the source (``compile_cost.py``). The
compact stepper (:meth:`varint.codegen.tm.TMBody.compact_stages`) is one
loop over the stage arrays with the same floating-point operations in the
same order. Measured here, for each form (forced through
:attr:`varint.methods.tm.TangentMapPropagator.COMPACT_WORK`):

1. compile: the first call of each case in ``--repeats`` new interpreters
   with empty varint and numba caches (``compile_cost.py``'s child, numba's
   compile seconds and the process CPU), median over repeats, the forms
   interleaved;
2. speed: ns per step (CPU) of long one-orbit runs in one process, the two
   forms interleaved, best of the repeats (``bench_stepper.py``'s Hénon–
   Heiles R1 cases: the orbit alone by ABA864, the spectrum by SBAB2C with
   QR every step and sparse; and SRKN14a compensated, s35odr10 with the
   orbit compensated);
3. bits: every case's result is compared between the forms (its bytes).

Stored as ``results/suite18/compact_steps.json``.

Usage: ``python studies/compact_steps.py [--repeats N] [--quick] [--out DIR]``
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from studies.common import RESULTS, STARTED, interleaved, parse_args, save_json  # noqa: E402
from studies.compile_cost import CHILD  # noqa: E402

#: COMPACT_WORK of each form: every one-orbit call below it runs compact.
FORMS = {"written out": 0, "compact": 10 ** 18}

_R1 = "m, x0 = varint.paper_orbit('R1'); w = np.eye(4)[:, :1]; "
#: The first call of each case (sets ``value``, whose bytes are compared).
CASES = {
    "R1 SRKN14a compensated, 1 vector": (
        _R1 + "r = varint.integrate(m, x0, 5.0, tau=0.05, scheme='SRKN14a', compensated=True, "
        "deviations=w); value = np.concatenate([r.state.ravel(), r.deviations.ravel()])"),
    "R1 SRKN14a, 1 vector": (
        _R1 + "r = varint.integrate(m, x0, 5.0, tau=0.05, scheme='SRKN14a', deviations=w); "
        "value = np.concatenate([r.state.ravel(), r.deviations.ravel()])"),
    "R1 ABA864 spectrum (k = 4)": (
        _R1 + "r = varint.lyapunov_spectrum(m, x0, t_end=5.0, tau=0.05, scheme='ABA864', "
        "progress=False); value = r.exponents"),
    "C2 s35odr10 orbit-compensated, 1 vector": (
        "m, x0 = varint.paper_orbit('C2'); w = np.eye(m.dim)[:, :1]; "
        "r = varint.integrate(m, x0, 5.0, tau=0.2, scheme='s35odr10', compensated='orbit', "
        "deviations=w); value = np.concatenate([r.state.ravel(), r.deviations.ravel()])"),
    "R1 MEGNO SBAB2C": (
        _R1 + "r = varint.megno(m, x0, t_end=5.0, tau=0.05, progress=False); value = r.megno"),
}


def child(case, work):
    """One new interpreter with empty caches running ``case`` with
    ``COMPACT_WORK = work``: compile_cost.py's measurements as a dict."""
    code = ("import varint, varint.methods.tm, numpy as np\n"
            f"varint.methods.tm.TangentMapPropagator.COMPACT_WORK = {work!r}\n"
            + CASES[case])
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, VARINT_CACHE_DIR=os.path.join(cache, "varint"),
                   NUMBA_CACHE_DIR=os.path.join(cache, "numba"))
        program = f"CASE = {code!r}\nPROFILE = False\n" + CHILD
        done = subprocess.run([sys.executable, "-c", program], env=env, capture_output=True,
                              text=True)
    if done.returncode:
        raise RuntimeError(f"case {case!r} failed:\n{done.stderr[-3000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def compile_rows(cases, repeats):
    """Per case and form: median compile and CPU seconds, dispatcher
    compiles, and whether the forms gave the same bytes."""
    raw: dict = {}
    for _ in range(repeats):
        for case in cases:
            for form, work in FORMS.items():
                raw.setdefault(case, {}).setdefault(form, []).append(child(case, work))
    rows = []
    for case, forms in raw.items():
        row: dict = {"case": case}
        for form, runs in forms.items():
            row[form] = {"compile s": round(statistics.median(r["compile"] for r in runs), 2),
                         "process CPU s": round(statistics.median(r["cpu"] for r in runs), 2),
                         "dispatcher compiles": len(runs[0]["compiles"])}
        # numba's compile seconds are wall time (its event API): on a
        # loaded machine the process CPU is the steadier figure.
        row["compile ratio"] = round(row["written out"]["compile s"]
                                     / row["compact"]["compile s"], 2)
        row["process CPU ratio"] = round(row["written out"]["process CPU s"]
                                         / row["compact"]["process CPU s"], 2)
        row["same bits"] = len({r["value"] for runs in forms.values() for r in runs}) == 1
        rows.append(row)
    return rows


#: Long one-orbit runs (bench_stepper.py's Hénon–Heiles cases and two
#: long schemes): (orbit, scheme, renorm, k, options, steps per call).
SPEED = {
    "HH orbit only, ABA864": ("R1", "ABA864", "none", 0, {}, 1.0),
    "R1 spectrum SBAB2C, QR every step": ("R1", "SBAB2C", "qr", 4, {"renormalize_every": 1}, 0.5),
    "R1 spectrum SBAB2C, sparse": ("R1", "SBAB2C", "qr", 4, {}, 0.5),
    "R1 SRKN14a compensated, 1 vector": ("R1", "SRKN14a", "none", 1, {"compensated": True},
                                         0.2),
    "C2 s35odr10 orbit-compensated, 1 vector": ("C2", "s35odr10", "none", 1,
                                                {"compensated": "orbit"}, 0.05),
}


def speed_rows(n_steps, repeats):
    """ns per step (CPU) of each form, interleaved, and the ratio; and
    whether the forms end in the same bits."""
    import varint
    from varint.methods.tm import TangentMapPropagator
    from varint.state import RunState

    tasks, labels = {}, []
    for case, (orbit, scheme, renorm, k, options, share) in SPEED.items():
        model, x0 = varint.paper_orbit(orbit)
        steps = max(1, int(n_steps * share))
        for form, work in FORMS.items():
            prop = TangentMapPropagator(model, 0.05, renorm, scheme=scheme, **options)
            prop.COMPACT_WORK = work

            def run(prop=prop, x0=x0, k=k, steps=steps):
                state = RunState.start(x0[None], np.eye(x0.size)[:, :k][None].copy())
                t0 = time.process_time()
                prop.advance(state, steps)
                return (time.process_time() - t0) / steps * 1e9, state

            run(steps=10)                                  # compile
            tasks[case, form] = run
        labels.append(case)
    best, out = interleaved(tasks, repeats, self_timed=set(tasks))
    rows = []
    for case in labels:
        a, b = out[case, "written out"], out[case, "compact"]
        rows.append({"case": case, "written out ns/step": round(best[case, "written out"], 2),
                     "compact ns/step": round(best[case, "compact"], 2),
                     "compact / written out": round(best[case, "compact"]
                                                    / best[case, "written out"], 4),
                     "same bits": bool(np.array_equal(a.x, b.x) and np.array_equal(a.W, b.W)
                                       and np.array_equal(a.acc_m, b.acc_m))})
    return rows


def main(argv=None):
    def extra(parser):
        parser.add_argument("--repeats", type=int, default=2)
        parser.add_argument("--skip-compile", action="store_true")

    args = parse_args(__doc__.split("\n\n")[0], argv, extra)
    out = args.out if args.out != RESULTS else RESULTS / "suite18"
    out.mkdir(parents=True, exist_ok=True)
    cases = list(CASES)[:2] if args.quick else list(CASES)
    compile_ = [] if args.skip_compile else compile_rows(cases, args.repeats)
    for row in compile_:
        print(f"{row['case']:42} compile {row['written out']['compile s']:7.2f} s written out, "
              f"{row['compact']['compile s']:7.2f} s compact ({row['compile ratio']}x; process "
              f"CPU {row['process CPU ratio']}x); "
              f"same bits {row['same bits']}")
    speed = speed_rows(20_000 if args.quick else 2_000_000, 2 if args.quick else 5)
    for row in speed:
        print(f"{row['case']:42} {row['written out ns/step']:9.2f} {row['compact ns/step']:9.2f}"
              f" ns/step  ratio {row['compact / written out']:.4f}  same bits {row['same bits']}")
    load_end = os.getloadavg()
    save_json(out, "compact_steps", {"compile": compile_, "speed": speed,
                                     "repeats": args.repeats, "loadavg at start": STARTED["load"],
                                     "loadavg at end": load_end})


if __name__ == "__main__":
    main()

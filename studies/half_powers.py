"""Half-integer powers in the generated constant-step stepper: ``pow``
against products and a square root (:mod:`varint.codegen.printer`), this
code against a baseline copy of varint that still prints ``b**(3/2)``.

Three models whose derivatives hold b^(p/2), p odd, each integrated with
one deviation vector (as an FLI or a Lyapunov exponent runs it) by the TM
method's generated stepper with SRKN14a at a fixed step:

* ``cr3bp``: the Sun–Jupiter restricted three-body problem, the regular
  orbit ``cr3bp_orbit("sun-jupiter-regular")`` (rotating frame, A's exact
  drift), τ = 0.05 to t = 1000;
* ``plummer``: a flattened Plummer sphere V = −1/√(1 + x² + y²/0.8²),
  q = (0.5, 0), p = (0, 0.5), τ = 0.05 to t = 1000;
* ``kepler``: the Kepler problem V = −1/√(x² + y²), q = (1, 0),
  p = (0, 1.2) (e = 0.44, starting at the pericentre), τ = 0.01 to t = 200.

(The planetary models are not among them: their ``tm`` runs take the part
stepper with the Kepler drift, whose interaction kernels are not printed
from SymPy, and are unchanged.)

Each code runs in its own worker process (``python -c`` with the code's
directory first on ``sys.path``); the workers alternate (interleaved
rounds); each takes the minimum CPU time of its repeated runs after a first
run that compiles or loads the stepper; the result is the minimum over
rounds, in ns per step. The workers also return the state and the vector
after one step and after the whole run, and the operations the step cost
model counts in one emitted step (:func:`varint.step_cost.
constant_gradient_cost`: ``pow`` calls, square roots, its predicted cost):
the relative differences between the codes show the change is round-off
(one step: a few units in the last place; the run: what a regular orbit's
round-off grows to, beside the baseline's own difference between x0 and
x0 moved by one unit in the last place, ``nudged``).

Usage::

    git archive main varint | tar -x -C /tmp/base
    python studies/half_powers.py --baseline /tmp/base [--quick]

Results ``half_powers.json`` (``quick/half_powers.json``: 2 rounds, 2
repeats). State the machine load (recorded) with every figure.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from studies.common import parse_args, save_json  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]

#: The worker: run in a fresh interpreter with one code's directory first
#: on sys.path; prints one JSON line.
WORKER = r"""
import json, sys, time
sys.path.insert(0, sys.argv[1])
import numpy as np
import sympy as sp
import varint
from varint.models import cr3bp_orbit, from_potential
from varint.codegen.expressions import symbolic_fits
from varint.step_cost import constant_gradient_cost
repeats = int(sys.argv[2])
x, y = sp.symbols("x y")
cases = {
    "cr3bp": (*cr3bp_orbit("sun-jupiter-regular"), 0.05, 1000.0),
    "plummer": (from_potential(-1 / sp.sqrt(1 + x**2 + y**2 / sp.Rational(16, 25)), [x, y],
                               name="flattened Plummer"), np.array([0.5, 0.0, 0.0, 0.5]),
                0.05, 1000.0),
    "kepler": (from_potential(-1 / sp.sqrt(x**2 + y**2), [x, y], name="Kepler"),
               np.array([1.0, 0.0, 0.0, 1.2]), 0.01, 200.0),
}
out = {"varint": varint.__file__}
for name, (model, x0, tau, t_end) in cases.items():
    assert symbolic_fits(model, 1), name   # the generated stepper runs it
    w = np.zeros((len(x0), 1))
    w[0, 0] = 1.0
    def call(t):
        return varint.integrate(model, x0, t, tau=tau, scheme="SRKN14a", deviations=w)
    one = call(tau)
    r = call(t_end)
    # The same code from x0 one unit in the last place away: the size of
    # a round-off difference after this run, to compare the codes with.
    nudged = varint.integrate(model, x0 + np.spacing(x0), t_end, tau=tau, scheme="SRKN14a",
                              deviations=w)
    cpu = float("inf")
    for _ in range(repeats):
        c0 = time.process_time()
        call(t_end)
        cpu = min(cpu, time.process_time() - c0)
    cost, counts = constant_gradient_cost(model, "SRKN14a", 1, None)
    steps = round(t_end / tau)
    out[name] = {"ns_per_step": cpu / steps * 1e9, "steps": steps, "tau": tau, "t_end": t_end,
                 "one_step": [*one.state.ravel().tolist(), *one.deviations.ravel().tolist()],
                 "end": [*r.state.ravel().tolist(), *r.deviations.ravel().tolist()],
                 "nudged": [*nudged.state.ravel().tolist(),
                            *nudged.deviations.ravel().tolist()],
                 "energy_error": float(np.max(np.abs(r.energy_error))),
                 "cost_per_force": cost, "pow": counts.get("pow", 0),
                 "sqrt": counts.get("sqrt", 0)}
print(json.dumps(out))
"""

#: The models each worker runs (:data:`WORKER`).
CASES = ("cr3bp", "plummer", "kepler")


def worker(code_dir, repeats):
    """One worker's minima (see :data:`WORKER`)."""
    done = subprocess.run([sys.executable, "-c", WORKER, str(code_dir), str(repeats)],
                          capture_output=True, text=True, check=True, env=dict(os.environ))
    return json.loads(done.stdout.strip().splitlines()[-1])


def _relative(a, b):
    """max |a − b| / max |b| over two lists of numbers."""
    diff = max(abs(u - v) for u, v in zip(a, b, strict=True))
    return diff / max(abs(v) for v in b)


def main(argv=None):
    def extra(parser):
        parser.add_argument("--baseline", type=Path, default=None,
                            help="directory holding the baseline's varint package (default: "
                                 "this code itself, which measures only the noise)")
        parser.add_argument("--rounds", type=int, default=5)
        parser.add_argument("--repeats", type=int, default=5)

    args = parse_args(__doc__.splitlines()[0], argv, extra)
    rounds, repeats = (2, 2) if args.quick else (args.rounds, args.repeats)
    baseline = ROOT if args.baseline is None else args.baseline.resolve()
    contenders = {"this": ROOT, "baseline": baseline}
    best: dict = {}
    load = [os.getloadavg()[0]]
    for _ in range(rounds):
        for label, code in contenders.items():
            got = worker(code, repeats)
            for case in CASES:
                b = best.setdefault(label, {}).setdefault(case, dict(got[case]))
                b["ns_per_step"] = min(b["ns_per_step"], got[case]["ns_per_step"])
                if b["end"] != got[case]["end"]:
                    raise RuntimeError(f"{label} {case}: results differ between workers")
    load.append(os.getloadavg()[0])
    summary = {}
    for case in CASES:
        this, base = best["this"][case], best["baseline"][case]
        summary[case] = {"this_ns_per_step": this["ns_per_step"],
                         "baseline_ns_per_step": base["ns_per_step"],
                         "ratio": base["ns_per_step"] / this["ns_per_step"],
                         "pow_per_step": [base["pow"], this["pow"]],
                         "sqrt_per_step": [base["sqrt"], this["sqrt"]],
                         "predicted_ratio": base["cost_per_force"] / this["cost_per_force"],
                         "one_step_relative_difference": _relative(this["one_step"],
                                                                   base["one_step"]),
                         "end_relative_difference": _relative(this["end"], base["end"]),
                         "nudged_relative_difference": _relative(base["nudged"], base["end"]),
                         "energy_error": [base["energy_error"], this["energy_error"]]}
    data = {"rounds": rounds, "repeats": repeats, "baseline": str(args.baseline),
            "load_1min": load, "best": best, "summary": summary}
    save_json(args.out, "half_powers", data)
    print(f"load (1 min) {load[0]:.1f} -> {load[1]:.1f}; ns per step, min of "
          f"{rounds} rounds x {repeats} repeats, CPU time")
    print("| model | pow/step before -> after | sqrt/step | before ns | after ns | ratio "
          "| predicted | one step rel. diff | end rel. diff | x0 + 1 ulp, before |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for case in CASES:
        s = summary[case]
        print(f"| {case} | {s['pow_per_step'][0]} -> {s['pow_per_step'][1]} "
              f"| {s['sqrt_per_step'][0]} -> {s['sqrt_per_step'][1]} "
              f"| {s['baseline_ns_per_step']:.0f} | {s['this_ns_per_step']:.0f} "
              f"| {s['ratio']:.2f}x | {s['predicted_ratio']:.2f}x "
              f"| {s['one_step_relative_difference']:.1e} | {s['end_relative_difference']:.1e} "
              f"| {s['nudged_relative_difference']:.1e} |")
    return data


if __name__ == "__main__":
    main()

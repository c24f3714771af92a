"""The defaults on a single short orbit: what the automatic step's pilots
cost against the run they choose, this code against a baseline copy of
varint (issues 28/29: on the bar orbit at t = 100 the pilots cost ≈ 10× the
run, every pilot covering the whole run and the part stepper, which took
no snapshots, advancing to each of a pilot's 50 checks in its own call).

Systems (:data:`SYSTEMS`): the rotating bar's regular and chaotic orbits
(:func:`varint.models.bar.bar_orbit`, t = 100, the hamiltonians study's
call: one deviation vector of equal components, one output), the
parametrically driven pendulum V = −cos q (1 + cos(3t/2)/5) in its chaotic
layer (time-dependent V, the generic TM stepper, t = 100), an FPU-β chain of
20 particles and a disordered Klein–Gordon chain of 32 sites (the part
stepper, t = 20, the fingerprints' states), each ``lyapunov_spectrum``
with one exponent; and, for the fixed cost of a call on other kinds of
model (issue 28), the paper's R1 orbit of Hénon–Heiles (a potential
model, t = 100) and two held-out ``from_hamiltonian`` models of
:mod:`studies.general_h_heldout` ("relativistic", separable, and "angular
coupling", general; t = 100), with the defaults' spectrum.

Per system and code, each a minimum over calls and then over interleaved
rounds (a worker process per code and round, ``python -c`` with the code's
directory first on ``sys.path``):

* ``defaults_ms``: the call without τ (pilots included);
* ``pilot_ms``: its :func:`varint.stepsize.choose_step` alone (timed
  inside the same calls);
* ``run_ms``: the same call at the τ the pilots chose;
* ``t1_ms``: the call at that τ to t = 1 (the fixed cost per call), and
  ``t1_cpu_ms`` the same in CPU time (``time.process_time``, less
  sensitive to the other processes of a shared machine);

and the SHA-256 of the defaults', the given τ's and the t = 1 call's
results: every array, the accuracy verdict and the provenance but its
clock (wall and CPU time, timing, creation time, the machine's load) and
the code's commit, source digest and "modified" flag (``sha256_*``): the
two codes must agree bitwise.

Usage::

    git worktree add /tmp/base 3556484
    python studies/short_run_cost.py --baseline /tmp/base
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

#: The systems each worker times (:data:`WORKER`).
SYSTEMS = ("bar regular", "bar chaotic", "forced pendulum", "FPU-beta 20", "KG 32", "R1",
           "relativistic", "angular coupling")

#: The worker: one code's minima, one JSON line.
WORKER = r"""
import dataclasses, hashlib, json, sys, time
sys.path.insert(0, sys.argv[1])
import numpy as np
import sympy as sp
import varint
from varint import stepsize
from varint.models import DisorderedKG, FPUBeta, from_potential
from varint.models.bar import bar_orbit
from varint.models import from_hamiltonian
from studies.general_h_heldout import heldout

calls = int(sys.argv[2])
q, t = sp.symbols("q t")
forced = from_potential(-sp.cos(q) * (1 + sp.Rational(1, 5) * sp.cos(sp.Rational(3, 2) * t)),
                        [q], time=t)
fpu = FPUBeta(20, 1.0)
x_fpu = np.concatenate([0.1 * np.sin(np.arange(1, 21)), 0.05 * np.cos(np.arange(1, 21))])
kg = DisorderedKG(32, W=4.0, seed=1)
w_bar = np.full((6, 1), 1 / np.sqrt(6))
bar_kw = {"deviations": w_bar, "t_out": [100.0]}
systems = {"bar regular": (*bar_orbit("regular"), 100.0, bar_kw),
           "bar chaotic": (*bar_orbit("chaotic"), 100.0, bar_kw),
           "forced pendulum": (forced, np.array([0.0, 2.0]), 100.0, {}),
           "FPU-beta 20": (fpu, x_fpu, 20.0, {}),
           "KG 32": (kg, kg.initial_block(4, 0.4), 20.0, {}),
           "R1": (*varint.paper_orbit("R1"), 100.0, {})}
for name in ("relativistic", "angular coupling"):
    H, qs, ps, x0, _ = heldout()[name]
    systems[name] = (from_hamiltonian(H, qs, ps, name=name), np.array(x0), 100.0, {})
pilot = []
choose = stepsize.choose_step


def timed_choice(*args, **kwargs):
    t0 = time.perf_counter()
    out = choose(*args, **kwargs)
    pilot.append(time.perf_counter() - t0)
    return out


stepsize.choose_step = timed_choice


CLOCK = {"wall_time", "cpu_time", "timing", "created"}


def digest(r):
    h = hashlib.sha256()
    for f in dataclasses.fields(r):
        v = getattr(r, f.name)
        if f.name == "provenance":
            d = {g.name: getattr(v, g.name) for g in dataclasses.fields(v)
                 if g.name not in CLOCK}
            d["code"] = {k: c for k, c in d["code"].items() if k not in ("commit", "source", "modified")}
            d["machine"] = {k: c for k, c in d["machine"].items() if k != "load"}
            h.update(json.dumps(d, sort_keys=True, default=repr).encode())
            continue
        if f.name == "accuracy":
            v = {g.name: getattr(v, g.name) for g in dataclasses.fields(v)}
        if isinstance(v, dict):
            for key in sorted(v):
                w = v[key]
                items = sorted(w.items()) if isinstance(w, dict) else [("", w)]
                for k, a in items:
                    h.update(f"{key}.{k}".encode())
                    h.update(repr(type(a)).encode() + np.ascontiguousarray(a).tobytes())
        else:
            h.update(repr(type(v)).encode() + np.ascontiguousarray(v).tobytes())
    return h.hexdigest()


out = {"varint": varint.__file__}
for name, (model, x0, t_end, kw) in systems.items():
    r = varint.lyapunov_spectrum(model, x0, t_end, **kw)
    tau = r.provenance.tau
    given = varint.lyapunov_spectrum(model, x0, t_end, tau=tau, **kw)
    short = {**kw, "t_out": None} if "t_out" in kw else kw
    tau1 = 1.0 / round(1.0 / tau) if tau < 1 else 1.0
    t1 = lambda: varint.lyapunov_spectrum(model, x0, 1.0, tau=tau1, **short)
    # (Two calls: a repeated call may take another path than the first.)
    row = {"tau": tau, "pilots": len(r.provenance.tau_choice["tried"]),
           "sha256_defaults": digest(r), "sha256_given": digest(given),
           "sha256_t1": digest(t1()) + digest(t1())}
    tasks = {"defaults_ms": lambda: varint.lyapunov_spectrum(model, x0, t_end, **kw),
             "run_ms": lambda: varint.lyapunov_spectrum(model, x0, t_end, tau=tau, **kw),
             "t1_ms": t1, "t1_cpu_ms": t1}
    for label, task in tasks.items():
        clock = time.process_time if label == "t1_cpu_ms" else time.perf_counter
        task()
        best = float("inf")
        for _ in range(calls):
            del pilot[:]
            t0 = clock()
            task()
            best = min(best, clock() - t0)
            if label == "defaults_ms":
                row["pilot_ms"] = min(row.get("pilot_ms", float("inf")), pilot[0] * 1e3)
        row[label] = best * 1e3
    out[name] = row
print(json.dumps(out))
"""


def worker(code_dir, calls):
    """One worker's minima (see :data:`WORKER`)."""
    done = subprocess.run([sys.executable, "-c", WORKER, str(code_dir), str(calls)],
                          capture_output=True, text=True, check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def main(argv=None):
    def extra(parser):
        parser.add_argument("--baseline", type=Path, default=None,
                            help="directory holding the baseline's varint package (default: "
                                 "this code itself, which measures only the noise)")
        parser.add_argument("--rounds", type=int, default=3)
        parser.add_argument("--calls", type=int, default=15)

    args = parse_args(__doc__.splitlines()[0], argv, extra)
    rounds, calls = (1, 2) if args.quick else (args.rounds, args.calls)
    baseline = ROOT if args.baseline is None else args.baseline.resolve()
    contenders = {"this": ROOT, "baseline": baseline}
    keys = ("defaults_ms", "pilot_ms", "run_ms", "t1_ms", "t1_cpu_ms")
    hashes = ("sha256_defaults", "sha256_given", "sha256_t1")
    best = {}
    load_before = os.getloadavg()
    for _ in range(rounds):
        for label, code in contenders.items():
            got = worker(code, calls)
            for name in SYSTEMS:
                b = best.setdefault(label, {}).setdefault(name, dict(got[name]))
                for key in keys:
                    b[key] = min(b[key], got[name][key])
                for key in hashes:
                    if b[key] != got[name][key]:
                        raise RuntimeError(f"{label} {name}: results differ between workers")
    summary = {}
    for name in SYSTEMS:
        this, base = best["this"][name], best["baseline"][name]
        summary[name] = {
            **{f"{key}_{label}": best[label][name][key] for key in keys for label in contenders},
            "defaults_over_run_this": this["defaults_ms"] / this["run_ms"],
            "defaults_over_run_baseline": base["defaults_ms"] / base["run_ms"],
            "speedup_defaults": base["defaults_ms"] / this["defaults_ms"],
            "speedup_t1_cpu": base["t1_cpu_ms"] / this["t1_cpu_ms"],
            "bitwise_equal": all(this[k] == base[k] for k in (*hashes, "tau"))}
    data = {"rounds": rounds, "calls": calls, "baseline": str(args.baseline),
            "load": {"before": load_before, "after": os.getloadavg(), "cpus": os.cpu_count()},
            "best": best, "summary": summary}
    save_json(args.out, "short_run_cost", data)
    print(f"load {data['load']['before']} -> {data['load']['after']}")
    print(f"{'system':16s} {'code':8s} {'defaults':>9s} {'pilots':>8s} {'run':>8s} "
          f"{'t=1':>7s} {'t=1 cpu':>8s} {'def/run':>8s}  (ms)")
    for name in SYSTEMS:
        for label in contenders:
            r = best[label][name]
            print(f"{name:16s} {label:8s} {r['defaults_ms']:9.2f} {r['pilot_ms']:8.2f} "
                  f"{r['run_ms']:8.2f} {r['t1_ms']:7.2f} {r['t1_cpu_ms']:8.3f} "
                  f"{r['defaults_ms'] / r['run_ms']:8.2f}")
        print(f"{'':16s} bitwise equal: {summary[name]['bitwise_equal']}, defaults "
              f"{summary[name]['speedup_defaults']:.2f}x faster, t = 1 (CPU) "
              f"{summary[name]['speedup_t1_cpu']:.2f}x faster")
    return data


if __name__ == "__main__":
    main()

"""A general H(q, p) in a fresh process and in a short call, this code
against a baseline tree (issues 28 and 29: a first run in a second process
within 1.5 s, the fixed cost of a one-step run within 50 µs).

The model is :mod:`studies.compile_cost`'s ``general`` case, H = ½|p|² +
q₁p₁p₂/10 + ½|q|² + q₁²q₂ ("general": Gauss–Legendre GL8 on the part
stepper), and its run the same ``lyapunov_spectrum`` (t = 10, τ = 0.1, two
exponents). Per code, one warm-up process fills its own empty varint and
numba cache folders (the cold compile, not timed here: see
``compile_cost.py``); then ``--repeats`` new processes per code,
interleaved, each on those folders (a second process), measure in CPU time
(``time.process_time``):

* ``import``: ``import sympy, numpy, varint`` (varint loads its parts on
  demand);
* ``make``: ``from_hamiltonian`` (varint.models imported on the way, then
  the structure recognised, the kernels' source written and loaded from
  the caches);
* ``make CR3BP`` and ``make relativistic``: two more models, an
  integrable and a separable one, made after the first (their own
  recognition and kernels);
* ``first run``: the run, the first in the process;
* ``to first result``: the process's CPU time when that run returns (the
  interpreter's start, the imports, the making and the run: issue 28's
  "first run in a second process");
* ``process``: the process's CPU time when it ends (imports included);
* ``one step``: the fixed cost of a call: the smallest CPU time of 200
  calls ``lyapunov_spectrum(m, x0, 0.1, tau=0.1, n_exponents=2)`` (one
  step) after two
  (the first builds the remembered call, :mod:`varint.remembered`).

The medians over the processes are stored, and the SHA-256 of the first
run's and of a one-step call's arrays (exponents, energy errors, final
state): both codes must agree bitwise.

Usage: ``git worktree add /tmp/base <commit>`` then
``python studies/general_h_start.py --baseline /tmp/base [--repeats N]``.
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

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from studies.common import parse_args, save_json  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]

#: One process: its CPU times (s) and digests, one JSON line.
WORKER = r"""
import hashlib, json, sys, time
clock = time.process_time
t0 = clock()
sys.path.insert(0, sys.argv[1])
import numpy as np
import sympy as sp
import varint
t_import = clock()
q = sp.symbols("q1 q2"); p = sp.symbols("p1 p2")
H = ((p[0]**2 + p[1]**2) / 2 + sp.Rational(1, 10) * q[0] * p[0] * p[1]
     + (q[0]**2 + q[1]**2) / 2 + q[0]**2 * q[1])
m = varint.models.from_hamiltonian(H, q, p)
t_make = clock()
x0 = np.array([0.1, 0.05, 0.2, 0.1])
r = varint.lyapunov_spectrum(m, x0, 10.0, tau=0.1, n_exponents=2, progress=False)
t_run = clock()
mu = sp.Rational(1, 100)
r1 = sp.sqrt((q[0] + mu)**2 + q[1]**2); r2 = sp.sqrt((q[0] - 1 + mu)**2 + q[1]**2)
cr3bp = ((p[0]**2 + p[1]**2) / 2 + q[1] * p[0] - q[0] * p[1] - (1 - mu) / r1 - mu / r2)
t = clock(); varint.models.from_hamiltonian(cr3bp, q, p); t_cr3bp = clock() - t
t = clock()
varint.models.from_hamiltonian(sp.sqrt(1 + p[0]**2 + p[1]**2) + (q[0]**2 + q[1]**2) / 2
                               + q[0]**4 / 4, q, p)
t_rel = clock() - t


def digest(res):
    h = hashlib.sha256()
    for a in (res.exponents, res.energy_error, res.state):
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()


one = lambda: varint.lyapunov_spectrum(m, x0, 0.1, tau=0.1, n_exponents=2, progress=False)
one(); short = one()
best = float("inf")
for _ in range(200):
    t = clock(); one(); best = min(best, clock() - t)
print(json.dumps({"import": t_import - t0, "make": t_make - t_import, "first run": t_run - t_make,
                  "to first result": t_run, "make CR3BP": t_cr3bp, "make relativistic": t_rel, "process": clock(),
                  "one step us": best * 1e6, "varint": varint.__file__,
                  "sha256 run": digest(r), "sha256 one step": digest(short)}))
"""

KEYS = ("import", "make", "first run", "to first result", "make CR3BP", "make relativistic",
        "process", "one step us")


def worker(tree, env):
    """One process of ``tree``'s code on the cache folders of ``env``."""
    done = subprocess.run([sys.executable, "-c", WORKER, str(tree)], env=env, cwd=tree,
                          capture_output=True, text=True)
    if done.returncode:
        raise RuntimeError(f"worker failed:\n{done.stderr[-3000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def main(argv=None):
    def extra(parser):
        parser.add_argument("--baseline", type=Path, default=None,
                            help="the baseline's source tree (default: this code, the noise)")
        parser.add_argument("--repeats", type=int, default=5)

    args = parse_args(__doc__.splitlines()[0], argv, extra)
    repeats = 2 if args.quick else args.repeats
    trees = {"this": ROOT, "baseline": (ROOT if args.baseline is None
                                        else args.baseline.resolve())}
    load = os.getloadavg()
    runs = {label: [] for label in trees}
    with tempfile.TemporaryDirectory() as cache:
        envs = {}
        for label, tree in trees.items():
            envs[label] = dict(os.environ, PYTHONPATH=str(tree),
                               VARINT_CACHE_DIR=os.path.join(cache, label, "varint"),
                               NUMBA_CACHE_DIR=os.path.join(cache, label, "numba"))
            worker(tree, envs[label])          # the cold compile fills the caches
        for _ in range(repeats):
            for label, tree in trees.items():
                runs[label].append(worker(tree, envs[label]))
    summary = {}
    for label, got in runs.items():
        row = {f"median {key}": round(statistics.median(r[key] for r in got), 4)
               for key in KEYS}
        row["min one step us"] = round(min(r["one step us"] for r in got), 2)
        row["same bits in every process"] = all(
            r[k] == got[0][k] for r in got for k in ("sha256 run", "sha256 one step"))
        summary[label] = row
    this, base = runs["this"][0], runs["baseline"][0]
    summary["bitwise equal"] = all(this[k] == base[k] for k in ("sha256 run", "sha256 one step"))
    for key in KEYS:
        summary[f"speed-up {key}"] = round(summary["baseline"][f"median {key}"]
                                           / summary["this"][f"median {key}"], 2)
    data = {"summary": summary, "runs": runs, "repeats": repeats,
            "baseline": str(args.baseline), "loadavg at start": load,
            "loadavg at end": os.getloadavg(),
            "finished": time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime())}
    save_json(args.out, "general_h_start", data)
    print(f"load {load} -> {os.getloadavg()}")
    print(f"{'CPU (median)':22s} {'this':>10s} {'baseline':>10s} {'speed-up':>9s}")
    for key in KEYS:
        print(f"{key:22s} {summary['this'][f'median {key}']:10.4f} "
              f"{summary['baseline'][f'median {key}']:10.4f} {summary[f'speed-up {key}']:9.2f}")
    print(f"bitwise equal: {summary['bitwise equal']}")
    return data


if __name__ == "__main__":
    main()

"""Bitwise check of the general H(q, p)'s runs against another tree: the
same calls in a worker per code (a new interpreter with empty varint and
numba caches, the code's directory first on ``sys.path``), the SHA-256 of
each result's arrays, accuracy verdict and provenance but its clock (wall
and CPU time, timing, creation time, the machine's load) and the code's
commit, source digest and "modified" flag, as ``studies/short_run_cost.py``
hashes them.

Cases (:data:`WORKER`): the held-out general models of
:mod:`studies.general_h_heldout` ("angular coupling", "position-dependent
mass", "three dof") by GL4, GL6, GL8 (their default, with its pilots) and
TAO4, with the spectrum, SALI, MEGNO and FLI, output times and a full
tangent map; a time-dependent H(q, p, t) by GL6.

Usage: ``git worktree add /tmp/base <commit>`` then
``python studies/general_h_bits.py --baseline /tmp/base``.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from studies.common import parse_args, save_json  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]

#: The worker: one code's hashes, one JSON line.
WORKER = r"""
import dataclasses, hashlib, json, sys
sys.path.insert(0, sys.argv[1])
import numpy as np
import sympy as sp
import varint
from varint.models import from_hamiltonian
from studies.general_h_heldout import heldout

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


models = {}
for name in ("angular coupling", "position-dependent mass", "three dof"):
    H, qs, ps, x0, _ = heldout()[name]
    models[name] = (from_hamiltonian(H, qs, ps, name=name), np.array(x0, dtype=float))
q, p, t = sp.symbols("q p t")
timed = from_hamiltonian(p ** 2 / 2 * (1 + q ** 2 / 4) - sp.cos(q) * (1 + sp.cos(t) / 5),
                         [q], [p], time=t, name="driven general")
out = {}
m, x0 = models["angular coupling"]
for scheme in ("GL4", "GL6", "GL8"):
    out[f"angular coupling/{scheme}/lyapunov"] = digest(varint.lyapunov_spectrum(
        m, x0, 20.0, tau=0.2, scheme=scheme, t_out=np.arange(2.0, 21.0, 2.0), progress=False))
out["angular coupling/defaults/lyapunov"] = digest(varint.lyapunov_spectrum(
    m, x0, 20.0, progress=False))
out["angular coupling/TAO4/lyapunov"] = digest(varint.lyapunov_spectrum(
    m, x0, 5.0, tau=0.05, scheme="TAO4", progress=False))
m, x0 = models["position-dependent mass"]
for ind in ("sali", "megno", "fli"):
    out[f"position-dependent mass/GL8/{ind}"] = digest(varint.run(
        m, x0, ind, 20.0, tau=0.2, progress=False))
m, x0 = models["three dof"]
out["three dof/GL8/integrate"] = digest(varint.integrate(
    m, x0, 10.0, tau=0.2, deviations=np.eye(6), t_out=[5.0, 10.0]))
out["driven general/GL6/lyapunov"] = digest(varint.lyapunov_spectrum(
    timed, np.array([0.5, 0.2]), 20.0, tau=0.1, scheme="GL6", progress=False))
print(json.dumps({"varint": varint.__file__, "hashes": out}))
"""


def worker(code_dir):
    """One code's hashes, in a new interpreter with empty caches."""
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, VARINT_CACHE_DIR=os.path.join(cache, "varint"),
                   NUMBA_CACHE_DIR=os.path.join(cache, "numba"), PYTHONPATH=str(code_dir))
        done = subprocess.run([sys.executable, "-c", WORKER, str(code_dir)], env=env,
                              cwd=code_dir, capture_output=True, text=True)
    if done.returncode:
        raise RuntimeError(f"worker on {code_dir} failed:\n{done.stderr[-3000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def main(argv=None):
    def extra(parser):
        parser.add_argument("--baseline", type=Path, required=True,
                            help="directory holding the baseline's varint package")

    args = parse_args(__doc__.splitlines()[0], argv, extra)
    load = os.getloadavg()
    got = {"this": worker(ROOT), "baseline": worker(args.baseline.resolve())}
    this, base = got["this"]["hashes"], got["baseline"]["hashes"]
    equal = {case: this[case] == base.get(case) for case in this}
    for case, same in equal.items():
        print(f"{case:40s} {'equal' if same else 'DIFFERENT'}  {this[case][:16]}")
    save_json(args.out, "general_h_bits", {
        "baseline": str(args.baseline), "varint": {k: v["varint"] for k, v in got.items()},
        "load": {"before": load, "after": os.getloadavg()}, "hashes": got,
        "equal": equal, "all equal": all(equal.values()) and set(this) == set(base)})


if __name__ == "__main__":
    main()

"""Energies of several models bitwise against another tree (issue 28,
energy24): the results of one-shot and repeated calls, whose repeats take
the short path (:class:`varint.rerun.ShortCall`, its accuracy verdict from
H over its states, :meth:`varint.models.hamiltonian.HamiltonianModel.start_and_later_energies`),
and H at a few states, of this code and of ``--base``.

Models: the CR3BP, the magnetic bottle, a general H, the relativistic
particle, the Larmor model, a time-dependent H, the rotating bar's regular
and chaotic orbits, Hénon–Heiles' V by ``from_potential`` and the built-in
Hénon–Heiles. Per model and horizon (t = 1, τ = 0.1; t = 20, τ = 0.05),
``lyapunov_spectrum`` with one given vector from three nearby states (the
second and third are remembered calls' short path), then a prepared
``integrate`` run's three calls; each result's SHA-256 (exponents, times,
state, energy errors, vectors and the accuracy verdict; for the prepared
runs the state and energy errors), an error's message where one is raised.

Each tree runs in a child process (the two at once) with its directory
first on ``sys.path`` and its own fresh numba and varint caches. Stored as
``energy_bits.json``: both trees' digests and the cases that differ.

Usage: ``python studies/energy_bits.py --base /path/to/worktree``
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from studies.common import parse_args, save_json  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]

#: The child: one tree's digests, one JSON document.
WORKER = r"""
import hashlib, json, math, sys
import numpy as np
import sympy as sp
sys.path.insert(0, sys.argv[1])
import varint
from tests.flows.steppers import cr3bp, bottle, coupled_general, relativistic, larmor
from varint.models import from_hamiltonian, from_potential
from varint.models.bar import bar_orbit

def digest(r):
    h = hashlib.sha256()
    for name in ("exponents", "t", "state", "energy_error", "deviations", "states", "megno", "fli", "sali"):
        v = getattr(r, name, None)
        if v is not None:
            h.update(name.encode()); h.update(np.ascontiguousarray(np.asarray(v, dtype=float)).tobytes())
    a = r.accuracy
    h.update(repr((float(np.asarray(a.energy_error).ravel()[0]), np.asarray(a.t_worst).tolist(), np.asarray(a.accurate).tolist(),
                   {k: np.asarray(v).tolist() for k, v in a.conserved.items()})).encode())
    return h.hexdigest()[:16]

q, p, s = sp.symbols("q p s")
x, y = sp.symbols("x y")
timed = from_hamiltonian(p ** 2 / 2 + q ** 2 * p + q ** 4 / 4 + q * s, [q], [p], time=s)
pot = from_potential((x**2 + y**2) / 2 + x**2 * y - y**3 / 3, [x, y])
bar, bx0 = bar_orbit("regular")
barc, bcx0 = bar_orbit("chaotic")
cases = {
    "cr3bp": (cr3bp(), np.array([0.3, 0.2, 0.1, 0.5])),
    "bottle": (bottle(), np.array([0.3, 0.2, 0.1, 0.5, 0.4, 0.3])),
    "general": (coupled_general(), None),
    "relativistic": (relativistic(), None),
    "larmor": (larmor(), None),
    "timed": (timed, np.array([0.3, 0.2])),
    "bar": (bar, bx0),
    "bar_chaotic": (barc, bcx0),
    "from_potential HH": (pot, np.array([0.0, 0.1, 0.35, 0.0])),
    "HH": (__import__("varint.models", fromlist=["HenonHeiles"]).HenonHeiles(), np.array([0.0, 0.1, 0.35, 0.0])),
}
out = {}
for name, (model, x0) in cases.items():
    if model is None: continue
    if x0 is None:
        x0 = np.array([0.3, 0.2, 0.1, 0.5, 0.4, 0.3][:model.dim])
    w = np.full((model.dim, 1), 1 / math.sqrt(model.dim))
    for t_end, tau in ((1.0, 0.1), (20.0, 0.05)):
        digests = []
        for rep in range(3):
            x1 = x0 + rep * 1e-3
            try:
                r = varint.lyapunov_spectrum(model, x1, t_end, tau=tau, deviations=w, t_out=[t_end / 2, t_end])
                digests.append(digest(r))
            except Exception as e:
                digests.append(f"error {type(e).__name__}: {e}"[:80])
        # a prepared run's calls
        try:
            run = varint.prepare(model, "integrate", t_end, tau=tau)
            for rep in range(3):
                r = run(x0 + rep * 1e-3)
                h = hashlib.sha256(np.asarray(r.state).tobytes() + np.asarray(r.energy_error).tobytes()).hexdigest()[:16]
                digests.append(h)
        except Exception as e:
            digests.append(f"error {type(e).__name__}: {e}"[:80])
        out[f"{name} t={t_end}"] = digests
        # energies directly
    X = np.random.default_rng(3).uniform(-0.5, 0.5, (5, model.dim)) + x0
    e = model.energy(X) if not getattr(model, "time_dependent", False) else model.energy(X, 0.7)
    out[f"{name} energy"] = hashlib.sha256(np.asarray(e, dtype=float).tobytes()).hexdigest()[:16]
print(json.dumps(out, indent=0))
"""


def digests(tree):
    """The digests of the code in ``tree`` (a child process, fresh caches)."""
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=os.path.join(cache, "numba"),
                   VARINT_CACHE_DIR=os.path.join(cache, "varint"))
        done = subprocess.run([sys.executable, "-c", WORKER, str(tree)], env=env, cwd=tree,
                              capture_output=True, text=True, check=True)
    return json.loads(done.stdout)


def main(argv=None):
    def extra(parser):
        parser.add_argument("--base", type=Path, required=True,
                            help="a worktree of the code to compare with")

    args = parse_args(__doc__.splitlines()[0], argv, extra)
    load = [round(x, 2) for x in os.getloadavg()]
    # (The two children side by side: each compiles every model's steppers.)
    with ThreadPoolExecutor(2) as pool:
        base, this = pool.map(digests, (args.base.resolve(), ROOT))
    found = {"base": base, "this": this}
    differ = sorted(k for k in found["base"] if found["base"][k] != found["this"].get(k))
    print(f"{len(found['base'])} cases, {len(found['base']) - len(differ)} equal; differ: {differ}")
    save_json(args.out, "energy_bits", {"base": str(args.base), "cases": len(found["base"]),
                                        "differ": differ, "digests": found, "load": load,
                                        "load_end": [round(x, 2) for x in os.getloadavg()]})
    return differ


if __name__ == "__main__":
    main()

"""The lattices' part flows from their stencils against the hand-written
kernels they replaced: bitwise the same, and as fast.

The Klein–Gordon and FPUT lattices became stencils (varint.models.stencil)
and the DDNLS hopping a use of the shared neighbour sweep; their kernels
before that change are read from git (``--old``, default ``main``) into a
private package and compiled beside today's. For each lattice, size and
number of vectors k, each part's fused flow (orbit and k vectors) is run
``reps`` times inside one compiled loop, old and new interleaved in one
process, minimum over repeats (CPU time); the states after the loops must
be bitwise equal. Stored as ``bench_stencil.csv`` (ratio new/old with its
spread over the turns).

Usage: ``python studies/bench_stencil.py [--quick] [--out DIR] [--old REV]``
"""

from __future__ import annotations

import importlib
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from numba import njit

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import varint  # noqa: E402
from studies.common import interleaved, parse_args, ratio_spread, save_csv  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
NEW = {"kg": varint.models.kg, "fput": varint.models.fput, "ddnls": varint.models.ddnls}
OLD_MODULES = ("lattice", "kg", "fput", "ddnls")


def old_package(rev, where):
    """The lattice modules of ``rev`` as the package ``old_lattices`` in
    ``where`` (their relative imports of the rest of varint made absolute)."""
    pkg = Path(where) / "old_lattices"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    for name in OLD_MODULES:
        src = subprocess.run(["git", "show", f"{rev}:varint/models/{name}.py"], cwd=ROOT,
                             check=True, capture_output=True, text=True).stdout
        src = re.sub(r"from \.\.(\w+)", r"from varint.\1", src)
        src = re.sub(r"from \.(base|symbolic)\b", r"from varint.models.\1", src)
        src = re.sub(r"from \.(lattice|kg|fput|ddnls)\b", r"from old_lattices.\1", src)
        # The old kernels compile in this process only (no cache of a
        # temporary folder).
        src = src.replace("cache=True, ", "")
        (pkg / f"{name}.py").write_text(src)
    sys.path.insert(0, str(where))
    return {name: importlib.import_module(f"old_lattices.{name}") for name in OLD_MODULES}


def driver(apply, K):
    """A compiled loop of ``reps`` flows of part ``part``, ``apply`` and the
    number of vectors ``K`` compiled in (as the part stepper has them)."""

    @njit(error_model="numpy")
    def run(part, h, x, V, par, work, reps):
        for _ in range(reps):
            apply(part, h, x, V, K, par, work)

    return run


def cases(quick):
    """(label, build) of each lattice; ``build(models)`` takes the module
    of today's models or of the old ones (name -> module)."""
    kg_sizes = ((64,), (32, 32)) if quick else ((64,), (1024,), (32, 32))
    fpu_sizes = (64,) if quick else (64, 4096)
    for shape in kg_sizes:
        yield f"KG {shape}", lambda m, s=shape: m["kg"].DisorderedKG(s[0] if len(s) == 1 else s)
    for n in fpu_sizes:
        yield f"FPU-beta {n}", lambda m, n=n: m["fput"].FPUT(n, 0.0, 1.5)
    yield "DDNLS (32, 32)", lambda m: m["ddnls"].DDNLS((32, 32), 10.0, 1.0, 1)


def main(argv=None):
    def extra(parser):
        parser.add_argument("--old", default="main", help="git revision of the old kernels")

    args = parse_args(__doc__.splitlines()[0], argv, extra)
    repeats = 3 if args.quick else 7
    rng = np.random.default_rng(1)
    with tempfile.TemporaryDirectory() as where:
        old = old_package(args.old, where)
        rows = []
        for label, build in cases(args.quick):
            model = build(NEW)
            models = {"old": build(old), "new": model}
            parts = [p for p in model.parts.names if p != "L"]
            n = model.n_sites
            reps = max(20, int((2e4 if args.quick else 2e5) / n))
            x0 = rng.uniform(-0.3, 0.3, 2 * n)
            for k in (1, 4):
                V0 = rng.standard_normal((k, 2 * n))
                work = np.empty(0)
                tasks, states = {}, {}
                for who, m in models.items():
                    run, par = driver(m.parts.apply, k), m.params
                    for part in parts:
                        index = model.parts.index(part)
                        x, V = x0.copy(), V0.copy()
                        run(index, 1e-3, x, V, par, work, 2)   # compile, and the bits
                        states[who, part] = (x, V)
                        xs, Vs = x0.copy(), V0.copy()
                        tasks[who, part] = (lambda run=run, index=index, xs=xs, Vs=Vs, par=par,
                                            work=work, reps=reps:
                                            run(index, 1e-9, xs, Vs, par, work, reps))
                turns = {}
                best, _ = interleaved(tasks, repeats, clock=time.process_time, turns=turns)
                for part in parts:
                    same = all(np.array_equal(a, b) for a, b in zip(states["old", part],
                                                                    states["new", part],
                                                                    strict=True))
                    spread = ratio_spread(turns, ("old", part), ("new", part))
                    row = {"case": label, "k": k, "part": part,
                           "old_ns": best["old", part] / reps * 1e9,
                           "new_ns": best["new", part] / reps * 1e9,
                           "new_over_old": best["new", part] / best["old", part],
                           "spread_lo": spread[0], "spread_hi": spread[1], "bitwise": same}
                    rows.append(row)
                    print("{case:16s} k={k} {part}: old {old_ns:9.1f} ns  new {new_ns:9.1f} ns"
                          "  new/old {new_over_old:.3f} [{spread_lo:.2f}, {spread_hi:.2f}]"
                          "  bitwise {bitwise}".format(**row), flush=True)
    path = save_csv(args.out, "bench_stencil", rows, list(rows[0]))
    print(f"stored {path}")
    return 0 if all(r["bitwise"] for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())

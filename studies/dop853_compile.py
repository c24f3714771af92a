"""What the DOP853 baseline costs to compile in a first and in a second
process (issue 28: every compiled kernel cached across processes; issue 26:
the test files that run ``method="dop853"``).

For each source tree given (``--tree LABEL=PATH``, copies of a varint
checkout), interleaved, ``--repeats`` times: a new interpreter with an
empty cache directory runs the compiled DOP853 engine (the default) on
three models in turn — Hénon–Heiles at R1 (the generated right-hand side),
a ``from_potential`` model of two degrees of freedom (generated too, from
the model's own expression) and a time-dependent potential (the right-hand
side from the model's kernels and parameters) — and reports, for each,
the seconds numba spent compiling (:func:`varint.compiling.compile_seconds`)
and the wall seconds of the call; then a second interpreter on the same,
now warm, cache directory runs the same three: what every later process
pays (a user's next script, the other test worker). The values must be the
same bits in every tree and process.

``speed``: for each tree, alternating processes on a warm cache, the time
per interval of the compiled engine on R1 (full spectrum, τ = 0.05,
t = 2000), the minimum over ``--repeats`` processes of the best of four
calls (the first may compile): compiling the right-hand side in must not slow the engine down.

Run: ``python studies/dop853_compile.py compile --tree after=<tree> --tree
before=<tree>`` and ``python studies/dop853_compile.py speed --tree
after=<tree> --tree before=<tree>`` (``--quick``: one repeat, stored under
``results/quick``).
"""

from __future__ import annotations

import json

try:
    from common import save_json
    from step_body_compile import child, load, tree_study
except ImportError:  # imported as studies.dop853_compile
    from .common import save_json
    from .step_body_compile import child, load, tree_study

#: The child: the three models in one process, one short run each.
CHILD = """
import json, time
t0 = time.perf_counter()
import numpy as np
import sympy as sp
import varint
from varint import compiling
from varint.models import from_potential
imported = time.perf_counter() - t0
m, x = varint.paper_orbit("R1")
q = sp.symbols("q0:2")
pot = from_potential((q[0]**2 + q[1]**2) / 2 + q[0]**4 / 4 + q[0]**2 * q[1]**2 / 3, q)
qf, t = sp.symbols("q t")
forced = from_potential(-sp.cos(qf) * (1 + sp.cos(t) / 5), [qf], time=t)
kw = dict(t_end=1.0, tau=0.05, method="dop853", progress=False)
runs = {"R1": lambda: varint.lyapunov_spectrum(m, x, **kw),
        "from_potential": lambda: varint.lyapunov_spectrum(pot, [0.3, 0.1, 0.2, 0.4], **kw),
        "time-dependent": lambda: varint.lyapunov_spectrum(forced, [0.0, 2.0], **kw)}
out = {"import s": imported}
for name, run in runs.items():
    c0, w0 = compiling.compile_seconds(), time.perf_counter()
    values = run().exponents
    out[name] = {"compile s": compiling.compile_seconds() - c0,
                 "wall s": time.perf_counter() - w0,
                 "values": np.ascontiguousarray(values).tobytes().hex()}
print(json.dumps(out))
"""

#: The child of ``speed``: seconds per interval, best of four calls.
SPEED_CHILD = """
import json, time
import varint
m, x = varint.paper_orbit("R1")
steps = 40000
best = float("inf")
for _ in range(4):
    t0 = time.process_time()
    r = varint.lyapunov_spectrum(m, x, t_end=steps * 0.05, tau=0.05, method="dop853",
                                 progress=False)
    best = min(best, time.process_time() - t0)
print(json.dumps({"us/interval": best / steps * 1e6, "values": r.exponents.tobytes().hex()}))
"""

CASES = ("R1", "from_potential", "time-dependent")
PROCESSES = ("first process", "second process")


def compile_times(args, trees, scratch):
    runs = {label: [] for label in trees}
    for rep in range(args.repeats):
        for label, tree in trees.items():
            cache = scratch / f"{label}-{rep}"
            cache.mkdir()
            before = load()
            first = child(tree, CHILD, cache)
            second = child(tree, CHILD, cache)
            runs[label].append({"load": [before, load()], "first process": first,
                                "second process": second})
            for name in CASES:
                print(f"{label:8s} {rep} {name:15s} compile s: first process "
                      f"{first[name]['compile s']:6.1f}, second "
                      f"{second[name]['compile s']:6.1f} (wall {first[name]['wall s']:6.1f}, "
                      f"{second[name]['wall s']:6.1f})", flush=True)
    values = {label: {name: sorted({r[p][name]["values"] for r in rs for p in PROCESSES})
                      for name in CASES} for label, rs in runs.items()}
    same = (len({json.dumps(v, sort_keys=True) for v in values.values()}) == 1
            and all(len(v) == 1 for case in values.values() for v in case.values()))
    summary = {label: {name: {f"min {p} {what}": min(r[p][name][what] for r in rs)
                              for p in PROCESSES for what in ("compile s", "wall s")}
                       for name in CASES} for label, rs in runs.items()}
    print(json.dumps(summary, indent=1), "\nsame bits in every tree and process:", same)
    save_json(args.out, "dop853_compile", {"summary": summary, "same bits": same,
                                           "runs": runs, "trees": sorted(trees)})


def speed(args, trees, scratch):
    for label, tree in trees.items():        # warm each tree's cache first
        (scratch / label).mkdir()
        child(tree, SPEED_CHILD.replace("steps = 40000", "steps = 4"), scratch / label)
    runs = {label: [] for label in trees}
    for rep in range(args.repeats):
        for label, tree in trees.items():
            before = load()
            runs[label].append(dict(child(tree, SPEED_CHILD, scratch / label),
                                    load=[before, load()]))
            print(f"{label:8s} {rep} {runs[label][-1]['us/interval']:8.2f} us/interval",
                  flush=True)
    best = {label: min(r["us/interval"] for r in rs) for label, rs in runs.items()}
    same = len({r["values"] for rs in runs.values() for r in rs}) == 1
    labels = list(trees)
    ratio = best[labels[0]] / best[labels[-1]]
    print(json.dumps({"min us/interval": best, f"{labels[0]}/{labels[-1]}": ratio}, indent=1),
          "\nsame bits in every tree:", same)
    save_json(args.out, "dop853_speed", {"min us/interval": best,
                                         f"ratio {labels[0]}/{labels[-1]}": ratio,
                                         "same bits": same, "runs": runs, "trees": labels})


def main(argv=None):
    tree_study(__doc__, compile_times, speed, "varint-dop853-compile-", argv)


if __name__ == "__main__":
    main()

"""Study: generated LH modules' lanes kernels against each other on the
cored map, interleaved in one process (issue 27, lh19).

Each argument is the source file of an LH module for the cored map and
ABA864 (:func:`studies.lh_lanes._setup`), emitted by a variant of
:mod:`varint.codegen.lh` (a lane width; the potential's logarithm by libm's
``log`` or by a branch-free ``vlog``); its ``lanes0``/``lanes1`` replace the
stepper's, and ``LogHamiltonian.outputs`` runs the 120 orbits to
``--t-end`` with one vector. Reported: each variant's hash of (FLI, final
states), its force evaluations, and the minimum over the repeats of wall
and CPU time per force evaluation, the variants interleaved.

``--emit DIR`` writes the variants of this tree's emitter instead: lane
widths ``--widths`` (``varint.codegen.lh_lanes.LANE_WIDTH`` set before
emitting) with the emitter's own branch-free logarithm (``select<W>.py``:
:func:`varint.kernels.lh_log.lane_log`, the bits of
``varint.kernels.logarithm.vlog``, tested in ``tests/test_lh_log.py``), so
that the potential's own loop over the lanes vectorises, and with libm's
``log`` in its place (``lanes<W>.py``, which keeps that loop scalar; the
LH stepper printed libm's ``log`` before lh22). This study's own
branch-free copy of ``vlog`` (lh19) became ``lane_log``.

Run: ``python studies/lh_lane_variants.py --emit DIR [--widths 8,16,32]``,
then ``python studies/lh_lane_variants.py --out DIR [--repeats N]
[--t-end T] MODULE.py ...``; writes ``lh_lane_variants.json``.
"""

from __future__ import annotations

import copy
import hashlib
import importlib.util
import os
import sys
import time
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from studies.common import parse_args, save_json  # noqa: E402
from studies.lh_lanes import EVERY, H, _setup  # noqa: E402
from varint.codegen import lh_lanes  # noqa: E402


def emit(folder, widths):
    """The variant modules (module docstring) into ``folder``."""
    folder.mkdir(parents=True, exist_ok=True)
    for width in widths:
        lh_lanes.LANE_WIDTH = width
        text = _setup()[0].source()
        (folder / f"select{width}.py").write_text(text)
        (folder / f"lanes{width}.py").write_text(text.replace("lane_log(", "math.log("))


def main(argv=None):
    def extra(parser):
        parser.add_argument("modules", nargs="*")
        parser.add_argument("--emit", type=Path, default=None)
        parser.add_argument("--widths", default="8,16,32")
        parser.add_argument("--repeats", type=int, default=5)
        parser.add_argument("--t-end", type=float, default=200.0)

    cli = parse_args(__doc__.split("\n\n")[0], argv, extra)
    if cli.emit is not None:
        emit(cli.emit, [int(w) for w in cli.widths.split(",")])
        return
    lh, X, W0 = _setup()
    runs, res = {}, {"load": os.getloadavg(), "t_end": cli.t_end, "variants": {}}
    for path in cli.modules:
        name = Path(path).stem
        spec = importlib.util.spec_from_file_location(f"lh_variant_{name}", path)
        mod = importlib.util.module_from_spec(spec)
        # Registered: numba's cache of its kernels imports it by name.
        sys.modules[spec.name] = mod
        spec.loader.exec_module(mod)
        run = copy.copy(lh)
        run.lanes_kernels = (mod.lanes0, mod.lanes1)
        out = run.outputs(X, W0, cli.t_end, H, every=EVERY)   # compiles
        runs[name] = run
        res["variants"][name] = {
            "hash": hashlib.sha256(out.fli.tobytes() + out.x.tobytes()).hexdigest()[:16],
            "gradients": int(out.counts[:, 2].sum()), "wall": float("inf"),
            "cpu": float("inf")}
    res["load_timed"] = os.getloadavg()
    for _ in range(cli.repeats):
        for name, run in runs.items():
            t0, c0 = time.perf_counter(), time.process_time()
            run.outputs(X, W0, cli.t_end, H, every=EVERY)
            row = res["variants"][name]
            row["wall"] = min(row["wall"], time.perf_counter() - t0)
            row["cpu"] = min(row["cpu"], time.process_time() - c0)
    res["load_end"] = os.getloadavg()
    for name, row in res["variants"].items():
        row["wall_ns_per_gradient"] = 1e9 * row["wall"] / row["gradients"]
        row["cpu_ns_per_gradient"] = 1e9 * row["cpu"] / row["gradients"]
        print(f"{name:12s} {row['hash']}  wall {row['wall_ns_per_gradient']:6.2f} ns  "
              f"cpu {row['cpu_ns_per_gradient']:6.2f} ns per force evaluation")
    print(f"load {res['load']} -> {res['load_end']}")
    save_json(cli.out, "lh_lane_variants", res)


if __name__ == "__main__":
    main()

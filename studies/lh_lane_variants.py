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
emitting) with libm's ``log`` (``lanes<W>.py``) and with :data:`SELECT`
(``select<W>.py``): ``varint.kernels.logarithm.vlog`` written without
branches (every path computed, the result chosen by selects; k converted by
the exact 1.5·2⁵² bit trick), the same value bit for bit (checked by
``--emit`` on 2.4e6 arguments: every binade, near 1, subnormals, specials), so that the
potential's own loop over the lanes vectorises (libm's ``log`` keeps it
scalar). A study variant only: it changes the LH map's bits against libm
(vlog ≤ 0.79 ulp).

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

import math  # noqa: E402

import numpy as np  # noqa: E402
from numba import njit  # noqa: E402

from studies.common import parse_args, save_json  # noqa: E402
from studies.lh_lanes import EVERY, H, _setup  # noqa: E402
from varint.codegen import lh_lanes  # noqa: E402
from varint.kernels.fma import fma  # noqa: E402
from varint.kernels.logarithm import as_bits, from_bits  # noqa: E402

#: ``vlog_select(x)``: vlog without branches (module docstring).
SELECT = '''
def vlog_select(x):
    """``vlog(x)``, bit for bit, without branches."""
    ix = as_bits(x)
    low = ix < 0x0010000000000000
    x = x * 18014398509481984.0 if low else x
    k = -54 if low else 0
    ix = as_bits(x)
    hx = ix >> 32
    k += (hx >> 20) - 1023
    hx &= 0xFFFFF
    i = (hx + 0x95F64) & 0x100000
    y = from_bits(((hx | (i ^ 0x3FF00000)) << 32) | (ix & 0xFFFFFFFF))
    k += i >> 20
    f = y - 1.0
    dk = from_bits(k + 0x4338000000000000) - 6755399441055744.0
    hi = dk * 6.93147180369123816490e-01
    lo = dk * 1.90821492927058770002e-10
    rt = f * f * (0.5 - 0.33333333333333333 * f)
    tiny = f - rt if k == 0 else hi - ((rt - lo) - f)
    tiny = hi + lo if f == 0.0 else tiny
    s = f / (2.0 + f)
    z = s * s
    w = z * z
    t1 = w * fma(w, fma(w, 1.531383769920937332e-01, 2.222219843214978396e-01),
                 3.999999999940941908e-01)
    t2 = z * fma(w, fma(w, fma(w, 1.479819860511658591e-01, 1.818357216161805012e-01),
                        2.857142874366239149e-01), 6.666666666666735130e-01)
    r = t2 + t1
    hfsq = 0.5 * f * f
    wide = f - (hfsq - s * (hfsq + r)) if k == 0 else hi - ((hfsq - (s * (hfsq + r) + lo)) - f)
    narrow = f - s * (f - r) if k == 0 else hi - ((s * (f - r) - lo) - f)
    out = wide if ((hx - 0x6147A) | (0x6B851 - hx)) > 0 else narrow
    out = tiny if ((2 + hx) & 0xFFFFF) < 3 else out
    out = math.nan if ix < 0 else out
    out = -math.inf if (as_bits(x) & 0x7FFFFFFFFFFFFFFF) == 0 else out
    return x + x if ix >= 0x7FF0000000000000 else out
'''


def _select():
    scope = {"math": math, "fma": fma, "as_bits": as_bits, "from_bits": from_bits}
    exec(compile(SELECT, "<studies.lh_lane_variants>", "exec"), scope)
    return njit(inline="always", error_model="numpy")(scope["vlog_select"])


#: :data:`SELECT` compiled (the select variants import it).
vlog_select = _select()


def check_select():
    """:data:`SELECT` against ``vlog``, bit for bit, on random bit patterns
    (every binade, both signs, subnormals, NaNs), arguments near 1 and
    around the cored map's, and the special values; the count compared."""
    from varint.kernels.logarithm import vlog

    @njit(error_model="numpy")
    def both(a, o1, o2):
        for i in range(a.shape[0]):
            o1[i] = vlog(a[i])
        for i in range(a.shape[0]):
            o2[i] = vlog_select(a[i])

    rng = np.random.default_rng(1)
    bits = rng.integers(0, 2 ** 63, 2_000_000, dtype=np.int64)
    a = np.concatenate([bits.view(np.float64), -bits[:1000].view(np.float64),
                        1 + rng.standard_normal(200_000) * 1e-7,
                        np.exp(rng.uniform(-8, 5, 200_000)),
                        [0.0, -0.0, np.inf, -np.inf, np.nan, 1.0, 5e-324,
                         2.2250738585072014e-308, 1 - 2 ** -53, 1 + 2 ** -52]])
    o1, o2 = np.empty_like(a), np.empty_like(a)
    both(a, o1, o2)
    if not np.array_equal(o1.view(np.int64), o2.view(np.int64)):
        raise AssertionError("vlog_select differs from vlog")
    return len(a)


def emit(folder, widths):
    """The variant modules (module docstring) into ``folder``, after
    :func:`check_select`."""
    print(f"vlog_select == vlog, bit for bit, on {check_select()} arguments")
    folder.mkdir(parents=True, exist_ok=True)
    for width in widths:
        lh_lanes.LANE_WIDTH = width
        text = _setup()[0].source()
        (folder / f"lanes{width}.py").write_text(text)
        text = text.replace("import math\n", "import math\n"
                            "from studies.lh_lane_variants import vlog_select\n", 1)
        (folder / f"select{width}.py").write_text(text.replace("math.log(_", "vlog_select(_"))


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

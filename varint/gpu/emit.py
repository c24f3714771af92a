"""The CUDA target of the generated tangent-map steppers: one orbit per thread.

The code-generation layer (:mod:`varint.codegen`) writes a stepper as a
step body (:class:`varint.codegen.tm.TMBody`) inside an emitted stepping
skeleton (:class:`varint.codegen.interval.Interval`) whose *target* says
where the state lives and how control flows. This module adds a third
target beside ``OneOrbit`` and ``Lanes``: :class:`Thread`, one orbit per
CUDA thread. The step and the end of every step are written by the very
methods that write the CPU steppers, so a thread does the CPU's arithmetic
in the CPU's order:

* as for one orbit, the state is in locals (registers) for the whole loop,
  a failure leaves the loop, and work is done where it is due (the
  renormalisation, its sparse schedule, the overflow check and the copies
  at output steps, all inside the thread);
* the caller's arrays keep the orbit index innermost (structure of arrays):
  thread ``m`` reads and writes column ``m``, ``X[i, m]``, so a warp's 32
  loads of one quantity are one coalesced transaction;
* drifts and kicks keep their explicit fused multiply–adds, integer powers
  are written as the products numba's CPU target computes (half-integer
  ones as the CPU steppers print them, :mod:`varint.codegen.printer`), and the
  schedule's :func:`~varint.kernels.interval.next_interval` is written out
  (a kernel cannot call the CPU's compiled function);
* an orbit that fails (escape, non-finite state, a singular derivative,
  degenerate vectors) stops; as after the CPU's SIMD lanes, the caller
  recomputes it with the CPU's one-orbit stepper from the call's start
  (:mod:`varint.gpu.advance`), so a failed orbit is left exactly as the CPU
  leaves it.

Compiled with contraction of separate multiplies and adds switched off
(:mod:`varint.gpu.device`), every operation of the kernel is rounded as the
CPU's (its PTX has only ``.rn`` additions, multiplications, fused
multiply–adds, square roots and reciprocals). The logarithms (the sparse
schedule's, MEGNO's, FLI's readout) are :mod:`varint.kernels.logarithm`'s
``vlog``, written into the kernel from the source the CPU steppers compile,
so they are the CPU's bits too; ``exp``, ``sqrt`` of a model's potential and
the like come from libdevice on the GPU and from the C library on the CPU
and may differ in the last place. On numba's CUDA simulator the kernel
gives the CPU's bits (``tests/test_gpu.py``). On an H100 the Hénon–Heiles
FLI map differed from the CPU's by up to 1e-11 relative at t = 100, with
libdevice's log and with ``vlog`` alike, while the kernel was linked with
link-time optimisation, which contracts products and sums again
(:mod:`varint.gpu.device`); linked without, its FLI, SALI and MEGNO maps
are the CPU's bits, and a Toda map (``exp``) differs by 4.7e-15
(``studies/results/bench_gpu_h100.md``).
"""

from __future__ import annotations

import re
from functools import lru_cache

import sympy as sp  # type: ignore[import-untyped]

from ..codegen.expressions import ensure_form, expressions, model_key
from ..codegen.interval import Interval, OneOrbit
from ..codegen.printer import StepperPrinter
from ..codegen.stepper import Plan, _accumulator_id, _generator_id
from ..codegen.tm import TMBody
from ..kernels.checks import CHECK_EVERY, HUGE_Q2
from ..kernels.interval import (EARLY, SPARSE_COND_LOG, SPARSE_MAX_STEPS, SPARSE_NORM_LOG,
                                SPARSE_QR_MAX_STEPS)
from ..kernels.logarithm import SOURCE as LOG_SOURCE
from ..protocol import TANGENT_LIMIT, Renorm
from . import device

__all__ = ["Thread", "CudaInterval", "cuda_source", "cuda_stepper", "emittable"]


_FMA = re.compile(r"(?<![\w.])fma\(")

#: The arguments of ``thread``, in the order :mod:`varint.gpu.advance`
#: launches it with.
ARGUMENTS = ("X", "W", "am", "ae", "st", "fs", "nxt", "itv", "n_steps", "step0", "tau", "h",
             "hc", "escape_r2", "mode", "every", "aux", "outs", "snap_x", "snap_W", "snap_m",
             "snap_e", "snap_aux")


def _power(base, n):
    """``base**n`` (n ≥ 1) as the products numba compiles it to
    (``numba.cpython.numbers.static_power_impl``: binary powering, the
    result multiplied by the squares), so that the source says the
    arithmetic the CPU does rather than leaving it to the target: on the
    simulator ``**`` is the C library's ``pow``, not always the same
    bits."""
    result, square = None, base
    while n:
        if n & 1:
            result = square if result is None else f"{result} * {square}"
        n >>= 1
        if n:
            square = f"({square} * {square})"
    return f"({result})"


class _Printer(StepperPrinter):
    """The CPU steppers' printer (half-integer powers as products and a
    square root), with integer powers written as products too."""

    def _print_Pow(self, expr, rational=False):
        if expr.exp.is_Integer and 2 <= int(expr.exp) <= 64:
            return _power(self.parenthesize(expr.base, sp.printing.precedence.precedence(expr)),
                          int(expr.exp))
        return super()._print_Pow(expr, rational=rational)


class Thread(OneOrbit):
    """The third target of the emitted skeleton (beside
    :class:`~varint.codegen.interval.OneOrbit` and
    :class:`~varint.codegen.interval.Lanes`): one orbit per CUDA thread.

    As for one orbit, the state is in locals (registers) and a failure
    records its code and leaves the loop; the work is not counted (the
    caller counts it from the scheme, :func:`varint.codegen.tm.step_counts`).
    The state is loaded from and stored to column ``m`` (the thread's
    orbit) of arrays with the orbit index innermost, and so are the
    snapshots: a warp's 32 loads of one quantity are one transaction.
    """

    counts = False
    #: The logarithm of an accumulator's rule: the kernel's own ``vlog``
    #: (the CPU's algorithm written into the kernel, above); a device
    #: kernel has no ``vlog_called``.
    log = "vlog"

    def snap(self, array, *index):
        return f"{array}[jo, {', '.join(map(str, index))}, m]"

    def snap_aux(self, j, c):
        return f"snap_aux[jo, m, {j}, {c}]"


class CudaInterval(Interval):
    """Writes ``thread``: the skeleton of :class:`~varint.codegen.interval.Interval`
    with the :class:`Thread` target around the same step body."""

    def schedule(self):
        """The sparse schedule's next renormalisation
        (:meth:`Interval.schedule`) with
        :func:`~varint.kernels.interval.next_interval` written out, its
        arithmetic in its order: a kernel cannot call the CPU's compiled
        function."""
        src = self.src
        logs = [f"vlog(r{j})" for j in range(self.k)]
        src(f"lmax = max({', '.join(logs)})" if self.k > 1 else f"lmax = {logs[0]}")
        src(f"spread = lmax - min({', '.join(logs)}) if mode == QR else 0.0" if self.k > 1
            else "spread = 0.0")
        src("done = max(step - (next_renorm - interval), 1)", "allowed = done * 2.0")
        with src.block("if lmax > 0.0:"):
            src("allowed = min(allowed, done * NORM_LOG / lmax)")
        with src.block("if spread > 0.0:"):
            src("allowed = min(allowed, done * COND_LOG / spread, QR_MAX_STEPS)")
        src("interval = int(max(1.0, min(allowed, MAX_STEPS)))")
        with src.block("if every > 0 and interval > every:"):
            src("interval = every")
        src("next_renorm = step + interval")

    def orbit_columns(self):
        """(local, where column ``m`` holds it) of the state."""
        n, k, body = self.n, self.k, self.body
        out = [(body.coordinate(i), f"X[{i}, m]") for i in range(2 * n)]
        out += [(body.component(i, j), f"W[{i}, {j}, m]") for i in range(2 * n)
                for j in range(k)]
        for j in range(k):
            out += [(f"am{j}", f"am[{j}, m]"), (f"ae{j}", f"ae[{j}, m]")]
        return out + [("next_renorm", "nxt[m]"), ("interval", "itv[m]")]

    def module(self, accumulator_id):
        """The kernel's source: ``thread`` and the constants it reads
        (``cuda``, ``float64``, ``int64``, the logarithm's ``as_bits`` and
        ``from_bits`` and, on the simulator, ``fma`` are given by the
        loader)."""
        src, body, k = self.src, self.body, self.k
        self.t = Thread()
        src('"""Generated by varint.gpu.emit; do not edit."""',
            f"# accumulator: {accumulator_id or 'none'}",
            "import math", "import numpy as np", "",
            f"ACC_BIG = {2.0 ** 500!r}", f"ACC_SMALL = {2.0 ** -500!r}",
            f"TANGENT_LIMIT = {TANGENT_LIMIT!r}", f"EARLY = {EARLY!r}", f"HUGE = {HUGE_Q2!r}",
            f"CHECK_EVERY = {CHECK_EVERY}", f"LN2 = {0.6931471805599453!r}",
            f"NONE, QR = {int(Renorm.NONE)}, {int(Renorm.QR)}",
            f"NORM_LOG, COND_LOG = {SPARSE_NORM_LOG!r}, {SPARSE_COND_LOG!r}",
            f"MAX_STEPS, QR_MAX_STEPS = {float(SPARSE_MAX_STEPS)!r}, "
            f"{float(SPARSE_QR_MAX_STEPS)!r}", "", "",
            # The CPU's logarithm, written out (varint.kernels.logarithm).
            "@cuda.jit(device=True)", *LOG_SOURCE.strip("\n").splitlines(),
            "", "", f"def thread({', '.join(ARGUMENTS)}):")
        with src.block():
            src("m = cuda.grid(1)", "if m >= X.shape[1]:", "    return")
            body.prologue(src)
            for local, where in self.orbit_columns() + self.live_columns(
                    lambda j, c: f"aux[m, {j}, {c}]"):
                src(f"{local} = {where}")
            for j in range(k):
                src(f"r{j} = 1.0")
            body.defaults(src)
            src("status = 0", "s = 0")
            self.loop()
            for local, where in self.orbit_columns():
                src(f"{where} = {local}")
            for j in range(k):
                self.columns_out(j, lambda j, c: f"aux[m, {j}, {c}]")
            # A failed orbit is recomputed by the caller on the CPU.
            src("st[m] = status", "fs[m] = s if status != 0 else n_steps")
        return src.text()


def emittable(accumulator):
    """Whether a run with ``accumulator`` can be emitted for CUDA: none
    (SALI, GALI, Lyapunov exponents read the stretching and the vectors),
    or one with an update rule that the generator writes out (FLI, MEGNO,
    OFLI). Any other is a compiled CPU function, which a GPU thread cannot
    call."""
    return accumulator is None or accumulator.rule is not None


def cuda_source(model, kinds, corrected, k, accumulator=None):
    """The CUDA kernel's Python source for ``model`` (one that
    :func:`~varint.codegen.expressions.symbolic_fits`), the scheme's stages
    and ``k`` vectors."""
    if not emittable(accumulator):
        raise ValueError(f"backend='cuda' runs indicators without an accumulator or with an "
                         f"update rule; this one's accumulator ({accumulator.name!r}) is "
                         "compiled for the CPU only")
    if getattr(model, "extra_force", None) is not None:
        raise ValueError(f"backend='cuda' cannot run {model.name}: its potential has a compiled "
                         "CPU term (an extra force) that a GPU thread cannot call; use "
                         "backend='cpu'")
    plan = Plan(kinds=tuple(int(v) for v in kinds), corrected=tuple(bool(c) for c in corrected),
                k=int(k), accumulator=_accumulator_id(accumulator))
    key = model_key(model)
    # As the CPU's loader: the source only from the model's own form.
    ensure_form(model, key)
    return _source(key, plan, accumulator, device.simulated())


@lru_cache(maxsize=64)
def _source(key, plan, accumulator, simulated):
    body = TMBody(expressions(key), plan.kinds, plan.corrected, plan.k)
    body.printer = _Printer()
    source = CudaInterval(body, plan.k, accumulator).module(plan.accumulator)
    # The fused multiply–adds are CUDA's on a GPU (the CPU's is an LLVM
    # intrinsic of numba's CPU target); the simulator's cuda.fma rounds
    # twice, so there they stay a global given by the loader.
    if not simulated:
        source = _FMA.sub("cuda.fma(", source)
    return f"# varint CUDA generator {_generator_id()}\n" + source


def cuda_stepper(model, kinds, corrected, k, accumulator=None):
    """The compiled CUDA kernel for this model, scheme, ``k`` and
    accumulator (see :func:`cuda_source`), built once per process; on the
    simulator (``NUMBA_ENABLE_CUDASIM=1``) a simulated kernel."""
    return _compiled(cuda_source(model, kinds, corrected, k, accumulator))


@lru_cache(maxsize=64)
def _compiled(source):
    return device.generated_kernel(source, "varint_cuda_", "thread")

"""The CUDA target of the generated tangent-map steppers: one orbit per thread.

The same emitter that writes the CPU steppers (:mod:`varint.kernels.generate`)
writes the step here; only the frame around it differs. The CPU's ``lanes``
kernel holds a block of orbits with the orbit index innermost and does the
whole step of one orbit per pass of its loop over lanes, branch-free; on a
GPU that pass is one thread. So the CUDA kernel is ``lanes`` with the loop
over lanes replaced by the thread index:

* the caller's arrays keep the orbit index innermost (structure of arrays):
  thread ``m`` reads ``X[i, m]``, so a warp's 32 loads of one quantity are
  one coalesced transaction;
* the lane's work arrays ``F`` and ``I`` become thread-local arrays of one
  column indexed only by constants, which the compiler keeps in registers;
* the step — drifts and kicks as explicit fused multiply–adds, ∇V, D²V and
  the corrector as straight-line expressions with common subexpressions
  eliminated, the end-of-step checks, the renormalisation with its
  mantissa/exponent bookkeeping, FLI's and MEGNO's accumulators written out
  — is emitted by the very methods that emit ``lanes``, so it is the same
  arithmetic in the same order;
* the schedule of sparse renormalisation, the overflow check and the copies
  at output steps, which ``lanes`` runs in loops of their own, run in the
  thread;
* a thread whose orbit fails (escape, non-finite state, a singular
  derivative, degenerate vectors) stops at once; as with ``lanes``, the
  caller recomputes that orbit with the CPU's one-orbit stepper from the
  call's start (:mod:`varint.gpu.advance`), so a failed orbit is left
  exactly as the CPU leaves it.

Compiled with contraction of separate multiplies and adds switched off
(:mod:`varint.gpu.device`), every operation of the kernel is rounded as the
CPU's (its PTX has only ``.rn`` additions, multiplications, fused
multiply–adds, square roots and reciprocals); ``exp``, ``log`` and the like
come from libdevice on the GPU and from the C library on the CPU and may
differ in the last place. On numba's CUDA simulator the kernel gives the
CPU's bits (``tests/test_gpu.py``); on an H100 the Hénon–Heiles FLI map
differed from the CPU's by up to 1e-11 relative at t = 100, a difference
not explained yet (``studies/results/bench_gpu_h100.md``).
"""

from __future__ import annotations

import hashlib
import re
import types
from functools import lru_cache

import sympy as sp

from ..kernels import generate as G
from ..models.symbolic import _KernelPrinter
from ..schemes import DRIFT
from . import device

__all__ = ["cuda_source", "cuda_stepper", "emittable"]


_FMA = re.compile(r"(?<![\w.])fma\(")


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


class _Printer(_KernelPrinter):
    """The CPU kernels' printer, with integer powers written as products."""

    def _print_Pow(self, expr, rational=False):
        if expr.exp.is_Integer and 2 <= int(expr.exp) <= 64:
            return _power(self.parenthesize(expr.base, sp.printing.precedence.precedence(expr)),
                          int(expr.exp))
        return super()._print_Pow(expr, rational=rational)


class CudaEmitter(G._Emitter):
    """Writes ``thread``: the step of ``lanes`` (:class:`~varint.kernels.generate._Emitter`)
    for one orbit per CUDA thread."""

    def __init__(self, E, plan, simulated):
        super().__init__(E, plan)
        self.printer = _Printer()
        # The fused multiply–adds are CUDA's on a GPU (the CPU's is an LLVM
        # intrinsic of numba's CPU target); the simulator's cuda.fma rounds
        # twice, so there they stay a global given by the loader.
        self.fma = "fma(" if simulated else "cuda.fma("

    def __call__(self, *lines):
        super().__call__(*(_FMA.sub(self.fma, line) for line in lines))

    def next_interval(self, target, interval, growth, spread):
        """``target = next_interval(interval, growth, spread)``
        (:func:`varint.kernels.generate.next_interval`), written out with
        its arithmetic in its order: a kernel cannot call the CPU's
        compiled function, and a device function would need a GPU to be
        compiled at all (the tests compile this kernel's PTX without one)."""
        self(f"allowed = {interval} * 2.0",
             f"if {growth} > 0.0:",
             f"    allowed = min(allowed, {interval} * NORM_LOG / {growth})",
             f"if {spread} > 0.0:",
             f"    allowed = min(allowed, {interval} * COND_LOG / {spread}, QR_MAX_STEPS)",
             f"{target} = int(max(1.0, min(allowed, MAX_STEPS)))")

    def thread_schedule(self):
        """The sparse schedule of this thread's orbit, when it was
        renormalised in this step (``lanes``' :meth:`lane_schedule`, for one
        lane)."""
        k = self.k
        logs = [f"math.log(F[{self.fr + j}, b])" for j in range(k)]
        self(f"if every != 0 and F[{self.fr}, b] != 0.0:")
        self.indent()
        self(f"lmax = max({', '.join(logs)})" if k > 1 else f"lmax = {logs[0]}")
        if k > 1:
            self(f"spread = lmax - min({', '.join(logs)}) if mode == QR else 0.0")
        else:
            self("spread = 0.0")
        self(f"done = max(step - (I[{self.inxt}, b] - iv), 1)")
        self.next_interval("iv", "done", "lmax", "spread")
        self("if every > 0 and iv > every:", "    iv = every",
             f"I[{self.inxt}, b] = step + iv")
        self.dedent()

    def source(self):
        plan, n, k = self.plan, self.n, self.k
        kinds = plan.kinds
        self.lane_layout()
        inline = bool(plan.inline)
        rows = self.lane_rows()
        big = " or ".join(f"not (abs(F[{self.fw + c}, b]) < TANGENT_LIMIT)"
                          for c in range(2 * n * k))
        self('"""Generated by varint.gpu.emit; do not edit."""',
             "import math", "import numpy as np", "",
             f"ACC_BIG = {2.0 ** 500!r}", f"ACC_SMALL = {2.0 ** -500!r}",
             f"TANGENT_LIMIT = {G.TANGENT_LIMIT!r}", f"EARLY = {G._EARLY!r}",
             f"HUGE = {G.HUGE_Q2!r}", f"CHECK_EVERY = {G.CHECK_EVERY}", f"LN2 = {G._LN2!r}",
             f"NONE, QR = {int(G.Renorm.NONE)}, {int(G.Renorm.QR)}",
             f"NORM_LOG, COND_LOG = {G._NORM_LOG!r}, {G._COND_LOG!r}",
             f"MAX_STEPS, QR_MAX_STEPS = {G._MAX_STEPS!r}, {G._QR_MAX_STEPS!r}", "", "",
             # cuda, float64 and int64 are given by the loader (device or
             # simulator).
             "def thread(X, W, am, ae, st, fs, nxt, itv, n_steps, step0, tau, h, hc, escape_r2,"
             " mode, every, aux, outs, snap_x, snap_W, snap_m, snap_e, snap_aux):")
        self.indent()
        self("m = cuda.grid(1)", "if m >= X.shape[1]:", "    return", "b = 0",
             f"F = cuda.local.array(({self.nf}, 1), float64)",
             f"I = cuda.local.array(({self.ni}, 1), int64)",
             f"for c in range({self.nf}):", "    F[c, 0] = 0.0",
             f"for c in range({self.ni}):", "    I[c, 0] = 0")
        for stage in range(len(kinds)):
            self(f"h{stage} = h[{stage}]")
            if plan.corrected[stage]:
                self(f"hc{stage} = hc[{stage}]")
        self("renorm = mode != NONE", "s = 0", "step = step0")
        # In: the caller's column m into F and I.
        for i in range(2 * n):
            self(f"F[{i}, b] = X[{i}, m]")
            for j in range(k):
                self(f"F[{self.fw + i * k + j}, b] = W[{i}, {j}, m]")
        for j in range(k):
            self(f"F[{self.fam + j}, b] = am[{j}, m]", f"I[{self.iae + j}, b] = ae[{j}, m]")
            for c in range(self.ncols):
                self(f"F[{self.faux + j * self.ncols + c}, b] = aux[m, {j}, {c}]")
        self("I[0, b] = st[m]", "I[1, b] = fs[m]", f"I[{self.inxt}, b] = nxt[m]", "iv = itv[m]")
        if self.reuse:
            for i in range(n):
                self(f"q{i} = F[{i}, b]")
            self("code = I[0, b]", "fstep = I[1, b]")
            self.derivatives(0, self.needs(plan.corrected[0]), lane=True)
            for c, name in enumerate(self.reuse):
                self(f"F[{self.fd + c}, b] = {name}")
            self("I[0, b] = code", "I[1, b] = fstep")
        self("jo = 0", "while jo < outs.shape[0] and outs[jo] <= step0:", "    jo += 1",
             "for s in range(n_steps):")
        self.indent()
        self("if I[0, b] != 0:", "    break",   # failed: recomputed by the caller
             "step = step0 + s + 1", "chk = step % CHECK_EVERY == 0")
        if inline:
            self("t = step * tau")
        for local, row in rows:
            self(f"{local} = {row}")
        for stage, kind in enumerate(kinds):
            if kind == DRIFT:
                self.drift(stage)
                continue
            corrected = plan.corrected[stage]
            if not (stage == 0 and self.reuse):
                self.derivatives(stage, self.needs(corrected), lane=True)
            self.kick(stage, corrected, count=False)
        self("rq = " + " + ".join(f"{v} * {v}" for v in self.q),
             "rp = " + " + ".join(f"{v} * {v}" for v in self.p))
        self.lane_fail("rq > escape_r2", G._ESCAPED)
        self.lane_fail("not (rq + rp < np.inf)", G._NONFINITE)
        if k:
            self.lane_renormalize()
            if inline:
                self.lane_inline(kinds)
        for local, row in rows:
            self(f"{row} = {local}")
        if k:
            self("if renorm:")
            self.indent()
            self.thread_schedule()
            self.dedent()
            self("elif chk:", f"    if ({big}) and I[0, b] == 0:",
                 f"        I[0, b] = {G._OVERFLOW}", "        I[1, b] = s")
        self("if jo < outs.shape[0] and step == outs[jo]:")
        self.indent()
        if k:
            self(f"if mode == NONE and ({big}) and I[0, b] == 0:",
                 f"    I[0, b] = {G._OVERFLOW}", "    I[1, b] = s")
        for i in range(2 * n):
            self(f"snap_x[jo, {i}, m] = F[{i}, b]")
            for j in range(k):
                self(f"snap_W[jo, {i}, {j}, m] = F[{self.fw + i * k + j}, b]")
        for j in range(k):
            self(f"snap_m[jo, {j}, m] = F[{self.fam + j}, b]",
                 f"snap_e[jo, {j}, m] = I[{self.iae + j}, b]")
            self.lane_aux_out(j, "snap_aux[jo, m, {}, {}]")
        self("jo += 1")
        self.dedent()
        self.dedent()
        # Out: F and I back into column m.
        for i in range(2 * n):
            self(f"X[{i}, m] = F[{i}, b]")
            for j in range(k):
                self(f"W[{i}, {j}, m] = F[{self.fw + i * k + j}, b]")
        for j in range(k):
            self(f"am[{j}, m] = F[{self.fam + j}, b]", f"ae[{j}, m] = I[{self.iae + j}, b]")
            self.lane_aux_out(j, "aux[m, {}, {}]")
        self("st[m] = I[0, b]", "fs[m] = I[1, b]", f"nxt[m] = I[{self.inxt}, b]", "itv[m] = iv")
        self.dedent()
        return "\n".join(self.lines) + "\n"


def emittable(accumulator):
    """Whether a run with ``accumulator`` can be emitted for CUDA: none
    (SALI, GALI, Lyapunov exponents read the stretching and the vectors),
    or one that the generator writes out (FLI, MEGNO and OFLI). Any other
    is a compiled CPU function, which a GPU thread cannot call."""
    return accumulator is None or bool(G._inline_kind(accumulator))


def cuda_source(model, kinds, corrected, k, accumulator=None):
    """The CUDA kernel's Python source for ``model`` (one that
    :func:`~varint.kernels.generate.symbolic_fits`), the scheme's stages
    and ``k`` vectors."""
    if not emittable(accumulator):
        raise ValueError(f"backend='cuda' runs indicators without an accumulator or with "
                         f"FLI's or MEGNO's; this one's accumulator ({accumulator.key!r}) is "
                         "compiled for the CPU only")
    plan = G.Plan(kinds=tuple(int(v) for v in kinds), corrected=tuple(bool(c) for c in corrected),
                  k=int(k), accumulator="" if accumulator is None else accumulator.key,
                  flow=bool(accumulator is not None and accumulator.needs_flow),
                  inline=G._inline_kind(accumulator))
    key = G._model_key(model)
    if key not in G._FORMS and G._facts_now(model)[1] != key:
        # As the CPU's loader: source only from the model's own form.
        raise RuntimeError(f"the cached symbolic facts of {model.name} do not match its form")
    return _source(key, plan, device.simulated())


@lru_cache(maxsize=64)
def _source(key, plan, simulated):
    return (f"# varint CUDA generator {G._generator_id()}\n"
            + CudaEmitter(G._expressions(key), plan, simulated).source())


def cuda_stepper(model, kinds, corrected, k, accumulator=None):
    """The compiled CUDA kernel for this model, scheme, ``k`` and
    accumulator (see :func:`cuda_source`), built once per process; on the
    simulator (``NUMBA_ENABLE_CUDASIM=1``) a simulated kernel."""
    return _compiled(cuda_source(model, kinds, corrected, k, accumulator))


@lru_cache(maxsize=64)
def _compiled(source):
    name = "varint_cuda_" + hashlib.sha256(source.encode()).hexdigest()[:24]
    module = types.ModuleType(name)
    module.__dict__.update(device.kernel_globals())
    # The source is made in this process from the model's own form: nothing
    # read from disk is run.
    exec(compile(source, f"<{name}>", "exec"), module.__dict__)
    return device.kernel(module.thread)

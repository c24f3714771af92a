"""The logarithmic-Hamiltonian (LH) stepper, emitted: one model × scheme
written out as straight-line source, signed and cached on disk like the
TM steppers (:mod:`varint.codegen.stepper`).

The step of :mod:`varint.kernels.time_transform` (its docstring is the
specification: the two flows of Γ, their rank-one tangent terms, the
projection to equal physical time, the landing on output times) is
unrolled over the scheme's stages: each drift evaluates A and ∇A, moves the
orbit and the vectors by A's exact flow over the physical time τ = h/W and
adds the rank-one term; each kick evaluates V, ∇V and D²V and applies the
kick of length h/U with its symmetric rank-one term. The orbit is held in
local variables for the whole step; A's flow (free motion or the rotating
frame's :func:`varint.flows.split.planar_flow`) is written out with the
model's constants as literals.

Round-off. Every quantity is computed by the same operations in the same
order as the generic loop over the stage arrays that this stepper replaced
(stop 40): A, ∇A, V, ∇V and D²V by the same common-subexpression groups (a
group of SymPy's CSE changes its summation order, hence its bits, when its
members change), the flows as :func:`~varint.flows.split.planar_flow` and
:func:`~varint.flows.split.oscillator` compute them, the tangent sums with
the same initial values — with one exception: a half-integer power
b^(p/2), |p| ≥ 3 (the r⁻³ and r⁻⁵ of point masses), is written as
products of b and √b, a square root and a few multiplications instead of
a call of ``pow`` (which costs several times more and took most of a
three-body step), as in every generated stepper
(:class:`~varint.codegen.printer.StepperPrinter`); its value differs from
``pow``'s by a few units in the last place. So the emitted stepper gives
the generic loop's bits on a model without such powers (the cored
logarithmic potential: checked on its FLI map), and agrees with it to
round-off on one with them (the three-body problem, a softened point
mass). A logarithm of the model is printed ``lane_log`` (:class:`_LHPrinter`,
:mod:`varint.kernels.lh_log`: fdlibm's algorithm, the bits of
:func:`varint.kernels.logarithm.vlog`, within 1 ulp), not the C library's
``log`` (within 0.51 ulp): since lh22 the LH map of a logarithmic potential
(the cored one) computes V one ulp away from before for some q, so its
chaotic orbits' values differ from before in their digits (its lanes
vectorise the logarithm, :mod:`varint.codegen.lh_lanes`); a model without
a logarithm gets the same source but for one import, hence the same bits.
No fused multiply–adds: the time of an LH step goes to the
derivatives and, in a rotating frame, to a sine and a cosine per drift,
not to the latency of the updates.

The loop around the step — ``advance`` (LH steps, the undone step, the
physical-time tail, the projection), ``project`` and ``outputs`` — is emitted
unchanged for every model (:data:`_SKELETON`); ``outputs`` over SIMD lanes
(``lanes0``, ``lanes1``) by :mod:`varint.codegen.lh_lanes`, from this
emitter's groups and flows.

References
----------
S. Mikkola & K. Tanikawa, MNRAS 310, 745 (1999).
H. Preto & S. Tremaine, AJ 118, 2532 (1999).
"""

from __future__ import annotations

import hashlib
import importlib.metadata
import math
from functools import lru_cache
from pathlib import Path

from ..kernels.time_transform import BUDGET, U_NOT_POSITIVE
from ..protocol import Status
from .lh_lanes import emit_lanes
from .printer import StepperPrinter
from .source import Source

__all__ = ["lh_source", "lh_name", "Flow", "generator_sources"]

_OK = int(Status.OK)
_NONFINITE = int(Status.ORBIT_NONFINITE)
_GRAD = int(Status.GRADIENT_NONFINITE)


class Flow:
    """A's exact flow as the emitter needs it: ``kind`` "free" with the
    inverse masses ``minv`` (A = ½pᵀM⁻¹p), or "planar" with the parameters
    of :func:`varint.flows.split.planar_params` (``par``)."""

    def __init__(self, kind, values):
        if kind not in ("free", "planar"):
            raise ValueError(f"flow kind must be 'free' or 'planar', got {kind!r}")
        self.kind, self.values = kind, tuple(float(v) for v in values)

    def __repr__(self):
        return f"Flow({self.kind!r}, {self.values!r})"


def generator_sources():
    """The files an LH module's source is made of besides the model: this
    emitter, the specification module whose constants it writes in, the
    protocol's status codes, the source builder, the printers
    (:mod:`varint.codegen.printer` and ``varint.models.symbolic``) and the
    logarithm the module inlines (:mod:`varint.kernels.lh_log`, with the
    bit casts and fused multiply–add it calls)."""
    package = Path(__file__).resolve().parent.parent
    kernels = package / "kernels"
    return [Path(__file__), Path(__file__).with_name("lh_lanes.py"),
            Path(__file__).with_name("printer.py"), kernels / "lh_log.py",
            kernels / "logarithm.py", kernels / "fma.py",
            Path(__file__).with_name("source.py"), package / "protocol.py",
            package / "kernels" / "time_transform.py", package / "models" / "symbolic.py"]


@lru_cache(maxsize=1)
def _generator_id():
    """A hash of :func:`generator_sources` and SymPy's version, whose CSE
    and printing write the expressions; a change of any names new
    modules."""
    digest = hashlib.sha256(importlib.metadata.version("sympy").encode())
    for path in generator_sources():
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def lh_name(key):
    """The module name of the LH stepper whose ingredients ``key`` (text)
    names: the emitter's code, A, V, the flow and the scheme's stage kinds
    determine its source."""
    return "varint_lh_" + hashlib.sha256(f"{_generator_id()}|{key}".encode()).hexdigest()[:24]


def lh_source(A, V, q, p, flow, kinds):
    """The source of the LH stepper module of H = A(q, p) + V(q) (SymPy in
    the symbols ``q``, ``p``), A's exact ``flow`` (:class:`Flow`) and the
    scheme's stage ``kinds`` (0 drift, 1 kick).

    The module defines ``kinetic(x, gA) -> A``, ``potential(q, gV, HV,
    hess) -> V`` and ``advance``, ``step``, ``project``, ``outputs`` with the
    signatures of :mod:`varint.kernels.time_transform`'s docstring.
    """
    import sympy as sp  # type: ignore[import-untyped]  # emitting only

    n = len(q)
    xs = (*q, *p)
    names = {s: sp.Symbol(f"x_{i}") for i, s in enumerate(xs)}
    gA = [sp.diff(A, s).xreplace(names) for s in xs]
    gV = [sp.diff(V, s) for s in q]
    HV = [sp.diff(gV[i], q[j]).xreplace(names) for i in range(n) for j in range(n)]
    gV = [e.xreplace(names) for e in gV]
    A, V = A.xreplace(names), V.xreplace(names)
    em = _Emitter(_LHPrinter(), n, flow)
    # The groups of common subexpressions (module docstring: the same bits).
    em.kinetic_group = ([f"gA_{i}" for i in range(2 * n)] + ["a"], [*gA, A])
    em.potential_group = ([f"gV_{i}" for i in range(n)] + ["v"], [*gV, V])
    em.hessian_group = ([f"HV_{i}_{j}" for i in range(n) for j in range(n)], HV)
    src = Source()
    src(f"# varint LH generator {_generator_id()}",
        '"""Generated by varint.codegen.lh; do not edit."""', "import math", "",
        "import numpy as np", "from numba import njit", "",
        "from varint.kernels.lh_log import lane_log", "")
    em.arrays(src, "kinetic(x, gA)", "x", 2 * n, em.kinetic_group, "gA", "a")
    em.arrays(src, "potential(q, gV, HV, hess)", "q", n, em.potential_group, "gV", "v",
              hessian=True)
    em.step(src, tuple(int(k) for k in kinds))
    src(*_SKELETON.splitlines())
    emit_lanes(src, em, tuple(int(k) for k in kinds))
    return src.text()


class _LHPrinter(StepperPrinter):
    """:class:`~varint.codegen.printer.StepperPrinter` with the model's
    logarithms written ``lane_log(…)`` (:mod:`varint.kernels.lh_log`: the
    bits of :func:`varint.kernels.logarithm.vlog`, branch-free), not
    ``math.log``: the LH lanes then vectorise a kick that takes one
    (module docstring, "Round-off")."""

    def _print_log(self, expr):
        if len(expr.args) != 1:
            raise ValueError(f"a logarithm with a base in the model: {expr}; expected "
                             "log(x) (SymPy writes log(x, b) as log(x)/log(b))")
        return f"lane_log({self._print(expr.args[0])})"


class _Emitter:
    """Writes the functions of one LH module (:func:`lh_source`)."""

    def __init__(self, printer, n, flow):
        self.printer, self.n, self.flow = printer, n, flow
        self.kinetic_group = self.potential_group = self.hessian_group = ([], [])

    def group(self, src, group, rename=None):
        """``targets = exprs`` of ``group`` with SymPy's CSE (as
        :func:`varint.models.symbolic._assignments` did for the generic
        loop)."""
        import sympy as sp  # type: ignore[import-untyped]

        targets, exprs = group
        temps, reduced = sp.cse(list(exprs), symbols=sp.numbered_symbols("_t"))
        for s, e in temps:
            src(f"{s} = {self.printer.doprint(e)}")
        for t, e in zip(targets, reduced, strict=True):
            src(f"{rename(t) if rename else t} = {self.printer.doprint(e)}")

    def arrays(self, src, signature, arg, m, group, out, value, hessian=False):
        """A function of the state array ``arg`` that writes the gradient
        into the array ``out`` and returns the value (``kinetic``,
        ``potential``; with ``hessian``, D²V into ``HV`` when ``hess``)."""
        src("", "@njit(cache=True, error_model='numpy')")
        with src.block(f"def {signature}:"):
            src(*(f"x_{i} = {arg}[{i}]" for i in range(m)))
            self.group(src, group,
                       lambda t: t if t == value else f"{out}[{t.split('_', 1)[1]}]")
            if hessian:
                with src.block("if hess:"):
                    self.group(src, self.hessian_group,
                               lambda t: "HV[{}, {}]".format(*t.split("_")[1:]))
            src(f"return {value}")
        src("")

    # -- the step ------------------------------------------------------------------------
    def step(self, src, kinds):
        d = 2 * self.n
        src("", "@njit(cache=True, error_model='numpy')")
        with src.block("def step(x, V, dt, dpt, clock, kinds, coef, h, par, log, C, counts, "
                       "gA, gV, HV, dtau):"):
            src('"""One LH step (``log``), else the ordinary step of length ``h``, of '
                f"the scheme with stage kinds {list(kinds)}",
                "(``kinds`` and ``par`` are those this module was emitted for and are "
                'not read)."""',
                "k = V.shape[0]", *(f"x_{i} = x[{i}]" for i in range(d)),
                "t = clock[0]", "wc = clock[1]")
            for st, kind in enumerate(kinds):
                src(f"hs = coef[{st}] * h")
                if kind == 0:
                    self.drift(src)
                else:
                    self.kick(src)
            self.store(src)
            for i in range(d):
                with src.block(f"if x_{i} - x_{i} != 0.0:"):
                    src(f"return {_NONFINITE}")
            src(f"return {_OK}")

    def store(self, src):
        src(*(f"x[{i}] = x_{i}" for i in range(2 * self.n)), "clock[0] = t")

    def drift(self, src):
        """A's flow over τ = hs/W (LH) or hs, with the rank-one term."""
        n, d = self.n, 2 * self.n
        with src.block("if log:"):
            self.group(src, self.kinetic_group)
            src("W = a + wc", "tau = hs / W")
            with src.block("for c in range(k):"):
                src("s = dpt[c]", *(f"s += gA_{i} * V[c, {i}]" for i in range(d)),
                    "dtau[c] = -(tau / W) * s")
        with src.block("else:"):
            src("tau = hs")
        self.flow_lines(src)
        src("t += tau")
        with src.block("if log and k > 0:"):
            self.group(src, self.kinetic_group)
            with src.block("for c in range(k):"):
                for i in range(n):
                    src(f"V[c, {i}] += gA_{n + i} * dtau[c]",
                        f"V[c, {n + i}] -= gA_{i} * dtau[c]")
                src("dt[c] += dtau[c]")

    def flow_lines(self, src):
        """A's exact flow over ``tau`` on the orbit and every vector: as
        free motion, ``x_i += (τ m_i) p_i``, or
        :func:`~varint.flows.split.planar_flow`, constants as literals."""
        n = self.n
        if self.flow.kind == "free":
            for i, m in enumerate(self.flow.values):
                src(f"am = tau * {m!r}", f"x_{i} += am * x_{n + i}")
                with src.block("for c in range(k):"):
                    src(f"V[c, {i}] += am * V[c, {n + i}]")
            return
        par = self.flow.values
        u, v = int(par[0]), int(par[1])
        a, b, omega = par[2:5]
        self.oscillator(src, a, b)
        self.pair(src, u, n + u, "oc", "os1", "os2")
        self.pair(src, v, n + v, "oc", "os1", "os2")
        # Rotation by −Ωτ of (q_u, q_v) and (p_u, p_v): the flow of −Ω L.
        src(f"cr = math.cos({omega!r} * tau)", f"sr = math.sin({omega!r} * tau)",
            "msr = -sr")
        self.pair(src, u, v, "cr", "sr", "msr")
        self.pair(src, n + u, n + v, "cr", "sr", "msr")
        for i in range(n):
            if i in (u, v):
                continue
            self.oscillator(src, par[5 + 2 * i], par[5 + 2 * i + 1])
            self.pair(src, i, n + i, "oc", "os1", "os2")

    @staticmethod
    def oscillator(src, a, b):
        """(oc, os1, os2) of the flow of ½a p² + ½b q² over ``tau``, by the
        operations of :func:`varint.flows.split.oscillator`."""
        ab = a * b
        if ab == 0.0:
            src("oc = 1.0", f"os1 = {a!r} * tau", f"os2 = {-b!r} * tau")
            return
        w = math.sqrt(abs(ab))
        sin, cos = ("math.sin", "math.cos") if ab > 0.0 else ("math.sinh", "math.cosh")
        src(f"zs = {sin}({w!r} * tau)", f"oc = {cos}({w!r} * tau)",
            f"os1 = {a!r} * zs / {w!r}", f"os2 = {-b!r} * zs / {w!r}")

    @staticmethod
    def pair(src, i, j, cm, s1, s2):
        """(x_i, x_j) ← (cm x_i + s1 x_j, s2 x_i + cm x_j) on the orbit and
        every vector (:func:`varint.flows.split.planar_flow`'s pair)."""
        src(f"zi = x_{i}", f"zj = x_{j}", f"x_{i} = {cm} * zi + {s1} * zj",
            f"x_{j} = {s2} * zi + {cm} * zj")
        with src.block("for c in range(k):"):
            src(f"zi = V[c, {i}]", f"zj = V[c, {j}]", f"V[c, {i}] = {cm} * zi + {s1} * zj",
                f"V[c, {j}] = {s2} * zi + {cm} * zj")

    def kick(self, src):
        """p ← p − (hs/U) ∇V (LH) or hs ∇V, δp with the symmetric
        rank-one term (the specification's kick)."""
        n = self.n
        self.group(src, self.potential_group)
        src("counts[2] += 1")
        finite = " or ".join(f"gV_{i} - gV_{i} != 0.0" for i in range(n))
        with src.block(f"if v - v != 0.0 or {finite}:"):
            self.store(src)
            src(f"return {_GRAD}")
        src("w = hs", "r = 0.0")
        with src.block("if log:"):
            src("u = C - v")
            with src.block("if not u > 0.0:"):
                self.store(src)
                src(f"return {U_NOT_POSITIVE}")
            src("w = hs / u", "r = w / u")
        src(*(f"x_{n + i} -= w * gV_{i}" for i in range(n)))
        # D²V (a function of q alone, which the kick leaves) and the
        # tangent kick in one block: D²V is defined only there.
        with src.block("if k > 0:"):
            self.group(src, self.hessian_group)
            with src.block("for c in range(k):"):
                src("s = 0.0", *(f"s += gV_{j} * V[c, {j}]" for j in range(n)))
                for i in range(n):
                    src("acc = 0.0", *(f"acc += HV_{i}_{j} * V[c, {j}]" for j in range(n)),
                        f"V[c, {n + i}] -= w * acc + r * gV_{i} * s")


#: The loop around the step, the same for every model: the landing on
#: output times and the projection of :mod:`varint.kernels.time_transform`.
_SKELETON = f'''

@njit(cache=True, error_model='numpy')
def project(x, V, dt, par, gA, gV, HV):
    """δx ← δx − f_H(x) δt, δt ← 0."""
    d = x.shape[0]
    n = d // 2
    k = V.shape[0]
    if k == 0:
        return
    kinetic(x, gA)
    potential(x[:n], gV, HV, False)
    for c in range(k):
        for i in range(n):
            V[c, i] -= gA[n + i] * dt[c]
            V[c, n + i] += (gA[i] + gV[i]) * dt[c]
        dt[c] = 0.0


@njit(cache=True, error_model='numpy')
def advance(x, V, dt, clock, kinds, coef, h, t_end, max_steps, par, C, counts):
    """LH steps of fictitious length h while they end before t_end, then
    the physical-time tail; the vectors projected on return."""
    d = x.shape[0]
    n = d // 2
    k = V.shape[0]
    gA, gV, HV = np.empty(d), np.empty(n), np.empty((n, n))
    dtau = np.empty(k)
    # Each vector stays on the energy shell: dp_t = -grad H(x).dx, constant.
    dpt = np.zeros(k)
    if k > 0:
        kinetic(x, gA)
        potential(x[:n], gV, HV, False)
        for c in range(k):
            s = 0.0
            for i in range(n):
                s += (gA[i] + gV[i]) * V[c, i] + gA[n + i] * V[c, n + i]
            dpt[c] = -s
    x0, V0, dt0, c0 = x.copy(), V.copy(), dt.copy(), clock.copy()
    last = 0.0
    steps = 0
    while True:
        if steps >= max_steps:
            project(x, V, dt, par, gA, gV, HV)
            return {BUDGET}
        # Copies by explicit loops: numba's slice assignment of small
        # arrays costs more than the copy.
        for i in range(d):
            x0[i] = x[i]
        for c in range(k):
            dt0[c] = dt[c]
            for i in range(d):
                V0[c, i] = V[c, i]
        c0[0] = clock[0]
        c0[1] = clock[1]
        status = step(x, V, dt, dpt, clock, kinds, coef, h, par, True, C, counts, gA, gV,
                      HV, dtau)
        if status != {_OK}:
            x[:] = x0
            V[:, :] = V0
            dt[:] = dt0
            clock[:] = c0
            project(x, V, dt, par, gA, gV, HV)
            return status
        if clock[0] > t_end:
            last = clock[0] - c0[0]
            x[:] = x0
            V[:, :] = V0
            dt[:] = dt0
            clock[:] = c0
            break
        steps += 1
        counts[0] += 1
    # The tail: m ordinary steps in physical time, each no longer than the
    # undone LH step.
    project(x, V, dt, par, gA, gV, HV)
    rest = t_end - clock[0]
    if rest <= 0.0:
        return {_OK}
    m = max(1, int(math.ceil(rest / last)))
    tau = rest / m
    for _ in range(m):
        status = step(x, V, dt, dpt, clock, kinds, coef, tau, par, False, C, counts, gA,
                      gV, HV, dtau)
        if status != {_OK}:
            return status
        counts[1] += 1
    clock[0] = t_end   # the tail's lengths sum to it up to round-off
    return {_OK}


@njit(cache=True, error_model='numpy')
def outputs(X, W0, pt, C, h, t_end, every, max_steps, kinds, coef, par, fli, status, counts,
            x_end, t_end_at, x_worst, t_worst):
    """Every orbit X[m] with its vectors W0[m] (k, 2N; k = 0 or 1) to the
    physical time t_end through outputs at the multiples of every, with its
    own fictitious step h[m]: the FLI sup ln|w| over the outputs (the
    vector normalised at each; NaN without a vector), the status, the
    final state and its time, and the output state whose H = A + V lies
    furthest from H(x0) = -p_t, with its time."""
    M, d = X.shape
    n = d // 2
    k = W0.shape[1]
    gA, gV, HV = np.empty(d), np.empty(n), np.empty((n, n))
    for m in range(M):
        x = X[m].copy()
        V = W0[m].copy()
        dt = np.zeros(k)
        clock = np.array([0.0, pt[m] + C[m]])
        e0 = -pt[m]
        acc = best = big = 0.0
        x_worst[m, :] = x
        t_worst[m] = 0.0
        j = 0
        st = {_OK}
        while clock[0] < t_end and st == {_OK}:
            j += 1
            stop = min(j * every, t_end)
            st = advance(x, V, dt, clock, kinds, coef, h[m], stop, max_steps, par, C[m],
                         counts[m])
            if k > 0:
                norm = 0.0
                for i in range(d):
                    norm += V[0, i] * V[0, i]
                norm = math.sqrt(norm)
                acc += math.log(norm)
                best = max(best, acc)
                for i in range(d):
                    V[0, i] /= norm
            e = abs(kinetic(x, gA) + potential(x[:n], gV, HV, False) - e0)
            if not e <= big:   # larger, or NaN: the state that shows it
                big = e
                x_worst[m, :] = x
                t_worst[m] = clock[0]
        fli[m] = best if k > 0 else math.nan
        status[m] = st
        x_end[m, :] = x
        t_end_at[m] = clock[0]
'''

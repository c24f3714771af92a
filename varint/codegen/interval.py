"""The stepping skeleton, emitted: the loop over steps and the end of every
step of a generated stepper, written once for one orbit and for SIMD lanes.

The compiled skeleton (:mod:`varint.kernels.interval`) serves steppers
whose state lives in arrays; a generated stepper keeps its state in local
variables — registers — and is emitted as source. Its end-of-step contract
is the same, in the same order and with the same arithmetic, so a
generated stepper gives the bits it would give through that contract:

1. the orbit's checks (escape, non-finite state);
2. the renormalisation of the vectors with the mantissa/exponent
   bookkeeping of their stretching (:mod:`varint.kernels.checks`) — every
   step, every n steps, or on the adaptive schedule of
   :func:`varint.kernels.interval.next_interval`, and at once when a vector
   grew beyond 1e100;
3. the indicator's accumulator: its rule written out
   (:mod:`varint.codegen.accumulators`), or its compiled update called;
4. the overflow check of unrenormalised vectors every ``CHECK_EVERY``
   steps;
5. copies of the state at the requested output steps (*snapshots*).

One piece of code writes each of them (:class:`Interval`); a *target* says
only where the state lives and how control flows:

* :class:`OneOrbit`: locals loaded before the loop and stored after it; a
  failure leaves the loop; work is done where it is due (branches).
* :class:`Lanes`: a block of up to :data:`LANE_WIDTH` orbits, the orbit
  index innermost. Each step is one loop over the lanes that does the whole
  step of each orbit, branch-free, so that LLVM vectorises it: a lane that
  fails is marked (and recomputed afterwards by the one-orbit stepper, from
  the call's start), a renormalisation is computed everywhere and kept
  where due. Work that branches or calls (the schedule, an update without
  a rule, the overflow check, snapshots) runs in loops of its own.

The step itself is the method's (:class:`varint.codegen.tm.TMBody`).
"""

from __future__ import annotations

from collections import namedtuple

from ..kernels.checks import CHECK_EVERY, HUGE_Q2
from ..kernels.interval import EARLY, orbit_record
from ..protocol import TANGENT_LIMIT, Renorm, Status
from ..threads import in_threads
from .accumulators import emit_readout, emit_rule
from .source import Source

__all__ = ["Interval", "OneOrbit", "Lanes", "StepperOrbit", "CompensatedOrbit", "StepperSetup",
           "Outputs", "LaneBlock", "LANE_WIDTH", "blocks_in_threads"]

_OK, _ESCAPED, _NONFINITE = int(Status.OK), int(Status.ESCAPED), int(Status.ORBIT_NONFINITE)
_DEGENERATE, _OVERFLOW = int(Status.TANGENT_DEGENERATE), int(Status.TANGENT_OVERFLOW)
_LN2 = 0.6931471805599453

#: Orbits per block of ``lanes`` at most (its work arrays' width).
LANE_WIDTH = 64

#: One orbit's record (:mod:`varint.kernels.interval`); ``schedule`` (2,):
#: the next renormalisation step and the current interval of the sparse
#: schedule.
StepperOrbit = orbit_record("StepperOrbit", ("schedule",))

#: One orbit of a compensated stepper (:class:`varint.codegen.tm.TMBody`):
#: a :data:`StepperOrbit` and ``compensation`` (2N, 1 + k), the Kahan
#: compensations of the state (column 0) and of each vector (columns 1 … k).
CompensatedOrbit = orbit_record("CompensatedOrbit", ("schedule", "compensation"))

#: What a call reads besides :class:`~varint.kernels.interval.Call`: the
#: stage lengths (:func:`varint.schemes.stage_arrays`) and ``every``:
#: renormalise every step (0), on the adaptive schedule (−1), or every
#: ``every`` steps.
StepperSetup = namedtuple("StepperSetup", ("h", "hc", "every"))

#: The output steps and where the state is copied at each: for one orbit
#: ``x`` (S, 2N), ``W`` (S, 2N, k), ``acc_m``, ``acc_e`` (S, k), ``aux``
#: (S, k, columns); for a block of lanes the lanes last, ``x`` (S, 2N, L),
#: …, but ``aux`` (S, L, k, columns).
Outputs = namedtuple("Outputs", ("steps", "x", "W", "acc_m", "acc_e", "aux"))

#: A block of orbits as SIMD lanes, the lanes last: ``x`` (2N, L), ``W``
#: (2N, k, L), ``acc_m``, ``acc_e`` (k, L), ``aux`` (L, k, columns), and per
#: lane the status and failure step and the schedule (next renormalisation
#: step, interval).
LaneBlock = namedtuple("LaneBlock", ("x", "W", "acc_m", "acc_e", "aux", "status", "fail_step",
                                     "next", "interval"))


def blocks_in_threads(kernel, blocks, setup, call, outputs):
    """A generated stepper's ``blocks_serial`` (``kernel``) over the blocks
    of lanes ``blocks`` (a :data:`LaneBlock` of arrays with a leading axis
    of blocks, the snapshots ``outputs`` too), on threads, one block at a
    time (:func:`varint.threads.in_threads`): a thread that is descheduled
    holds up one block. Slices of the leading axis stay C-contiguous, so
    every call runs the one compiled kernel."""
    def work(lo, hi):
        kernel(LaneBlock(*(a[lo:hi] for a in blocks)), setup, call,
               Outputs(outputs.steps, *(a[lo:hi] for a in outputs[1:])))

    in_threads(work, blocks.x.shape[0], slice_size=1)


class OneOrbit:
    """One orbit whose state is in locals: a failure is recorded in
    ``status`` and leaves the loop (the locals are stored after it); the
    work is counted."""

    carries = False
    counts = True
    #: The logarithm of an accumulator's rule: called, not inlined — the
    #: rule runs only where the vectors are renormalised, where numba's
    #: inlining of the logarithm's IR at each use is compile time for
    #: nothing (the end of the step is over half of a generated MEGNO
    #: kernel's compile, studies/stepper_compile_parts.py); the same bits.
    log = "vlog_called"

    def fail(self, src, condition, value, settle=()):
        """Where ``condition`` holds: the statements ``settle`` (what puts
        the state in its locals mid-step: :meth:`~varint.codegen.tm.TMBody.
        unsettled`), the status, out of the loop."""
        with src.block(f"if {condition}:"):
            src(*settle, f"status = {value}", "break")

    fail_each = fail
    fail_due = fail

    def value(self, name):
        return name

    def each(self):
        return self

    def working(self, src, names):
        return names

    def keep(self, src, name, value):
        src(f"{name} = {value}")

    def add(self, src, name, value):
        src(f"{name} += {value}")

    def stretching(self, src, j):
        pass

    def commit(self, src, names, copies):
        pass

    def guard(self, src):
        return None

    def snap(self, array, *index):
        return f"{array}[jo, {', '.join(map(str, index))}]"

    def snap_aux(self, j, c):
        return f"snap_aux[jo, {j}, {c}]"

    def interval(self, src, iv):
        """A step and its end, in the order of the contract; renormalising
        and what follows it only where due."""
        iv.step()
        iv.check()
        if not iv.k:
            return
        with src.block("if mode != NONE:"):
            src("due = every == 0 or step >= next_renorm")
            with src.block("if not due and step % CHECK_EVERY == 0:"):
                src(f"due = {' or '.join(iv.early())}")
            with src.block("if due:"):
                iv.renormalise()
                iv.accumulate_rule()
                with src.block("if every != 0:"):
                    iv.schedule()
                iv.accumulate_call()
        with src.block("elif step % CHECK_EVERY == 0:"):
            iv.overflow()

    def orbits(self, src):
        """The per-orbit sections (snapshots): one orbit, nothing to loop."""
        return _Nothing()


class Lanes:
    """A block of orbits as SIMD lanes, copied into two arrays allocated
    here, floats ``F`` and integers ``I``, :data:`LANE_WIDTH` columns each,
    one row per quantity. Their rows are a constant distance apart, so LLVM
    proves the loop over lanes free of aliasing and vectorises it; over the
    caller's arrays (strides unknown to it) it needed more run-time overlap
    checks than it allows and kept the loop scalar: 28 against 4.4 ns per
    orbit and step (Hénon–Heiles, SBAB2C, one vector, AVX-512).

    A lane that fails is marked (``code``, ``fstep``; selects, so the loop
    still vectorises) and goes on being computed; the caller recomputes it
    exactly with the one-orbit stepper. A renormalisation is computed on
    copies of the vectors and kept where it was due.
    """

    carries = True
    counts = False
    #: The logarithm of an accumulator's rule: inlined, so that the loop
    #: over the lanes vectorises.
    log = "vlog"

    def __init__(self, iv):
        self.rows = iv.lane_rows()

    def fail(self, src, condition, value):
        src(f"bad = ({condition}) & (code == 0)",
            f"code = ({value}) if bad else code", "fstep = s if bad else fstep")

    def fail_due(self, src, condition, value):
        self.fail(src, f"due & ({condition})", value)

    def fail_each(self, src, condition, value):
        with src.block(f"if ({condition}) and I[0, b] == 0:"):
            src(f"I[0, b] = {value}", "I[1, b] = s")

    def value(self, name):
        """Where a quantity of lane ``b`` is read outside the loop over lanes."""
        return self.rows[name]

    def each(self):
        """This target as seen from a loop of its own over the lanes: a
        failure is written to the lane's row."""
        return _Each(self)

    def working(self, src, names):
        copies = {key: f"c{name}" for key, name in names.items()}
        for key, name in names.items():
            src(f"{copies[key]} = {name}")
        return copies

    def keep(self, src, name, value):
        src(f"{name} = {value} if due else {name}")

    def add(self, src, name, value):
        src(f"{name} += {value} if due else 0")

    def stretching(self, src, j):
        src(f"{self.rows[f'r{j}']} = r{j} if due else 0.0")

    def commit(self, src, names, copies):
        for key, name in names.items():
            self.keep(src, name, copies[key])

    def guard(self, src):
        src("ok = due & (code == 0)")
        return "ok"

    def snap(self, array, *index):
        return f"{array}[jo, {', '.join(map(str, index))}, b]"

    def snap_aux(self, j, c):
        return f"snap_aux[jo, b, {j}, {c}]"

    def interval(self, src, iv):
        """A step of every lane in one branch-free loop; the schedule, an
        update without a rule and the overflow check in loops of their own."""
        k = iv.k
        src("chk = step % CHECK_EVERY == 0")
        with src.block("for b in range(nb):"):
            for local, row in iv.carried_rows():
                src(f"{local} = {row}")
            iv.step()
            iv.check()
            if k:
                src("early = " + " | ".join(f"({term})" for term in iv.early()),
                    f"due = renorm & ((every == 0) | (step >= {self.rows['next_renorm']}) | "
                    "(chk & early))")
                iv.renormalise()
                iv.accumulate_rule()
            for local, row in iv.carried_rows():
                src(f"{row} = {local}")
        if not k:
            return
        with src.block("if renorm:"):
            with src.block("if every != 0:"), src.block("for b in range(nb):"):
                src(f"if {self.rows['r0']} == 0.0:", "    continue")
                iv.schedule()
            if iv.calls:
                with src.block("for b in range(nb):"):
                    src("if I[0, b] != 0:", "    continue")
                    iv.accumulate_call()
        with src.block("elif chk:"), src.block("for b in range(nb):"):
            iv.overflow()

    def orbits(self, src):
        """The per-orbit sections (snapshots): a loop over the lanes."""
        return src.block("for b in range(nb):")


class _Each:
    """A :class:`Lanes` target inside a per-lane loop."""

    carries = True
    counts = False

    def __init__(self, lanes):
        self.fail = lanes.fail_each


class _Nothing:
    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False


class Interval:
    """Writes a generated stepper module: ``orbit`` (one orbit) and
    ``lanes`` (a block of SIMD lanes), each with its batch wrappers, around
    the step of ``body`` (:class:`~varint.codegen.tm.TMBody`) for ``k``
    vectors and the accumulator ``acc`` (an
    :class:`~varint.protocol.Accumulator`, or None)."""

    def __init__(self, body, k, acc):
        self.body, self.k, self.n = body, k, body.n
        self.acc = acc
        self.rule = None if acc is None else acc.rule
        self.calls = acc is not None and self.rule is None
        self.flow = acc is not None and acc.needs_flow
        self.columns = () if acc is None else tuple(acc.columns)
        self.live = () if self.rule is None else tuple(self.rule.live)
        self.src = Source()
        self.t = None

    # -- names ------------------------------------------------------------------------
    def vectors(self):
        """(i, j) → local of every vector component, vector by vector."""
        return {(i, j): self.body.component(i, j) for j in range(self.k)
                for i in range(2 * self.n)}

    def live_local(self, j, col):
        return f"u{j}_{self.columns.index(col)}"

    def locals(self):
        """(local, where the one-orbit stepper loads and stores it)."""
        n, k, body = self.n, self.k, self.body
        out = []
        for i in range(n):
            out += [(body.q[i], f"x[{i}]"), (body.p[i], f"x[{n + i}]")]
            for j in range(k):
                out += [(body.a[i][j], f"W[{i}, {j}]"), (body.b[i][j], f"W[{n + i}, {j}]")]
        for j in range(k):
            out += [(f"am{j}", f"acc_m[{j}]"), (f"ae{j}", f"acc_e[{j}]")]
        # The compensations a level changes (those of the others stay zero
        # in the state: not loaded, not kept in registers).
        c, kept = body.compensation, body.compensated_names()
        out += [(c(body.coordinate(i)), f"comp[{i}, 0]") for i in range(2 * n)
                if body.coordinate(i) in kept]
        out += [(c(body.component(i, j)), f"comp[{i}, {j + 1}]") for j in range(k)
                for i in range(2 * n) if body.component(i, j) in kept]
        return out + [("next_renorm", "rsched[0]"), ("interval", "rsched[1]")]

    def live_columns(self, where):
        """(local, ``where(j, c)``) of every live column of a rule."""
        return [(self.live_local(j, col), where(j, self.columns.index(col)))
                for j in range(self.k) for col in self.live]

    def lane_rows(self):
        """Every quantity of a lane → its row of ``F`` or ``I`` (lane ``b``)."""
        n, k, body = self.n, self.k, self.body
        rows = {body.coordinate(i): f"F[{i}, b]" for i in range(2 * n)}
        fw = 2 * n                                   # W[i, j] -> fw + i k + j
        rows.update({body.component(i, j): f"F[{fw + i * k + j}, b]"
                     for i in range(2 * n) for j in range(k)})
        fam = fw + 2 * n * k
        rows.update({f"am{j}": f"F[{fam + j}, b]" for j in range(k)})
        fr = fam + k                                 # r_j where renormalised, else 0
        rows.update({f"r{j}": f"F[{fr + j}, b]" for j in range(k)})
        fd = fr + k
        carried = self.body.carried()
        rows.update({name: f"F[{fd + c}, b]" for c, name in enumerate(carried)})
        faux = fd + len(carried)
        rows.update({self.live_local(j, col): f"F[{faux + j * len(self.live) + c}, b]"
                     for j in range(k) for c, col in enumerate(self.live)})
        self.n_floats = faux + k * len(self.live)
        # I: status, failure step, ae_j, next renormalisation step.
        rows.update({"code": "I[0, b]", "fstep": "I[1, b]", "next_renorm": f"I[{2 + k}, b]",
                     "interval": "itv[b]"})
        rows.update({f"ae{j}": f"I[{2 + j}, b]" for j in range(k)})
        self.n_ints = 3 + k
        return rows

    def carried_rows(self):
        """(local, row) of everything a lane carries through a step."""
        rows, body, k = self.t.rows, self.body, self.k
        names = [body.coordinate(i) for i in range(2 * self.n)]
        names += [body.component(i, j) for i in range(2 * self.n) for j in range(k)]
        names += [f"am{j}" for j in range(k)] + [f"ae{j}" for j in range(k)]
        names += body.carried()
        names += [self.live_local(j, c) for j in range(k) for c in self.live]
        return [(name, rows[name]) for name in names + ["code", "fstep"]]

    # -- the end of a step, written once ---------------------------------------------------
    def step(self):
        self.body.step(self.src, self.t)

    def check(self):
        """The end-of-step checks of varint.kernels.checks.orbit_status."""
        src, q, p = self.src, self.body.q, self.body.p
        src("rq = " + " + ".join(f"{v} * {v}" for v in q),
            "rp = " + " + ".join(f"{v} * {v}" for v in p))
        self.t.fail(src, "rq > escape_r2", _ESCAPED)
        self.t.fail(src, "not (rq + rp < np.inf)", _NONFINITE)

    def early(self):
        """The terms of "a vector grew huge": renormalise at the next check."""
        return [f"abs({v}) > EARLY" for v in self.vectors().values()]

    def orthogonalize(self, j, w):
        """Modified Gram–Schmidt of vector ``j`` against the earlier ones
        (QR only); returns the expression of its squared norm."""
        src, n2 = self.src, 2 * self.n
        if j:
            with src.block("if mode == QR:"):
                for c in range(j):
                    src("rr = " + " + ".join(f"{w[i, c]} * {w[i, j]}" for i in range(n2)))
                    for i in range(n2):
                        src(f"{w[i, j]} -= rr * {w[i, c]}")
        return " + ".join(f"{w[i, j]} * {w[i, j]}" for i in range(n2))

    def renormalise(self):
        """Modified Gram–Schmidt (QR) or normalisation; the stretching r{j}
        is multiplied into am{j}/ae{j}, the mantissa rescaled by exact powers
        of two (:mod:`varint.kernels.checks`)."""
        src, t, k = self.src, self.t, self.k
        names = self.vectors()
        w = t.working(src, names)
        for j in range(k):
            sq = self.orthogonalize(j, w)
            src(f"r{j} = math.sqrt({sq})")
            t.fail_due(src, f"not (r{j} > 0.0 and r{j} < np.inf)", _DEGENERATE)
            src(f"aa = am{j} * r{j}",
                "ee = 500 if aa > ACC_BIG else (-500 if aa < ACC_SMALL else 0)",
                "aa = aa * ACC_SMALL if aa > ACC_BIG else (aa * ACC_BIG if aa < ACC_SMALL else aa)")
            t.keep(src, f"am{j}", "aa")
            t.add(src, f"ae{j}", "ee")
            t.stretching(src, j)
            src(f"inv = 1.0 / r{j}")
            for i in range(2 * self.n):
                src(f"{w[i, j]} *= inv")
                if names[i, j] in self.body.compensated_names():
                    # The vector is scaled: its compensation with it (one
                    # orbit only: lanes are not emitted compensated).
                    src(f"{self.body.compensation(names[i, j])} *= inv")
        t.commit(src, names, w)

    def dot(self, j, flow):
        """``dot(a, b)`` of a rule, written out from 0.0 in component order."""
        body, n2 = self.body, 2 * self.n
        terms = {"x": [body.coordinate(i) for i in range(n2)],
                 "w": [body.component(i, j) for i in range(n2)], "f": flow}

        def dot(a, b):
            if not (terms[a] and terms[b]):
                raise ValueError(f"accumulator {self.acc.name!r}: its rule reads the flow f; "
                                 "declare needs_flow=True")
            products = " + ".join(f"{u} * {v}" for u, v in zip(terms[a], terms[b], strict=True))
            return f"(0.0 + {products})"
        return dot

    def accumulate_rule(self):
        """The accumulator's rule written out for every vector (lanes: kept
        where the interval ended well)."""
        if self.rule is None:
            return
        src, t = self.src, self.t
        guard = t.guard(src)
        src("t = step * tau")
        flow = self.body.flow(src, t) if self.flow else []
        for j in range(self.k):
            names = {"r": f"r{j}", "t": "t", "am": f"am{j}", "ae": f"ae{j}",
                     **{c: self.live_local(j, c) for c in self.live}}
            emit_rule(src, self.rule, self.columns, names, self.dot(j, flow), f"ac{j}_", guard,
                      t.log)

    def accumulate_call(self):
        """An accumulator without a rule: its compiled update called (with
        the state, vectors and flow copied to buffers)."""
        if not self.calls:
            return
        src, t, n, k, body = self.src, self.t, self.n, self.k, self.body
        v = t.value
        for j in range(k):
            src(f"rbuf[{j}] = {v(f'r{j}')}")
        for i in range(2 * n):
            src(f"xbuf[{i}] = {v(body.coordinate(i))}")
            for j in range(k):
                src(f"Wbuf[{i}, {j}] = {v(body.component(i, j))}")
        if self.flow:
            one = isinstance(t, OneOrbit)
            flow = body.flow(src, t.each(), None if one else v)
            for i, f in enumerate(flow):
                src(f"flowbuf[{i}] = {f}")
        aux = "aux" if isinstance(t, OneOrbit) else "aux[b]"
        # The time from the integer step: it does not depend on chunking.
        src(f"accumulate({aux}, rbuf, xbuf, Wbuf, flowbuf, step * tau)")

    def schedule(self):
        """The next renormalisation of the sparse schedule (every ≠ 0): the
        adaptive rule's (:func:`~varint.kernels.interval.next_interval`), at
        most ``every`` steps when one is given."""
        src, v, k = self.src, self.t.value, self.k
        # Called, not inlined: numba inlining the logarithm's IR at each of
        # these calls (off the hot path) cost a third of a stepper's compile,
        # in numba's SSA reconstruction above all (studies/stepper_compile.py).
        logs = [f"lg{j}" for j in range(k)]
        src(*(f"lg{j} = vlog_called({v(f'r{j}')})" for j in range(k)))
        nxt, itv = v("next_renorm"), v("interval")
        src(f"lmax = max({', '.join(logs)})" if k > 1 else f"lmax = {logs[0]}")
        src(f"spread = lmax - min({', '.join(logs)}) if mode == QR else 0.0" if k > 1
            else "spread = 0.0")
        src(f"{itv} = next_interval(max(step - ({nxt} - {itv}), 1), lmax, spread)")
        with src.block(f"if every > 0 and {itv} > every:"):
            src(f"{itv} = every")
        src(f"{nxt} = step + {itv}")

    def overflow(self):
        """Unrenormalised vectors beyond TANGENT_LIMIT (or not finite)."""
        self.t.fail_each(self.src, self.big(), _OVERFLOW)

    def big(self):
        v = self.t.value
        return " or ".join(f"not (abs({v(name)}) < TANGENT_LIMIT)"
                           for name in self.vectors().values())

    def snapshot(self):
        """Copy the state at an output step; check raw vectors there too."""
        src, t, n, k, body = self.src, self.t, self.n, self.k, self.body
        v = t.value
        with src.block("if jo < outs.shape[0] and step == outs[jo]:"):
            with t.orbits(src):
                if k:
                    t.fail_each(src, f"mode == NONE and ({self.big()})", _OVERFLOW)
                for i in range(2 * n):
                    src(f"{t.snap('snap_x', i)} = {v(body.coordinate(i))}")
                    for j in range(k):
                        src(f"{t.snap('snap_W', i, j)} = {v(body.component(i, j))}")
                for j in range(k):
                    src(f"{t.snap('snap_m', j)} = {v(f'am{j}')}",
                        f"{t.snap('snap_e', j)} = {v(f'ae{j}')}")
                    self.columns_out(j, t.snap_aux)
                if self.calls:
                    aux = "aux" if isinstance(t, OneOrbit) else "aux[b]"
                    with src.block(f"for jj in range({aux}.shape[0]):"), \
                            src.block(f"for cc in range({aux}.shape[1]):"):
                        src(f"{t.snap_aux('jj', 'cc')} = {aux}[jj, cc]")
            src("jo += 1")

    def columns_out(self, j, target):
        """Vector ``j``'s accumulator columns (a rule's: the live ones and
        its readout) to ``target(j, column index)``."""
        if self.rule is None:
            return
        v = self.t.value
        names = {"am": v(f"am{j}"), "ae": v(f"ae{j}"),
                 **{c: v(self.live_local(j, c)) for c in self.live}}
        values = emit_readout(self.src, self.rule, self.columns, names, f"ro{j}_", self.t.log)
        for c, col in enumerate(self.columns):
            self.src(f"{target(j, c)} = {values[col]}")

    # -- the functions ---------------------------------------------------------------------
    def module(self, accumulator_id):
        """The source of the module."""
        src = self.src
        src('"""Generated by varint.codegen; do not edit."""',
            f"# accumulator: {accumulator_id or 'none'}",
            "import math", "import numpy as np",
            "from numba import njit",
            "from varint.codegen.interval import CompensatedOrbit, LaneBlock, Outputs, "
            "StepperOrbit, blocks_in_threads",
            "from varint.kernels.fma import fma",
            "from varint.kernels.interval import next_interval",
            "from varint.kernels.logarithm import vlog, vlog_called",
            "from varint.threads import orbits_in_threads", "",
            f"ACC_BIG = {2.0 ** 500!r}", f"ACC_SMALL = {2.0 ** -500!r}",
            f"TANGENT_LIMIT = {TANGENT_LIMIT!r}", f"EARLY = {EARLY!r}", f"HUGE = {HUGE_Q2!r}",
            f"CHECK_EVERY = {CHECK_EVERY}", f"LANE_WIDTH = {LANE_WIDTH}", f"LN2 = {_LN2!r}",
            f"NONE, QR = {int(Renorm.NONE)}, {int(Renorm.QR)}")
        self.orbit()
        self.batch("orbit")
        # Compensated steppers run one orbit at a time: their lanes would
        # need the compensations in the lane arrays too. A compact step's
        # loop over stages inside the loop over lanes would not vectorise.
        if not (self.body.compensated or self.body.compact):
            self.lanes()
            self.batch("lanes")
        return src.text()

    def unpack(self, record, fields, names=None):
        names = names or fields
        self.src(f"{', '.join(names)} = " + ", ".join(f"{record}.{f}" for f in fields))

    def orbit(self):
        """``orbit(state, setup, call, outputs) -> (status, steps)``: one orbit
        (a :class:`StepperOrbit`, or :class:`CompensatedOrbit` when the body
        is compensated; :class:`StepperSetup`,
        :class:`~varint.kernels.interval.Call`, :class:`Outputs`)."""
        src, body, k = self.src, self.body, self.k
        self.t = OneOrbit()
        src("", "", "@njit(cache=True, error_model='numpy', nogil=True)",
            "def orbit(state, setup, call, outputs):")
        with src.block():
            fields = ("x", "W", "acc_m", "acc_e", "aux", "counters", "schedule")
            names = ("x", "W", "acc_m", "acc_e", "aux", "counters", "rsched")
            if body.compensated:
                fields, names = fields + ("compensation",), names + ("comp",)
            self.unpack("state", fields, names)
            self.common_unpack()
            body.prologue(src)
            for local, where in self.locals() + self.live_columns(
                    lambda j, c: f"aux[{j}, {c}]"):
                src(f"{local} = {where}")
            for j in range(k):
                src(f"r{j} = 1.0")
            src(*(f"{c} = 0" for c in body.counters()))
            self.buffers()
            body.defaults(src)
            src("status = 0", "s = 0")
            self.loop()
            for local, where in self.locals():
                src(f"{where} = {local}")
            for j in range(k):
                self.columns_out(j, lambda j, c: f"aux[{j}, {c}]")
            src(*(f"counters[{i}] += {c}" for i, c in enumerate(body.counters())))
            src("if status != 0:", "    return status, s", f"return {_OK}, n_steps")

    def common_unpack(self):
        self.unpack("setup", ("h", "hc", "every"))
        self.unpack("call", ("n_steps", "step0", "tau", "renorm", "escape_r2"),
                    ("n_steps", "step0", "tau", "mode", "escape_r2"))
        self.unpack("outputs", ("steps", "x", "W", "acc_m", "acc_e", "aux"),
                    ("outs", "snap_x", "snap_W", "snap_m", "snap_e", "snap_aux"))

    def buffers(self):
        """The buffers an update without a rule is called with."""
        if self.calls:
            n, k = self.n, self.k
            self.src(f"rbuf = np.empty({k})", f"xbuf = np.empty({2 * n})",
                     f"Wbuf = np.empty(({2 * n}, {k}))",
                     f"flowbuf = np.empty({2 * n if self.flow else 0})")

    def loop(self):
        """The loop over steps, with the snapshots after each."""
        src = self.src
        src("jo = 0", "while jo < outs.shape[0] and outs[jo] <= step0:", "    jo += 1")
        with src.block("for s in range(n_steps):"):
            src("step = step0 + s + 1")
            self.t.interval(src, self)
            self.snapshot()

    def lanes(self):
        """``lanes(block, setup, call, outputs)``: a block of at most
        LANE_WIDTH orbits (a :class:`LaneBlock`), each step one loop over
        the lanes that does the whole step of each orbit with the arithmetic
        of ``orbit`` — bitwise its results, with the same renormalisation
        schedule."""
        src, body = self.src, self.body
        self.t = Lanes(self)
        rows = self.t.rows
        src("", "", "@njit(cache=True, error_model='numpy', nogil=True)",
            "def lanes(block, setup, call, outputs):")
        with src.block():
            self.unpack("block", LaneBlock._fields,
                        ("X", "W", "am", "ae", "aux", "st", "fs", "nxt", "itv"))
            self.common_unpack()
            body.prologue(src)
            src("nb = X.shape[1]",
                "if nb > LANE_WIDTH:",
                "    raise ValueError('a block of lanes is at most LANE_WIDTH orbits wide')",
                f"F = np.zeros(({self.n_floats}, LANE_WIDTH))",
                f"I = np.zeros(({self.n_ints}, LANE_WIDTH), dtype=np.int64)",
                "renorm = mode != NONE", "s = 0", "step = step0")
            self.buffers()
            # In: the caller's block into F and I (and the first kick's values).
            with src.block("for b in range(nb):"):
                for local, where in self.lane_arrays() + self.live_columns(
                        lambda j, c: f"aux[b, {j}, {c}]"):
                    src(f"{rows[local]} = {where}")
                if body.carried():
                    for i in range(self.n):
                        src(f"{body.q[i]} = {rows[body.q[i]]}")
                    src("code = I[0, b]", "fstep = I[1, b]")
                    body.start(src, self.t)
                    for name in body.carried():
                        src(f"{rows[name]} = {name}")
                    src("I[0, b] = code", "I[1, b] = fstep")
            self.loop()
            # Out: F and I back into the caller's block.
            with src.block("for b in range(nb):"):
                for local, where in self.lane_arrays():
                    if local != "interval":
                        src(f"{where} = {rows[local]}")
                for j in range(self.k):
                    self.columns_out(j, lambda j, c: f"aux[b, {j}, {c}]")

    def lane_arrays(self):
        """(quantity, where a block holds it for lane ``b``)."""
        n, k, body = self.n, self.k, self.body
        out = [(body.coordinate(i), f"X[{i}, b]") for i in range(2 * n)]
        out += [(body.component(i, j), f"W[{i}, {j}, b]") for i in range(2 * n)
                for j in range(k)]
        for j in range(k):
            out += [(f"am{j}", f"am[{j}, b]"), (f"ae{j}", f"ae[{j}, b]")]
        return out + [("code", "st[b]"), ("fstep", "fs[b]"), ("next_renorm", "nxt[b]")]

    def batch(self, kernel):
        """``batch_serial`` and ``batch_parallel`` over orbits (``orbit``),
        or ``blocks_serial`` and ``blocks_parallel`` over blocks of lanes
        (``lanes``): the serial kernel calls the kernel once per item and
        is cached on disk (``nogil``); the parallel one is that kernel on
        Python threads over slices of the items (:mod:`varint.threads`;
        blocks one at a time, :func:`blocks_in_threads`): the serial bits,
        one compile."""
        src = self.src
        one = kernel == "orbit"
        prefix, items = ("batch", "states") if one else ("blocks", "blocks")
        orbit_type = CompensatedOrbit if self.body.compensated else StepperOrbit
        fields = orbit_type._fields if one else LaneBlock._fields
        record = orbit_type.__name__ if one else "LaneBlock"
        # Snapshots are (S, M, …) over orbits, (blocks, S, …) over blocks.
        part = "[:, m]" if one else "[m]"
        args = f"{items}, setup, call, outputs" + (", status, done" if one else "")
        src("", "", "@njit(cache=True, error_model='numpy', nogil=True)",
            f"def {prefix}_serial({args}):")
        with src.block():
            size = "status.shape[0]" if one else f"{items}.x.shape[0]"
            with src.block(f"for m in range({size}):"):
                if one:
                    src("if status[m] != 0:", "    done[m] = 0", "    continue")
                item = f"{record}(" + ", ".join(f"{items}.{f}[m]" for f in fields) + ")"
                outs = ("Outputs(outputs.steps, " + ", ".join(
                    f"outputs.{f}{part}" for f in ("x", "W", "acc_m", "acc_e", "aux")) + ")")
                if one:
                    src(f"st, steps = orbit({item}, setup, call, {outs})",
                        "status[m] = st", "done[m] = steps")
                else:
                    src(f"lanes({item}, setup, call, {outs})")
        src("", "", f"def {prefix}_parallel({args}):")
        with src.block():
            if one:
                src("orbits_in_threads(batch_serial, (states, setup, call, outputs), status, "
                    "done)")
            else:
                src("blocks_in_threads(blocks_serial, blocks, setup, call, outputs)")

"""The LH map's ``outputs`` over SIMD lanes: ``lanes0`` (no vector) and
``lanes1`` (one vector per orbit), emitted into the LH module of
:mod:`varint.codegen.lh` beside the one-orbit ``outputs``, with its
signature and, for every orbit, its bits.

Layout. A pool of at most :data:`LANE_WIDTH` lanes, fed from the orbits in
order: each lane holds one orbit's state, one row per quantity of an array
``F`` allocated in the kernel, so the rows are a constant distance apart
and LLVM proves the loop over the lanes free of aliasing (as the TM lanes,
:class:`varint.codegen.interval.Lanes`). Every iteration every lane takes
one LH step: the step of :func:`varint.codegen.lh.lh_source` with the same
statements in the same order (no fused multiply–adds, no reassociation: the
same bits in a vector lane as in the one-orbit kernel), its failures marked
in a row (``bad``) by selects instead of returns. A group of statements that
calls a function LLVM cannot vectorise (the rotating frame's sine and
cosine) runs in a loop of its own over the lanes, its results passed on in
rows, so that the rest of the step vectorises. So does a potential's
logarithm (``lane_log``, :mod:`varint.kernels.lh_log`), which vectorises in
that loop of its own (lh22: the cored race map's kernel 1.06× over the C
library's ``log`` there, ``studies/lh_log_lanes.py``), and slowed the step
down inlined into the kicks' loops (:data:`_OWN_LOOP_CALLS`).

Events. Then one scalar pass over the lanes: a lane whose step ended before
its next output time and did not fail counts the step and goes on. The
rare others (about one step in a few hundred: the step that passes the
output time, a failure, the step budget) are finished one by one by the
one-orbit kernel's own functions in the one-orbit ``advance``'s order: a
failed step is replayed from the saved state by ``step`` (its status and
force count are the one-orbit kernel's), the passing step is undone and
replaced by the physical-time tail, the vectors are projected, then the
output's bookkeeping (FLI, renormalisation, the worst energy) and the next
output interval's start (δp_t); an orbit that is done gives its lane to the
next one.

Pool. Every pass runs over the pool's first ``nb`` lanes, live or not; once
no orbit is left to start, an orbit that ends frees its lane for good, and
the pool shrinks to its live lanes (the last lane's orbit, with all its
rows, moves into the idle one). A lane's arithmetic does not depend on its
column, so an orbit's bits do not change when it moves. Without it, the
idle lanes of the map's last orbits ran every step with the live ones: on
the cored map of ``studies/map_steps.py`` (120 orbits of about 60 000 LH
steps each) the last 8 orbits ran in a pool of 16, 6 % of the lanes' passes
for nothing (``studies/lh_pool.py``).
"""

from __future__ import annotations

import re

from ..kernels.time_transform import BUDGET
from .source import Source

__all__ = ["LANE_WIDTH", "emit_lanes"]

#: Lanes in the pool of one ``lanes`` call at most.
LANE_WIDTH = 16

#: A call that LLVM vectorises (an exactly rounded instruction); any other
#: call of ``math`` in a group sends the group to a loop of its own.
_VECTOR_CALLS = ("math.sqrt",)
#: The model's logarithm (:mod:`varint.kernels.lh_log`): it vectorises,
#: and its group still runs in a loop of its own. Inlined into the kicks'
#: loop, the whole step in one loop, the cored race map's lanes kernel
#: took 814.9 ms CPU against 520.0 ms in loops of their own (and 549.7 ms
#: with the C library's ``log``), interleaved, load 0.8 → 1.9 (lh22;
#: ``studies/lh_log_lanes.py``, ``studies/results/lh22/lh_log_lanes.json``).
_OWN_LOOP_CALLS = ("lane_log",)


def _calls(lines):
    """Whether ``lines`` call a ``math`` function other than
    :data:`_VECTOR_CALLS`, or one of :data:`_OWN_LOOP_CALLS`."""
    return any(name not in _VECTOR_CALLS for line in lines
               for name in re.findall(r"\b(math\.\w+|{})\(".format("|".join(_OWN_LOOP_CALLS)),
                                      line))


def _printed(em, group):
    tmp = Source()
    em.group(tmp, group)
    return tmp.lines


class _NoLanes(Exception):
    """The step cannot be written over lanes (a kinetic part with calls:
    its flow's libm calls would sit in the lanes' loop)."""


class _Step:
    """The loops of one LH step of every lane (``k`` vectors, 0 or 1), for
    the emitter ``em`` (:class:`varint.codegen.lh._Emitter`) and the stage
    ``kinds``; ``rows`` names every quantity's row of ``F``."""

    def __init__(self, em, kinds, k):
        self.em, self.kinds, self.k = em, kinds, k
        n = em.n
        names = [f"x_{i}" for i in range(2 * n)] + ["t", "wc", "Cl", "hl", "bad"]
        names += [f"x0_{i}" for i in range(2 * n)] + ["t0"]
        if k:
            names += [f"V_{i}" for i in range(2 * n)] + ["dtv", "dpt"]
            names += [f"V0_{i}" for i in range(2 * n)] + ["dt0"]
        self.potential_calls = _calls(_printed(em, em.potential_group))
        self.hessian_calls = k and _calls(_printed(em, em.hessian_group))
        if _calls(_printed(em, em.kinetic_group)):
            raise _NoLanes("a kinetic part with calls has no lanes")
        if self.potential_calls:
            names += [f"gV_{i}" for i in range(n)] + ["v"]
        if self.hessian_calls:
            names += [f"HV_{i}_{j}" for i in range(n) for j in range(n)]
        self.flow_calls = em.flow.kind == "planar"
        if self.flow_calls:
            names += ["tau", "dtau", *self._coefficient_names()]
        self.rows = {name: r for r, name in enumerate(names)}
        self.carried = [f"x_{i}" for i in range(2 * n)] + ["t", "bad"]
        if k:
            self.carried += [f"V_{i}" for i in range(2 * n)] + ["dtv"]
        self.constant = ["wc", "Cl", "hl"] + (["dpt"] if k else [])
        self.segments = []
        self.cur = None

    def _coefficient_names(self):
        par, n = self.em.flow.values, self.em.n
        u, v = int(par[0]), int(par[1])
        out = ["oc", "os1", "os2", "cr", "sr", "msr"]
        for i in range(n):
            if i not in (u, v):
                out += [f"oc_{i}", f"os1_{i}", f"os2_{i}"]
        return out

    def f(self, name):
        return f"F[{self.rows[name]}, b]"

    # -- segments ----------------------------------------------------------------------
    def open(self, save=False):
        """A loop over the lanes that loads a lane's state into locals
        (and, first in a step, saves it: the state an event restores)."""
        self.cur = Source()
        for name in self.carried + self.constant:
            self.cur(f"{name} = {self.f(name)}")
        if save:
            saved = [f"x_{i}" for i in range(2 * self.em.n)] + ["t"]
            if self.k:
                saved += [f"V_{i}" for i in range(2 * self.em.n)] + ["dtv"]
            for name in saved:
                to = {"t": "t0", "dtv": "dt0"}.get(name, name.replace("_", "0_", 1))
                self.cur(f"{self.f(to)} = {name}")

    def close(self):
        for name in self.carried:
            self.cur(f"{self.f(name)} = {name}")
        self.segments.append(self.cur.lines)
        self.cur = None

    def own_loop(self, lines):
        self.segments.append(lines)

    # -- the step ----------------------------------------------------------------------
    def build(self):
        self.open(save=True)
        for st, kind in enumerate(self.kinds):
            if kind == 0:
                self.drift(st)
            else:
                self.kick(st)
        d = 2 * self.em.n
        self.cur("if " + " | ".join(f"(x_{i} - x_{i} != 0.0)" for i in range(d)) + ":",
                 "    bad = 1.0")
        self.close()
        return self.segments

    def drift(self, st):
        em, n, k, src = self.em, self.em.n, self.k, self.cur
        src(f"hs = cf{st} * hl")
        em.group(src, em.kinetic_group)
        src("W = a + wc", "tau = hs / W")
        if k:
            src("s = dpt", *(f"s += gA_{i} * V_{i}" for i in range(2 * n)),
                "dtau = -(tau / W) * s")
        if self.flow_calls:
            # The flow's coefficients (sines, cosines of τ) in a loop of
            # their own; τ and δτ pass through rows.
            src(f"{self.f('tau')} = tau", f"{self.f('dtau')} = dtau" if k else "")
            self.close()
            own = Source()
            own(f"tau = {self.f('tau')}")
            self.coefficients(own)
            self.own_loop(own.lines)
            self.open()
            src = self.cur
            src(f"tau = {self.f('tau')}", f"dtau = {self.f('dtau')}" if k else "",
                *(f"{name} = {self.f(name)}" for name in self._coefficient_names()))
            self.planar(src)
        else:
            for i, m in enumerate(em.flow.values):
                src(f"am = tau * {m!r}", f"x_{i} += am * x_{n + i}")
                if k:
                    src(f"V_{i} += am * V_{n + i}")
        src("t += tau")
        if k:
            em.group(src, em.kinetic_group)
            for i in range(n):
                src(f"V_{i} += gA_{n + i} * dtau", f"V_{n + i} -= gA_{i} * dtau")
            src("dtv += dtau")

    def coefficients(self, src):
        """The planar flow's coefficients over ``tau`` into their rows, by
        the operations of :meth:`varint.codegen.lh._Emitter.flow_lines`."""
        em, par, n = self.em, self.em.flow.values, self.em.n
        u, v = int(par[0]), int(par[1])
        em.oscillator(src, par[2], par[3])
        src(f"cr = math.cos({par[4]!r} * tau)", f"sr = math.sin({par[4]!r} * tau)",
            "msr = -sr")
        src(*(f"{self.f(name)} = {name}" for name in ("oc", "os1", "os2", "cr", "sr", "msr")))
        for i in range(n):
            if i not in (u, v):
                em.oscillator(src, par[5 + 2 * i], par[5 + 2 * i + 1])
                src(*(f"{self.f(f'{name}_{i}')} = {name}" for name in ("oc", "os1", "os2")))

    def planar(self, src):
        """:meth:`varint.codegen.lh._Emitter.flow_lines`' pairs on the
        orbit and the vector, the coefficients read from their rows."""
        par, n = self.em.flow.values, self.em.n
        u, v = int(par[0]), int(par[1])
        self.pair(src, u, n + u, "oc", "os1", "os2")
        self.pair(src, v, n + v, "oc", "os1", "os2")
        self.pair(src, u, v, "cr", "sr", "msr")
        self.pair(src, n + u, n + v, "cr", "sr", "msr")
        for i in range(n):
            if i not in (u, v):
                self.pair(src, i, n + i, f"oc_{i}", f"os1_{i}", f"os2_{i}")

    def pair(self, src, i, j, cm, s1, s2):
        for a in ("x",) + (("V",) if self.k else ()):
            src(f"zi = {a}_{i}", f"zj = {a}_{j}", f"{a}_{i} = {cm} * zi + {s1} * zj",
                f"{a}_{j} = {s2} * zi + {cm} * zj")

    def kick(self, st):
        em, n, k = self.em, self.em.n, self.k
        if self.potential_calls:
            # V, ∇V (and D²V) in a loop of their own: the kick leaves q.
            self.close()
            own = Source()
            own(*(f"x_{i} = {self.f(f'x_{i}')}" for i in range(n)))
            em.group(own, em.potential_group)
            own(*(f"{self.f(f'gV_{i}')} = gV_{i}" for i in range(n)), f"{self.f('v')} = v")
            if self.hessian_calls:
                em.group(own, em.hessian_group)
                own(*(f"{self.f(f'HV_{i}_{j}')} = HV_{i}_{j}" for i in range(n)
                      for j in range(n)))
            self.own_loop(own.lines)
            self.open()
            self.cur(*(f"gV_{i} = {self.f(f'gV_{i}')}" for i in range(n)), f"v = {self.f('v')}")
        else:
            em.group(self.cur, em.potential_group)
        src = self.cur
        src(f"hs = cf{st} * hl")
        src("if (v - v != 0.0) | " + " | ".join(f"(gV_{i} - gV_{i} != 0.0)" for i in range(n))
            + ":", "    bad = 1.0")
        src("u = Cl - v", "if not u > 0.0:", "    bad = 1.0", "w = hs / u", "r = w / u")
        src(*(f"x_{n + i} -= w * gV_{i}" for i in range(n)))
        if not k:
            return
        if self.hessian_calls:
            src(*(f"HV_{i}_{j} = {self.f(f'HV_{i}_{j}')}" for i in range(n) for j in range(n)))
        else:
            em.group(src, em.hessian_group)
        src("s = 0.0", *(f"s += gV_{j} * V_{j}" for j in range(n)))
        for i in range(n):
            src("acc = 0.0", *(f"acc += HV_{i}_{j} * V_{j}" for j in range(n)),
                f"V_{n + i} -= w * acc + r * gV_{i} * s")


def emit_lanes(src, em, kinds):
    """Write ``lanes0`` and ``lanes1`` (module docstring) into ``src``, the
    LH module of the emitter ``em`` (whose ``step``, ``project``,
    ``kinetic`` and ``potential`` they call for the events); nothing where
    the step cannot be written over lanes (a kinetic part with calls)."""
    try:
        steps = [_Step(em, kinds, k) for k in (0, 1)]
    except _NoLanes:
        return
    src("", f"LANE_WIDTH = {LANE_WIDTH}")
    kicks = sum(1 for kind in kinds if kind != 0)
    for k, step in enumerate(steps):
        _kernel(src, step, k, kicks, len(kinds))


def _kernel(src, step, k, kicks, stages):
    """``lanes{k}``: ``outputs`` (same arguments) for orbits with ``k``
    vectors."""
    rows, n = step.rows, step.em.n
    d = 2 * n
    segments = step.build()

    def f(name):
        return f"F[{rows[name]}, b]"

    src("", "", "@njit(cache=True, error_model='numpy')")
    with src.block(f"def lanes{k}(X, W0, pt, C, h, t_end, every, max_steps, kinds, coef, par, "
                   "fli, status, counts, x_end, t_end_at, x_worst, t_worst):"):
        src(f'"""``outputs`` over lanes for orbits with {k} vector(s) (varint.codegen.lh_lanes)."""',
            "M = X.shape[0]", f"d = {d}", f"n = {n}", "nb = min(M, LANE_WIDTH)",
            f"F = np.zeros(({len(rows)}, LANE_WIDTH))",
            # Per lane: its orbit (-1: idle), output count, steps in this
            # interval, next output time, FLI sums and worst energy error.
            "orbit = np.full(LANE_WIDTH, -1)", "jout = np.zeros(LANE_WIDTH, dtype=np.int64)",
            "nsteps = np.zeros(LANE_WIDTH, dtype=np.int64)", "stop = np.zeros(LANE_WIDTH)",
            "acc_l = np.zeros(LANE_WIDTH)", "best_l = np.zeros(LANE_WIDTH)",
            "big_l = np.zeros(LANE_WIDTH)",
            # One orbit's arrays for the one-orbit functions.
            "x = np.empty(d)", f"V = np.empty(({k}, d))", f"dt = np.zeros({k})",
            "clock = np.zeros(2)", f"dpt_a = np.zeros({k})", f"dtau_a = np.empty({k})",
            "x0 = np.empty(d)", f"V0 = np.empty(({k}, d))", f"dt0 = np.zeros({k})",
            "c0 = np.zeros(2)", "gA, gV, HV = np.empty(d), np.empty(n), np.empty((n, n))",
            *(f"cf{st} = coef[{st}]" for st in range(stages)),
            "nxt = 0", "live = 0")
        # Lanes get their first orbits.
        with src.block("for b in range(nb):"):
            src("m = nxt", "nxt += 1", "live += 1")
            _start(src, step, k, f)
        with src.block("while live > 0:"):
            for lines in segments:
                with src.block("for b in range(nb):"):
                    src(*lines)
            with src.block("for b in range(nb):"):
                src("m = orbit[b]", "if m < 0:", "    continue")
                with src.block(f"if {f('bad')} == 0.0 and not {f('t')} > stop[b] "
                               "and nsteps[b] + 1 < max_steps:"):
                    src("nsteps[b] += 1", "counts[m, 0] += 1", f"counts[m, 2] += {kicks}",
                        "continue")
                _event(src, step, k, kicks, f)
            _compact(src, len(rows))


def _compact(src, n_rows):
    """Once no orbit waits for a lane, the pool shrinks to its live lanes:
    the last lane's orbit moves into an idle one, so every pass over the
    lanes runs over orbits still going (the rest of a map, M not a
    multiple of the width, or orbits of unequal length; module docstring,
    "Pool")."""
    with src.block("if live < nb:"):
        src("b = 0")
        with src.block("while b < nb:"):
            with src.block("if orbit[b] >= 0:"):
                src("b += 1", "continue")
            src("nb -= 1")
            with src.block("if b < nb:"):
                with src.block(f"for r in range({n_rows}):"):
                    src("F[r, b] = F[r, nb]")
                src(*(f"{a}[b] = {a}[nb]" for a in _LANE_ARRAYS), "orbit[nb] = -1")


#: The per-lane arrays of a pool besides ``F``'s rows: a lane that moves
#: (:func:`_compact`) takes them along.
_LANE_ARRAYS = ("orbit", "jout", "nsteps", "stop", "acc_l", "best_l", "big_l")


def _store(src, step, k, f):
    """The one-orbit arrays into the lane's rows."""
    d = 2 * step.em.n
    src(*(f"{f(f'x_{i}')} = x[{i}]" for i in range(d)), f"{f('t')} = clock[0]",
        f"{f('wc')} = clock[1]", f"{f('bad')} = 0.0")
    if k:
        src(*(f"{f(f'V_{i}')} = V[0, {i}]" for i in range(d)), f"{f('dtv')} = dt[0]",
            f"{f('dpt')} = dpt_a[0]")


def _start(src, step, k, f):
    """Orbit ``m`` into lane ``b``, as the one-orbit ``outputs`` starts it,
    then its first output interval (:func:`_interval`)."""
    src("orbit[b] = m", "x[:] = X[m]", "V[:, :] = W0[m]", "dt[:] = 0.0",
        "clock[0] = 0.0", "clock[1] = pt[m] + C[m]",
        "acc_l[b] = 0.0", "best_l[b] = 0.0", "big_l[b] = 0.0",
        "x_worst[m, :] = x", "t_worst[m] = 0.0", "jout[b] = 0",
        f"{f('Cl')} = C[m]", f"{f('hl')} = h[m]")
    _interval(src, step, k, f)


def _interval(src, step, k, f):
    """The next output interval of the lane's orbit: its output time, δp_t
    of its vectors (the one-orbit ``advance``'s start), the state into the
    lane's rows."""
    src("jout[b] += 1", "stop[b] = min(jout[b] * every, t_end)", "nsteps[b] = 0")
    if k:
        src("kinetic(x, gA)", "potential(x[:n], gV, HV, False)", "s = 0.0")
        with src.block("for i in range(n):"):
            src("s += (gA[i] + gV[i]) * V[0, i] + gA[n + i] * V[0, n + i]")
        src("dpt_a[0] = -s")
    _store(src, step, k, f)


def _event(src, step, k, kicks, f):
    """The slow path of lane ``b`` (module docstring, "Events")."""
    d = 2 * step.em.n
    src(*(f"x0[{i}] = {f(f'x0_{i}')}" for i in range(d)), f"c0[0] = {f('t0')}",
        f"c0[1] = {f('wc')}")
    if k:
        src(*(f"V0[0, {i}] = {f(f'V0_{i}')}" for i in range(d)), f"dt0[0] = {f('dt0')}",
            f"dpt_a[0] = {f('dpt')}")
    with src.block(f"if {f('bad')} != 0.0:"):
        # Replayed by the one-orbit step from the saved state: its status
        # and force count.
        src("x[:] = x0", "V[:, :] = V0", "dt[:] = dt0", "clock[:] = c0",
            "st = step(x, V, dt, dpt_a, clock, kinds, coef, h[m], par, True, C[m], counts[m], "
            "gA, gV, HV, dtau_a)")
    with src.block("else:"):
        src(*(f"x[{i}] = {f(f'x_{i}')}" for i in range(d)), f"clock[0] = {f('t')}",
            f"clock[1] = {f('wc')}", "st = 0", f"counts[m, 2] += {kicks}")
        if k:
            src(*(f"V[0, {i}] = {f(f'V_{i}')}" for i in range(d)), f"dt[0] = {f('dtv')}")
    with src.block("if st == 0 and not clock[0] > stop[b]:"):
        src("nsteps[b] += 1", "counts[m, 0] += 1")
        with src.block("if nsteps[b] < max_steps:"):
            _store(src, step, k, f)
            src("continue")
        src("project(x, V, dt, par, gA, gV, HV)", f"st = {BUDGET}")
    with src.block("elif st == 0:"):
        # The step passed the output time: undone, then the tail.
        src("last = clock[0] - c0[0]", "x[:] = x0", "V[:, :] = V0", "dt[:] = dt0",
            "clock[:] = c0", "project(x, V, dt, par, gA, gV, HV)", "rest = stop[b] - clock[0]")
        with src.block("if rest > 0.0:"):
            src("mt = max(1, int(math.ceil(rest / last)))", "tau = rest / mt")
            with src.block("for _ in range(mt):"):
                src("st = step(x, V, dt, dpt_a, clock, kinds, coef, tau, par, False, C[m], "
                    "counts[m], gA, gV, HV, dtau_a)")
                with src.block("if st != 0:"):
                    src("break")
                src("counts[m, 1] += 1")
            with src.block("if st == 0:"):
                src("clock[0] = stop[b]")
    with src.block("else:"):
        src("x[:] = x0", "V[:, :] = V0", "dt[:] = dt0", "clock[:] = c0",
            "project(x, V, dt, par, gA, gV, HV)")
    # The output (the one-orbit outputs' bookkeeping).
    if k:
        src("norm = 0.0")
        with src.block("for i in range(d):"):
            src("norm += V[0, i] * V[0, i]")
        src("norm = math.sqrt(norm)", "acc_l[b] += math.log(norm)",
            "best_l[b] = max(best_l[b], acc_l[b])")
        with src.block("for i in range(d):"):
            src("V[0, i] /= norm")
    src("e0 = -pt[m]", "e = abs(kinetic(x, gA) + potential(x[:n], gV, HV, False) - e0)")
    with src.block("if not e <= big_l[b]:"):
        src("big_l[b] = e", "x_worst[m, :] = x", "t_worst[m] = clock[0]")
    with src.block("if clock[0] < t_end and st == 0:"):
        _interval(src, step, k, f)
        src("continue")
    # The orbit is done: its results, then the next orbit into the lane.
    src("fli[m] = best_l[b]" if k else "fli[m] = math.nan", "status[m] = st",
        "x_end[m, :] = x", "t_end_at[m] = clock[0]")
    with src.block("if nxt < M:"):
        src("m = nxt", "nxt += 1")
        _start(src, step, k, f)
    with src.block("else:"):
        src("orbit[b] = -1", "live -= 1")

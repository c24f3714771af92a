"""The TM method's step, emitted: the stages of a splitting scheme written
out as straight-line code for one model (Skokos & Gerlach 2010, Sect. V.C).

Each kick evaluates ∇V, D²V and, for a corrector, ∇C and D²C as
straight-line expressions of q with common subexpressions eliminated
(:mod:`varint.codegen.expressions`; half-integer powers as products and a
square root, :mod:`varint.codegen.printer`), and applies the orbit kick and the
tangent kick (eqs. 47, 53) in one go; drifts and kicks are chains of fused
multiply–adds (:mod:`varint.kernels.fma`), which halves the latency of a
step. Compensated (``compensated=True``), every drift and kick of the orbit
and of the vectors adds its increment by Kahan's compensated summation
(Kahan 1965; Møller 1965): the low-order bits an addition loses are kept
in a compensation local per component and fed into its next increment, so
the round-off of a long run grows like a random walk instead of linearly
(Hairer, McLachlan & Razakarivony, BIT 48, 231 (2008)). With
``compensated="orbit"`` only the orbit's drifts and kicks are, the vectors
add plainly: the orbit is bitwise full compensation's, and where the
vectors' error follows the orbit's (on the Hénon–Heiles orbits,
``studies/compensation_levels.py``) so does their accuracy, for half the
compensated updates (a step is bound by its floating-point operations,
four per compensated update instead of one). With ``compensated="step"``
the orbit's drifts and kicks add plainly, but to its displacement since
the step began (small: its round-off is that of the increments, not of
the state), and the displacement is added to the state once per step by
Kahan's summation; the vectors add plainly. A step's latency then grows
by one addition per drift (q = start + displacement, for the next kick's
forces) instead of two per drift and kick (Kahan's), and its round-off is
that of compensated summation at the step's granularity (the error growth
law: ``tests/test_compensated.py``).
The orbit and the
deviation vectors are local variables (registers) for the whole loop. For
H = A + V(q) with A the solvable quadratic of a rotating frame or a uniform
magnetic field (:attr:`~varint.codegen.expressions.Expressions.planar`),
the drift is A's exact flow (:func:`varint.flows.split.planar_flow`): free
motion or an oscillator's rotation in each (q_i, p_i), then the rotation by
Ωh of the plane's (q_u, q_v) and (p_u, p_v); linear, so the same map moves
every deviation vector, and its coefficients depend only on the stage's
length, worked out once per call. Each is written as an increment
(cos θ − 1 = −2 sin²(θ/2)), so that compensation applies to it too.
Compact (``compact=True``), the stages are one loop over the stage arrays,
each kind of stage written once, with the same operations in the same
order (:meth:`TMBody.compact_stages`): the same bits from a few times less
source, for one orbit. The loop around the step and the end of every step are the emitted skeleton's
(:mod:`varint.codegen.interval`), the same for one orbit and for SIMD
lanes; this body writes into either through its *target*, which says how a
failure is recorded and whether work is counted.
"""

from __future__ import annotations

import numpy as np

from ..protocol import Status
from ..schemes import DRIFT

__all__ = ["TMBody", "step_counts", "LEVELS", "level", "compact_shape"]

_NONFINITE = int(Status.ORBIT_NONFINITE)
_GRAD, _HESS, _THIRD = (int(Status.GRADIENT_NONFINITE), int(Status.HESSIAN_NONFINITE),
                        int(Status.THIRD_NONFINITE))


#: The levels of compensated summation (module docstring): none, every drift
#: and kick, the orbit's drifts and kicks, the orbit's displacement per step.
LEVELS = (False, True, "orbit", "step")


def level(compensated):
    """``compensated`` as one of :data:`LEVELS` (a named level as it is,
    anything else as a bool)."""
    return compensated if isinstance(compensated, str) and compensated in LEVELS \
        else bool(compensated)


class TMBody:
    """The step body of the TM method for expressions ``E``
    (:class:`~varint.codegen.expressions.Expressions`), stage kinds
    ``kinds``, which kicks carry a corrector, and ``k`` vectors.

    The orbit is ``q{i}``, ``p{i}``; component i of vector j is ``a{i}_{j}``
    (δq) or ``b{i}_{j}`` (δp); compensated, each of them has its
    compensation ``c`` + its name (:meth:`compensation`), which only the
    components :meth:`compensates` change (the others' stay zero; with
    ``"step"``, the orbit's, once per step: :meth:`step`). The stage lengths
    are the locals ``h{s}`` and ``hc{s}`` (:meth:`prologue`). After the
    first step, the first kick of a BAB-type step reuses the values of the
    last kick (same q): one orbit evaluates them once in its first step,
    SIMD lanes once when a block is loaded and carry them between steps
    (:meth:`carried`).
    """

    def __init__(self, E, kinds, corrected, k, compensated=False, compact=False):
        self.E, self.kinds, self.corrected, self.k = E, tuple(kinds), tuple(corrected), k
        #: The stages as a loop over the stage lengths (:meth:`compact_stages`)
        #: instead of written out one by one; ``kinds`` and ``corrected`` are
        #: then a scheme's :func:`compact_shape`.
        self.compact = bool(compact)
        #: False, True (every drift and kick), "orbit" (the orbit's only) or
        #: "step" (the orbit's displacement over each step).
        self.compensated = level(compensated)
        n = self.n = E.n
        self.q = [f"q{i}" for i in range(n)]
        self.p = [f"p{i}" for i in range(n)]
        # δq_i and δp_i of vector j.
        self.a = [[f"a{i}_{j}" for j in range(k)] for i in range(n)]
        self.b = [[f"b{i}_{j}" for j in range(k)] for i in range(n)]
        # SymPy's printers are imported only when a stepper's source is
        # emitted: a process that loads cached steppers never needs them.
        from .printer import StepperPrinter

        self.printer = StepperPrinter()
        self.reuse_first = self.kinds[0] != DRIFT and self.kinds[-1] != DRIFT
        #: The momenta a kick of the step being written has moved and no
        #: stage has read since (:meth:`unsettled`).
        self._unsettled = []

    # -- names --------------------------------------------------------------------------
    def coordinate(self, i):
        """The local of component ``i`` (0 … 2N−1) of the state."""
        return self.q[i] if i < self.n else self.p[i - self.n]

    def component(self, i, j):
        """The local of component ``i`` (0 … 2N−1) of vector ``j``."""
        return self.a[i][j] if i < self.n else self.b[i - self.n][j]

    def compensation(self, name):
        """The local that holds the compensation of state local ``name``:
        what the last addition to it added too much (Kahan's ``c``; the
        sum is ``name − c{name}``)."""
        return f"c{name}"

    def compensates(self, name):
        """Whether updates of state local ``name`` add by compensated
        summation: all of them with ``compensated=True``, the orbit's
        (q and p) with ``"orbit"``, none with ``"step"`` (the orbit's
        displacement over a step is added compensated: :meth:`step`)."""
        if self.compensated == "orbit":
            return name in self.q or name in self.p
        return self.compensated is True

    def compensated_names(self):
        """The state and vector locals whose compensation the level changes
        (:meth:`compensates`, or the orbit's with ``"step"``): the others'
        stay zero, and the stepper neither loads nor keeps them."""
        names = self.q + self.p + [v for rows in (self.a, self.b) for row in rows for v in row]
        return {v for v in names if self.compensates(v) or self.displaces(v)}

    def displaces(self, name):
        """Whether updates of state local ``name`` add to its displacement
        since the step began (``compensated="step"``: the orbit's)."""
        return self.compensated == "step" and (name in self.q or name in self.p)

    def start_of_step(self, name):
        """The local that holds state local ``name`` as the step began
        (``compensated="step"``)."""
        return f"{name}_at"

    def displacement(self, name):
        """The local that holds the displacement of state local ``name``
        since the step began, less its compensation (``compensated="step"``:
        the state is ``start_of_step + displacement``)."""
        return f"d{name}"

    def needs(self, corrected):
        """What a kick stage evaluates: ∇V; D²V with vectors; ∇C (and D²C
        with vectors) with a corrector."""
        k = self.k
        return {"g"} | ({"H"} if k else set()) | ({"gc"} if corrected else set()) \
            | ({"HC"} if corrected and k else set())

    def carried(self):
        """The values SIMD lanes carry from one step to the next: those of
        the last kick, which the first kick of a BAB-type step reuses."""
        if not self.reuse_first:
            return []
        E, n = self.E, self.n
        what = self.needs(self.corrected[0])
        names = [f"g{i}" for i in range(n)]
        if "gc" in what:
            names += [f"gc{i}" for i in range(n)]
        if "H" in what:
            names += [f"H{i}_{j}" for i, j in E.H]
        if "HC" in what:
            names += [f"HC{i}_{j}" for i, j in E.HC]
        return names

    def counters(self):
        """The locals one orbit counts its work in, in the order of
        :data:`varint.protocol.COUNTERS`."""
        return ("c_grad", "c_hess", "c_third", "c_tan")

    # -- what is written before the loop ---------------------------------------------
    def prologue(self, src):
        """The stage lengths as locals, from ``h`` and ``hc``; with a
        rotating frame, each drift's coefficients (:meth:`planar_drift`).
        Compact, the stage count and the drifts' coefficients as arrays
        over the stages, worked out by the same expressions."""
        self.extra_scratch(src)
        if self.compact:
            src("nst = h.shape[0]")
            if self.E.planar is not None:
                names = self.planar_names("_")
                src(*(f"A{name} = np.zeros(nst)" for name in names))
                with src.block(f"for stg in range({int(self.kinds[0] != DRIFT)}, nst, 2):"):
                    src("h_ = h[stg]")
                    self.planar_coefficients(src, "_")
                    src(*(f"A{name}[stg] = {name}" for name in names))
            return
        for st in range(len(self.kinds)):
            src(f"h{st} = h[{st}]")
            if self.corrected[st]:
                src(f"hc{st} = hc[{st}]")
            if self.E.planar is not None and self.kinds[st] == DRIFT:
                self.planar_coefficients(src, st)

    def extra_scratch(self, src):
        """With an :class:`~varint.codegen.expressions.ExtraForce`, the
        arrays its kernel is called with (positions, gradient, Hessian) and
        its constants, once per call of the stepper (:meth:`extra_call`)."""
        extra = self.E.extra
        if extra is None:
            return
        n = self.n
        src(f"xq = np.empty({n})", f"xg = np.empty({n})", f"xD = np.empty(({n}, {n}))")
        for i, c in enumerate(extra.constants):
            value = (f"np.array([{', '.join(repr(float(v)) for v in c)}])"
                     if isinstance(c, tuple) else repr(float(c)))
            src(f"xc{i} = {value}")

    def extra_call(self, src, hessian):
        """Add the extra term's gradient (and, if ``hessian``, its Hessian)
        to the closed part's ``g{i}`` (``H{i}_{j}``) just evaluated: through
        the kernel's arrays, which it adds to in its own order (the upper
        triangle of its Hessian is read back)."""
        n = self.n
        src(*(f"xq[{i}] = {self.q[i]}" for i in range(n)),
            *(f"xg[{i}] = g{i}" for i in range(n)))
        if hessian:
            src(*(f"xD[{i}, {j}] = H{min(i, j)}_{max(i, j)}" for i in range(n)
                  for j in range(n)))
        args = ", ".join(f"xc{i}" for i in range(len(self.E.extra.constants)))
        src(f"extra_force(xq, xg, xD, {hessian}, {args})")
        src(*(f"g{i} = xg[{i}]" for i in range(n)))
        if hessian:
            src(*(f"H{i}_{j} = xD[{i}, {j}]" for i, j in self.E.H))

    def _groups(self):
        """The rotating frame's coordinates by their oscillator (a, b): a
        list of (name, a, b, coordinates); the plane's two share one."""
        u, v, a, b, _, pairs = self.E.planar
        groups = [("p", a, b, (u, v))]
        groups += [(str(i), ai, bi, (i,)) for i, (ai, bi) in enumerate(pairs) if i not in (u, v)]
        return groups

    def planar_names(self, st):
        """The locals :meth:`planar_coefficients` writes for drift ``st``."""
        names = []
        for g, a, b, _ in self._groups():
            if b != 0.0:
                names += [f"oc{st}_{g}", f"os1{st}_{g}", f"os2{st}_{g}"]
            elif a != 1.0:
                names.append(f"da{st}_{g}")
        return names + [f"rc{st}", f"rs{st}"]

    def planar_coefficients(self, src, st):
        """The locals of drift ``st`` of A: per oscillator (a, b) the free
        motion's ``da`` = a h (b = 0), or the flow of ½a p² + ½b q²,
        q ← q + oc q + os1 p, p ← p + os2 q + oc p (oc = cos wh − 1 or
        cosh wh − 1, w = √|ab|; :func:`varint.flows.split.oscillator`), and
        the rotation by θ = Ωh: ``rc`` = cos θ − 1, ``rs`` = sin θ."""
        omega = self.E.planar[4]
        for g, a, b, _ in self._groups():
            if b == 0.0:
                if a != 1.0:
                    src(f"da{st}_{g} = h{st} * {a!r}")
                continue
            w = float(np.sqrt(abs(a * b)))
            sin = "math.sin" if a * b > 0 else "math.sinh"
            sign = "-2.0" if a * b > 0 else "2.0"
            src(f"zs = {sin}({0.5 * w!r} * h{st})", f"oc{st}_{g} = {sign} * (zs * zs)",
                f"zs = {sin}({w!r} * h{st})", f"os1{st}_{g} = {a / w!r} * zs",
                f"os2{st}_{g} = {-b / w!r} * zs")
        src(f"zs = math.sin({0.5 * omega!r} * h{st})", f"rc{st} = -2.0 * (zs * zs)",
            f"rs{st} = math.sin({omega!r} * h{st})")

    def defaults(self, src):
        """Everything a kick computes, defined before the loop: after the
        first step the first kick of a step reuses the last kick's values."""
        E = self.E
        for i in range(self.n):
            src(f"g{i} = 0.0", f"gc{i} = 0.0")
        for i, j in E.H:
            src(f"H{i}_{j} = 0.0")
        for i, j in E.HC:
            src(f"HC{i}_{j} = 0.0")

    def start(self, src, target):
        """The first kick's values at the loaded state (SIMD lanes)."""
        if self.reuse_first:
            self.derivatives(src, target, 0, self.needs(self.corrected[0]))

    # -- the step ------------------------------------------------------------------------
    def step(self, src, target):
        """One step: the scheme's stages, drifts and kicks.

        With ``compensated="step"`` the orbit's stages add to its
        displacement since the step began, which starts at minus the
        compensation (Kahan's y = x − c, formed once per step), and the
        step ends by adding it to the state: ``s = start + displacement``,
        the new compensation ``(s − start) − displacement`` (exact where
        |start| ≥ |displacement|: Dekker's Fast2Sum; :meth:`update`).
        """
        orbit = self.q + self.p if self.compensated == "step" else []
        for x in orbit:
            src(f"{self.start_of_step(x)} = {x}",
                f"{self.displacement(x)} = -{self.compensation(x)}")
        self._unsettled = []
        self.stages(src, target)
        for x in orbit:
            x0, d = self.start_of_step(x), self.displacement(x)
            src(f"ks = {x0} + {d}", f"{self.compensation(x)} = (ks - {x0}) - {d}", f"{x} = ks")
        self._unsettled = []

    def stages(self, src, target):
        """The scheme's stages, drifts and kicks, in order."""
        if self.compact:
            self.compact_stages(src, target)
            return
        for st, kind in enumerate(self.kinds):
            if kind == DRIFT:
                self.drift(src, st)
                continue
            corrected = self.corrected[st]
            what = self.needs(corrected)
            if st == 0 and self.reuse_first:
                if not target.carries:
                    with src.block("if s == 0:"):
                        self.derivatives(src, target, st, what)
            else:
                self.derivatives(src, target, st, what)
            self.kick(src, target, st, corrected)

    def compact_stages(self, src, target):
        """The stages as one loop over them (``stg``), each drift and each
        kind of kick written once: drifts and kicks alternate, so a stage's
        parity says which it is; a corrected kick is the first or last
        stage (:func:`compact_shape`). Its lengths ``h_``, ``hc_`` and a
        rotating frame's coefficients are read from the stage arrays. The
        same floating-point operations in the same order as the stages
        written out (:meth:`stages`), so the same bits: a stepper compiled
        from a few times less source, a loop and a branch per stage."""
        drift_parity = int(self.kinds[0] != DRIFT)
        first_kick = 1 - drift_parity
        ends = any(self.corrected)
        with src.block("for stg in range(nst):"):
            src("h_ = h[stg]")
            with src.block(f"if stg % 2 == {drift_parity}:"):
                if self.E.planar is not None:
                    src(*(f"{name} = A{name}[stg]" for name in self.planar_names("_")))
                self.drift(src, "_")
            kicks = [(True, "stg == 0 or stg == nst - 1")] if ends else []
            kicks.append((False, None))
            for corrected, condition in kicks:
                with src.block("else:" if condition is None else f"elif {condition}:"):
                    if corrected:
                        src("hc_ = hc[stg]")
                    what = self.needs(corrected)
                    label = "c" if corrected else "k"
                    if self.reuse_first and (corrected or not ends):
                        # After the first step the first kick reuses the
                        # last kick's values (same q).
                        with src.block("if stg > 0 or s == 0:"):
                            self.derivatives(src, target, label, what, first_kick)
                    else:
                        self.derivatives(src, target, label, what, first_kick)
                    self.kick(src, target, "_", corrected)
        if not target.carries:
            # A failure left the loop over stages: leave the loop over steps.
            src("if status != 0:", "    break")

    def derivatives(self, src, target, label, what, first_kick=None):
        """Evaluate ∇V and, as ``what`` asks, D²V, ∇C, D²C at the current q,
        with a singular value caught before it is used.

        The orbit's quantities (∇V, ∇C) and the tangent ones (D²V, D²C) are
        simplified separately, so the orbit gets the same bits whether or
        not deviation vectors are carried.
        """
        import sympy as sp  # type: ignore[import-untyped]  # emitting only, as the printer

        E = self.E
        orbit = [("g", [f"g{i}" for i in range(self.n)], list(E.g), _GRAD, "c_grad")]
        if "gc" in what:
            orbit.append(("gc", [f"gc{i}" for i in range(self.n)], list(E.gc), _THIRD, None))
        tangent = []
        if "H" in what:
            tangent.append(("H", [f"H{i}_{j}" for i, j in E.H], list(E.H.values()), _HESS,
                            "c_hess"))
        if "HC" in what:
            tangent.append(("HC", [f"HC{i}_{j}" for i, j in E.HC], list(E.HC.values()), _THIRD,
                            "c_third"))
        # At an enormous |q| the derivatives overflow before the state does:
        # that is the orbit running away, not a singular potential.
        rq = " + ".join(f"{v} * {v}" for v in self.q)
        if E.extra is not None and ("gc" in what or "HC" in what):
            raise ValueError("a corrector needs the third derivatives of the model's extra "
                             "force, which its kernel does not give: use a scheme without "
                             "corrector")
        # With an extra force the checks wait for its kernel, which adds to
        # ∇V and D²V in one call.
        checks = []
        for part, groups in (("o", orbit), ("w", tangent)):
            if not groups:
                continue
            targets = [t for g in groups for t in g[1]]
            exprs = [e for g in groups for e in g[2]]
            temps, reduced = sp.cse(exprs, symbols=sp.numbered_symbols(f"t{label}{part}_"))
            for t, e in temps:
                src(f"{t} = {self.printer.doprint(e)}")
            for t, e in zip(targets, reduced, strict=True):
                src(f"{t} = {self.printer.doprint(e)}")
            checks.append(groups)
            if E.extra is None:
                self.checks(src, target, checks.pop(), rq, first_kick)
        if E.extra is not None:
            self.extra_call(src, "H" in what)
            for groups in checks:
                self.checks(src, target, groups, rq, first_kick)

    def checks(self, src, target, groups, rq, first_kick):
        """Count the evaluations of ``groups`` and catch a non-finite value
        of each (:meth:`derivatives`)."""
        settle = self.unsettled(first_kick)
        for _, names, _, status, counter in groups:
            if counter and target.counts:
                src(f"{counter} += 1")
            if names:
                src(f"fin = {' + '.join(names)}")
                target.fail(src, "fin - fin != 0.0",
                            f"{status} if {rq} < HUGE else {_NONFINITE}",
                            **({"settle": settle} if settle else {}))

    def unsettled(self, first_kick=None):
        """The statements that put the state's locals mid-step where a
        failure leaves the loop: with ``compensated="step"``, each p a kick
        of this step has moved and no stage has read since, as the start
        plus its displacement (the values the plain stepper's locals hold
        there, bit for bit those a stage reading them would have). In the
        compact loop, every p the kicks move (:meth:`update`), where stage
        ``stg`` comes after the step's first kick ``first_kick``."""
        if first_kick is not None:
            moved = [p for p in self.p if self.displaces(p) and self.E.planar is None]
            if not moved:
                return []
            return [f"if stg > {first_kick}:"] + [
                f"    {p} = {self.start_of_step(p)} + {self.displacement(p)}" for p in moved]
        return [f"{p} = {self.start_of_step(p)} + {self.displacement(p)}"
                for p in self._unsettled]

    # Drifts and kicks are chains of fused multiply–adds (varint.kernels.fma).
    def drift(self, src, st):
        if self.E.planar is not None:
            self.planar_drift(src, st)
            return
        for i in range(self.n):
            m = self.E.minv[i]
            h = f"h{st}" if m == 1.0 else f"(h{st} * {m!r})"
            p = self.p[i]
            if self.displaces(p):
                # h p = h p_start + h δp: the first product is off the chain
                # of dependent operations from the last kick to this drift.
                self.update(src, self.q[i], lambda acc, h=h, p=p: (
                    f"fma({h}, {self.displacement(p)}, fma({h}, {self.start_of_step(p)}, "
                    f"{acc}))"))
            else:
                self.update(src, self.q[i], lambda acc, h=h, p=p: f"fma({h}, {p}, {acc})")
            for j in range(self.k):
                self.update(src, self.a[i][j],
                            lambda acc, i=i, j=j, h=h: f"fma({h}, {self.b[i][j]}, {acc})")

    def planar_drift(self, src, st):
        """Drift ``st`` as A's exact flow (module docstring), in the order of
        :func:`varint.flows.split.planar_flow`: each coordinate's oscillator
        (free motion for b = 0), then the rotation of the plane's positions
        and momenta by Ωh; the orbit and then every vector, (δq, δp) moving
        as (q, p)."""
        u, v = self.E.planar[:2]
        pairs = [(self.q, self.p)] + [([a[j] for a in self.a], [b[j] for b in self.b])
                                      for j in range(self.k)]
        for g, a, b, coords in self._groups():
            for qs, ps in pairs:
                for i in coords:
                    if b == 0.0:
                        h = f"h{st}" if a == 1.0 else f"da{st}_{g}"
                        self.update(src, qs[i], lambda acc, h=h, p=ps[i]: f"fma({h}, {p}, {acc})")
                    else:
                        self.turn(src, qs[i], ps[i], f"oc{st}_{g}", f"os1{st}_{g}",
                                  f"os2{st}_{g}")
        for qs, ps in pairs:
            for x in (qs, ps):
                self.turn(src, x[u], x[v], f"rc{st}", f"rs{st}", f"-rs{st}")

    def turn(self, src, x, y, cm, s1, s2):
        """(x, y) ← (x + cm x + s1 y, y + s2 x + cm y): a linear flow of one
        pair as increments, from the old values."""
        src(f"zx = {x}", f"zy = {y}")
        self.update(src, x, lambda acc: f"fma({s1}, zy, fma({cm}, zx, {acc}))")
        self.update(src, y, lambda acc: f"fma({s2}, zx, fma({cm}, zy, {acc}))")

    def update(self, src, name, increment):
        """``name`` += the increment ``increment(acc)`` adds to ``acc``.

        Plain: ``name = increment(name)``, one rounding per fused
        multiply–add. Compensated: the increment less the compensation is
        formed from −c (its fused multiply–adds round once each), then added
        by Kahan's summation, and what that addition lost becomes the new
        compensation: ``(s − name) − y`` is exactly the rounding error of
        ``s = name + y`` whenever ``|name| ≥ |y|`` (Dekker's Fast2Sum, 1971),
        which holds for a component and its small increment except in the
        steps where the component passes near zero (there the compensation
        is approximate and the round-off of that addition is small anyway,
        as the component is). The operations must stay in this order (numba does not reassociate
        floating point without fastmath).
        """
        if self.displaces(name):
            # To the displacement, plainly, and the state read from it where
            # a stage reads it (q for the forces; p in a rotating frame's
            # drift); a kick's p otherwise only where the step fails before
            # it ends (:meth:`unsettled`): it would be kept in a register,
            # or spilled, through every failure check of the step.
            d = self.displacement(name)
            src(f"{d} = {increment(d)}")
            if name in self.q or self.E.planar is not None:
                src(f"{name} = {self.start_of_step(name)} + {d}")
            elif name not in self._unsettled:
                self._unsettled.append(name)
            return
        if not self.compensates(name):
            src(f"{name} = {increment(name)}")
            return
        c = self.compensation(name)
        src(f"ky = {increment(f'-{c}')}", f"ks = {name} + ky", f"{c} = (ks - {name}) - ky",
            f"{name} = ks")

    def kick(self, src, target, st, corrected):
        """p −= h ∇V + hc ∇C and δp −= (h D²V + hc D²C) δq (paper eqs. 47, 53)."""
        E, n, k = self.E, self.n, self.k
        for i in range(n):
            def orbit(acc, i=i):
                if corrected:
                    acc = f"fma(-hc{st}, gc{i}, {acc})"
                return f"fma(-h{st}, g{i}, {acc})"
            self.update(src, self.p[i], orbit)
        if not k:
            return
        if target.counts:
            src("c_tan += 1")
        entries = set(E.H) | (set(E.HC) if corrected else set())
        for key in sorted(entries):
            name = f"{key[0]}_{key[1]}"
            if key in E.H and corrected and key in E.HC:
                src(f"K{name} = fma(hc{st}, HC{name}, h{st} * H{name})")
            elif key in E.H:
                src(f"K{name} = h{st} * H{name}")
            else:
                src(f"K{name} = hc{st} * HC{name}")
        for j in range(k):
            for i in range(n):
                terms = [(f"K{min(i, l)}_{max(i, l)}", self.a[l][j]) for l in range(n)
                         if (min(i, l), max(i, l)) in entries]
                if not terms:
                    continue

                def tangent(acc, terms=terms):
                    for K, a in terms:
                        acc = f"fma(-{K}, {a}, {acc})"
                    return acc
                self.update(src, self.b[i][j], tangent)

    def flow(self, src, target, value=None):
        """The phase-space velocity (M⁻¹p, −∇V) at the end of the step, as
        2N expressions; ∇V is evaluated there when the step ends on a drift.
        ``value`` maps a local to where it is read (SIMD lanes read the
        state from their rows in a loop of their own, and the last kick's
        ∇V from the carried values when the step ends on a kick)."""
        n = self.n
        if value is not None and (self.kinds[-1] == DRIFT or not self.reuse_first):
            for i in range(n):
                src(f"{self.q[i]} = {value(self.q[i])}")
            self.derivatives(src, target, "f", {"g"})
        elif value is not None:
            for i in range(n):
                src(f"g{i} = {value(f'g{i}')}")
        elif self.kinds[-1] == DRIFT:
            self.derivatives(src, target, "f", {"g"})
        read = value or (lambda name: name)
        if self.E.planar is not None:
            return self.planar_flow(read)
        out = []
        for i in range(n):
            m = self.E.minv[i]
            out.append(read(self.p[i]) if m == 1.0 else f"({m!r} * {read(self.p[i])})")
        return out + [f"(-g{i})" for i in range(n)]

    def planar_flow(self, read):
        """Hamilton's equations of A + V: q̇ = ∂A/∂p and ṗ = −∂A/∂q − ∇V,
        with A = ½a|p_⊥|² + ½b|q_⊥|² − Ω(q_u p_v − q_v p_u) + Σ ½a_i p_i² +
        ½b_i q_i² (q̇_u gains Ω q_v, q̇_v −Ω q_u; ṗ_u gains Ω p_v, ṗ_v −Ω p_u)."""
        u, v, _, _, omega, pairs = self.E.planar
        q = [read(name) for name in self.q]
        p = [read(name) for name in self.p]
        dq = [f"({a!r} * {p[i]})" for i, (a, _) in enumerate(pairs)]
        dp = [f"(-g{i})" if b == 0.0 else f"(-{b!r} * {q[i]} - g{i})"
              for i, (_, b) in enumerate(pairs)]
        dq[u] = f"({dq[u]} + {omega!r} * {q[v]})"
        dq[v] = f"({dq[v]} - {omega!r} * {q[u]})"
        dp[u] = f"({dp[u]} + {omega!r} * {p[v]})"
        dp[v] = f"({dp[v]} - {omega!r} * {p[u]})"
        return dq + dp


def step_counts(kinds, corrected, k, flow=False):
    """Derivative evaluations of one step of a generated stepper, as
    ``(per_step, first)``: what every step costs (gradients, Hessians,
    corrector Hessians, tangent kicks) and what the first step of a call
    costs on top (the first kick of a BAB-type step reuses the last kick's
    values, except right after a call starts)."""
    kinds = list(kinds)
    reuse_first = kinds[0] != DRIFT and kinds[-1] != DRIFT
    per, first = np.zeros(4, dtype=np.int64), np.zeros(4, dtype=np.int64)
    for stage, kind in enumerate(kinds):
        if kind == DRIFT:
            continue
        c = np.array([1, 1 if k else 0, 1 if corrected[stage] and k else 0, 1 if k else 0])
        tan = np.array([0, 0, 0, c[3]])
        if stage == 0 and reuse_first:
            per += tan
            first += c - tan
        else:
            per += c
    if flow and kinds[-1] == DRIFT:
        per[0] += 1
    return per, first


def compact_shape(kinds, corrected):
    """The stage structure a compact stepper (:meth:`TMBody.compact_stages`)
    is emitted for, as ``(kinds, corrected)`` of the shortest scheme that
    has it, or None when the stages do not fit its loop. Drifts and kicks
    must alternate; correctors, if any, sit on the first and last stages,
    both kicks (every scheme of :data:`varint.schemes.SCHEMES`:
    :func:`varint.schemes.stage_arrays`). Schemes of one shape, whatever
    their stage count, share one compact stepper."""
    kinds, corrected = [int(v) for v in kinds], [bool(c) for c in corrected]
    n = len(kinds)
    if n < 2 or any(kinds[i] == kinds[i + 1] for i in range(n - 1)):
        return None
    ends = [i for i, c in enumerate(corrected) if c]
    if ends and (ends != [0, n - 1] or DRIFT in (kinds[0], kinds[-1])):
        return None
    # Three stages hold every (first, last) pair of an alternation but
    # (D, K) and (K, D), which two hold.
    short = kinds[:3] if kinds[0] == kinds[-1] else kinds[:2]
    return tuple(short), tuple([bool(ends)] + [False] * (len(short) - 2) + [bool(ends)])

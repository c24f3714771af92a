"""Steps that follow the orbit: the logarithmic-Hamiltonian time
transformation of the TM method (Mikkola & Tanikawa 1999; Preto & Tremaine
1999), for H = A(q, p) + V(q) with A's flow exact.

:class:`LogHamiltonian` builds the compiled LH stepper of a model and
scheme (specified in :mod:`varint.kernels.time_transform`: the step, its
exact tangent map, the landing on physical output times; emitted as
straight-line source by :mod:`varint.codegen.lh`, signed and cached on
disk, so a later process loads it without compiling) and runs orbits with
their deviation vectors to a physical time. Steps are uniform in the fictitious time s,
dt/ds = 1/U(q), U = C − V(q): where the orbit falls deep into the potential
(a near-singular core, a close passage by a primary) the physical steps
shrink in proportion to 1/U.

The constant C is chosen once per orbit from its energy E: C = E + δ with
δ = max(−E, 1) in the model's energy units (δ = ``offset`` when it is
given; a map's pilot prices a few δ and takes the cheapest,
:func:`varint.time_transform_step.agreeing_offset`): C = 0 and U = −V, the classical LH of Mikkola & Tanikawa for a
potential that vanishes far away, for orbits bound below E = −1, and U ≥ 1
otherwise. The ratio of the physical
steps at two points of an orbit is the inverse ratio of U there, so a small δ
adapts strongly. For a kinetic A ≥ 0, V ≤ E on the orbit and U ≥ δ > 0; for a
rotating frame A is not positive and a kick that finds U ≤ 0 stops the orbit
with a message naming C.

Indicators read physical time: every output's vectors are the deviations at
equal physical time (δt projected out, see the kernel module), and the
state lands on each output time exactly.

References
----------
S. Mikkola & K. Tanikawa, MNRAS 310, 745 (1999).
H. Preto & S. Tremaine, AJ 118, 2532 (1999).
"""

from __future__ import annotations

import copy
import numbers
from dataclasses import dataclass

import numpy as np
import sympy as sp  # type: ignore[import-untyped]

from . import codecache
from .codegen.lh import Flow, lh_name, lh_source
from .flows.split import planar_params
from .kernels.time_transform import BUDGET, U_NOT_POSITIVE
from .lh_offset import offset_constant
from .protocol import Status
from .schemes import DRIFT, get_scheme, stage_arrays

__all__ = ["LogHamiltonian", "LHResult", "LHOutputs", "Starts", "TIME_TRANSFORMS",
           "offset_constant", "lanes_work", "takes_lanes", "MIN_LANES", "LANES_WORK"]

#: The values of ``time_transform``.
TIME_TRANSFORMS = ("log",)

#: Orbits from which :meth:`LogHamiltonian.outputs` runs them over SIMD
#: lanes (:mod:`varint.codegen.lh_lanes`), not one at a time.
MIN_LANES = 4

#: Work from which :meth:`LogHamiltonian.outputs` runs the orbits over
#: lanes: the LH steps :func:`lanes_work` estimates they take (Σ t_end·U₀/h).
#: The lanes kernel's first compile costs about as much again as the
#: one-orbit kernel's (``studies/results/lhlanes17/lh_lanes_compile.json``:
#: the first calls of a cold process 124.6 s one orbit at a time, 172.5 s
#: with lanes, loaded). A pilot's short runs (16 orbits to t = 100, about
#: 1e5 steps) would pay it and save a few milliseconds; a map's run of
#: 1e6 steps or more saves at least half a second at every call (0.98 →
#: 0.31 µs a step, ``lh_lanes.json``) and later processes load it cached.
#: Both kernels give the same bits for every orbit, so the choice never
#: changes a result; :func:`varint.step_cost.log_gradient_cost` prices the
#: LH by the kernel this decision takes (:meth:`LogHamiltonian.runs_in_lanes`).
LANES_WORK = 1e6



def lanes_work(U0, t_end, h):
    """The LH steps orbits take to the physical time ``t_end`` at the
    fictitious step ``h`` (a number or one per orbit), estimated from
    ``U0`` (M,), U = C − V at each orbit's start: Σ t_end·U₀/h. A step
    lasts h/U of physical time, so an orbit takes t_end·Ū/h steps, Ū the
    mean of U along it in physical time, which is not known before the run:
    U₀ stands for it (Σ t_end/h, U ≈ 1, was the estimate before; on the
    cored map of ``studies/map_steps.py``, whose orbits start at the bottom
    of the core, U₀ is about 4 times Ū: an overestimate there). An orbit
    with U₀ ≤ 0 (it stops at once) or not finite counts nothing."""
    U0 = np.asarray(U0, dtype=float)
    with np.errstate(invalid="ignore"):
        steps = np.where(U0 > 0, U0, 0.0) * float(t_end) / np.asarray(h, dtype=float)
    return float(np.sum(steps))


def takes_lanes(orbits, work):
    """Whether a run of ``orbits`` orbits whose :func:`lanes_work` is
    ``work`` runs over SIMD lanes (:data:`MIN_LANES`, :data:`LANES_WORK`)."""
    return bool(orbits >= MIN_LANES and work >= LANES_WORK)


#: Steps one output interval may take before the orbit is stopped.
MAX_STEPS = 10_000_000


@dataclass(frozen=True)
class LHResult:
    """Orbits moved to a physical time by :meth:`LogHamiltonian.advance`.

    Attributes
    ----------
    x : ndarray (M, 2N)
        The orbits at ``t``.
    W : ndarray (M, 2N, k)
        Their deviation vectors at equal physical time.
    t : ndarray (M,)
        The physical time reached (``t_end`` unless ``status`` says why not).
    status : ndarray (M,)
        0, a :class:`~varint.protocol.Status`, or −1 (U ≤ 0: C too low),
        −2 (the step budget ran out).
    steps, tail_steps, gradients : ndarray (M,)
        LH steps, physical-time tail steps and force evaluations.
    C, pt : ndarray (M,)
        Each orbit's constant of U = C − V and its momentum conjugate to
        time, p_t = −E at the start (conserved: part of the state, which a
        resumed run must be given back, not recompute from x).
    """

    x: np.ndarray
    W: np.ndarray
    t: np.ndarray
    status: np.ndarray
    steps: np.ndarray
    tail_steps: np.ndarray
    gradients: np.ndarray
    C: np.ndarray
    pt: np.ndarray


@dataclass(frozen=True)
class LHOutputs:
    """Orbits run to a physical time through outputs every ``every`` time
    units by :meth:`LogHamiltonian.outputs` (the FLI of a map, or a pilot).

    Attributes
    ----------
    fli : ndarray (M,)
        sup ln‖w‖ over the outputs (the vector normalised at each); NaN for
        an orbit that stopped, and without vectors.
    status : ndarray (M,)
        As :attr:`LHResult.status`.
    x : ndarray (M, 2N)
        The final states: at ``t_end``, or where the orbit stopped (the
        last completed step).
    t : ndarray (M,)
        The physical time of ``x``.
    x_worst, t_worst : ndarray (M, 2N), (M,)
        The output state whose energy H = A + V is furthest from the
        initial one (the initial state if none moved it), and its time:
        every conserved quantity of the models the LH takes is a function
        of H, so the largest error of each over the outputs is its error
        there.
    counts : ndarray (M, 3)
        LH steps, tail steps and force evaluations per orbit.
    """

    fli: np.ndarray
    status: np.ndarray
    x: np.ndarray
    t: np.ndarray
    x_worst: np.ndarray
    t_worst: np.ndarray
    counts: np.ndarray


@dataclass(frozen=True)
class Starts:
    """H = A + V and V at the starts of orbits, by the generated kernels
    (:meth:`LogHamiltonian.starts`): what every run of the same orbits
    needs before it starts (C = E + δ and p_t = −E for each δ, U₀ = C − V
    for the lanes' work), computed once by a pilot that runs them again
    and again (a Python loop over the orbits, two kernel calls each: on the
    cored map of ``studies/map_steps.py`` the defaults' switch made 47 LH
    runs of the same 16 orbits, and asked U₀ of the map's 120 orbits in
    each of its 5 descents).

    Attributes
    ----------
    energy : ndarray (M,)
        H = A + V, as :meth:`LogHamiltonian.energy` (the same bits).
    potential : ndarray (M,)
        V(q).
    """

    energy: np.ndarray
    potential: np.ndarray

    def rows(self, idx):
        """These values of the orbits ``idx``."""
        return Starts(self.energy[idx], self.potential[idx])

    def u(self, offset, C=None):
        """U₀ = C − V with C = E + δ (:func:`offset_constant` of
        ``offset``), or the given ``C``."""
        return (offset_constant(self.energy, offset) if C is None
                else np.asarray(C, dtype=float)) - self.potential


def _symbolic_parts(model):
    """(A, V, q, p, flow, par) of ``model``: A(q, p) and V(q) as SymPy in
    the symbols q, p, A's exact flow (:class:`~varint.codegen.lh.Flow`)
    and its parameters; a one-line ``ValueError`` for a model of another
    form."""
    structure = getattr(model, "structure", None)
    if structure == "integrable":
        s = model.symbolic()
        pl = model.planar
        par = planar_params(model.n_dof, pl["plane"], pl["a"], pl["b"], pl["omega"],
                            pl["others"])
        return s.A, s.V, tuple(s.q), tuple(s.p), Flow("planar", par), par
    s = model.symbolic() if callable(getattr(model, "symbolic", None)) else None
    if structure is None and hasattr(s, "inverse_mass") and s.time is None:
        q = tuple(s.q)
        p = sp.symbols(f"p_0:{len(q)}")
        A = sum((m * pi**2 / 2 for m, pi in zip(s.inverse_mass, p, strict=True)), sp.Integer(0))
        par = np.array([float(m) for m in s.inverse_mass])
        return A, s.V, q, p, Flow("free", par), par
    raise ValueError(f"time_transform='log' needs an autonomous H = ½pᵀM⁻¹p + V(q) from "
                     f"from_potential or an integrable H = A + V(q) (a rotating frame), "
                     f"got {model!r}")


class LogHamiltonian:
    """The LH-transformed TM method for ``model`` with a two-part
    ``scheme`` (module docstring).

    Parameters
    ----------
    model : Model
        From :func:`~varint.models.from_potential` (autonomous) or an
        integrable :func:`~varint.models.from_hamiltonian` (e.g.
        :class:`~varint.models.CR3BP`).
    scheme : str or SplittingScheme
        A two-part scheme without a corrector: A's flow is its drift, the
        kick of V its kick (every order applies unchanged).
    offset : float, optional
        δ of C = E + δ for every orbit (module docstring); > 0.
    """

    def __init__(self, model, scheme="ABA864", offset=None):
        (A, V, q, p, flow, par), sch = refuse(model, scheme, offset)
        kinds, h, _ = stage_arrays(sch, 1.0)
        self.model, self.scheme, self.offset = model, sch, None if offset is None else float(offset)
        self._kinetic_flow = flow.kind == "free"
        self.kinds = np.where(kinds == DRIFT, 0, 1).astype(np.int64)
        self.coef = h.astype(float)
        self.par = np.asarray(par, dtype=float)
        # The stepper is emitted for this model and scheme
        # (varint.codegen.lh), signed and cached: its name hashes what its
        # source is made from, so a later process loads it without emitting.
        key = "|".join([sp.srepr(A), sp.srepr(V), sp.srepr(q), sp.srepr(p), repr(flow),
                        repr(tuple(self.kinds.tolist()))])
        self._emit = lambda: lh_source(A, V, q, p, flow, self.kinds)
        self._source = None
        mod = codecache.load_module(lh_name(key), "kernels", self.source)
        self._kinetic, self._potential = mod.kinetic, mod.potential
        self.advance_kernel, self.step_kernel, self.project_kernel, self.outputs_kernel = \
            mod.advance, mod.step, mod.project, mod.outputs
        # outputs over SIMD lanes, one kernel per number of vectors (absent
        # where the step cannot be written over lanes).
        self.lanes_kernels = (getattr(mod, "lanes0", None), getattr(mod, "lanes1", None))

    def with_offset(self, offset):
        """This stepper with δ = ``offset`` (> 0, or None: the rule of the
        module docstring): the same compiled kernels, another C = E + δ
        (what :func:`varint.time_transform_step.agreeing_offset` prices)."""
        checked_offset(offset)
        other = copy.copy(self)
        other.offset = None if offset is None else float(offset)
        return other

    @property
    def kinetic(self):
        """Whether A is a kinetic energy ½pᵀM⁻¹p ≥ 0, so that U = A + δ ≥ δ
        on every orbit for any δ > 0 (False for a rotating frame, whose A
        takes both signs: there U > 0 only where C is above V)."""
        return self._kinetic_flow

    def source(self):
        """The source of this stepper's module (:func:`~varint.codegen.lh.lh_source`),
        emitted once per instance: what :mod:`varint.step_cost` reads."""
        if self._source is None:
            self._source = self._emit()
        return self._source

    # -- values ------------------------------------------------------------------------
    def starts(self, X):
        """H = A + V and V(q) of states ``X`` (M, 2N) by the generated
        kernels (:class:`Starts`)."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        n = X.shape[1] // 2
        gA, gV, HV = np.empty(2 * n), np.empty(n), np.empty((n, n))
        K, V = np.empty(len(X)), np.empty(len(X))
        for m, x in enumerate(X):
            K[m] = self._kinetic(x, gA)
            V[m] = self._potential(x[:n].copy(), gV, HV, False)
        return Starts(K + V, V)

    def energy(self, X):
        """H = A + V of states ``X`` (M, 2N), by the generated kernels."""
        return self.starts(X).energy

    def constants(self, X, starts=None):
        """C of every orbit of ``X`` (module docstring); ``starts``, if
        given, are :meth:`starts` of ``X``."""
        return offset_constant((self.starts(X) if starts is None else starts).energy,
                               self.offset)

    def start_u(self, X, C=None, starts=None):
        """U = C − V(q) of every orbit of ``X`` (M, 2N) at its start, by
        the generated kernels (``C``: :meth:`constants` where not given;
        ``starts``, if given, are :meth:`starts` of ``X``)."""
        return (self.starts(X) if starts is None else starts).u(self.offset, C)

    def lanes_ready(self, vectors=1):
        """Whether the lanes kernel for ``vectors`` (0 or 1) vectors has
        been compiled (or loaded from numba's cache) in this process: a
        pilot's run over it then costs no compile, and the same bits as one
        orbit at a time."""
        # numba's dispatcher holds its compiled versions in ``overloads``
        # (``signatures`` lists them, hashing every type: ~0.1 ms a call).
        return len(getattr(self.lanes_kernels[vectors], "overloads", ())) > 0

    def runs_in_lanes(self, X, t_end, h, vectors=1, C=None, starts=None):
        """Whether :meth:`outputs` runs the orbits ``X`` with ``vectors``
        (0 or 1) each to ``t_end`` at the fictitious step ``h`` over SIMD
        lanes (:mod:`varint.codegen.lh_lanes`): a lanes kernel for that
        many vectors, :func:`takes_lanes` of :func:`lanes_work`
        (``starts``, if given, are :meth:`starts` of ``X``)."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        return (self.lanes_kernels[vectors] is not None and len(X) >= MIN_LANES
                and takes_lanes(len(X), lanes_work(self.start_u(X, C, starts), t_end, h)))

    # -- runs --------------------------------------------------------------------------
    def advance(self, X, W, t_end, h, t0=0.0, C=None, pt=None, max_steps=MAX_STEPS):
        """Move orbits ``X`` (M, 2N) and vectors ``W`` (M, 2N, k) from
        ``t0`` to the physical time ``t_end`` with LH steps of fictitious
        length ``h`` (:class:`LHResult`); a resumed run passes the ``C``
        and ``pt`` of the result it continues."""
        X, W, t_end, h = _checked(X, W, t_end, h)
        if not t0 < t_end:
            raise ValueError(f"t_end must be after t0 = {t0!r}, got {t_end!r}")
        M = len(X)
        E = self.energy(X) if C is None or pt is None else None
        C = offset_constant(E, self.offset) if C is None else np.broadcast_to(
            np.asarray(C, float), M)
        pt = -E if pt is None else np.broadcast_to(np.asarray(pt, float), M)
        out_x, out_W = X.copy(), W.copy()
        t, status = np.zeros(M), np.zeros(M, dtype=np.int64)
        counts = np.zeros((M, 3), dtype=np.int64)
        for m in range(M):
            x = out_x[m]
            V = np.ascontiguousarray(out_W[m].T)
            dt = np.zeros(V.shape[0])
            clock = np.array([float(t0), pt[m] + C[m]])
            status[m] = self.advance_kernel(x, V, dt, clock, self.kinds, self.coef, h, t_end,
                                            max_steps, self.par, float(C[m]), counts[m])
            out_W[m] = V.T
            t[m] = clock[0]
        return LHResult(out_x, out_W, t, status, counts[:, 0], counts[:, 1], counts[:, 2],
                        np.array(C, dtype=float), np.array(pt, dtype=float))

    def fli(self, X, W0, t_end, h, every=10.0, C=None, max_steps=MAX_STEPS):
        """The FLI sup ln‖w‖ of every orbit over the multiples of ``every``
        (where the vector is normalised) and t_end, the per-orbit counts
        [LH steps, tail steps, gradients] and status (:func:`describe`
        says why an orbit stopped; its FLI is NaN)."""
        X, W0, t_end, h = _checked(X, W0[..., None], t_end, h)
        E = self.energy(X)
        C = offset_constant(E, self.offset) if C is None else np.broadcast_to(
            np.asarray(C, float), len(X))
        run = self._run(X, np.ascontiguousarray(np.swapaxes(W0, 1, 2)), t_end,
                        np.full(len(X), h), float(every), C, max_steps, -E)
        return run.fli, run.counts, run.status

    def outputs(self, X, W0, t_end, h, every=10.0, C=None, max_steps=MAX_STEPS, lanes=None,
                starts=None):
        """Orbits ``X`` (M, 2N) with one vector each (``W0`` (M, 2N), or
        None: no vector) to the physical time ``t_end`` through outputs at
        the multiples of ``every``, with the fictitious step ``h`` (a number,
        or one per orbit (M,)): the FLI as :meth:`fli` computes it (the
        same bits for the same h), the final states and the output state
        furthest from the initial energy (:class:`LHOutputs`). Over SIMD
        lanes where their work repays them (``lanes`` None:
        :func:`takes_lanes`), or wherever there are :data:`MIN_LANES`
        orbits (``lanes`` True: a pilot whose map runs over lanes, which
        compiles them anyway); the same bits either way. ``starts``, if
        given, are :meth:`starts` of ``X`` (a pilot that runs the same
        orbits again passes them: the same values, not recomputed)."""
        X, W, every, starts = self._laid_out(X, W0, every, starts)
        t_end, hs = _checked_run(t_end, h, len(X))
        E = starts.energy
        C = offset_constant(E, self.offset) if C is None else np.broadcast_to(
            np.asarray(C, float), len(X))
        return self._run(X, W, t_end, hs, every, C, max_steps, -E, lanes, starts.potential)

    def _laid_out(self, X, W0, every, starts):
        """:meth:`outputs`' orbits ``X`` (M, 2N), their vectors in the
        kernels' layout (M, k, 2N) (k = 0 where ``W0`` is None), ``every``
        and their :class:`Starts`, after refusing what is not finite or
        not of their shapes."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        M, d = X.shape
        W = np.zeros((M, d, 0)) if W0 is None else np.asarray(W0, dtype=float)[..., None]
        X, W, _, _ = _checked(X, W, 1.0, 1.0)
        W = np.ascontiguousarray(np.swapaxes(W, 1, 2))   # rows: the kernels' layout
        if isinstance(every, bool) or not isinstance(every, numbers.Real) \
                or not float(every) > 0.0 or not np.isfinite(every):
            raise ValueError(f"every must be a finite number > 0, got {every!r}")
        # The energies once for C and p_t (a Python loop over the orbits:
        # a pilot passes them, computed once for all its runs).
        if starts is None:
            starts = self.starts(X)
        elif len(starts.energy) != M:
            raise ValueError(f"starts must hold the {M} orbits of X, got {len(starts.energy)}")
        return X, W, float(every), starts

    def _run(self, X, W, t_end, hs, every, C, max_steps, pt, lanes=None, V=None):
        """The generated ``outputs`` loop over checked orbits ``X``, vectors
        ``W`` (M, k, 2N), steps ``hs`` (M,), constants ``C`` (M,) and
        p_t = −H (M,); an orbit that stopped has a NaN FLI. ``V`` (M,), if
        given, is V(q) at the orbits' starts (for the lanes' work)."""
        M = len(X)
        fli, status = np.zeros(M), np.zeros(M, dtype=np.int64)
        counts = np.zeros((M, 3), dtype=np.int64)
        x_end, t, x_worst, t_worst = np.empty_like(X), np.zeros(M), np.empty_like(X), np.zeros(M)
        kernel = self.outputs_kernel
        over_lanes = self.lanes_kernels[W.shape[1]]
        # Orbits too few for lanes need no estimate of their work.
        if (over_lanes is not None and max_steps >= 1 and M >= MIN_LANES
                and (lanes or takes_lanes(M, lanes_work(
                    self.start_u(X, C) if V is None else C - V, t_end, hs)))):
            kernel = over_lanes   # the same bits for every orbit (varint.codegen.lh_lanes)
        # C as a writable copy: a C given by the caller is broadcast (a
        # read-only view), and numba compiles its kernels again for a
        # read-only array (another signature: 20-50 CPU s cold for the
        # lanes and outputs kernels, stop 55's suite profile).
        kernel(X, W, pt, np.array(C, dtype=float), hs,
               t_end, every, max_steps, self.kinds, self.coef, self.par, fli,
               status, counts, x_end, t, x_worst, t_worst)
        fli[status != 0] = np.nan   # nothing computed is passed off as a value
        return LHOutputs(fli, status, x_end, t, x_worst, t_worst, counts)


def refuse(model, scheme="ABA864", offset=None):
    """The symbolic parts of ``model`` (:func:`_symbolic_parts`) and the
    scheme, after refusing in one line, before anything compiles, a model
    of another form, a scheme with a corrector or processor and an offset
    that is not a finite number > 0."""
    parts = _symbolic_parts(model)
    sch = get_scheme(scheme)
    if getattr(sch, "corrector", None) is not None or not hasattr(sch, "stages"):
        raise ValueError(f"time_transform='log' needs a two-part scheme without a "
                         f"corrector or processor, got {sch.name!r}")
    checked_offset(offset)
    return parts, sch


def checked_offset(offset):
    """``offset`` (δ), after refusing one that is neither None nor a finite
    number > 0."""
    if offset is not None and (isinstance(offset, bool)
                               or not isinstance(offset, numbers.Real)
                               or not float(offset) > 0.0 or not np.isfinite(offset)):
        raise ValueError(f"offset must be a finite number > 0, got {offset!r}")
    return offset


def describe(status):
    """The reason for an LH ``status``."""
    if status == U_NOT_POSITIVE:
        return "U = C − V(q) ≤ 0 on the orbit: C is not above V there (give a larger offset)"
    if status == BUDGET:
        return "the step budget ran out before the output time (a larger h?)"
    return Status(int(status)).name


def _checked_run(t_end, h, M):
    """``t_end`` and the steps ``h`` of ``M`` orbits ((M,): one number
    each), after refusing what is not finite and > 0."""
    if isinstance(t_end, bool) or not isinstance(t_end, numbers.Real) \
            or not float(t_end) > 0.0 or not np.isfinite(t_end):
        raise ValueError(f"t_end must be a finite number > 0, got {t_end!r}")
    hs = np.array(np.broadcast_to(np.asarray(h, dtype=float), (M,)))
    if not (np.all(np.isfinite(hs)) and np.all(hs > 0)):
        raise ValueError(f"h must be finite numbers > 0, got {h!r}")
    return float(t_end), hs


def _checked(X, W, t_end, h):
    X = np.atleast_2d(np.asarray(X, dtype=float))
    W = np.asarray(W, dtype=float)
    if W.ndim == 2:
        W = W[None]
    if W.shape[:2] != X.shape:
        raise ValueError(f"W must have shape (M, 2N, k) = ({X.shape[0]}, {X.shape[1]}, k), "
                         f"got {W.shape}")
    for name, v in (("t_end", t_end), ("h", h)):
        if isinstance(v, bool) or not isinstance(v, numbers.Real) or not float(v) > 0.0 \
                or not np.isfinite(v):
            raise ValueError(f"{name} must be a finite number > 0, got {v!r}")
    if not np.all(np.isfinite(X)):
        raise ValueError("X must be finite")
    return X, W, float(t_end), float(h)

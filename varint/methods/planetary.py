"""The tangent map method on planetary systems (:class:`varint.models.Planetary`):
what ``method="tm"`` runs for them.

The Wisdom–Holman family — WH (SABA1, the default), SABA_n, SBAB_n,
ABA864, ABA1064, any two-part scheme of :data:`varint.SCHEMES` without the
Laskar–Robutel corrector, ``SplittingScheme.repeated(m)`` for m steps per
interval, and the three-part compositions in democratic heliocentric
coordinates — runs through the model's part flows (Kepler drifts and
interaction kicks fused with their tangent maps) in the part stepper
(:class:`varint.methods.parts.PartsPropagator`), which owns the loop and
the end of every interval — or, for several orbits in Jacobi coordinates,
in blocks of SIMD lanes with the same end of every interval
(:mod:`varint.kernels.planetary_batch`), bit for bit the same.

What this adds is processing: with ``corrector=p`` the symplectic corrector
C of Wisdom, Holman & Touma (1996) of order p (:mod:`varint.correctors`)
turns the WH map W into C ∘ W ∘ C⁻¹, whose energy error is O(ετ^{p+1} +
ε²τ²) instead of O(ετ²). The map runs on the mapped state y = C⁻¹(x₀) and
its vectors DC⁻¹·W₀; at the end of every call (every output) the state is
x = C(y) and the vectors DC(y)·W_y, renormalised as the indicator asks
(copies: the stretching accumulated per interval is that of W_y, and C is a
near-identity symplectic map, so every indicator's law is unchanged). With
``renorm="none"`` the vectors are the exact tangent map of the processed
map. y and W_y live in ``state.extra``, so chunking and checkpoints resume
bit for bit.

Orbits whose planets meet (the model's ``close_encounter``) stop with
status ``CLOSE_ENCOUNTER``, those whose Kepler drift cannot be solved with
``KEPLER_FAILED``. A Kepler drift longer than a planet's pericentre
passage time is warned about at the start (:meth:`PlanetaryPropagator.advance`): the map does not
resolve such a pericentre: its error there does not fall with ε.

References
----------
J. Wisdom, M. Holman & J. Touma, Fields Inst. Commun. 10, 217 (1996);
H. Rein & D. Tamayo, Mon. Not. R. Astron. Soc. 452, 376 (2015).
"""

from __future__ import annotations

import warnings
from functools import cache

import numba
import numpy as np
from numba import njit

from ..accuracy import AccuracyWarning
from ..correctors import WHT_ORDERS, corrector_word
from ..kernels.closures import cache_on_disk
from ..kernels.interval import Call, no_accumulator, use_parallel
from ..kernels.planetary_batch import LANES, lane_batch
from ..protocol import STATUS_OK, Renorm, Status
from ..schemes import get_scheme
from ..state import renormalized_copy
from .options import method_options
from .parts import PartsPropagator

__all__ = ["PlanetaryPropagator", "MAPPED_STATE", "MAPPED_VECTORS"]

#: Fewest active orbits a call steps as SIMD lanes (fewer: one at a time).
MIN_LANE_ORBITS = 4

#: Keys of the map's state y = C⁻¹(x) and vectors in ``RunState.extra``.
MAPPED_STATE, MAPPED_VECTORS = "wh_mapped_x", "wh_mapped_W"


@cache
def word_batch(apply, k):
    """``batch(parts, h, X, W, par, n_work, active, out_X, out_W)``:
    ``out_X[m], out_W[m]`` = the word (the flows ``parts[s]`` for times
    ``h[s]`` in order: a corrector, :mod:`varint.correctors`) applied to
    orbit m of ``X`` (M, 2N) and its ``k`` vectors ``W[m]`` (2N, k), for
    the ``active`` orbits; the others, and an orbit whose flow fails, are
    copied. Returns the status of each (0, or the first failure's).

    ``apply`` is the model's part flows (:func:`varint.kernels.nbody_unrolled.flows`,
    held bit for bit to the generic :func:`varint.kernels.nbody.apply_flow`
    by the tests), with ``k`` a constant as the part stepper calls it: the
    Kepler drift the stepper compiled serves the corrector too, where the
    generic flows cost a compile of their own (20 CPU s). Vectors are
    copied element by element (a slice assignment compiles numba's
    shape-error code)."""

    @njit(error_model="numpy")
    def batch(parts, h, X, W, par, n_work, active, out_X, out_W):
        m_all, dim = X.shape[0], X.shape[1]
        status = np.zeros(m_all, dtype=np.int64)
        work = np.empty(n_work)
        x = np.empty(dim)
        V = np.empty((k, dim))
        for m in range(m_all):
            st = 0
            if active[m]:
                for i in range(dim):
                    x[i] = X[m, i]
                    for c in range(k):
                        V[c, i] = W[m, i, c]
                for s in range(parts.shape[0]):
                    st = apply(parts[s], h[s], x, V, k, par, work)
                    if st != 0:
                        break
                status[m] = st
            moved = active[m] and st == 0
            for i in range(dim):
                out_X[m, i] = x[i] if moved else X[m, i]
                for c in range(k):
                    out_W[m, i, c] = V[c, i] if moved else W[m, i, c]
        return status

    return cache_on_disk(batch)


def _name_failures(state, was_active):
    """The planetary flows stop an orbit by a mark in its first coordinate,
    which the part stepper reports as non-finite — or, with an
    ``escape_radius``, +inf as escaped (its escape test comes first): +inf
    for a close encounter, NaN for a Kepler drift that could not be solved,
    the rest of the state finite (:func:`varint.kernels.nbody_unrolled.flows`).
    Name them."""
    failed = was_active & ((state.status == int(Status.ORBIT_NONFINITE))
                           | (state.status == int(Status.ESCAPED)))
    if not failed.any():
        return
    first = state.x[:, 0]
    marked = failed & np.isfinite(state.x[:, 1:]).all(axis=1)
    state.status[marked & (first == np.inf)] = int(Status.CLOSE_ENCOUNTER)
    state.status[marked & np.isnan(first)] = int(Status.KEPLER_FAILED)


def _kick_spacing(scheme):
    """The longest drift between two kicks, in units of τ (across the
    joint of two steps too): Σ|a| of the drifts between them."""
    gaps, gap = [], 0.0
    for kind, c in scheme.stages():
        if kind == 0:
            gap += abs(c)
        else:
            gaps.append(gap)
            gap = 0.0
    gaps[0] += gap              # the last drifts of a step join the next's first
    return max(gaps)


def _substeps(scheme):
    """m if ``scheme`` is the WH map (SABA1) repeated m times, else None."""
    wh = get_scheme("SABA1")
    m = scheme.n_kicks
    candidate = wh if m == 1 else wh.repeated(m)
    if scheme.corrector is None and scheme.stages() == candidate.stages():
        return m
    return None


class PlanetaryPropagator:
    """``method="tm"`` on a :class:`~varint.models.Planetary`: the part
    stepper, and the WHT corrector at the end of every call (module
    docstring).

    Parameters
    ----------
    model : Planetary
    tau : float
    renorm : Renorm
    accumulator : Accumulator, optional
    scheme : str or SplittingScheme or CompositionScheme, optional
        By default the model's (WH in Jacobi coordinates, ABC2 in
        democratic heliocentric ones).
    corrector : int, optional
        The order of the WHT corrector (3, 5, 7, 11 or 17); only with the WH
        map (SABA1, or SABA1 repeated m times: the corrector of its substep
        τ/m), in Jacobi coordinates.
    parallel : bool, optional
        As for :class:`~varint.methods.parts.PartsPropagator`.
    lanes : bool, optional
        Step the orbits of a call in blocks of SIMD lanes
        (:mod:`varint.kernels.planetary_batch`; default True, in Jacobi
        coordinates with a two-part scheme and at least
        :data:`MIN_LANE_ORBITS` active orbits): bit for bit what one orbit at
        a time gives (``lanes=False``), faster (studies/planetary_lanes.py).

    Raises
    ------
    ValueError
        For ``lanes`` not a bool; for a corrector of another order, on
        another scheme or in democratic heliocentric coordinates.
    """

    method = "tm"
    OPTIONS = ("scheme", "parallel", "corrector", "lanes")

    def __init__(self, model, tau, renorm, accumulator=None, **options):
        opts = method_options(self.method, options, self.OPTIONS)
        corrector = opts.pop("corrector", None)
        lanes = opts.pop("lanes", True)
        if not isinstance(lanes, bool):
            raise ValueError(f"lanes must be True or False, got {lanes!r}")
        self.inner = PartsPropagator(model, tau, renorm, accumulator, **opts)
        # Orbits stepped as SIMD lanes (kernels.planetary_batch): the Kepler
        # drift and the kick have lanes in Jacobi coordinates only, and the
        # Wisdom-Holman family's two parts.
        self.lanes = (lanes and model.coordinates == "jacobi"
                      and getattr(self.inner.scheme, "n_parts", 2) == 2
                      and not model.parts.timed)
        self.model = model
        self.tau = self.inner.tau
        self.renorm = Renorm.parse(renorm)
        self.corrector = None if corrector is None else self._check(model, corrector)
        if self.corrector is not None:
            dt = self.tau / _substeps(self.inner.scheme)
            self._to_map = self._word(corrector_word(self.corrector, inverse=True), dt)
            self._to_real = self._word(corrector_word(self.corrector), dt)

    def _check(self, model, corrector):
        if isinstance(corrector, bool) or corrector not in WHT_ORDERS:
            raise ValueError(f"corrector must be the order of a Wisdom-Holman-Touma corrector, "
                             f"one of {', '.join(map(str, WHT_ORDERS))}, got {corrector!r}")
        if model.coordinates != "jacobi":
            raise ValueError(f"the Wisdom-Holman-Touma correctors need Jacobi coordinates; "
                             f"{model.name} is in {model.coordinates} ones")
        scheme = self.inner.scheme
        if getattr(scheme, "n_parts", 2) != 2 or _substeps(scheme) is None:
            raise ValueError(f"the corrector of order {corrector} is that of the Wisdom-Holman "
                             f"map (scheme 'SABA1', or SABA1 repeated m times), not of scheme "
                             f"{scheme.name!r}")
        return int(corrector)

    def _word(self, word, dt):
        slots = self.model.parts.slots(2)
        return (np.array([slots[s] for s, _ in word], dtype=np.int64),
                np.array([c * dt for _, c in word], dtype=np.float64))

    def describe(self):
        d = self.inner.describe()
        d["corrector"] = None if self.corrector is None else {
            "order": self.corrector, "kind": "Wisdom, Holman & Touma (1996), at outputs"}
        return d

    def versions(self):
        return self.inner.versions()

    def advance(self, state, n):
        """Advance every active orbit of ``state`` by ``n`` intervals."""
        if state.step == 0:
            self._warn_unresolved(state)
        was_active = state.status == STATUS_OK
        if self.corrector is None:
            self._advance(state, n)
            _name_failures(state, was_active)
            return
        if MAPPED_STATE not in state.extra:
            # The first call: the map starts from C⁻¹(x₀), its vectors DC⁻¹·W₀.
            y, Wy = np.empty_like(state.x), np.empty_like(state.W)
            self._apply(self._to_map, state.x, state.W, y, Wy,
                        np.ones(state.n_orbits, dtype=np.bool_))
            state.extra[MAPPED_STATE], state.extra[MAPPED_VECTORS] = y, Wy
        y, Wy = state.extra[MAPPED_STATE], state.extra[MAPPED_VECTORS]
        state.x[...] = y
        state.W[...] = Wy
        self._advance(state, n)
        _name_failures(state, was_active)
        y[...] = state.x
        Wy[...] = state.W
        # Outputs: x = C(y) and DC(y)·W_y, renormalised as copies.
        x, W = np.empty_like(y), np.empty_like(Wy)
        self._apply(self._to_real, y, Wy, x, W, state.status <= STATUS_OK)
        if self.renorm != Renorm.NONE and state.k:
            W, _, _ = renormalized_copy(W, state.acc_m, state.acc_e, self.renorm)
        state.x[...] = x
        state.W[...] = W

    def _advance(self, state, n):
        """The part stepper's ``n`` intervals on the active orbits: in
        blocks of SIMD lanes where there are several (bit for bit the same,
        :mod:`varint.kernels.planetary_batch`), else one orbit at a time."""
        order = np.flatnonzero(state.status == STATUS_OK)
        if not (self.lanes and n > 0 and len(order) >= MIN_LANE_ORBITS):
            self.inner.advance(state, n)
            return
        inner, parts, m = self.inner, self.model.parts, state.n_orbits
        acc = inner.accumulator
        if acc is None:
            update, aux, flow = no_accumulator, np.empty((m, 0, 0)), False
        else:
            update, aux, flow = acc.update, state.extra[acc.key], acc.needs_flow
        parallel = use_parallel(inner.parallel, m)
        kernel = lane_batch(self.model.n_planets, state.k, parts.apply, parts.field, update,
                            flow, parallel)
        # One block of lanes per thread, each with an equal share of the orbits.
        blocks = min(-(-len(order) // LANES), numba.get_num_threads() if parallel else 1)
        groups = np.linspace(0, len(order), blocks + 1).astype(np.int64)
        counters = np.zeros((m, len(parts.names)), dtype=np.int64)
        done = np.zeros(m, dtype=np.int64)
        was_active = state.status == STATUS_OK
        kernel(state.x, state.W, state.acc_m, state.acc_e, aux, counters, inner._parts,
               inner._h, inner._par, inner._n_work,
               Call(int(n), state.step, inner.tau, int(inner.renorm), inner._escape_r2),
               state.status, done, order, groups)
        state.after_kernel(n, was_active, done, counters,
                           tuple(f"flow_{name}" for name in parts.names))

    def _warn_unresolved(self, state):
        """An :class:`~varint.accuracy.AccuracyWarning` where the Kepler
        drift's step exceeds a planet's pericentre passage time
        √(q³/μ(1 + e)) (the time to cross the pericentre distance at the
        pericentre speed): the Wisdom–Holman map then does not resolve the
        pericentre, and its error grows without bound as e → 1."""
        if getattr(self.inner.scheme, "n_parts", 2) != 2:
            return
        dt = self.tau * _kick_spacing(self.inner.scheme)
        times = self.model.pericentre_times(state.x)
        bad = (times < dt) & (state.status[:, None] <= STATUS_OK)
        if not bad.any():
            return
        m, i = np.argwhere(bad)[0]
        where = "" if state.n_orbits == 1 else f" of orbit {m} ({int(bad.any(axis=1).sum())} " \
                                                f"of {state.n_orbits} orbits)"
        warnings.warn(f"planet {i + 1}{where} has a pericentre passage time {times[m, i]:.3g}, "
                      f"shorter than the Kepler drift's step {dt:.3g}: the Wisdom-Holman map "
                      "does not resolve its pericentre (its error grows as e -> 1); use a "
                      "smaller tau or more steps per interval (SplittingScheme.repeated)",
                      AccuracyWarning, stacklevel=6)

    def _apply(self, word, X, W, out_X, out_W, active):
        parts, h = word
        word_batch(self.model.parts.apply, W.shape[2])(
            parts, h, X, W, self.model.params, self.model.parts.n_work,
            np.ascontiguousarray(active), out_X, out_W)

"""A step per orbit for chaos maps (``chaos_map(..., tau="orbit")``): each
orbit integrated with the largest step its own pilot allows, instead of the
step of the map's worst sampled orbit for all of them.

The steps are τ_m = U / n_m with one unit U for the whole map (the largest
step :mod:`varint.stepsize` would try, lowered to divide t_end) and an
integer n_m ≥ 1 per orbit. Every step therefore divides U, so every orbit
reaches the map's check times (whole multiples of U) exactly, and the map's
records, early stopping and ``t_stop`` stay on one time grid. A chunk runs
its orbits in groups of equal n (:func:`run_grouped`), one batch run each.

Groups. A batch run advances up to
:data:`~varint.codegen.interval.LANE_WIDTH` orbits of one step in SIMD
lanes; a group of a few orbits leaves most lanes empty, and its steps cost
several times those of a full block (SRKN14a on the cored map of
``studies/map_steps.py``: ~5 times for one orbit, ~1.3 times for 16,
full from ~32, measured while developing this at load 9–10, not stored).
Every divisor is therefore rounded up to :func:`on_ladder` (at most
:data:`LADDER_BITS` significant binary digits: 1, 2, 3, 4, 6, 8, 12, …),
a step at most 1.5 times smaller than the orbit's pilot asks for, from a
rule on n alone, so each orbit's step still depends on its own pilot only.
On that map's 120 orbits the divisors fell into 72 groups (one per
integer n from 38 to 150), 5 on the ladder: the run's 336 ns per orbit
step became 144 (the map's one step: 128; ``map_steps.py --quick --part
race --case core``, ``results/orbit16/map_steps_quick_core_race.json``). Only the search's result is
rounded: a search whose every trial is on the ladder took orbit 18 of that
map from n = 1 (energy error 0.099, far outside the order's law) to
n = 12 (0.072), found the error not shrinking and sent the orbit to the
fallback step, its energy error over the map 8.9e-3.

The pilot is :mod:`varint.stepsize`'s — the largest relative error of the
conserved quantities at 50 times along a short run, with the run's own
deviation vectors and stepper — but each orbit reads its own error and its
own map value at the pilot's end, and searches its own step:

1. every orbit starts at n = 1 (τ = U);
2. *the indicator's verdict* (a map passes its indicator as a
   :class:`Judge`): an orbit whose map value at the previous, larger step
   agrees with the value at this step — |u − u'| ≤ :data:`AGREEMENT` ·
   max(1, |u'|), u the value (FLI, MEGNO) or its log₁₀ (SALI, GALI) —
   and whose energy error at that larger step was within the judge's
   bound (:data:`BOUND_FACTOR` times the map's pilot tolerance, at most its
   ``energy_tol`` / :data:`~varint.stepsize.PILOT_MARGIN`, the bound a run's
   own pilot keeps) takes the larger step: halving it would not change
   what the map shows;
3. *the energy error*: an orbit whose error meets the map's pilot tolerance
   takes this step (the rule without a judge: the tolerance the map's one
   step meets);
4. otherwise it runs its pilot again at n' > n: the step the scheme's
   order p predicts meets the tolerance (e ∝ τ^p: τ' = τ (tol / e)^(1/p),
   n' = ⌈U / τ'⌉, at least n + 1, a factor 16 down for a non-finite
   error), but with a judge at most 2n once the error is within the
   judge's bound (each factor 2 of the step gets its verdict). An orbit
   whose error does not shrink with the step (it runs into a singularity,
   or escapes) takes the step nearest :data:`~varint.stepsize.FALLBACK_TAU`,
   as a map's pilot does, and the map warns once with their number.

The energy tolerance of a map is much stricter than what its classification
needs for most orbits (FLI maps of ``studies/map_steps.py``: the largest
step at which an orbit still classifies as a tight reference does is 6.0–6.4
times the step of the energy tolerance, ``map_steps_profile.json``), but the
energy error alone does not show the few orbits that need small steps; the
indicator's own change under halving the step does. The pilot reads the
value only at its end (t_pilot below), so an orbit whose indicator is
sensitive only later in the map is not seen.

Orbits with the same n in a round share one pilot batch; each orbit is
integrated on its own, so its step depends on its initial state, its
deviation vectors (``default_rng([seed, m])``) and the map's settings only:
not on the chunking, the threads, the other orbits or a resume.

The pilot runs to t = min(:data:`~varint.stepsize.PILOT_T`,
:data:`PILOT_SHARE` · t_end): it runs every orbit of the map, so it is kept
a fixed share of the map's work. The per-orbit pilot costs about that share
plus the first rounds at large steps; the global pilot costs the work of 16
orbits. Which one is cheaper for a map depends on how much the orbits' needs
differ. On the FLI maps of ``studies/map_steps.py`` (t = 500, one thread,
machine load 14–17, ``map_steps_race.json``) the orbits took 2.2 (cored
logarithmic potential with a small core, 440 orbits) and 2.0 (restricted
three-body problem, 290 orbits) times fewer steps than with the map's one
step, pilot included a 1.8 and 1.5 times shorter map; the cored map
classified 99.8 % of its orbits as a tight reference does (the map's one
step: 99.1 %), the three-body map 98.3 % (99.3 %): an orbit's energy error
and its FLI at the pilot's end can stay within their tolerances while its
FLI at t_end needs a smaller step, so this is not the default. The
indicator's verdict chose the step of 113 and 7 of those orbits; the rest
met the energy tolerance first (from an error above the judge's bound the
search jumps to the step the order predicts meets the tolerance). Letting
the judge's bound also steer the search (the step predicted to meet it,
then halving) took 11.0 M instead of 15.3 M steps on the cored map at
99.3 % but sent one orbit through the core to the fallback step (energy
error 7e-3), and 0.62 M instead of 0.83 M on the three-body map at 97.9 %;
with the bound at energy_tol / 100, a 5 % agreement at a pilot twice as
long still misclassified 10 of the 290 (measured while developing this
rule, not stored).
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from collections.abc import Callable

import numpy as np

from .accuracy import AccuracyWarning, Reference, user_stacklevel
from .protocol import is_failure
from .state import initial_deviations
from .stepsize import (FALLBACK_TAU, PILOT_MARGIN, PILOT_STEPS, PILOT_T, TAU_MAX, StepChoice,
                       default_scheme, dividing_step, pilot_errors)

__all__ = ["choose_steps", "run_grouped", "indicator_judge", "Judge", "PILOT_SHARE", "AGREEMENT",
           "BOUND_FACTOR", "LADDER_BITS"]

#: The per-orbit pilot runs to at most this share of t_end (and at most
#: PILOT_T time units).
PILOT_SHARE = 0.1
#: The indicator's verdict: largest relative difference of an orbit's map
#: value at two steps (at the pilot's end) for the larger step to count
#: as good enough (module docstring).
AGREEMENT = 0.05
#: The judge's bound on the pilot's energy error is this many times the
#: map's pilot tolerance (module docstring: the map's ``energy_tol`` /
#: PILOT_MARGIN alone let rare passages near a small core exceed the map's
#: ``energy_tol`` later in the map).
BOUND_FACTOR = 10.0
#: Factor by which n grows after a non-finite pilot error.
BLOWUP_DROP = 16
#: Every divisor n has at most this many significant binary digits (1, 2,
#: 3, 4, 6, 8, 12, 16, 24, …; :func:`on_ladder`): a step at most 1.5 times
#: smaller than the pilot asks for, and few groups of equal n, so that each
#: group fills the SIMD lanes of its batch run (module docstring, "Groups").
LADDER_BITS = 2


@dataclasses.dataclass(frozen=True)
class Judge:
    """How the pilot judges a step by the map's own indicator (module
    docstring, "The indicator's verdict").

    Attributes
    ----------
    value : callable
        ``value(rows, t) -> ndarray (M,)``: the map's value of each orbit
        from a :class:`~varint.state.Rows` at times ``t``.
    name : str
        The indicator's name (for the provenance).
    log_scale : bool
        Whether the values spread over decades (compared as log₁₀).
    agreement : float
        Largest relative difference of the values at two steps (see
        :meth:`agrees`).
    bound : float
        Largest relative energy error over the pilot a step chosen by the
        indicator may have (:func:`indicator_judge`).
    """

    value: Callable
    name: str
    log_scale: bool
    agreement: float
    bound: float

    def agrees(self, coarse, fine):
        """Per orbit, whether the value at the larger step lies within
        ``agreement`` · max(1, |u|) of the value at the smaller one (u the
        value, or its log₁₀ for a log-scale indicator); NaN agrees with
        nothing."""
        with np.errstate(all="ignore"):
            if self.log_scale:
                coarse, fine = np.log10(np.abs(coarse)), np.log10(np.abs(fine))
            return np.abs(coarse - fine) <= self.agreement * np.maximum(1.0, np.abs(fine))

    def describe(self):
        return {"indicator": self.name, "agreement": self.agreement,
                "energy_bound": self.bound}


def indicator_judge(indicator, model, options, tolerance, energy_tol):
    """The :class:`Judge` of a map of ``indicator`` (configured
    ``options``) whose pilot tolerance is ``tolerance`` and whose accuracy
    verdict is ``energy_tol``: its bound is :data:`BOUND_FACTOR` times the
    tolerance, at most ``energy_tol`` / :data:`~varint.stepsize.PILOT_MARGIN`."""

    def value(rows, t):
        return indicator.scalar(indicator.read(rows, model, t, options), model, options)

    return Judge(value=value, name=indicator.name, log_scale=bool(indicator.log_scale),
                 agreement=AGREEMENT,
                 bound=min(BOUND_FACTOR * float(tolerance), float(energy_tol) / PILOT_MARGIN))


def choose_steps(model, X, t_end, tolerance, *, scheme=None, cap=None, seed=0, k=0,
                 renorm="none", accumulator=None, judge=None):
    """Each orbit's step: the unit U and per orbit the divisor n (τ = U/n)
    of the largest step whose pilot meets ``tolerance``, or with a
    ``judge`` whose indicator agrees with a smaller step's (module
    docstring).

    Parameters
    ----------
    model : Model
    X : ndarray, shape (M, 2N)
        The map's initial states (checked); orbit m is index m of the map.
    t_end : float
    tolerance : float
        Largest relative error of the conserved quantities over the pilot.
    scheme : str or SplittingScheme, optional
    cap : float, optional
        Largest acceptable step (the map's first check time).
    seed, k, renorm, accumulator
        The map's seed, number of deviation vectors, renormalisation and
        accumulator: the pilot carries the map's own vectors and stepper.
    judge : Judge, optional
        The map's indicator, to accept a step whose value agrees with that
        of the next smaller step tried (None: the energy error alone).

    Returns
    -------
    unit : float
    divisions : ndarray of int64, shape (M,)
    choice : StepChoice
        ``rule`` "orbit", ``unit``, ``divisions`` (per orbit, in map
        order), ``scheme``, ``tolerance``, ``pilot_t``, ``fallback`` (the
        orbits with no step meeting the tolerance), ``rounds`` and
        ``counts`` (the pilot's work); with a judge, ``judge`` (its
        indicator, agreement and energy bound), ``judged`` (the orbits
        whose step the indicator chose) and ``compared`` (for each of them
        the divisor of the smaller step whose value it agreed with).
    """
    sch = default_scheme(model, scheme)
    unit = dividing_step(t_end, min(TAU_MAX, t_end, cap if cap is not None else math.inf))
    t_pilot = min(t_end, PILOT_T, max(unit, PILOT_SHARE * t_end))
    m = len(X)
    n = np.ones(m, dtype=np.int64)
    done = np.zeros(m, dtype=bool)
    fallback = np.zeros(m, dtype=bool)
    # Per orbit the divisor of the smaller step its indicator agreed with
    # (0: its step was not chosen by the indicator).
    compared = np.zeros(m, dtype=np.int64)
    # The previous round's divisor (0: none), value and error per orbit.
    prev_n, prev_v, prev_e = np.zeros(m, dtype=np.int64), np.full(m, np.nan), np.full(m, np.nan)
    # Every round's divisor (0: not tried) and error per orbit, for the
    # "not shrinking" test: a column per round.
    tried_n, tried_e = np.zeros((m, 0), dtype=np.int64), np.zeros((m, 0))
    counts = {}
    n_fallback = max(1, math.ceil(unit / FALLBACK_TAU * (1 - 1e-12)))
    n_most = max(1, int(PILOT_STEPS * unit / t_pilot))
    while not done.all():
        active = np.flatnonzero(~done)
        # Per orbit its error, and its map value at the pilot's end.
        errors, values = np.full(m, np.nan), np.full(m, np.nan)
        for level in np.unique(n[active]):
            rows = active[n[active] == level]
            W0 = initial_deviations(model.dim, k, len(rows), seed, rows)
            out = pilot_errors(model, X[rows], unit / level, t_pilot, sch,
                               Reference(model, X[rows]), counts,
                               (W0, renorm, accumulator, False),
                               value=None if judge is None else judge.value)
            errors[rows], values[rows] = (out, np.nan) if judge is None else out
        tried_n = np.column_stack([tried_n, np.where(done, 0, n)])
        tried_e = np.column_stack([tried_e, errors])
        if judge is not None:
            # The previous, larger step: its value agrees with this one's
            # and its energy error is within the judge's bound.
            agree = ~done & (prev_n > 0) & judge.agrees(prev_v, values) & (prev_e <= judge.bound)
            compared[agree] = n[agree]
            n[agree] = prev_n[agree]
            done |= agree
        met = ~done & (errors <= tolerance)
        done |= met
        missed = np.flatnonzero(~done)
        nxt = _next_divisor(n[missed], errors[missed], tolerance, sch.order)
        if judge is not None:
            # Within the judge's bound, at most half the step: every factor
            # 2 gets its verdict. Above it the search goes on as without a
            # judge (a large error, e.g. at a step too large for a passage
            # near a singularity, need not follow the order's law).
            nxt = np.where(errors[missed] <= judge.bound, np.minimum(nxt, 2 * n[missed]), nxt)
        stuck = (nxt > n_most) | _not_shrinking(tried_n[missed], tried_e[missed], n[missed],
                                                 errors[missed])
        prev_n[missed], prev_v[missed], prev_e[missed] = n[missed], values[missed], errors[missed]
        n[missed] = np.where(stuck, n_fallback, nxt)
        done[missed[stuck]] = fallback[missed[stuck]] = True
    # The search's own divisors (and the judge's comparisons) stay as they
    # were: an error at a step far too large need not follow the order's
    # law, and a search on the ladder sent an orbit through the core to the
    # fallback step (module docstring, "Groups").
    n = on_ladder(n)
    choice = StepChoice(rule="orbit", unit=unit, tau=unit, divisions=n.tolist(),
                        scheme=sch.name, tolerance=float(tolerance), pilot_t=float(t_pilot),
                        orbits=m, fallback=np.flatnonzero(fallback).tolist(),
                        rounds=tried_n.shape[1],
                        counts=counts)
    if judge is not None:
        judged = np.flatnonzero(compared)
        choice.update(judge=judge.describe(), judged=judged.tolist(),
                      compared=compared[judged].tolist())
    if fallback.any():
        warnings.warn(
            f"for {int(fallback.sum())} of {m} orbits no step of {sch.name} keeps the relative "
            f"energy error of a pilot run (to t = {t_pilot:g}) within {tolerance:g}, and it "
            "does not shrink with the step: they probably run into a singularity of the "
            f"potential or escape; they run with tau = {unit / n_fallback:g} "
            "(provenance.tau_choice['fallback'] lists them)", AccuracyWarning,
            stacklevel=user_stacklevel())
    return unit, n, choice


def on_ladder(n):
    """Per divisor, the smallest integer ≥ ``n`` with at most
    :data:`LADDER_BITS` significant binary digits (``n`` ≥ 1, int64)."""
    n = np.asarray(n, dtype=np.int64)
    if np.any(n < 1):
        raise ValueError(f"divisors must be at least 1, got {int(n.min())}")
    # Bits below the leading LADDER_BITS, rounded up (n < 2^62 here).
    low = np.array([max(0, int(v).bit_length() - LADDER_BITS) for v in n.ravel()],
                   dtype=np.int64).reshape(n.shape)
    return ((n + (np.int64(1) << low) - 1) >> low) << low


def _next_divisor(level, error, tolerance, order):
    """Per orbit, the divisor the order predicts meets the tolerance
    (e ∝ τ^p), at least one more than ``level``; :data:`BLOWUP_DROP` times
    ``level`` after a non-finite error."""
    with np.errstate(all="ignore"):
        # Capped where int64 ends (the caller's step limit is far below).
        predicted = np.minimum(np.ceil(level * (error / tolerance) ** (1.0 / order)), 2.0**62)
    finite = np.isfinite(error) & (error > 0)
    return np.where(finite, np.maximum(level + 1, np.where(finite, predicted, 0)),
                    level * BLOWUP_DROP).astype(np.int64)


def _not_shrinking(tried_n, tried_e, level, error):
    """Per orbit, whether an earlier try at a divisor at most half of
    ``level`` (a step at least twice as large) had an error less than twice
    ``error``: the error is not the scheme's truncation error."""
    earlier = (tried_n > 0) & (level[:, None] >= 2 * tried_n)
    with np.errstate(invalid="ignore"):
        return np.any(earlier & ~(error[:, None] <= tried_e / 2), axis=1)


def run_grouped(run_chunk, x0, indices, spec, reference=None):
    """One chunk of a map whose orbits have their own steps: its orbits in
    groups of equal divisor ``spec.divisions[indices]``, each group one
    ``run_chunk`` call of the map's run (``spec.run``) with τ = τ / n and
    the check steps n times its steps (the same times), merged back in the
    chunk's order; ``reference`` (the chunk's rows of the map's, or None)
    split with them.

    The stop times of orbits that ran to the end or were decided at a check
    are put on the unit's grid (the check steps times the unit τ) exactly, as the
    map's records expect; failed orbits keep their own step's time.
    """
    divisions, run, tau = spec.divisions[indices], spec.run, spec.run.tau
    parts, order = [], []
    for level in np.unique(divisions):
        rows = np.flatnonzero(divisions == level)
        sub = dataclasses.replace(spec, divisions=None, run=dataclasses.replace(
            run, tau=float(tau / level), steps=run.steps * level))
        parts.append(run_chunk(x0[rows], indices[rows], sub,
                               None if reference is None else reference.rows(rows)))
        order.append(rows)
        if parts[-1].interrupted:
            # The chunk is not kept, as a chunk whose one run was
            # interrupted.
            return parts[-1]
    rows = np.concatenate(order)
    back = np.empty_like(rows)
    back[rows] = np.arange(len(rows))
    merged = {f.name: np.concatenate([getattr(p, f.name) for p in parts])[back]
              for f in dataclasses.fields(parts[0])
              if isinstance(getattr(parts[0], f.name), np.ndarray)}
    on_grid = ~is_failure(merged["status"])
    merged["t_stop"][on_grid] = np.rint(merged["t_stop"][on_grid] / tau) * tau
    counts = {}
    for p in parts:
        for key, value in p.counts.items():
            counts[key] = counts.get(key, 0) + int(value)
    cpu = [p.cpu_time for p in parts]
    return dataclasses.replace(parts[0], **merged, counts=counts,
                               cpu_time=None if any(c is None for c in cpu) else sum(cpu))

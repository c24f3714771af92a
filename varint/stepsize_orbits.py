"""A step per orbit for chaos maps (``chaos_map(..., tau="orbit")``): each
orbit integrated with the largest step its own pilot allows, instead of the
step of the map's worst sampled orbit for all of them.

The steps are τ_m = U / n_m with one unit U for the whole map (the largest
step :mod:`varint.stepsize` would try, lowered to divide t_end) and an
integer n_m ≥ 1 per orbit. Every step therefore divides U, so every orbit
reaches the map's check times (whole multiples of U) exactly, and the map's
records, early stopping and ``t_stop`` stay on one time grid. A chunk runs
its orbits in groups of equal n (:func:`run_grouped`), one batch run each.

The pilot is :mod:`varint.stepsize`'s — the largest relative error of the
conserved quantities at 50 times along a short run, with the run's own
deviation vectors and stepper — but each orbit reads its own error and
searches its own step:

1. every orbit starts at n = 1 (τ = U);
2. an orbit whose error e exceeds the tolerance predicts its step from the
   scheme's order p (e ∝ τ^p): τ' = τ (tol / e)^(1/p), so n' = ⌈U / τ'⌉,
   at least n + 1 (a factor 16 down for a non-finite error), and runs its
   pilot again at n';
3. it stops at the first n that meets the tolerance. An orbit whose error
   does not shrink with the step (it runs into a singularity, or escapes)
   takes the step nearest :data:`~varint.stepsize.FALLBACK_TAU`, as a map's
   pilot does, and the map warns once with their number.

Orbits with the same n in a round share one pilot batch; each orbit is
integrated on its own, so its step depends on its initial state, its
deviation vectors (``default_rng([seed, m])``) and the map's settings only:
not on the chunking, the threads, the other orbits or a resume.

The pilot runs to t = min(:data:`~varint.stepsize.PILOT_T`,
:data:`PILOT_SHARE` · t_end): it runs every orbit of the map, so it is kept
a fixed share of the map's work. The per-orbit pilot costs about that share
plus the first rounds at large steps; the global pilot costs the work of 16
orbits. Which one is cheaper for a map depends on how much the orbits' needs
differ. On the FLI maps of ``studies/map_steps.py`` (t = 500) the orbits
took 2.1 (cored logarithmic potential with a small core, 440 orbits) and
2.0 (restricted three-body problem, 290 orbits) times fewer steps than with
the map's one step, pilot included a 1.5 and 1.6 times shorter map; but
the three-body map classified 3 more of its 290 orbits otherwise than a
tight reference does (an orbit's energy error can stay within the tolerance
while its FLI needs a smaller step), so this is not the default.
"""

from __future__ import annotations

import dataclasses
import math
import warnings

import numpy as np

from .accuracy import AccuracyWarning, Reference, user_stacklevel
from .protocol import is_failure
from .state import initial_deviations
from .stepsize import (FALLBACK_TAU, PILOT_STEPS, PILOT_T, TAU_MAX, StepChoice, _default_scheme,
                       _divide, pilot_errors)

__all__ = ["choose_steps", "run_grouped", "PILOT_SHARE"]

#: The per-orbit pilot runs to at most this share of t_end (and at most
#: PILOT_T time units).
PILOT_SHARE = 0.1
#: Factor by which n grows after a non-finite pilot error.
BLOWUP_DROP = 16


def choose_steps(model, X, t_end, tolerance, *, scheme=None, cap=None, seed=0, k=0,
                 renorm="none", accumulator=None):
    """Each orbit's step: the unit U and per orbit the divisor n (τ = U/n)
    of the largest step whose pilot meets ``tolerance`` (module docstring).

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

    Returns
    -------
    unit : float
    divisions : ndarray of int64, shape (M,)
    choice : StepChoice
        ``rule`` "orbit", ``unit``, ``divisions`` (per orbit, in map
        order), ``scheme``, ``tolerance``, ``pilot_t``, ``fallback`` (the
        orbits with no step meeting the tolerance), ``rounds`` and
        ``counts`` (the pilot's work).
    """
    sch = _default_scheme(model, scheme)
    unit = _divide(t_end, min(TAU_MAX, t_end, cap if cap is not None else math.inf))
    t_pilot = min(t_end, PILOT_T, max(unit, PILOT_SHARE * t_end))
    m = len(X)
    n = np.ones(m, dtype=np.int64)
    done = np.zeros(m, dtype=bool)
    fallback = np.zeros(m, dtype=bool)
    # Every round's divisor (0: not tried) and error per orbit, for the
    # "not shrinking" test: a column per round.
    tried_n, tried_e = np.zeros((m, 0), dtype=np.int64), np.zeros((m, 0))
    counts = {}
    n_fallback = max(1, math.ceil(unit / FALLBACK_TAU * (1 - 1e-12)))
    n_most = max(1, int(PILOT_STEPS * unit / t_pilot))
    while not done.all():
        active = np.flatnonzero(~done)
        errors = np.full(m, np.nan)
        for level in np.unique(n[active]):
            rows = active[n[active] == level]
            W0 = initial_deviations(model.dim, k, len(rows), seed, rows)
            errors[rows] = pilot_errors(model, X[rows], unit / level, t_pilot, sch,
                                        Reference(model, X[rows]), counts,
                                        (W0, renorm, accumulator, False))
        tried_n = np.column_stack([tried_n, np.where(done, 0, n)])
        tried_e = np.column_stack([tried_e, errors])
        met = ~done & (errors <= tolerance)
        done |= met
        missed = np.flatnonzero(~done)
        nxt = _next_divisor(n[missed], errors[missed], tolerance, sch.order)
        stuck = (nxt > n_most) | _not_shrinking(tried_n[missed], tried_e[missed], n[missed],
                                                 errors[missed])
        n[missed] = np.where(stuck, n_fallback, nxt)
        done[missed[stuck]] = fallback[missed[stuck]] = True
    choice = StepChoice(rule="orbit", unit=unit, tau=unit, divisions=n.tolist(),
                        scheme=sch.name, tolerance=float(tolerance), pilot_t=float(t_pilot),
                        orbits=m, fallback=np.flatnonzero(fallback).tolist(),
                        rounds=tried_n.shape[1],
                        counts=counts)
    if fallback.any():
        warnings.warn(
            f"for {int(fallback.sum())} of {m} orbits no step of {sch.name} keeps the relative "
            f"energy error of a pilot run (to t = {t_pilot:g}) within {tolerance:g}, and it "
            "does not shrink with the step: they probably run into a singularity of the "
            f"potential or escape; they run with tau = {unit / n_fallback:g} "
            "(provenance.tau_choice['fallback'] lists them)", AccuracyWarning,
            stacklevel=user_stacklevel())
    return unit, n, choice


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


def run_grouped(run_chunk, x0, indices, spec):
    """One chunk of a map whose orbits have their own steps: its orbits in
    groups of equal divisor ``spec.divisions[indices]``, each group one
    ``run_chunk`` call of the map's run (``spec.run``) with τ = τ / n and
    the check steps n times its steps (the same times), merged back in the
    chunk's order.

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
        parts.append(run_chunk(x0[rows], indices[rows], sub))
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

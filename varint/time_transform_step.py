"""The fictitious step h of a logarithmic-Hamiltonian map when none is
given.

:func:`agreeing_h` (the maps' rule) judges h by what the map reports: the
largest h = h₀·2^−j (j = :data:`TOP`, …) at which the FLI of the pilot
orbits, each with the map's own vector, agrees with the FLI at h/2 as the
map needs (:func:`map_verdict`): the same verdict at the chaotic level
ln(1000 t) where the pilot runs to the map's t_end; where the map runs
longer, to its own t_end (:func:`varint.step_agreement.agreeing`: the
values within 0.05 dex times t_pilot/t_end, or both chaotic), with the energy errors at h under a sanity ceiling (the map's
``energy_tol``). The pilot runs to t = 100, a map often much longer; a
regular orbit's phase error, and with it the error of its FLI, grows
linearly in time under a symplectic scheme (Hairer, Lubich & Wanner,
*Geometric Numerical Integration*, 2nd ed., Thm. X.3.1), so a map 20 times
longer than its pilot needs agreement 20 times closer at the pilot's t.
The rule before (:func:`~varint.step_agreement.same_verdict`: the same
side of the chaotic level at the pilot's t, whatever t_end; chosen on
held-out orbits run twice as long as the pilot, ``studies/lh_yardstick.py``)
chose h = 0.099 on the cored map of ``studies/map_steps.py`` (t_end =
2000), where 16 of 16 pilot orbits gave the same verdict at h and h/2 to
t = 100, and its map (every orbit retried to ``energy_tol``) called 9 of
120 regular orbits chaotic (92.5 %): a coarse step's spurious growth of
the FLI through the near-singular core shows only after the pilot's t.
This rule chooses h = 0.025 there, every orbit as a tight reference does
(``studies/lh_horizon.py``, ``studies/results/lhprice18/lh_horizon.json``,
with the three-body map, a softened point mass and a cored halo with a
central mass). Chaos maps ask for verdicts: an energy
tolerance tight enough for every orbit's value (the map pilot's 1e-7) costs
steps no verdict needs (the three-body map of ``studies/map_steps.py``
classifies every orbit as a tight reference does at h = 1.6, with energy
errors far above 1e-7). When no h of the ladder passes, the map falls back
to :func:`choose_h` and warns. ``tests/test_step_agreement.py`` checks that
the h chosen on 16 orbits keeps held-out orbits (a softened point mass;
the three-body problem at another Jacobi constant), run twice as long as
the pilot, on the same side of the chaotic level as the same orbits at
h/16, and that the ladder's rejected first step does not;
``tests/test_time_transform_step.py`` that the h chosen for a cored map 20
times longer than its pilot keeps every orbit's verdict there.

:func:`choose_h` is the energy rule: the largest h whose pilot keeps the
energy within a tolerance, as :func:`varint.stepsize.choose_step` chooses
a constant step.

The energy rule's pilot runs a seeded sample of at most :data:`~varint.stepsize.PILOT_ORBITS`
of the map's orbits, without vectors (the orbit does not depend on them),
with the map's LH stepper (:meth:`LogHamiltonian.outputs
<varint.time_transform.LogHamiltonian.outputs>`) to t = min(t_end,
:data:`~varint.stepsize.PILOT_T`), and measures each orbit's largest
relative error of the conserved quantities (:class:`varint.accuracy.Reference`)
at :data:`~varint.stepsize.PILOT_CHECKS` output times along it; the
:data:`~varint.maps.MAP_QUANTILE` quantile of the orbits must meet the
tolerance. The steps tried are h = h₀·2^(j/4), j = 0, −1, …, with h₀ the
median over the sample of U(q₀) = C − V(q₀) (one time unit of physical
time per step where the orbits start, the largest constant step of a pilot):
a rung that misses predicts the next from the scheme's order p (error ∝
h^p), descending at most a factor 4 at once (a softened point mass at
h₀ has saturated errors ~5e3: predicted from there, the next rung was 35
rungs down, nine below the answer), and the search then bisects the rungs
between the largest that met it and the smallest that did not, so it ends on the
largest rung that met the tolerance with a failing rung just above it.
When the error does not shrink with h (an orbit escapes, or C is too low
for it) no h helps: the map runs at the smallest rung tried and its
accuracy verdict says what happened.

A symplectic scheme's energy error stays bounded in fictitious time as in
physical time, so the pilot's error bounds the map's as for constant steps;
``tests/test_time_transform_step.py`` checks that the h chosen on one set of
orbits keeps held-out orbits of the same models (a softened point mass, the
restricted three-body problem) within the tolerance, up to one rung (a
factor 2 in the error of an order-4 scheme), and that 2h does not.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from .accuracy import Reference
from .kernels.time_transform import BUDGET
from .state import initial_deviations
from .step_agreement import descend, map_verdict, pilot_sample, summary
from .stepsize import PILOT_CHECKS, PILOT_ORBITS, PILOT_T, RUNGS, Bracket
from .time_transform import lanes_work, takes_lanes

__all__ = ["choose_h", "agreeing_h", "map_verdict", "agreeing_offset", "pilot_errors", "retried", "orbit_errors"]

#: The indicator pilot's steps h = h₀·2^−j, j = TOP … TOP + LEVELS − 1:
#: from 2h₀ (two time units per step where the orbits start) to h₀/256
#: (the energy pilot's h was h₀/23 on the three-body map of
#: ``studies/map_steps.py`` and h₀/80 on its cored map).
TOP, LEVELS = -1, 10
#: The most rungs one prediction descends (a factor 4 in h).
MAX_DROP = 2 * RUNGS
#: The search gives up below this fraction of h₀ (2^-12: 4096 times the
#: pilot's steps at h₀, ~4e5 per orbit of a pilot of 100 time units).
SMALLEST = 2.0**-12
#: The halvings of h an orbit of a map is retried at (:func:`retried`):
#: down to h/16, the step of the held-out reference of
#: ``studies/lh_yardstick.py``; an orbit still above the ceiling there
#: keeps that run and the map's accuracy verdict names it.
RETRY_LEVELS = 4
#: The pilot's energy ceiling of a map whose orbits are retried, in units
#: of the map's ``energy_tol``: the pilot's h only needs the verdicts to
#: agree and most orbits to pass at once; each orbit then meets
#: ``energy_tol`` itself (``studies/lh_yardstick.py --part retry``).
RETRY_CEILING = 10.0


def pilot_errors(lh, X, h, t_pilot, reference, counts=None, starts=None):
    """Per orbit of ``X``, the largest relative error of the conserved
    quantities at :data:`~varint.stepsize.PILOT_CHECKS` output times of an
    LH run with the fictitious step ``h`` to ``t_pilot`` (inf where the
    orbit stopped: U ≤ 0, the step budget, a non-finite state). ``counts``
    (3,), if given, accumulates the LH steps, tail steps and gradients;
    ``starts`` are :meth:`~varint.time_transform.LogHamiltonian.starts`
    of ``X`` (computed here where not given)."""
    out = lh.outputs(X, None, t_pilot, h, every=t_pilot / PILOT_CHECKS, starts=starts)
    if counts is not None:
        counts += out.counts.sum(axis=0)
    with np.errstate(all="ignore"):
        errs = reference.errors(out.x_worst)
    e = np.max(np.stack(list(errs.values())), axis=0)
    return np.where((out.status == 0) & np.isfinite(e), e, np.inf)


def choose_h(lh, X, t_end, tolerance, *, quantile, seed=0):
    """The largest fictitious step h of ``lh`` (a
    :class:`~varint.time_transform.LogHamiltonian`) whose pilot on a
    sample of the orbits ``X`` meets ``tolerance`` at ``quantile`` (module
    docstring).

    Returns
    -------
    h : float
    choice : dict
        ``rule`` ("pilot", or "smallest" when no rung met it), ``h``,
        ``h0``, ``tolerance``, ``quantile``, ``pilot_t``, ``orbits``, the
        ``tried`` steps with their errors, the pilot's ``counts`` and, for
        the rule "pilot", the ``gradient_rate`` at h (force evaluations per
        orbit and unit of physical time along the pilot); the same call
        chooses the same step, bit for bit.
    """
    pick = np.arange(len(X))
    if len(X) > PILOT_ORBITS:
        pick = np.sort(np.random.default_rng(seed).choice(len(X), PILOT_ORBITS, replace=False))
    sample = X[pick]
    n = sample.shape[1] // 2
    reference = Reference(lh.model, sample)
    starts = lh.starts(sample)   # every rung's run starts from them
    U = lh.constants(sample, starts) - lh.model.potential(sample[:, :n])
    h0 = float(np.median(U))
    t_pilot = float(min(t_end, PILOT_T))
    order = lh.scheme.order
    tried: dict[int, float] = {}
    counts = np.zeros(3, dtype=np.int64)

    def rung(j):
        return h0 * 2.0 ** (j / RUNGS)

    work: dict[int, int] = {}

    def error(j):
        if j not in tried:
            before = int(counts[2])
            e = pilot_errors(lh, sample, rung(j), t_pilot, reference, counts, starts)
            tried[j] = float(np.quantile(e, quantile, method="higher"))
            work[j] = int(counts[2]) - before
        return tried[j]

    j, tried_rungs = 0, Bracket()
    while True:
        e = error(j)
        tried_rungs.note(j, e <= tolerance)
        if tried_rungs.settled(0):
            break
        best, lowest_fail = tried_rungs.best, tried_rungs.lowest_fail
        if best is not None:
            # Halve the gap to the lowest failing rung (the error need not
            # follow h^p between them: a pericentre resolved or not).
            j = best + (1 if lowest_fail is None else max(1, (lowest_fail - best) // 2))
            continue
        # At most a factor 4 at once: at long steps the error saturates
        # (far from h^p), and a prediction from there lands far too low,
        # from where the climb back costs a pilot per rung.
        drop = (RUNGS * math.log2(e / tolerance) / order if math.isfinite(e) else RUNGS * 4)
        nxt = j - min(MAX_DROP, max(1, math.ceil(drop)))
        # Halving h (or more) must halve the error, once the error is below
        # 1: above, it has saturated and says nothing of the order.
        shrinking = e >= 1.0 or all(not (k >= j + RUNGS) or e <= v / 2
                                    for k, v in tried.items())
        if not shrinking or rung(nxt) < SMALLEST * h0:
            break
        j = nxt
    choice = {"h0": h0, "tolerance": float(tolerance), "quantile": float(quantile),
              "pilot_t": t_pilot, "orbits": len(sample), "scheme": lh.scheme.name,
              "tried": [[rung(k), v] for k, v in sorted(tried.items())],
              "counts": {"lh_steps": int(counts[0]), "tail_steps": int(counts[1]),
                         "gradient_evaluations": int(counts[2])}}
    best = tried_rungs.best
    if best is None:
        h = rung(min(tried))
        choice.update(rule="smallest", h=h)
        return h, choice
    h = rung(best)
    # The force evaluations per orbit and unit of physical time at h: what
    # the map will cost (the defaults compare it with constant steps').
    choice.update(rule="pilot", h=h, gradient_rate=work[best] / (len(sample) * t_pilot))
    return h, choice



def agreeing_h(lh, X, t_end, *, quantile, ceiling, seed=0, every=10.0, agree=map_verdict,
               retry=None, t_pilot=None, stop_above=math.inf, deviations=None, reference=None,
               starts=None):
    """The largest fictitious step h = h₀·2^−j (j = :data:`TOP`, …; h₀ as
    in :func:`choose_h`) at which the FLI of a sample of the orbits ``X``,
    each with the map's own vector (``default_rng([seed, m])``) and
    normalised every ``every`` time units as the map does, agrees with that
    at h/2 on a ``quantile`` share of them, with the ``quantile`` of their
    energy errors at h within ``ceiling`` (a map's ``energy_tol``;
    :mod:`varint.step_agreement`); the pilot runs to min(t_end,
    :data:`~varint.stepsize.PILOT_T`). "Agrees" is ``agree``:
    :func:`map_verdict` (the maps' rule, module docstring), or the same
    verdict at the pilot's t whatever t_end
    (:func:`~varint.step_agreement.same_verdict`, the rule before). ``retry``, the
    energy tolerance a map retries its orbits to (:func:`retried`), makes
    ``gradient_rate`` the price of the map with its retries, predicted from
    the pilot orbits' own errors at h, h/2, … (the runs the descent made).
    ``deviations``, if given, are the sample's vectors as this function
    draws them (:func:`_pilot_deviations`; a caller that runs several
    descents on the same orbits draws them once), and ``reference`` their
    :class:`~varint.accuracy.Reference` (the sample's rows of ``X``), and
    ``starts`` :meth:`~varint.time_transform.LogHamiltonian.starts` of
    ``X`` (the same for every offset: a caller that prices several passes
    them, computed once).

    Returns
    -------
    h : float or None
        None when no step of the ladder passed.
    choice : dict
        ``rule`` ("indicator", or "none"), ``h``, ``h0``, ``pilot_t``,
        ``orbits``, ``agreement`` (the name of ``agree``), ``tried`` ([h,
        agreeing share, energy error quantile] per step judged; the share
        None where the energy errors alone failed it,
        :func:`~varint.step_agreement.descend`), ``energy_error`` (the largest
        pilot orbit's at h), ``gradient_rate`` (force evaluations per
        orbit and unit of physical time at h), ``counts`` and
        ``summary``, the sentence the map reports.
    """
    pick = pilot_sample(X, seed)
    sample = X[pick]
    n = sample.shape[1] // 2
    W0 = _pilot_deviations(lh, X, seed) if deviations is None else deviations
    reference = Reference(lh.model, sample) if reference is None else reference
    starts = lh.starts(X) if starts is None else starts
    mine = starts.rows(pick)
    h0 = float(np.median(lh.constants(sample, mine) - lh.model.potential(sample[:, :n])))
    t_pilot = float(min(t_end, PILOT_T if t_pilot is None else t_pilot))
    counts = np.zeros(3, dtype=np.int64)
    runs: dict = {}
    # A rung whose map runs over lanes runs its pilot over them too (the
    # map compiles them anyway): the same bits, in about a third of the
    # time (studies/results/lhlanes17/lh_lanes.json); so does every rung
    # once this process has them compiled (a coarse rung before a fine one,
    # a later map).
    u0 = lh.start_u(X, starts=starts)

    def run(j):
        if j not in runs:
            h = h0 * 2.0**-j
            out = lh.outputs(sample, W0, t_pilot, h, every=every, starts=mine,
                             lanes=lh.lanes_ready(1) or takes_lanes(len(X),
                                                                    lanes_work(u0, t_end, h)))
            counts[:] += out.counts.sum(axis=0)

            # Measured where read (descend; _retry_rate): a run whose rate
            # stops the descent, or the fine run of the rung that passes
            # without retries, never needs its errors.
            @functools.cache
            def errors(out=out):
                with np.errstate(all="ignore"):
                    errs = reference.errors(out.x_worst)
                e = np.max(np.stack(list(errs.values())), axis=0)
                return np.where((out.status == 0) & np.isfinite(e), e, np.inf)

            runs[j] = (out.fli, errors, out.counts[:, 2].sum() / (len(sample) * t_pilot),
                       out.counts[:, 2])
        return runs[j][:3]

    tried, chosen = descend(run, range(TOP, TOP + LEVELS), lambda j: h0 * 2.0**-j, t_pilot,
                            t_end, quantile, ceiling, agree=agree, stop_above=stop_above)
    choice = {"h0": h0, "pilot_t": t_pilot, "orbits": len(sample), "quantile": float(quantile),
              "ceiling": float(ceiling), "agreement": agree.__name__,
              "scheme": lh.scheme.name, "tried": tried,
              "counts": {"lh_steps": int(counts[0]), "tail_steps": int(counts[1]),
                         "gradient_evaluations": int(counts[2])}}
    if chosen is None:
        choice.update(rule="none", h=None,
                      summary="the FLI of the pilot orbits did not agree between h and h/2 "
                              "at any step tried")
        return None, choice
    j, n_agree, largest = chosen
    rate = float(runs[j][2])
    if retry is not None:
        rate, share = _retry_rate(runs, j, retry, len(sample) * t_pilot)
        choice.update(retry_tolerance=float(retry), retried_share=share)
    choice.update(rule="indicator", h=h0 * 2.0**-j, energy_error=largest, gradient_rate=rate,
                  summary=summary(n_agree, len(sample), largest, "h"))
    return h0 * 2.0**-j, choice


def _pilot_deviations(lh, X, seed):
    """The vectors of :func:`agreeing_h`'s pilot orbits of ``X``: each the
    map's own (``default_rng([seed, m])`` for orbit m)."""
    pick = pilot_sample(X, seed)
    return initial_deviations(lh.model.dim, 1, len(pick), seed, pick)[:, :, 0]


#: The offsets δ of C = E + δ (:mod:`varint.time_transform`) the maps'
#: pilot prices, in this order (None: the rule δ = max(−E, 1) of
#: :class:`~varint.time_transform.LogHamiltonian`); :func:`agreeing_offset`.
OFFSETS = (None, 0.5, 0.25, 0.125)
#: The physical time of the pilots that price the offsets (a quarter of
#: :data:`~varint.stepsize.PILOT_T`: on the cored, softened point mass and
#: Hénon–Heiles pilots of ``studies/lh_offset.py`` they rank the offsets
#: as the pilots to t = 100 do, at a quarter of their force evaluations).
PRICE_T = PILOT_T / 4


def agreeing_offset(lh, X, t_end, *, quantile, ceiling, seed=0, every=10.0, retry=None,
                    offsets=OFFSETS, stop_above=math.inf, deviations=None, reference=None,
                    agree=map_verdict, starts=None):
    """The offset δ and the fictitious step h of an LH map of the orbits
    ``X`` whose ``lh`` has no offset of its own (δ = None): the cheapest δ
    of ``offsets`` whose pilot agrees, and the h of :func:`agreeing_h` at it.

    On an orbit of energy E, U = C − V = A + δ, so for a kinetic A the
    physical step h/U is h/(T + δ) (Preto & Tremaine 1999, eq. 14; Mikkola &
    Tanikawa 1999): the ratio of an orbit's longest step (T → 0) to its
    shortest (a core of depth |V_min| − E) is (T_max + δ)/δ, so a small δ
    concentrates the steps where the orbit is fast and δ → ∞ gives constant
    steps. Which δ needs the fewest force evaluations depends on the
    potential (``studies/lh_offset.py``: the cored map δ = 0.25, 1.6 times
    fewer than the rule's δ = 1; Hénon–Heiles the rule): the price decides.

    Each δ of ``offsets``, in order, is priced by :func:`agreeing_h` with the
    same rule, ceiling and ``retry`` on pilots to :data:`PRICE_T` (its
    ``gradient_rate``, force evaluations per orbit and unit of time, the
    retries counted; a descent stops once its steps cost more than the
    cheapest δ so far); the walk ends at the first δ not cheaper than the
    best before it (or whose pilot agrees at no h). The map's h is then
    :func:`agreeing_h` at the chosen δ (pilot to
    :data:`~varint.stepsize.PILOT_T`); where that finds no h, the rule's δ.
    Every figure is a count of the pilots' own runs, never a timing: the
    same call chooses the same δ and h, bit for bit. ``stop_above`` is the
    map's h descent's (:func:`agreeing_h`; not the pricing pilots'): a
    competitor cheaper than any step left stops it (h None). ``deviations``
    and ``reference`` are :func:`agreeing_h`'s, drawn here when not given
    (the defaults' switch shares those of its constant-step pilot, the same
    orbits with the same vectors), and so are ``agree`` and ``starts``
    (computed once here where not given: every δ's C and U₀ come from the
    same energies).

    For an A that takes both signs (a rotating frame,
    :attr:`~varint.time_transform.LogHamiltonian.kinetic` False) only the
    rule's C (= 0 for orbits bound below E = −1) keeps U > 0 along an orbit
    the pilot did not see: δ is the rule's, unpriced.

    Returns
    -------
    lh : LogHamiltonian
        ``lh`` at the chosen δ (:meth:`~varint.time_transform.LogHamiltonian.with_offset`).
    h : float or None
    choice : dict
        :func:`agreeing_h`'s at the chosen δ, with ``offset`` (None: the
        rule), ``offsets`` ([δ, h, price] per δ priced), ``offset_pricing``
        (the pricing pilots' force evaluations) and ``offset_summary``, the
        sentence the map's verdict carries.
    """
    # Every descent runs the same pilot orbits with the same vectors: drawn
    # once (a generator per orbit: ~2 ms a draw of 16 orbits on the loaded
    # 2-core machine, cProfile of the cored map's defaults; 5 draws a map).
    kwargs = {"quantile": quantile, "ceiling": ceiling, "seed": seed, "every": every,
              "retry": retry, "reference": reference, "agree": agree,
              "starts": lh.starts(X) if starts is None else starts,
              "deviations": _pilot_deviations(lh, X, seed) if deviations is None else deviations}
    priced, pricing = [], 0
    if lh.kinetic and lh.offset is None:
        best = None
        for offset in offsets:
            # Prices are force evaluations per orbit and unit of time: a
            # descent whose own steps already cost more cannot win.
            limit = math.inf if best is None else best[2]
            h, c = agreeing_h(lh.with_offset(offset), X, t_end, t_pilot=PRICE_T,
                              stop_above=limit, **kwargs)
            pricing += c["counts"]["gradient_evaluations"]
            price = math.inf if h is None else c["gradient_rate"]
            priced.append([offset, h, price])
            if best is not None and not price < best[2]:
                break
            if best is None or price < best[2]:
                best = priced[-1]
        offset = None if best is None or not math.isfinite(best[2]) else best[0]
        prices = "; ".join(f"δ = {'max(−E, 1)' if d is None else f'{d:g}'}: "
                           + (f"{p:.4g}" if math.isfinite(p) else "no agreement below the best")
                           for d, _, p in priced)
        why = (f"offset δ = {'max(−E, 1)' if offset is None else f'{offset:g}'}, the cheapest "
               f"of {len(priced)} priced on the pilot to t = {min(t_end, PRICE_T):g} (force "
               f"evaluations per orbit and unit of time, retries counted: {prices})")
    else:
        offset = lh.offset
        why = ("offset δ = max(−E, 1) (not priced: A takes both signs, only that C keeps "
               "U > 0)" if lh.offset is None else f"offset δ = {lh.offset:g} as given")
    chosen = lh.with_offset(offset)
    h, choice = agreeing_h(chosen, X, t_end, stop_above=stop_above, **kwargs)
    if h is None and offset is not None and lh.offset is None:
        why += f"; at δ = {offset:g} no h agreed to t = {min(t_end, PILOT_T):g}: the rule's δ"
        offset, chosen = None, lh.with_offset(None)
        h, choice = agreeing_h(chosen, X, t_end, stop_above=stop_above, **kwargs)
    choice.update(offset=offset, offsets=priced, offset_pricing=pricing, offset_summary=why)
    return chosen, h, choice


def _retry_rate(runs, j, tolerance, orbit_time):
    """The force evaluations per orbit and unit of time of a map at the
    pilot's rung ``j`` whose orbits are retried to ``tolerance``
    (:func:`retried`), predicted from the pilot's ``runs`` (:func:`agreeing_h`'s:
    (FLI, energy errors as a function, rate, force evaluations per orbit)
    by rung): each pilot orbit
    pays its runs at j, j + 1, … up to the first whose energy error meets
    ``tolerance`` (or the last rung the descent ran). Returns it and the
    share of pilot orbits retried."""
    work = runs[j][3].astype(float)
    failing = runs[j][1]() > tolerance
    share = float(np.mean(failing))
    for k in range(j + 1, j + 1 + RETRY_LEVELS):
        if k not in runs or not failing.any():
            break
        work = work + np.where(failing, runs[k][3], 0)
        failing &= runs[k][1]() > tolerance
    return float(work.sum() / orbit_time), share


def orbit_errors(reference, out):
    """Per orbit of ``out`` (:class:`~varint.time_transform.LHOutputs`),
    the largest relative error of its conserved quantities over its
    outputs (at the output state furthest from the initial energy and at
    the end; ``reference`` holds the initial values), inf where the orbit
    stopped or the error is not finite: what the map's verdict judges."""
    with np.errstate(all="ignore"):
        final, worst = reference.errors(out.x), reference.errors(out.x_worst)
    e = np.max(np.stack([np.fmax(final[k], worst[k]) for k in final]), axis=0)
    return np.where((out.status == 0) & np.isfinite(e), e, np.inf)


def retried(lh, X, W0, t_end, h, ceiling, reference, every=10.0, levels=RETRY_LEVELS):
    """Orbits ``X`` (M, 2N) with vectors ``W0`` (M, 2N) run by
    :meth:`LogHamiltonian.outputs
    <varint.time_transform.LogHamiltonian.outputs>` at the fictitious step
    ``h``, each orbit whose own largest energy error (:func:`orbit_errors`
    against ``reference``, the rows of ``X``) exceeds ``ceiling`` run again
    from its start at h/2, then h/4, … down to h/2^``levels``: every orbit
    ends at the coarsest of these steps at which it meets ``ceiling``
    (each orbit meets the map's tolerance itself, not a quantile of a
    pilot's), or at the finest. An orbit's steps depend on that orbit, h
    and ``ceiling`` alone, so the result is the same in any chunking and
    the same as the orbit run alone at its recorded step. An orbit the
    step budget stopped is not retried (a smaller h takes more steps).

    Returns
    -------
    out : LHOutputs
        Each orbit's final run; ``counts`` the work of every run.
    level : ndarray of int64 (M,)
        The halvings of each orbit's final run (its step h·2^−level).
    """
    out = lh.outputs(X, W0, t_end, h, every=every)
    fields = {name: np.array(getattr(out, name)) for name in
              ("fli", "status", "x", "t", "x_worst", "t_worst", "counts")}
    level = np.zeros(len(X), dtype=np.int64)
    todo = np.flatnonzero((orbit_errors(reference, out) > ceiling) & (out.status != BUDGET))
    for j in range(1, levels + 1):
        if len(todo) == 0:
            break
        again = lh.outputs(X[todo], None if W0 is None else W0[todo], t_end, h * 2.0**-j,
                           every=every)
        for name, v in fields.items():
            if name == "counts":
                v[todo] += again.counts
            else:
                v[todo] = getattr(again, name)
        level[todo] = j
        fail = (orbit_errors(reference.rows(todo), again) > ceiling) & (again.status != BUDGET)
        todo = todo[fail]
    return type(out)(**fields), level

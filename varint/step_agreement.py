"""Steps judged by what an FLI map reports: a step is good enough when the
pilot orbits' FLI at the step and at half of it agree (a Richardson-style
check on the indicator itself), not only when the energy error meets a
tolerance far below what the map's verdicts need.

The check (:func:`agreeing`) compares each pilot orbit's FLI at the
pilot's end, run with the map's own deviation vector, at the step and at
half of it: they agree where their log₁₀ max(1, FLI) differ by at most
:data:`AGREEMENT_DEX` (12 %: what a map drawn on a log scale shows; times
t_pilot / t_end for a map that runs longer than the pilot), or
where both lie above the level :func:`chaotic_level` no regular orbit
reaches (a chaotic orbit's FLI at two steps need not converge: its two
trajectories separate like e^(λt), but both say "chaotic"). A step passes
(:func:`passes`) when a :data:`~varint.maps.MAP_QUANTILE` share of the
pilot orbits agree and the same quantile of its energy errors is within a
sanity ceiling (the map's ``energy_tol``): halving a step too coarse for
an orbit usually changes its FLI, but two steps both too coarse can both
show numerical chaos, with energy errors far above the ceiling (the cored
map of ``studies/map_steps.py`` at h ≥ 0.43: FLI 10–90 at both, relative
energy errors 1–5).

Failure modes this does not see: an orbit whose indicator changes with
the step only after the pilot's end (the pilot runs to
min(t_end, :data:`~varint.stepsize.PILOT_T`)), and orbits outside the
pilot's sample (:data:`~varint.stepsize.PILOT_ORBITS`). The map keeps each
orbit's energy error and its accuracy verdict, which still warns where an
orbit's error exceeds ``energy_tol``.

A weaker rule, :func:`same_verdict`: the FLI at a step and at half of it
on the same side of the chaotic level at the pilot's t, the verdict a map
read at that level gives, whatever the map's t_end. It missed what a
coarse step does after the pilot's end (the logarithmic Hamiltonian's
cored map, :mod:`varint.time_transform_step`). The maps' rule,
:func:`map_verdict`, is that verdict where the pilot runs to the map's end
and :func:`agreeing` to the map's t_end where the map is longer.

:func:`agreeing_tau` searches the constant step of the map's stepper by
any of these rules (down from :data:`~varint.stepsize.TAU_MAX`); the
defaults of :func:`varint.chaos_map` search it by :func:`map_verdict` and
price it against the logarithmic Hamiltonian's
(:func:`varint.time_transform_step.agreeing_h`, the same rule), so that
both steppers are judged alike. ``studies/ladder_rule.py``
(``results/pilot19/ladder_rule.json``, counts): on the three-body, cored
and two-centres maps the defaults choose the same stepper and step, with
the same pilot runs and bits, with the constant ladder judged by either
rule (agreement with a tight reference 98.7 %, 100 %, 100 %); the
constant ladder alone, unstopped by a price, chooses τ = 0.25 on the
three-body map by both, none on the two centres, and on the cored map
1/128 against the verdict rule's 1/64 (where 7 of 16 pilot orbits' FLI
values at 1/64 and 1/128 agree to its t_end = 2000 and all 16 verdicts
at t = 100 do: the defaults' LH is cheaper than either).
"""

from __future__ import annotations

import functools
import math
import numbers

import numpy as np

from .accuracy import Reference
from .state import initial_deviations
from .stepsize import (PILOT_ORBITS, PILOT_T, TAU_MAX, PilotPropagators, default_scheme,
                       dividing_step, pilot_errors)

__all__ = ["agreeing", "chaotic_level", "descend", "passes", "pilot_sample", "agreeing_tau",
           "same_verdict", "map_verdict", "summary", "ConstantLadder",
           "AGREEMENT_DEX", "CHAOTIC_GROWTH", "LEVELS"]

#: Largest difference of log₁₀ max(1, FLI) at a step and at half of it for
#: an orbit's two values to agree (a factor 1.12).
AGREEMENT_DEX = 0.05
#: An FLI above ln(CHAOTIC_GROWTH · t) at time t is chaotic: a regular
#: orbit's deviation vector grows linearly, ‖w‖ ≈ 1 + g·t with a shear g of
#: order one (Froeschlé, Lega & Gonczi 1997); a thousand times that is
#: exponential growth.
CHAOTIC_GROWTH = 1e3
#: Steps of the constant-step ladder, TAU_MAX down to TAU_MAX/2^11 (the
#: energy pilot's step on the cored map of ``studies/map_steps.py``, R_c =
#: 0.03, is 1/150).
LEVELS = 12


def chaotic_level(t):
    """The FLI (ln‖w‖) above which an orbit counts as chaotic at time
    ``t``: ln(:data:`CHAOTIC_GROWTH` · t)."""
    return math.log(CHAOTIC_GROWTH * max(float(t), 1.0))


def agreeing(coarse, fine, t, t_end=None):
    """Per orbit, whether its FLI at a step (``coarse``) and at half of it
    (``fine``), both at time ``t``, agree (module docstring); NaN (a
    stopped orbit) agrees with nothing. For a map that runs to ``t_end`` >
    t the values must agree t / t_end times more closely: a regular
    orbit's phase error, and with it the error of its FLI, grows linearly
    in time."""
    coarse, fine = np.asarray(coarse, dtype=float), np.asarray(fine, dtype=float)
    level = chaotic_level(t)
    dex = AGREEMENT_DEX * (1.0 if t_end is None else min(1.0, float(t) / float(t_end)))
    with np.errstate(all="ignore"):
        close = np.abs(np.log10(np.maximum(coarse, 1.0))
                       - np.log10(np.maximum(fine, 1.0))) <= dex
        both_chaotic = (coarse > level) & (fine > level)
    return np.isfinite(coarse) & np.isfinite(fine) & (close | both_chaotic)


def same_verdict(coarse, fine, t, t_end=None):
    """Per orbit, whether its FLI at a step (``coarse``) and at half of it
    (``fine``), both at time ``t``, lie on the same side of
    :func:`chaotic_level` (t): the verdict a map read at that level gives
    agrees, whatever the values (:func:`map_verdict` where the pilot runs
    to the map's end; ``t_end`` is not used: a verdict, unlike a value, is
    not tightened for a longer map).
    NaN (a stopped orbit) agrees with nothing."""
    coarse, fine = np.asarray(coarse, dtype=float), np.asarray(fine, dtype=float)
    level = chaotic_level(t)
    with np.errstate(invalid="ignore"):
        return np.isfinite(coarse) & np.isfinite(fine) & ((coarse > level) == (fine > level))


def map_verdict(coarse, fine, t, t_end=None):
    """Per orbit, whether its FLI at a step (``coarse``) and at half of it
    (``fine``), both at the pilot's time ``t``, agree as a map to
    ``t_end`` needs: the same verdict at the chaotic level where the pilot
    runs to the map's end (:func:`same_verdict`), the values within
    :data:`AGREEMENT_DEX` times t/t_end where the map is longer
    (:func:`agreeing`: its verdict at t_end is not seen, and a regular
    orbit's FLI error grows linearly in time under a symplectic scheme,
    Hairer, Lubich & Wanner, *Geometric Numerical Integration*, 2nd ed.,
    Thm. X.3.1). The rule of both ladders of the defaults' switch
    (:func:`varint.maps._cheaper_steps`): the law holds for constant steps
    as for the logarithmic Hamiltonian's, so both are judged to the same
    horizon (``studies/ladder_rule.py``)."""
    if t_end is None or float(t_end) <= float(t):
        return same_verdict(coarse, fine, t)
    return agreeing(coarse, fine, t, t_end)


def passes(agree, errors, quantile, ceiling, worst=None):
    """Whether a step passes: at least a ``quantile`` share of ``agree``
    and the ``quantile`` of the energy ``errors`` within ``ceiling``;
    ``worst`` is that quantile where the caller has it already
    (:func:`descend`: ``np.quantile`` costs ~0.1 ms a call)."""
    if worst is None:
        worst = float(np.quantile(errors, quantile, method="higher"))
    return bool(np.mean(agree) >= quantile and worst <= ceiling), worst


def pilot_sample(X, seed):
    """The indices of the pilot's orbits among the map's ``X``: all, or a
    seeded sample of :data:`~varint.stepsize.PILOT_ORBITS` (as the energy
    pilots draw it). For an integer seed they depend on len(X) and the
    seed alone and are drawn once (the defaults' switch asks for them five
    times a map, a generator each); each caller gets its own copy (a
    read-only array would make numba compile its kernels again)."""
    if isinstance(seed, numbers.Integral) and not isinstance(seed, bool):
        return _sample_indices(len(X), int(seed)).copy()
    return _draw_sample(len(X), seed)


@functools.lru_cache(maxsize=64)
def _sample_indices(m, seed):
    pick = _draw_sample(m, seed)
    pick.flags.writeable = False   # shared: only copies leave
    return pick


def _draw_sample(m, seed):
    if m <= PILOT_ORBITS:
        return np.arange(m)
    return np.sort(np.random.default_rng(seed).choice(m, PILOT_ORBITS, replace=False))


def pilot_vectors(dim, k, pick, seed):
    """The pilot orbits' vectors (M, 2N, k): those of the map's orbits
    ``pick`` (:func:`~varint.state.initial_deviations`). For an integer
    seed they are drawn once (a generator and a QR per orbit, ~0.1 ms for
    the sixteen orbits of a map's pilot, at every map); each caller gets
    its own copy, as :func:`pilot_sample`."""
    if isinstance(seed, numbers.Integral) and not isinstance(seed, bool):
        return _kept_vectors(int(dim), int(k), int(seed), pick.dtype.str, pick.tobytes()).copy()
    return initial_deviations(dim, k, len(pick), seed, pick)


@functools.lru_cache(maxsize=64)
def _kept_vectors(dim, k, seed, dtype, pick):
    W = initial_deviations(dim, k, len(pick) // np.dtype(dtype).itemsize, seed,
                           np.frombuffer(pick, dtype=dtype))
    W.flags.writeable = False   # shared: only copies leave
    return W


def summary(n_agree, n, errors_max, step_name):
    """The sentence a result's step choice carries (``provenance.tau_choice``
    and its accuracy verdict)."""
    return (f"step chosen by indicator agreement between {step_name} and {step_name}/2 on "
            f"{n_agree}/{n} pilot orbits; energy errors up to {errors_max:.2g}")


def descend(run, levels, step, t_pilot, t_end, quantile, ceiling, stop_above=math.inf,
            agree=agreeing, floor=None):
    """Down a ladder of steps, the first that passes (:func:`passes`): the
    pilot's values at step(j) compared with those at step(j + 1) = step(j)/2
    by ``agree`` (:func:`agreeing`, or :func:`same_verdict`),
    for j in ``levels``.

    ``run(j)`` returns the pilot orbits' (indicator values, energy errors,
    force evaluations per orbit and unit of time) at step(j), memoised by
    the caller (each run serves as the fine run of one rung and the coarse
    one of the next). The energy errors may be a function that returns
    them (:func:`~varint.stepsize.pilot_errors` with ``lazy``): they are
    read only where run(j) is judged as a rung's coarse run, so the fine
    run of the rung that passes, and a run whose rate stops the descent,
    never measure theirs (on the three-body map of ``studies/map_steps.py``
    one run of each ladder; 50 checks of 16 orbits each). The descent stops early where the force evaluations
    exceed ``stop_above`` (a competitor is cheaper than any step left), or,
    where ``stop_above`` is a callable, where ``stop_above(rate)`` is true
    (a competitor's pilot that runs its own cheaper steps first,
    :class:`ConstantLadder`).

    Two shortcuts spare pilot runs without changing the rung chosen:

    - A rung whose energy errors at step(j) already exceed ``ceiling``
      fails whatever its fine run says (:func:`passes` asks for both), so
      its fine run is not made for it.
    - ``floor(j)``, if given, is a lower bound of the force evaluations of
      run(j) before it is made (None where it is made already, or where no
      bound is known): the rung below one that failed on its energy errors
      is not run where that bound already stops the descent. Stopping is
      monotone in the rate (a larger rate exceeds ``stop_above`` too; a
      :meth:`ConstantLadder.cheaper_than` true at a lower rate stays true at
      a higher one, the ladder descending further under a higher limit),
      so a bound that stops the descent stops it where the run's own rate
      would have.

    Where the logarithmic Hamiltonian wins, the constant ladder judged under
    its prices often ends on a rung failing on its energy errors, whose
    fine run, the ladder's dearest, was made for nothing: on the softened
    point mass map of ``tests/test_step_agreement.py`` (26 orbits) the
    ladder's force evaluations halve (6 runs to 5), and on the held-out
    maps of ``studies/switch_check.py`` (two centres, the rotating point
    mass, the halo with a central mass; 40 orbits, t = 500) the defaults
    made one pilot run fewer, every choice and map bitwise the same. On
    the three-body race map nothing changes (the same 7 runs).

    :class:`ConstantLadder` gives a floor (its rates double with each
    halving of τ); the logarithmic Hamiltonian's descent
    (:func:`varint.time_transform_step.agreeing_h`) does not: its steps in
    fictitious time double, but at a coarse h the orbit, and with it
    ∫U dt, is another, and its rate grew by as little as 1.11 from h₀ to
    h₀/2 on eccentric orbits of a softened point mass (every orbit run to
    the end at both; 1.69 on the three-body map of ``studies/map_steps.py``).

    Returns
    -------
    tried : list
        [step, agreeing share (None where the energy errors alone failed
        the rung), energy error quantile] per step judged.
    chosen : tuple or None
        (j, orbits agreeing, the largest finite energy error at step(j)),
        None when no step passed.
    """
    def stops(rate):
        return stop_above(rate) if callable(stop_above) else rate > stop_above

    tried: list = []
    for j in levels:
        bound = None if floor is None else floor(j)
        if bound is not None and stops(bound):
            break
        coarse, errors, rate = run(j)
        if stops(rate):
            break
        errors = errors() if callable(errors) else errors
        worst = float(np.quantile(errors, quantile, method="higher"))
        if not worst <= ceiling:
            tried.append([step(j), None, worst])
            continue
        agreed = agree(coarse, run(j + 1)[0], t_pilot, t_end)
        ok, worst = passes(agreed, errors, quantile, ceiling, worst)
        tried.append([step(j), float(np.mean(agreed)), worst])
        if ok:
            largest = float(np.max(errors[np.isfinite(errors)], initial=0.0))
            return tried, (j, int(agreed.sum()), largest)
    return tried, None


def agreeing_tau(model, X, t_end, *, scheme, seed, k, renorm, accumulator, value,
                 quantile, ceiling, stop_above=math.inf, agree=agreeing):
    """The largest constant step τ_j = τ₀·2^−j (τ₀ the largest step up to
    :data:`~varint.stepsize.TAU_MAX` that divides ``t_end``, j <
    :data:`LEVELS`) at which the map's FLI of the pilot orbits agrees with
    that at τ_j/2 and the energy errors are within ``ceiling``
    (:func:`passes`), searched downwards. "Agrees" is ``agree``: the value
    rule :func:`agreeing`, the verdict rule :func:`same_verdict`, or
    :func:`map_verdict` (the rule by which the defaults of
    :func:`varint.chaos_map` judge both steppers they price against each
    other).

    ``value`` reads the map's value from a pilot's rows
    (:func:`varint.stepsize_orbits.indicator_judge`); ``k``, ``renorm``,
    ``accumulator`` and ``seed`` are the map's, so the pilot carries its
    vectors and stepper. The search gives up (``rule`` "none") once the
    force evaluations per orbit and unit of time at τ_j exceed
    ``stop_above`` (a competitor is cheaper than any step left), or at the
    bottom of the ladder. :class:`ConstantLadder` runs the same search in
    parts (:meth:`~ConstantLadder.advance`), interleaved with a competitor's.

    Returns
    -------
    tau : float or None
    choice : dict
        ``rule`` ("indicator", or "none"), ``tau``, ``pilot_t``,
        ``orbits``, ``agreement`` (the name of ``agree``), ``tried`` ([τ,
        agreeing share, energy error quantile] per step judged; the share
        None where the energy errors alone failed it, :func:`descend`),
        ``energy_error`` (the largest pilot orbit's at τ),
        ``gradient_rate`` (force evaluations per orbit and unit of time at
        τ, or at the last step tried), ``counts`` and ``summary``.
    """
    ladder = ConstantLadder(model, X, t_end, scheme=scheme, seed=seed, k=k, renorm=renorm,
                            accumulator=accumulator, value=value, quantile=quantile,
                            ceiling=ceiling, agree=agree)
    ladder.advance(stop_above)
    return ladder.result()


class ConstantLadder:
    """The search of :func:`agreeing_tau` (same arguments but
    ``stop_above``), run in parts so that a competitor's pilot can be
    interleaved with it by price: :meth:`advance` descends its rungs while
    their force evaluations per orbit and unit of time stay within a
    limit, and a later call with a higher limit resumes where it stopped
    (every pilot run is memoised). Descending once to ``stop_above`` and
    descending to lower limits first ends on the same rung, with the same
    runs, as long as the rates grow down the ladder (they double with each
    halving of τ; an orbit that stops early only lowers them). The defaults
    of :func:`varint.chaos_map` run it under the logarithmic Hamiltonian's
    descent (:func:`varint.time_transform_step.agreeing_h`, whose
    ``stop_above`` is :meth:`cheaper_than`): each LH rung is run only once
    every constant step that costs less has been judged, so a constant step
    that wins stops the LH's pilot before its finer, dearer rungs."""

    def __init__(self, model, X, t_end, *, scheme, seed, k, renorm, accumulator, value,
                 quantile, ceiling, agree=agreeing):
        pick = pilot_sample(X, seed)
        self._sample = X[pick]
        #: The pilot orbits' vectors (M, 2N, k), each orbit's own
        #: (``default_rng([seed, m])``), and their :class:`~varint.accuracy.Reference`:
        #: a competitor's pilot of the same orbits may share them.
        self.W0 = pilot_vectors(model.dim, k, pick, seed)
        self.reference = Reference(model, self._sample)
        self._t_pilot = float(min(t_end, PILOT_T))
        self._model, self._t_end = model, t_end
        self._scheme = default_scheme(model, scheme)
        self._top = dividing_step(t_end, min(TAU_MAX, t_end))
        self._vectors = (self.W0, renorm, accumulator, False)
        # The rungs' propagators differ in τ alone: the class is chosen once.
        self._build = PilotPropagators(model, renorm, accumulator, self._scheme)
        self._value, self._quantile, self._ceiling, self._agree = value, quantile, ceiling, agree
        self.counts: dict = {}
        self._runs: dict = {}
        self._tried: list = []
        self._next = 0
        self._chosen = None

    def _step(self, j):
        return self._top * 2.0**-j

    def _run(self, j):
        if j not in self._runs:
            before = self.counts.get("gradient", 0)
            errors, values = pilot_errors(self._model, self._sample, self._step(j),
                                          self._t_pilot, self._scheme, self.reference,
                                          self.counts, self._vectors, value=self._value,
                                          build=self._build, lazy=True)
            self._runs[j] = (values, errors, (self.counts.get("gradient", 0) - before)
                             / (len(self._sample) * self._t_pilot))
        return self._runs[j]

    def _floor(self, j):
        """A lower bound of run j's force evaluations per orbit and unit of
        time before it is made (:func:`descend`): run j − 1's times the
        ratio of their steps to the pilot's end (about 2: each orbit's
        evaluations are its steps times the scheme's stages), where every
        pilot orbit reached the pilot's end at step(j − 1) (an orbit that
        then stopped early at step(j), escaping where the coarser step
        did not, would make it too high: not seen). None where run j is
        made or run j − 1 is not, or an orbit stopped early in it."""
        if j in self._runs or j - 1 not in self._runs \
                or not np.isfinite(self._runs[j - 1][0]).all():
            return None
        return float(self._runs[j - 1][2]) * self._steps(j) / self._steps(j - 1)

    def _steps(self, j):
        """The steps of a pilot run at step(j) to the pilot's end, as
        :func:`~varint.stepsize.pilot_errors` counts them."""
        return max(1, int(round(self._t_pilot / self._step(j))))

    def advance(self, stop_above):
        """Descend from the first rung not judged yet until one passes, the
        ladder ends, or a rung's force evaluations per orbit and unit of
        time exceed ``stop_above`` (:func:`descend`)."""
        if self._chosen is not None or self._next >= LEVELS:
            return
        tried, self._chosen = descend(self._run, range(self._next, LEVELS), self._step,
                                      self._t_pilot, self._t_end, self._quantile,
                                      self._ceiling, stop_above, agree=self._agree,
                                      floor=self._floor)
        self._tried += tried
        self._next += len(tried)

    @property
    def rate(self):
        """The force evaluations per orbit and unit of time at the step
        chosen so far (None while none passed)."""
        return None if self._chosen is None else float(self._runs[self._chosen[0]][2])

    def cheaper_than(self, rate, scale=1.0, margin=1.0):
        """Whether a step passed whose price is below a competitor's
        ``rate`` (force evaluations per orbit and unit of time) times
        ``scale`` (the price of the competitor's force evaluation in units of
        this stepper's) times ``margin`` (what the competitor's rung still
        has to run besides its map, e.g. its pilot run), once every rung
        priced below ``rate * scale`` has been judged: the ``stop_above`` of
        the competitor's descent."""
        limit = rate * scale
        self.advance(limit)
        return self.rate is not None and self.rate < limit * margin

    def result(self):
        """``(tau, choice)`` as :func:`agreeing_tau` returns them, of the
        rungs judged so far."""
        choice = {"pilot_t": self._t_pilot, "orbits": len(self._sample),
                  "quantile": float(self._quantile), "ceiling": float(self._ceiling),
                  "agreement": self._agree.__name__, "agreement_dex": AGREEMENT_DEX,
                  "scheme": self._scheme.name, "tried": list(self._tried),
                  "counts": {key: int(v) for key, v in self.counts.items()}}
        if self._chosen is None:
            last = max(self._runs)
            choice.update(rule="none", tau=None, gradient_rate=float(self._runs[last][2]),
                          summary="the FLI of the pilot orbits did not agree between tau and "
                                  "tau/2 at any step tried")
            return None, choice
        j, n_agree, largest = self._chosen
        tau = self._step(j)
        choice.update(rule="indicator", tau=tau, energy_error=largest,
                      gradient_rate=float(self._runs[j][2]),
                      summary=summary(n_agree, len(self._sample), largest, "tau"))
        return tau, choice

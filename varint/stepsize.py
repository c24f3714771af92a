"""The step when none is given: the largest step of the scheme whose error
in the conserved quantities over a short pilot run stays within a
tolerance — as an adaptive integrator's ``rtol`` chooses its steps, but once,
before the run, so the run itself keeps the fixed step a symplectic scheme
needs.

The pilot integrates the run's own initial states — a sample of them for a
batch or a map — with the run's deviation vectors (so that it runs the
compiled stepper the run will) to ``t = min(t_end, 100)``, a few percent of
a long run's work, and measures the largest relative energy error
(:mod:`varint.accuracy`) at 50 times along it. The steps tried are
τ = c·2^(j/4), j = 0, −1, …, from the largest down, where c = min(1, t_end,
the first output time), so that a requested first output time is a whole
step. A step that misses
the tolerance predicts the next from the scheme's order p (error ∝ τ^p),
and the search then climbs back one rung at a time, so it ends on the
largest rung that met the tolerance with a failing rung just above it
(typically three to five pilots). The step is then lowered to divide t_end
into whole steps.

The energy error is all the pilot bounds. That is enough for the
exponents of chaotic orbits too, where a higher-order scheme takes steps
of the order of the motion's time scale: over 128 states along the chaotic
orbit C1, the mean X1(t = 1e4) at the automatic steps of SBAB2C (τ = 0.125),
ABA864 (0.42), SRKN14a (1.0) and s11odr6 (0.5) lies within 0.2–2.0
combined standard errors (≤ 5 %) of ABA864's at τ = 0.02
(``studies/default_step.py``, "chaotic sea"; an earlier warning here, from
64 copies of C1 perturbed by 1e-9, compared what is nearly one sample: such
copies share one trajectory for the first ~400 time units).

A run with compensated summation (``compensated=True`` of the TM method)
pilots with it: near round-off the energy error depends on it (R1, SRKN14a,
t = 100: ~2e-14 plain at the steps a pilot tolerance of 1e-15 leads to,
~5e-16 compensated; ``tests/test_compensated.py``).

When the error does not shrink with the step (the orbit runs into a
singularity of V, or escapes), no step helps: the run falls back to
τ = 0.05 and an :class:`~varint.accuracy.AccuracyWarning` says so; the run's
own failure or accuracy verdict then reports what happened.

The tolerance is the run's ``energy_tol`` divided by :data:`PILOT_MARGIN`
(100): over t = 1e4 the energy errors of SBAB2C, ABA864 and s11odr6 on the
paper's orbits exceeded their pilot's by at most a factor 12
(``studies/energy_tolerance.py``), so a run whose pilot meets
``energy_tol / 100`` stays below ``energy_tol``. On the paper's five orbits
(t_end = 1e4, default tolerance) this chooses τ = 0.125 for SBAB2C on R1,
C1, C2 and R3 and τ = 0.105 on R2, at 0.41–0.49 times the force evaluations
of τ = 0.05 with the pilot (3–4 pilot runs, 3300–6200 gradients) included
(``studies/default_step.py``, ``tests/test_stepsize.py``).
"""

from __future__ import annotations

import dataclasses
import functools
import math
import threading
import warnings
import weakref

import numpy as np

from . import _validate as check
from .accuracy import AccuracyWarning, Reference, user_stacklevel
from .methods import METHODS, make_propagator, propagator_class
from .methods.tm import TangentMapPropagator
from .protocol import STATUS_OK, TIME_MOMENTUM, Renorm, Status
from .schemes import default_for, get_scheme
from .state import Rows, RunState, initial_deviations

__all__ = ["choose_step", "default_scheme", "dividing_step", "pilot_errors", "pilots", "check_options",
           "StepChoice", "PilotPropagators", "PILOT_MARGIN", "PILOT_T", "FALLBACK_TAU"]

#: The pilot's tolerance is the run's energy_tol divided by this (see the
#: module docstring for the measurements).
PILOT_MARGIN = 100.0
#: Pilot horizon (time units), shortened to t_end.
PILOT_T = 100.0
#: The search gives up on steps for which the pilot would take more steps
#: than this (τ < 1e-4 for the full pilot horizon).
PILOT_STEPS = 1_000_000
#: Times along the pilot at which the error is measured.
PILOT_CHECKS = 50
#: Most orbits a pilot integrates (a sample of a larger batch).
PILOT_ORBITS = 16
#: Rungs per factor 2 of the ladder τ = cap·2^(j/RUNGS), j ≤ 0, and the
#: largest step.
RUNGS = 4
TAU_MAX = 1.0
#: The step when no step meets the tolerance, or for methods whose τ is not
#: a step (adaptive integrators: τ is their renormalisation interval).
FALLBACK_TAU = 0.05
#: The TM method's step, bound when varint is imported. The pilot is not
#: part of the run: code that wraps the propagator's ``advance`` to act on a
#: run's chunks (fault injection, counting a run's work) sees the run's
#: chunks only, before and after the pilot alike.
_advance = TangentMapPropagator.advance


class Bracket:
    """The rungs of a step ladder tried so far (τ or h ∝ 2^(j/RUNGS)): the
    largest that met the tolerance, ``best``, and the smallest that did
    not, ``lowest_fail`` (None until one has). The pilots of
    :func:`choose_tau` and :func:`varint.time_transform_step.choose_h`
    climb and descend it differently but stop by the same rule
    (:meth:`settled`)."""

    def __init__(self):
        self.best = None
        self.lowest_fail = None

    def note(self, j, met):
        """Record that rung ``j`` met the tolerance (``met``) or not."""
        if met:
            self.best = j if self.best is None else max(self.best, j)
        else:
            self.lowest_fail = j if self.lowest_fail is None else min(self.lowest_fail, j)

    def settled(self, top):
        """Whether the largest rung that meets the tolerance is found: the
        ``top`` rung met it, or the rung above the best failed."""
        return self.best is not None and (self.best == top or self.best + 1 == self.lowest_fail)


class StepChoice(dict):
    """How the step was chosen (a dict, stored in the provenance as
    ``tau_choice``): ``rule`` ("pilot", "fallback", "fixed", or "orbit"
    for a map's steps per orbit, :mod:`varint.stepsize_orbits`), ``tau``,
    and for a pilot its ``scheme``, ``tolerance``, ``pilot_t``, ``orbits``,
    the ``tried`` steps with their errors and its ``counts`` (all of it
    deterministic: the same call chooses the same step, bit for bit)."""


def pilots(method):
    """Whether ``method``'s τ is the step of a splitting scheme, which a
    pilot chooses when τ is not given."""
    return "scheme" in getattr(propagator_class(method), "OPTIONS", ())


def default_scheme(model, scheme, method="tm"):
    """The scheme ``method`` runs ``model`` with: the given one, or its
    default (:func:`varint.schemes.default_for`: a lattice's own for "tm")."""
    parts = getattr(model, "parts", None)
    if parts is not None and parts.schemes is not None:
        return parts.resolve(scheme, model.name)
    return get_scheme(default_for(model, method) if scheme is None else scheme,
                      processed=method == "tm")


def check_options(method, options):
    """Refuse options ``method`` does not take before its pilot runs (a
    misspelt option must not wait for it), naming the methods that take
    them; otherwise the propagator checks them when it is built."""
    valid = tuple(propagator_class(method).OPTIONS)
    if set(options) <= set(valid):
        return
    others = {name: tuple(propagator_class(name).OPTIONS) for name in METHODS}
    check.method_options(method, options, valid, others)


def choose_step(model, X, t_end, tolerance, *, method="tm", scheme=None, cap=None,
                quantile=1.0, seed=0, W0=None, k=None, renorm="none", accumulator=None,
                compensated=False):
    """The largest step whose pilot meets ``tolerance`` (see the module
    docstring).

    Parameters
    ----------
    model : Model
    X : ndarray, shape (M, 2N)
        Initial states (checked); a sample of at most :data:`PILOT_ORBITS`
        of them runs the pilot.
    t_end : float
    tolerance : float
        Largest relative error of the conserved quantities over the pilot.
    method : str
        For methods without a splitting scheme the step is
        :data:`FALLBACK_TAU` and no pilot is run.
    scheme : str or SplittingScheme, optional
        The method's scheme (its default when None).
    cap : float, optional
        Largest acceptable step (e.g. the first requested output time).
    quantile : float
        Which quantile of the orbits' errors must meet the tolerance (1: all
        of them; a map takes 0.9, so a few orbits that escape or graze a
        singularity do not set the step of all).
    seed : int
        Seed of the sample of orbits.
    W0 : ndarray, shape (M, 2N, k), optional
        The run's initial deviation vectors, and its ``renorm`` and
        ``accumulator``: the pilot carries them too (their work is small
        over a pilot) so that it runs the very compiled stepper the run
        will, instead of compiling another.
    k : int, optional
        Instead of ``W0``: the number of vectors, drawn at random for the
        pilot's orbits.
    compensated : bool
        The run's compensated summation (TM), which the pilot uses too:
        near round-off the energy error it measures depends on it.

    Returns
    -------
    tau : float
    choice : StepChoice
    """
    cap = min(TAU_MAX, t_end, cap if cap is not None else math.inf)
    if not pilots(method):
        tau = dividing_step(t_end, min(FALLBACK_TAU, cap))
        return tau, StepChoice(rule="fixed", tau=tau, note=(
            f"{method}'s tau is its renormalisation interval, not its step; its accuracy is "
            "set by its tolerances"))
    sch = default_scheme(model, scheme, method)
    pick = np.arange(len(X))
    if len(X) > PILOT_ORBITS:
        pick = np.sort(np.random.default_rng(seed).choice(len(X), PILOT_ORBITS, replace=False))
    X = X[pick]
    if W0 is not None:
        W0 = W0[pick]
    else:
        W0 = initial_deviations(model.dim, k or 0, len(X), seed, pick)
    setup = (W0, renorm, accumulator, compensated)
    reference = Reference(model, X)
    tried, counts = {}, {}
    # The rungs' propagators differ in τ alone: the class is chosen once.
    build = PilotPropagators(model, renorm, accumulator, sch, compensated)

    def error(j):
        if j not in tried:
            tried[j] = _pilot(model, X, rung(j), t_end, sch, reference, quantile,
                              counts, setup, build)
        return tried[j]

    def rung(j):
        return cap * 2.0 ** (j / RUNGS)

    top = 0
    j, tried_rungs, stuck = top, Bracket(), False
    while True:
        e = error(j)
        tried_rungs.note(j, e <= tolerance)
        if tried_rungs.settled(top):
            break
        if tried_rungs.best is not None:
            j = tried_rungs.best + 1
            continue
        # No step met it yet: predict from the order, at least one rung down.
        drop = (RUNGS * math.log2(e / tolerance) / sch.order if math.isfinite(e) and e > 0
                else RUNGS * 4)
        nxt = j - max(1, math.ceil(drop))
        stuck = (_not_shrinking(tried, j)
                 or min(t_end, PILOT_T) / rung(nxt) > PILOT_STEPS)
        if stuck:
            break
        j = nxt
    info = StepChoice(scheme=sch.name, tolerance=float(tolerance),
                      pilot_t=float(min(t_end, PILOT_T)), orbits=len(X), quantile=quantile,
                      tried=[[rung(k), float(v)] for k, v in sorted(tried.items())],
                      counts=counts)
    best = tried_rungs.best
    if best is None:
        tau = dividing_step(t_end, min(FALLBACK_TAU, cap))
        smallest = min(tried)
        warnings.warn(
            f"no step of {sch.name} keeps the relative energy error of a pilot run (to t = "
            f"{info['pilot_t']:g}) within {tolerance:g}: it is still {tried[smallest]:.3g} at "
            f"tau = {rung(smallest):.3g} and does not shrink with the step, so the "
            "orbit probably runs into a singularity of the potential or escapes; running with "
            f"tau = {tau:g} (pass tau= to choose the step yourself)", AccuracyWarning,
            stacklevel=user_stacklevel())
        info.update(rule="fallback", tau=tau)
        return tau, info
    tau = dividing_step(t_end, rung(best))
    info.update(rule="pilot", tau=tau)
    return tau, info


def _not_shrinking(tried, j):
    """Whether halving the step (or more) has not halved the error: the
    error is not the scheme's truncation error."""
    e = tried[j]
    return any(k >= j + RUNGS and not (e <= v / 2) for k, v in tried.items())


def dividing_step(t_end, tau):
    """The largest step ≤ tau that divides t_end into whole steps."""
    return t_end / math.ceil(t_end / tau * (1 - 1e-12))


def _pilot_by_checks(prop, advance, state, checks):
    """The orbits' states at the ``checks`` steps, advancing to each in
    turn (propagators that take no snapshots): ``(x, taken, p_t)`` with
    ``x`` (C, M, 2N) the states at the C checks reached (C < len(checks)
    when every orbit stopped before the end), ``taken`` (C, M) whether the
    orbit was still running there, and ``p_t`` (C, M) its momentum
    conjugate to time (None without one). Filled in place, one row per
    check: what the errors need of each check, without a list of arrays
    and a concatenation per check (the per-check lists and array
    operations took about as long as the part stepper's ``advance``
    between two checks of a short orbit, profiled on the bar orbit)."""
    m = state.n_orbits
    x = np.empty((len(checks), m, state.x.shape[1]))
    taken = np.zeros((len(checks), m), dtype=bool)
    p_t = None
    reached = 0
    for s in checks:
        advance(prop, state, int(s - state.step))
        ok = state.status == STATUS_OK
        x[reached] = state.x
        taken[reached] = ok
        momentum = state.extra.get(TIME_MOMENTUM)
        if momentum is not None:
            if p_t is None:
                # Zero before the run made it (the reference's default).
                p_t = np.zeros((len(checks), m))
            p_t[reached] = momentum
        reached += 1
        if not ok.any():
            break
    return x[:reached], taken[:reached], None if p_t is None else p_t[:reached]


def _worst(reference, x, taken, t, p_t, status):
    """Per orbit, the largest relative error of the conserved quantities
    over the checks where it was ``taken`` (states ``x`` (C, M, 2N) at
    times ``t`` (C,), time momenta ``p_t`` (C, M) or None); inf for an
    orbit whose final ``status`` is a failure other than an escape (an
    escaped orbit counts up to its escape) or whose error is not finite.
    The errors are row by row, so measuring every check in one
    ``Reference.errors`` call gives the numbers of a call per check
    without its fixed cost."""
    c, m = taken.shape
    with np.errstate(all="ignore"):
        errs = reference.errors(x.reshape(c * m, -1), np.repeat(t, m),
                                0.0 if p_t is None else p_t.reshape(-1))
        e = np.max(np.stack(list(errs.values())), axis=0).reshape(c, m)
        worst = np.max(np.where(taken, np.where(np.isfinite(e), e, np.inf), 0.0), axis=0)
    worst[(status > STATUS_OK) & (status != Status.ESCAPED)] = np.inf
    return worst


def _pilot(model, X, tau, t_end, scheme, reference, quantile, counts, setup, build):
    """The ``quantile`` over orbits of the largest relative error of the
    conserved quantities along a pilot with step ``tau`` (inf if an orbit
    became non-finite; an escaped orbit counts up to its escape)."""
    worst = pilot_errors(model, X, tau, min(t_end, PILOT_T), scheme, reference, counts, setup,
                         build=build)
    return float(np.quantile(worst, quantile, method="higher"))


def pilot_errors(model, X, tau, t_pilot, scheme, reference, counts, setup, value=None,
                 build=None, lazy=False):
    """Per orbit, the largest relative error of the conserved quantities
    at :data:`PILOT_CHECKS` times along a pilot with step ``tau`` to
    ``t_pilot`` (inf if the orbit became non-finite; an escaped orbit counts
    up to its escape). Each orbit is integrated on its own, so its error
    does not depend on the other orbits of ``X``. ``counts`` accumulates the
    pilot's work; ``setup`` is ``(W0, renorm, accumulator, compensated)`` (see
    :func:`choose_step`).

    With ``value`` (``value(rows, t) -> ndarray (M,)``, e.g. a map's
    indicator value from a :class:`~varint.state.Rows`) it returns
    ``(errors, values)``: also each orbit's ``value`` at the pilot's end
    (NaN for an orbit that stopped before it), read as a run reads its
    outputs.

    ``build`` (``build(tau) -> propagator``, :class:`PilotPropagators`)
    builds the propagator; by default :func:`~varint.methods.make_propagator`.
    With ``lazy`` the errors are a function that computes them on its
    first call and returns the same array after (a ladder's rule reads a
    run's energy errors only where it judges that run as a rung's coarse
    run: :func:`varint.step_agreement.descend`); the same numbers either
    way.

    The states at the checks come from one compiled call where the
    propagator copies them there (the generated TM stepper's snapshots;
    the part stepper's ``advance_checks``, where ``takes_checks()``), else
    from an ``advance`` to each check in turn: the same bits (rule 3 of
    the propagator protocol, ``tests/test_parts_checks.py``)."""
    W0, renorm, accumulator, compensated = setup
    n = max(1, int(round(t_pilot / tau)))
    # A copy: numba compiles a kernel again for a read-only array.
    checks = _checks(n).copy()
    if build is None:
        build = PilotPropagators(model, renorm, accumulator, scheme, compensated)
    prop = build(tau)
    advance = _advance if type(prop) is TangentMapPropagator else type(prop).advance
    state = RunState.start(X, W0)
    if accumulator is not None:
        state.extra[accumulator.key] = np.tile(np.array(accumulator.initial, dtype=np.float64),
                                               (len(X), W0.shape[2], 1))
    if advance is _advance and prop.takes_snapshots(state):
        # One compiled call copies the state at every check.
        snaps = advance(prop, state, n, checks)

        def measure():
            # A check after an orbit stopped has no copy (NaN).
            return _worst(reference, snaps.x, np.isfinite(snaps.x).all(axis=2), checks * tau,
                          None, state.status)

        # The copy at the last check (the pilot's end), as a run reads it.
        rows = dataclasses.replace(snaps, steps=snaps.steps[-1:], x=snaps.x[-1:],
                                   W=snaps.W[-1:], acc_m=snaps.acc_m[-1:],
                                   acc_e=snaps.acc_e[-1:],
                                   extra={key: v[-1:] for key, v in snaps.extra.items()}
                                   ).rows(Renorm.parse(renorm)) if value is not None else None
    else:
        if getattr(prop, "takes_checks", bool)():
            # One compiled call copies the orbits at every check (the part
            # stepper: the same kernel as the run's).
            x, p_t = prop.advance_checks(state, checks)
            taken = np.isfinite(x).all(axis=2)
        else:
            x, taken, p_t = _pilot_by_checks(prop, advance, state, checks)
        worst = _worst(reference, x, taken, checks[:len(x)] * tau, p_t, state.status)
        rows = state.renormalized(renorm) if getattr(prop, "sparse", 0) else Rows.of(state)

        def measure():
            return worst
    for key, number in state.counts.items():
        counts[key] = counts.get(key, 0) + int(number)
    errors = functools.cache(measure) if lazy else measure()
    if value is None:
        return errors
    with np.errstate(all="ignore"):
        values = np.asarray(value(rows, rows.step * tau), dtype=float)
    # An orbit that stopped before the end has no value there.
    values[(state.status != STATUS_OK) | (rows.step != n)] = np.nan
    return errors, values


@functools.lru_cache(maxsize=64)
def _checks(n):
    """The steps of a pilot of ``n`` steps at which its errors are
    measured: :data:`PILOT_CHECKS` nearly equally spaced, the last one
    ``n`` (worked out once per ``n``: a ladder's rungs repeat from map to
    map; read-only, as it is shared: callers copy it)."""
    checks = np.unique(np.round(np.linspace(0, n, PILOT_CHECKS + 1)).astype(np.int64))[1:]
    checks.flags.writeable = False
    return checks


class PilotPropagators:
    """The propagators of a pilot's rungs, one per step τ, for one model,
    scheme, ``renorm``, ``accumulator`` and ``compensated``:
    :func:`~varint.methods.make_propagator` for the first, which chooses
    the class (a lattice's "tm" is its part stepper, and the checks of that
    choice ask the model's symbolic form, ~0.3 ms a call on the CR3BP); the
    same class with the same arguments but τ for the others, as
    ``make_propagator`` would build them: its choice does not depend on τ.
    A propagator holds no state of a run, so each one's runs are those of a
    fresh one (``tests/test_step_agreement.py``), and a propagator built
    once serves every later pilot of the same model and settings at its τ
    (:func:`_kept_propagators`: a map's ladders repeat their rungs from map
    to map; each new one would look up its stepper again)."""

    def __init__(self, model, renorm, accumulator, scheme, compensated=False):
        self._model, self._accumulator = model, accumulator
        self._renorm = Renorm.parse(renorm)
        # As given: the propagator checks the value.
        self._options = {"scheme": scheme,
                         **({} if compensated is False else {"compensated": compensated})}
        self._kept = _kept_propagators(model, (self._renorm, accumulator, scheme, compensated))

    def __call__(self, tau):
        kept = self._kept
        prop = kept.get(tau)
        if prop is not None:
            return prop
        # (Locked: maps run in threads share these dicts.)
        with _KEPT_LOCK:
            cls = kept.get(_CLASS)
            if cls is None:
                prop = make_propagator("tm", self._model, tau, self._renorm, self._accumulator,
                                       **self._options)
                kept[_CLASS] = type(prop)
            else:
                prop = cls(self._model, tau, self._renorm, accumulator=self._accumulator,
                           **self._options)
            if len(kept) > _KEPT_STEPS:
                del kept[next(k for k in kept if k != _CLASS)]   # the oldest step
            kept[float(tau)] = prop
        return prop


#: The key of the propagators' class among the steps of :func:`_kept_propagators`.
_CLASS = "class"

#: Most propagators kept per model and settings (a ladder has
#: :data:`varint.step_agreement.LEVELS` + 1 steps; maps of other lengths
#: start other ladders).
_KEPT_STEPS = 32

#: The pilots' propagators per model (:func:`_kept_propagators`): beside
#: the model, not in it (a model must stay picklable, Dask).
_PILOT_PROPAGATORS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
_KEPT_LOCK = threading.Lock()


def _kept_propagators(model, settings):
    """The propagators built for ``model`` with ``settings`` (renorm,
    accumulator, scheme, compensated), by step τ, and their class (key
    :data:`_CLASS`): a dict shared by every :class:`PilotPropagators` of
    the same model in the same state. Keyed as the generated steppers
    (:func:`varint.methods.tm._generated_stepper`), by what the propagator
    reads of the model besides its form: its parameters, masses, escape
    radius and time dependence, so a model changed in place gets new ones.
    A fresh dict (nothing shared) where the model or the settings cannot
    be keyed."""
    try:
        key = (settings, np.asarray(model.params, dtype=float).tobytes(),
               np.asarray(model.inverse_mass, dtype=float).tobytes(), model.escape_radius,
               bool(model.time_dependent))
        with _KEPT_LOCK:
            return _PILOT_PROPAGATORS.setdefault(model, {}).setdefault(key, {})
    except (TypeError, AttributeError):
        # A model without these attributes or weak references, settings
        # that cannot be hashed.
        return {}

"""The rules by which every study judges a claim: one rule per kind of
claim, each with its tolerance as a named constant.

The paper states its results in a few recurring forms, and each has one
rule here, applied wherever that form occurs (Table I, Figs. 2–11, and
varint's own checks):

=====================  ==================================================
rule                   the paper's wording
=====================  ==================================================
:func:`agrees`         "X1 ≈ 2.3e-5 at t = 1e8" (a number)
:func:`in_band`        "relative energy error 2e-8" (one sample of an
                       oscillating error)
:func:`at_most`        "|X1+X4| ≲ 1e-7", "|X2| < 1e-5"
:func:`above`          "levels off above TM's", "TDHeps is the best"
:func:`power_law`      "G3 ∝ t⁻²", "X1 grows like τ²"
:func:`rate_law`       "GALI_k ∝ exp(−[(σ1−σ2)+…]t)" (eq. 14)
:func:`levels_off`     "X1 levels off", "tends to a constant"
:func:`inverse_t`      "X1 ∝ 1/t", "the pair sums tend to zero"
:func:`departure`      "follows the law up to t ≈ 1e4, then falls"
:func:`same_time`      "t ≈ 1e4" (a time read off a log-log plot)
:func:`costs_more`,    "needs more CPU time", "does not depend on δ"
:func:`same_cost`
:func:`same_law`       "X1 ≈ 4.5e-2" of a chaotic orbit: the sample of
                       finite-time values of nearby orbits against the
                       reference's sample (a two-sample test)
:func:`dominates`      "as fast and as accurate as" (a baseline against
                       its library driven directly)
=====================  ==================================================

Each rule returns a :class:`Judgement`: the verdict, the measured value,
the window of times it was measured over and the tolerance, so that every
claim records how it was judged (``Claims.add(..., rules=[...])``).
The measurements themselves (slopes, departure series) are in
:mod:`studies.laws`; nothing here integrates anything.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from varint.departure import departure_time

from studies.laws import decade_slopes, slope

__all__ = ["Judgement", "verdict", "EDGE", "RATIO_FACTOR", "ABOVE_FACTOR", "SLOPE_TOLERANCE",
           "LATE_DECADES", "DEPARTURE_FACTOR", "PLOT_FACTOR", "COST_NOISE", "late_window",
           "agrees", "in_band", "at_most", "above", "power_law", "power_tolerance",
           "power_law_decades", "rate_law", "levels_off", "inverse_t", "grows", "departure",
           "same_time", "costs_more", "same_cost", "exponent_law", "EXPONENT_TOLERANCE",
           "EXPONENT_UNRESOLVED", "ACCURACY_NOISE", "ROUNDOFF_ERROR", "dominates",
           "SAME_LAW_ALPHA", "same_law", "in_sample", "pareto", "cost_at", "as_cheap_at_equal_error",
           "RULES"]

#: Numbers agree within this factor. The paper's numbers come from single
#: runs of finite-time indicators from one random set of deviation vectors
#: (ours from another), most are read to one significant figure, and the
#: levels of the TDH methods are near-cancellations of two errors
#: (studies/tdheps_variants.py); a factor of 3 is half a decade on the
#: paper's log-log plots, the resolution at which those plots are read.
RATIO_FACTOR = 3.0
#: "A above B" needs A > ABOVE_FACTOR × B. Two numbers within RATIO_FACTOR
#: of each other count as the same number, so "above" has to mean more
#: than that, or one pair could be both equal and above.
ABOVE_FACTOR = RATIO_FACTOR
#: A fitted log-log slope s follows the law t^p when
#: |s − p| ≤ SLOPE_TOLERANCE × max(2, |p|): ±0.3 for the powers 0, −1, −2
#: and 15 % of the steeper GALI powers (t⁻⁴ … t⁻¹⁶), whose fitted slopes
#: scatter in proportion to p over a decade. The band ±0.3 is under a third
#: of the distance between "levels off" (0) and "falls as 1/t" (−1), so no
#: series can pass both; it admits the logarithm of a finite-time exponent
#: of a regular orbit, (ln t + c)/t, whose local slope −1 + 1/(ln t + c)
#: is within it once ln t + c > 3.3.
SLOPE_TOLERANCE = 0.15
#: "Levels off" and "∝ 1/t" are statements about the end of a run: the
#: slope is fitted over its last LATE_DECADES decades. Two decades, because
#: on the paper's plots (6–8 decades of t) a law is a straight line over
#: more than one; one decade would call a shoulder a level.
LATE_DECADES = 2.0
#: A quantity has left its law (or a reference run) once it stays this
#: factor away from it: a decade, the smallest gap that is unambiguous on a
#: log-log plot spanning 10–40 decades of GALI.
DEPARTURE_FACTOR = 10.0
#: Times read off the paper's log-log plots ("t ≈ 1e4") agree with ours
#: within half a decade either way.
PLOT_FACTOR = math.sqrt(10.0)
#: CPU times (``time.process_time()`` on a 2-core machine shared with other
#: jobs) differ when their ratio exceeds 1 + COST_NOISE. The CPU time per
#: step of one method, measured in separate runs at four step sizes,
#: varies by 2 % (TM: 1.10–1.12e-7 s, TDHeps: 1.69–1.72e-7 s per step,
#: Table I runs); 10 % leaves room for the load of the machine.
COST_NOISE = 0.10


@dataclass(frozen=True)
class Judgement:
    """One application of a rule.

    Attributes
    ----------
    rule : str
        The rule's name (a function of this module).
    holds : bool or None
        None when the rule cannot be applied (missing values, too few
        points).
    value : float or None
        What was measured: a ratio, a slope, a level, a time.
    window : tuple of float or None
        First and last time of the data the rule looked at.
    tolerance : str
        The tolerance, as applied.
    text : str
        The measurement in words, for the "ours" column.
    edge : float or None
        How the measured quantity compares with the threshold it is judged
        by, as their ratio (1 on the threshold; a verdict with an edge
        within :data:`EDGE` of 1 sits on its threshold and is reported
        with its margin, :meth:`margin`).
    """

    rule: str
    holds: bool | None
    value: float | None
    window: tuple | None
    tolerance: str
    text: str
    edge: float | None = None

    def record(self):
        """The JSON form stored with a claim."""
        out = {"rule": self.rule, "holds": self.holds, "value": self.value,
               "window": None if self.window is None else [float(w) for w in self.window],
               "tolerance": self.tolerance}
        if self.edge is not None:
            out["edge"] = self.edge
        return out

    def margin(self):
        """"on its threshold (…)" when the verdict would flip with a change
        of the measured quantity by less than :data:`EDGE`, else ""."""
        if self.edge is None or self.holds is None or abs(self.edge - 1) > EDGE:
            return ""
        return (f"{self.rule} sits on its threshold: {self.text} against "
                f"{self.tolerance} (the measured quantity is {self.edge:.3f} of the "
                f"threshold; a {100 * abs(self.edge - 1):.1f} % change would flip it)")


#: A verdict whose measured quantity is within this fraction of its
#: threshold is stated with its margin: 10 %, the noise allowed for CPU
#: times and about the spread of two readings of a log-log plot.
EDGE = 0.10


def verdict(judgements):
    """The verdict of a claim resting on several rules: True when all hold,
    False when any fails, None otherwise (some could not be applied)."""
    found = [j.holds for j in judgements]
    if any(v is False for v in found):
        return False
    return True if found and all(v is True for v in found) else None


def _finite(*values):
    return all(v is not None and np.isfinite(v) for v in values)


def late_window(t, decades=LATE_DECADES):
    """The last ``decades`` decades of the times ``t``: (t_end/10^decades, t_end)."""
    t_end = float(np.asarray(t)[-1])
    return t_end / 10 ** decades, t_end


def agrees(ours, paper, what=""):
    """Rule: a number agrees with the paper's when both have the same sign
    and their ratio is within :data:`RATIO_FACTOR` either way."""
    tol = f"ours/paper within ×{RATIO_FACTOR:g}"
    if not _finite(ours, paper) or paper == 0:
        return Judgement("agrees", None, None, None, tol, f"{what}no value")
    ratio = float(ours) / float(paper)
    holds = bool(ratio > 0 and abs(math.log(ratio)) < math.log(RATIO_FACTOR))
    edge = max(ratio, 1 / ratio) / RATIO_FACTOR if ratio > 0 else None
    return Judgement("agrees", holds, ratio, None, tol,
                     f"{what}{float(ours):.2g} (ours/paper {ratio:.3g})", edge)


def in_band(paper, median, maximum, window=None):
    """Rule: the paper's value of a quantity that oscillates along the orbit
    (the energy error of a symplectic scheme) is one sample of the band
    ours fills; it agrees when it lies within that band, widened by
    :data:`RATIO_FACTOR` (median/3 … 3 × maximum)."""
    tol = f"median/{RATIO_FACTOR:g} … {RATIO_FACTOR:g}×max"
    if not _finite(paper, median, maximum):
        return Judgement("in_band", None, None, window, tol, "no value")
    holds = bool(median / RATIO_FACTOR <= paper <= maximum * RATIO_FACTOR)
    return Judgement("in_band", holds, float(paper), window, tol,
                     f"band {median:.2g}–{maximum:.2g}")


def at_most(ours, bound, what=""):
    """Rule: "ours ≲ bound" (the paper's "≲ 1e-7", "< 1e-5") holds unless
    ours is above the bound by the factor within which two numbers are the
    same (:data:`RATIO_FACTOR`)."""
    tol = f"ours/bound ≤ {RATIO_FACTOR:g}"
    if not _finite(ours, bound) or bound <= 0:
        return Judgement("at_most", None, None, None, tol, f"{what}no value")
    ratio = abs(float(ours)) / float(bound)
    return Judgement("at_most", bool(ratio <= RATIO_FACTOR), ratio, None, tol,
                     f"{what}{abs(float(ours)):.2g}", ratio / RATIO_FACTOR)


def above(a, b, what=""):
    """Rule: ``a`` is above ``b`` when a > :data:`ABOVE_FACTOR` × b (both
    positive); "below" is ``above(b, a)``."""
    tol = f"ratio > {ABOVE_FACTOR:g}"
    if not _finite(a, b) or b <= 0 or a <= 0:
        return Judgement("above", None, None, None, tol, f"{what}no value")
    ratio = float(a) / float(b)
    return Judgement("above", bool(ratio > ABOVE_FACTOR), ratio, None, tol,
                     f"{what}ratio {ratio:.2g}", ratio / ABOVE_FACTOR)


def power_tolerance(power):
    """The slope tolerance of :func:`power_law` for the law t^power."""
    return SLOPE_TOLERANCE * max(2.0, abs(power))


def power_law(t, y, power, window=None, rule="power_law"):
    """Rule: |y| follows t^power over ``window`` (default: the last
    :data:`LATE_DECADES` decades) when its least-squares log-log slope is
    within :func:`power_tolerance` of ``power``."""
    lo, hi = late_window(t) if window is None else window
    s = slope(t, y, lo, hi)
    tol = f"|slope − ({power:g})| ≤ {power_tolerance(power):.2g}"
    if not np.isfinite(s):
        return Judgement(rule, None, None, (lo, hi), tol, "too few points")
    return Judgement(rule, bool(abs(s - power) <= power_tolerance(power)), s, (lo, hi), tol,
                     f"slope {s:.2f} over t = {lo:.0e}–{hi:.0e}")


def power_law_decades(t, y, power, start, until=None):
    """Rule :func:`power_law` applied to each whole decade from ``start``
    until ``until`` (default: the end of the run; e.g. the time a GALI
    reaches its round-off floor): holds when every such decade follows
    t^power. ``value`` is the end of the unbroken run of decades from
    ``start`` that do (None if the first does not)."""
    until = float(np.asarray(t)[-1]) if until is None else until
    slopes = decade_slopes(t, y, start)
    judged = [(lo, hi, s) for lo, hi, s in slopes if hi <= until * (1 + 1e-9)]
    tol = f"|slope − ({power:g})| ≤ {power_tolerance(power):.2g} per decade"
    end = None
    for _, hi, s in judged:
        if not abs(s - power) <= power_tolerance(power):
            break
        end = hi
    holds = all(abs(s - power) <= power_tolerance(power) for _, _, s in judged)
    window = (float(start), judged[-1][1]) if judged else None
    return Judgement("power_law", holds, end, window, tol,
                     ", ".join(f"{s:.2f}" for _, _, s in slopes))


def rate_law(rate, theory, window, what=""):
    """Rule: a fitted exponential rate (GALI_k ∝ e^{−σt}) agrees with the
    rate a law predicts when |σ/σ_law − 1| ≤ :data:`SLOPE_TOLERANCE`: the
    15 % of the steep power laws, relative throughout because a rate has no
    law of zero."""
    tol = f"|rate/law − 1| ≤ {SLOPE_TOLERANCE:g}"
    if not _finite(rate, theory) or theory == 0:
        return Judgement("rate_law", None, None, window, tol, f"{what}no value")
    return Judgement("rate_law", bool(abs(rate / theory - 1) <= SLOPE_TOLERANCE),
                     float(rate), window, tol, f"{what}{rate:.3g} (law {theory:.3g})")


def levels_off(t, y, window=None):
    """Rule: |y| levels off when its log-log slope over ``window`` (default:
    the last :data:`LATE_DECADES` decades) is within ±0.3 of 0
    (:func:`power_law` with power 0). The level is the median of |y| over
    the window, stated with its spread (smallest to largest value)."""
    j = power_law(t, y, 0.0, window, rule="levels_off")
    if j.holds is None:
        return j
    tt, yy = np.asarray(t, dtype=float), np.abs(np.asarray(y, dtype=float))
    use = (tt >= j.window[0]) & (tt <= j.window[1])
    level = float(np.median(yy[use]))
    return Judgement("levels_off", j.holds, j.value, j.window, j.tolerance,
                     f"slope {j.value:.2f} over t = {j.window[0]:.0e}–{j.window[1]:.0e}, level "
                     f"{level:.2g} ({yy[use].min():.2g}–{yy[use].max():.2g})")


def inverse_t(t, y, window=None):
    """Rule: |y| falls as 1/t when its log-log slope over ``window``
    (default: the last :data:`LATE_DECADES` decades) is within ±0.3 of −1
    (:func:`power_law` with power −1)."""
    return power_law(t, y, -1.0, window, rule="inverse_t")


def grows(t, y, window=None):
    """Rule: |y| grows when its log-log slope over ``window`` (default: the
    last :data:`LATE_DECADES` decades) is positive and beyond the band of
    :func:`levels_off`."""
    j = power_law(t, y, 0.0, window, rule="grows")
    if j.holds is None:
        return j
    band = power_tolerance(0.0)
    return Judgement("grows", bool(j.value > band), j.value, j.window, f"slope > {band:.2g}",
                     j.text)


def departure(t, log_excess, what=""):
    """Rule: a quantity has left its law, or a reference run, at the
    earliest time from which it stays more than :data:`DEPARTURE_FACTOR`
    away from it. ``log_excess`` is the natural logarithm of that distance
    at each time (:mod:`studies.laws` computes it for a stretch against a
    reference run, a GALI against a reference or a fitted law). Holds when
    it departs within the run; ``value`` is the time."""
    t = np.asarray(t, dtype=float)
    tol = f"×{DEPARTURE_FACTOR:g} from the law, to the end"
    t_d = departure_time(t, log_excess, math.log(DEPARTURE_FACTOR))
    return Judgement("departure", t_d is not None, t_d, (float(t[0]), float(t[-1])), tol,
                     f"{what}departs at t ≈ {'—' if t_d is None else f'{t_d:.2g}'}")


def same_time(found, paper_t, horizon):
    """Rule: the paper's time ``paper_t`` (read off a log-log plot) agrees
    with ours when it lies within the range of the times ``found`` (one or
    several, e.g. one per GALI order; None where not seen) widened by
    :data:`PLOT_FACTOR` either way. None if nothing was seen and the run's
    ``horizon`` ends before the paper's time could be reached."""
    seen = [float(v) for v in np.atleast_1d(np.array(found, dtype=object)) if v is not None]
    tol = f"within ×{PLOT_FACTOR:.3g}"
    if seen:
        holds = bool(min(seen) / PLOT_FACTOR <= paper_t <= max(seen) * PLOT_FACTOR)
        # The nearer end of the widened range, as the factor by which the
        # paper's time lies from it.
        edge = max(paper_t / (max(seen) * PLOT_FACTOR), min(seen) / PLOT_FACTOR / paper_t)
        return Judgement("same_time", holds, min(seen), None, tol,
                         f"t ≈ {min(seen):.3g}" + (f"–{max(seen):.3g}" if len(seen) > 1 else "")
                         + f" (paper {paper_t:.2g})", edge)
    holds = None if horizon < paper_t * PLOT_FACTOR else False
    return Judgement("same_time", holds, None, None, tol, f"not seen to t = {horizon:.0e}")


def costs_more(a, b, what=""):
    """Rule: CPU time ``a`` exceeds ``b`` when a/b > 1 + :data:`COST_NOISE`."""
    ratio = float(a) / float(b)
    return Judgement("costs_more", bool(ratio > 1 + COST_NOISE), ratio, None,
                     f"ratio > {1 + COST_NOISE:g}", f"{what}{ratio:.3g}×",
                     (1 + COST_NOISE) / ratio)


def same_cost(a, b, what=""):
    """Rule: CPU times ``a`` and ``b`` are the same when |a/b − 1| ≤
    :data:`COST_NOISE`."""
    ratio = float(a) / float(b)
    return Judgement("same_cost", bool(abs(ratio - 1) <= COST_NOISE), ratio, None,
                     f"|ratio − 1| ≤ {COST_NOISE:g}", f"{what}{ratio:.3g}×",
                     abs(ratio - 1) / COST_NOISE if ratio != 1 else None)


#: Two global errors of adaptive integrators run at the same tolerance are
#: the same error within this factor: where the steps and restarts fall
#: moves the error of one run by up to ~2× (CVODE on R1 at 1e-10, one solve
#: against blocks of 50 time units: 3.8e-8 against 4.3e-8).
ACCURACY_NOISE = 2.0
#: Errors at or below this (of numbers of order one) are round-off: no
#: integrator in double precision is told apart below it.
ROUNDOFF_ERROR = 1e-13


def dominates(time_a, error_a, time_b, error_b, what=""):
    """Rule: contender a is as fast and as accurate as b — its time at most
    b's × (1 + COST_NOISE), and its error at most b's × ACCURACY_NOISE or
    both at round-off (≤ ROUNDOFF_ERROR). The value is b's time over a's."""
    ratio = float(time_b) / float(time_a)
    faster = time_a <= (1 + COST_NOISE) * time_b
    accurate = (error_a <= ACCURACY_NOISE * error_b
                or max(error_a, error_b) <= ROUNDOFF_ERROR)
    return Judgement("dominates", bool(faster and accurate), ratio, None,
                     f"time ≤ {1 + COST_NOISE:g}× and error ≤ {ACCURACY_NOISE:g}× (or both ≤ "
                     f"{ROUNDOFF_ERROR:g})",
                     f"{what}{ratio:.2f}× faster, error {error_a:.1e} vs {error_b:.1e}")


def pareto(points):
    """The cost–error front of (cost, error) points: each kept point is
    more accurate than every cheaper one; sorted by cost."""
    front = []
    for cost, err in sorted(points):
        if np.isfinite(err) and (not front or err < front[-1][1]):
            front.append((cost, err))
    return front


def cost_at(front, error):
    """Cost of a front at ``error``, log–log interpolated; (cost, how):
    how = "interpolated", "at most" (the front's cheapest point is already
    more accurate: its cost bounds it) or "unreachable"."""
    if not front:
        return None, "unreachable"
    if error >= front[0][1]:
        return front[0][0], "at most"
    if error < front[-1][1]:
        return None, "unreachable"
    for (c0, e0), (c1, e1) in itertools.pairwise(front):
        if e1 <= error <= e0:
            f = math.log(error / e0) / math.log(e1 / e0)
            return math.exp(math.log(c0) + f * math.log(c1 / c0)), "interpolated"
    return None, "unreachable"


def as_cheap_at_equal_error(front, cost, error, what=""):
    """Rule: a contender whose cost–error front (:func:`pareto`) is
    ``front`` reaches ``error`` at no more than (1 + COST_NOISE)·``cost``
    (read off its front: :func:`cost_at`). The value is ``cost`` over the
    front's cost at that error (how many times cheaper)."""
    mine, how = cost_at(front, error)
    tol = f"front's cost at the error ≤ {1 + COST_NOISE:g}× (log–log interpolated)"
    if mine is None:
        return Judgement("as_cheap_at_equal_error", False, None, None, tol,
                         f"{what}error {error:.1e} not reached")
    ratio = float(cost) / float(mine)
    return Judgement("as_cheap_at_equal_error", bool(mine <= (1 + COST_NOISE) * cost), ratio,
                     None, tol, f"{what}{ratio:.2f}× cheaper at error {error:.1e} ({how})")


#: Significance level of :func:`same_law`: a sample is said to differ from
#: the reference's only when a two-sample test rejects at 1 %, so that of
#: the many comparisons of a study run few fail by chance.
SAME_LAW_ALPHA = 0.01


def same_law(sample, reference, what=""):
    """Rule: two samples of a chaotic orbit's finite-time indicator (e.g.
    X1(t) of 64 orbits started within 1e-7 of it) come from the same
    distribution: the two-sample Kolmogorov–Smirnov test (scipy's
    ``ks_2samp``, exact for these sizes) does not reject at
    :data:`SAME_LAW_ALPHA`.

    For a chaotic orbit one trajectory is no reference: runs that are all
    equally valid follow different trajectories after a few Lyapunov times,
    and their finite-time exponents scatter (C1's X1(1e4) over 0.026–0.055).
    What an accurate method must reproduce is that scatter. The value is
    the p-value; the text gives both medians and the statistic D."""
    from scipy.stats import ks_2samp

    a = np.asarray(sample, dtype=float)
    b = np.asarray(reference, dtype=float)
    tol = f"KS p ≥ {SAME_LAW_ALPHA:g}"
    if a.size < 8 or b.size < 8 or not (np.isfinite(a).all() and np.isfinite(b).all()):
        return Judgement("same_law", None, None, None, tol, f"{what}too few finite values")
    test = ks_2samp(a, b)
    return Judgement("same_law", bool(test.pvalue >= SAME_LAW_ALPHA), float(test.pvalue), None,
                     tol, f"{what}median {np.median(a):.4g} vs {np.median(b):.4g}, "
                          f"D = {test.statistic:.2f}, p = {test.pvalue:.2g}")


def in_sample(value, sample, what=""):
    """Rule: one run's value of a chaotic orbit's finite-time indicator is
    a draw from the distribution of a sample of nearby orbits (the other
    form of :func:`same_law`, for one value): it holds when the value lies
    within the sample's range. For a sample of n an honest draw falls
    outside it with probability 2/(n + 1) (3 % for 64). The value is the
    draw's rank in the sample, as a fraction."""
    s = np.sort(np.asarray(sample, dtype=float))
    tol = f"within the range of {s.size} nearby orbits"
    if s.size < 8 or not np.isfinite(s).all() or not _finite(value):
        return Judgement("in_sample", None, None, None, tol, f"{what}no sample")
    rank = float(np.searchsorted(s, value) / s.size)
    return Judgement("in_sample", bool(s[0] <= value <= s[-1]), rank, None, tol,
                     f"{what}{value:.3g} (sample {s[0]:.3g}–{s[-1]:.3g}, median "
                     f"{np.median(s):.3g})")


#: A disorder-averaged exponent (m₂ ∝ t^a, Λ ∝ t^a of the lattice papers)
#: agrees with the paper's within this, or within two standard errors of
#: the mean single-realisation slope if that is larger: half the smallest
#: gap between the papers' neighbouring laws (Λ: −0.25 weak vs −0.3 strong
#: chaos in 1D), so that one slope cannot agree with both.
EXPONENT_TOLERANCE = 0.025
#: Two standard errors above this and the ensemble cannot tell the m₂ laws
#: (1/5, 1/3, 1/2: gaps 0.13–0.17) apart: no verdict.
EXPONENT_UNRESOLVED = 0.1


def exponent_law(a, stderr, law, window, what=""):
    """Rule: the exponent ``a`` of a disorder-averaged power law, with the
    standard error ``stderr`` of the realisations' slopes, agrees with the
    paper's ``law`` when |a − law| ≤ max(EXPONENT_TOLERANCE, 2·stderr); no
    verdict when 2·stderr > EXPONENT_UNRESOLVED (too few realisations)."""
    tol = f"|a − ({law:.3g})| ≤ max({EXPONENT_TOLERANCE:g}, 2σ)"
    if not _finite(a, stderr):
        return Judgement("exponent_law", None, None, window, tol, f"{what}no value")
    text = f"{what}a = {a:.3f} ± {stderr:.3f}"
    if 2 * stderr > EXPONENT_UNRESOLVED:
        return Judgement("exponent_law", None, float(a), window, tol,
                         text + " (too few realisations to tell)")
    holds = abs(a - law) <= max(EXPONENT_TOLERANCE, 2 * stderr)
    return Judgement("exponent_law", bool(holds), float(a), window, tol, text)


#: The rules in the order of the report's table: name -> (function, the
#: tolerance in words, why that tolerance).
RULES = {
    "agrees": (agrees, f"ours/paper within ×{RATIO_FACTOR:g}",
               "single runs of finite-time indicators from different random vectors; the "
               "paper's numbers have one significant figure; half a decade on a log-log plot"),
    "in_band": (in_band, f"paper within median/{RATIO_FACTOR:g} … {RATIO_FACTOR:g}×max of ours "
                         "over the last decade",
                "a symplectic scheme's energy error oscillates: the paper's value at 1e8 is "
                "one sample of the band ours fills"),
    "at_most": (at_most, f"ours/bound ≤ {RATIO_FACTOR:g}",
                "'≲ bound' fails only when ours is above it by more than two equal numbers "
                "can differ"),
    "above": (above, f"ratio > {ABOVE_FACTOR:g}",
              "numbers within the agreement factor are the same number, so 'above' needs more"),
    "power_law": (power_law, f"|slope − p| ≤ {SLOPE_TOLERANCE:g}·max(2, |p|) over the last "
                             f"{LATE_DECADES:g} decades or each decade of a stated window",
                  "±0.3 keeps 'level' (0) and '1/t' (−1) apart and admits the logarithm of "
                  "eq. 12; 15 % of steep GALI powers, whose fitted slopes scatter with p"),
    "rate_law": (rate_law, f"|rate/law − 1| ≤ {SLOPE_TOLERANCE:g}",
                 "the 15 % of the power laws, relative because a rate has no zero law"),
    "levels_off": (levels_off, f"|slope| ≤ {power_tolerance(0):.2g} over the last "
                               f"{LATE_DECADES:g} decades; level = median (min–max)",
                   "the power law t⁰; two decades, so that a shoulder is not a level"),
    "inverse_t": (inverse_t, f"|slope + 1| ≤ {power_tolerance(-1):.2g} over the last "
                             f"{LATE_DECADES:g} decades",
                  "the power law t⁻¹; (ln t + c)/t passes once ln t + c > 3.3"),
    "grows": (grows, f"slope > {power_tolerance(0):.2g} over the last {LATE_DECADES:g} decades",
              "beyond the band of 'levels off'"),
    "departure": (departure, f"stays ×{DEPARTURE_FACTOR:g} away from its law or reference, to "
                             "the end of the run",
                  "a decade: the smallest gap unambiguous on plots spanning 10–40 decades"),
    "same_time": (same_time, f"within ×{PLOT_FACTOR:.3g}",
                  "times read off a log-log plot: half a decade either way"),
    "costs_more": (costs_more, f"CPU ratio > {1 + COST_NOISE:g}",
                   "CPU time per step of one method varies 2 % between runs on this shared "
                   "machine; 10 % leaves room for its load"),
    "same_cost": (same_cost, f"|CPU ratio − 1| ≤ {COST_NOISE:g}", "as costs_more"),
    "dominates": (dominates, f"time ≤ {1 + COST_NOISE:g}× and error ≤ {ACCURACY_NOISE:g}× "
                             f"(or both ≤ {ROUNDOFF_ERROR:g})",
                  "as costs_more for time; where steps and restarts fall moves one run's "
                  "error by up to 2× at the same tolerance"),
    "as_cheap_at_equal_error": (as_cheap_at_equal_error,
                                f"cost at the same error ≤ {1 + COST_NOISE:g}× (front "
                                "interpolated in log–log)",
                                "the global error of an adaptive integrator at a given "
                                "tolerance moves by factors with where its steps fall: "
                                "equal accuracy is read off the cost–error front"),
    "in_sample": (in_sample, "within the range of a sample of nearby orbits",
                  "one run of a chaotic orbit is one draw of its finite-time exponents: it "
                  "must look like a draw of the sample (outside its range by chance: "
                  "2/(n + 1))"),
    "same_law": (same_law, f"two-sample Kolmogorov–Smirnov p ≥ {SAME_LAW_ALPHA:g}",
                 "a chaotic orbit's finite-time values scatter with the trajectory: samples "
                 "of nearby orbits are compared, not one run; 1 % so that few of a study's "
                 "many comparisons fail by chance"),
    "exponent_law": (exponent_law, f"|a − p| ≤ max({EXPONENT_TOLERANCE:g}, 2σ) of the "
                                   "disorder-averaged slope; no verdict when 2σ > "
                                   f"{EXPONENT_UNRESOLVED:g}",
                     "half the gap between the lattice papers' neighbouring laws (0.05)"),
}

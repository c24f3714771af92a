"""Choosing a method, scheme and step for a target accuracy, by measuring.

:func:`select_scheme` runs short pilot integrations of each candidate
(method, scheme, τ) from the user's own initial state, measures their error
against the cached extended-precision Taylor reference
(:func:`varint.cache.reference`) and their speed, predicts both at t_end,
and returns the cheapest candidate that meets the target, with the whole
table.

How the pilot horizon relates to t_end
--------------------------------------
Errors are measured at two pilot times, T/4 and T (T = ``pilot_t``, by
default the largest T ≤ min(t_end, 100) with T/4 a multiple of every candidate
τ), and extrapolated to t_end with the power law
through them, error ∝ t^a (a ≥ 0). That law is what theory gives where a
choice is meaningful:

* energy, symplectic schemes: bounded (a ≈ 0), so the pilot value holds for
  exponentially long times; non-symplectic methods drift (a ≈ 1);
* tangent vectors and X1 on regular orbits: the error grows linearly
  (a ≈ 1; phase error along the torus).

When the choice can be wrong:

* chaotic orbits: tangent and orbit errors grow exponentially, so any
  extrapolation beyond a few Lyapunov times is meaningless (the measured a
  is large and the row is marked ``unreliable``; a warning names the
  choice). For chaotic orbits ask for the energy or X1 metric, or shorten
  t_end to the predictability horizon.
* sticky or weakly chaotic orbits (the paper's C2) look regular over the
  pilot and are not;
* τ near a scheme's stability limit: an error that is fine over the pilot
  can blow up later (resonances); prefer candidates well inside the table.
* cost is measured as wall time per unit time on this machine, so it
  depends on the load and on k (the number of deviation vectors carried,
  ``k``).

Compensated summation
---------------------
Near the round-off floor of plain summation a smaller τ no longer helps;
compensated summation (``compensated=True`` of the TM method) lowers that
floor (on R1 to t = 1e3 from about 1e-12 to a few 1e-14,
``studies/compensated_floor.py``) at some cost per step. A TM candidate
whose predicted error misses the target by at most :data:`COMPENSATION_RANGE`
is therefore piloted again compensated, at each level, and each variant
enters the table as a candidate of its own (``compensated`` True, every
drift and kick; ``"orbit"``, the orbit's only, the vectors plain: cheaper
per step, and as accurate where the vectors' error follows the orbit's,
``studies/compensation_levels.py``; ``"step"``, the orbit's displacement
over each step, cheaper again); candidates far from the target are not
(truncation, not round-off, sets their error).
"""

from __future__ import annotations

import math
import time
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from . import _validate as check
from .driver import IntegrationError
from .methods import METHODS, make_propagator
from .methods.tm import TangentMapPropagator
from .models.base import Model
from .runspec import specify
from .schemes import get_scheme
from .state import RunState, initial_deviations

__all__ = ["select_scheme", "SchemeChoice", "DEFAULT_SCHEMES", "DEFAULT_TAUS",
           "HIGH_ORDER_CANDIDATES", "COMPENSATION_RANGE", "default_pilot"]

#: Schemes tried by default: 2nd order without and 4th order with corrector
#: (the paper's SBAB2C), the optimised 4th-order ABA864, two 6th-order ones.
DEFAULT_SCHEMES = ("SABA2", "SBAB2C", "SABA3C", "ABA864", "s11odr6", "SRKN14a")
DEFAULT_TAUS = (0.2, 0.1, 0.05, 0.02, 0.01, 0.005)
#: The orders 8 and 10 at the steps of :data:`DEFAULT_TAUS` where they are
#: not already at round-off (so the default pilot horizon stays as it was):
#: for the orbit and one tangent vector of R1 to t = 1e3, s17odr8 reaches
#: global errors of 3e-8, 1.3e-10 and 1.5e-12 at τ = 0.2, 0.1 and 0.05, and
#: s35odr10 1.5e-12 at τ = 0.2 in about half the CPU time SRKN14a needs for
#: 1.2e-12 (τ = 1/32; ``studies/frontier.py``).
HIGH_ORDER_CANDIDATES = (("tm", "s17odr8", 0.2), ("tm", "s17odr8", 0.1),
                         ("tm", "s17odr8", 0.05), ("tm", "s35odr10", 0.2))
METRICS = ("energy", "tangent", "X1")
#: A TM candidate whose predicted error is above the target by at most this
#: factor is piloted again with compensated summation: at the plain floor
#: compensation lowered the global error (R1 and C2, t = 1e3 and 1e4) by a factor 30–250
#: (``studies/compensated_floor.py``), so a candidate that misses by more
#: cannot be rescued by it.
COMPENSATION_RANGE = 100.0
#: Growth exponent a above which an extrapolation is flagged (an error that
#: grows faster than t³ over the pilot is exponential, not a power law).
_UNRELIABLE = 3.0
#: Wall time a speed measurement lasts at least.
_TIMING_SECONDS = 0.05


@dataclass
class SchemeChoice:
    """What :func:`select_scheme` chose, and the table it chose from.

    Attributes
    ----------
    method, scheme, tau :
        The choice (``scheme`` None for methods without one).
    compensated : bool, "orbit" or "step"
        Whether the choice runs with compensated summation (TM only), and
        at which level (True: every drift and kick; "orbit": the orbit's,
        not the vectors'; "step": the orbit's displacement over each step).
    error : float
        Its error predicted at t_end (``metric``).
    seconds : float
        Its predicted wall time to t_end on this machine.
    table : list of dict
        Every candidate: method, scheme, tau, compensated, error at T/4 and
        T, growth exponent a, predicted error and seconds, meets (bool),
        unreliable (bool); cheapest first.
    """

    method: str
    scheme: str | None
    tau: float
    error: float
    seconds: float
    metric: str
    target_error: float
    pilot_t: float
    t_end: float
    table: list = field(default_factory=list)
    compensated: bool | str = False

    def options(self):
        """Keyword arguments for the run functions: ``method``, ``tau``,
        ``scheme`` (when the method takes one) and ``compensated`` (when
        chosen)."""
        out = {"method": self.method, "tau": self.tau}
        if self.scheme is not None:
            out["scheme"] = self.scheme
        if self.compensated:
            out["compensated"] = self.compensated
        return out

    def to_dataframe(self):
        """The table as a pandas DataFrame."""
        from .tables import _pandas

        return _pandas().DataFrame(self.table)

    def __str__(self):
        head = (f"{'method':7} {'scheme':9} {'tau':>7} {'err(T/4)':>9} {'err(T)':>9} "
                f"{'growth a':>8} {'err(t_end)':>10} {'sec(t_end)':>10}  ok")
        lines = [f"select_scheme: {self.metric} error <= {self.target_error:g} at t_end = "
                 f"{self.t_end:g} (pilot to {self.pilot_t:g})", head, "-" * len(head)]
        for r in self.table:
            mark = "*" if (r["method"], r["scheme"], r["tau"], r["compensated"]) == (
                self.method, self.scheme, self.tau, self.compensated) else " "
            verdict = ("yes" if r["meets"] else "no") + (" (unreliable)" if r["unreliable"] else "")
            scheme = (r["scheme"] or "-") + {True: "+c", "orbit": "+co", "step": "+cs"}.get(
                r["compensated"], "")
            lines.append(f"{r['method']:7} {scheme:9} {r['tau']:7.3g} "
                         f"{r['error_quarter']:9.2e} {r['error_pilot']:9.2e} {r['growth']:8.2f} "
                         f"{r['error']:10.2e} {r['seconds']:10.3g} {mark}{verdict}")
        lines.append(f"err(T/4), err(T): the pilot's error at T/4 and T = {self.pilot_t:g}; "
                     "growth a: the error grows as t^a between them (a > "
                     f"{_UNRELIABLE:g}: exponential, the extrapolation is unreliable); "
                     f"err(t_end) = err(T) (t_end/T)^a; sec(t_end): predicted wall time; "
                     "+c: compensated summation (+co: of the orbit only; +cs: of the orbit's "
                     "displacement per step); *: the choice")
        return "\n".join(lines)


def _candidates(candidates):
    if candidates is None:
        return ([("tm", s, tau) for s in DEFAULT_SCHEMES for tau in DEFAULT_TAUS]
                + list(HIGH_ORDER_CANDIDATES))
    if isinstance(candidates, (str, bytes)) or not hasattr(candidates, "__iter__"):
        raise ValueError(f"candidates must be a list of (method, scheme or None, tau), got "
                         f"{candidates!r}")
    out = []
    for c in candidates:
        if not (isinstance(c, (tuple, list)) and len(c) == 3):
            raise ValueError(f"each candidate must be (method, scheme or None, tau), got {c!r}")
        method, scheme, tau = c
        method = check.choice(method, METHODS, "method")
        if scheme is not None:
            # An unknown name fails now, listing the valid ones (and a
            # processed scheme anywhere but in the TM method).
            get_scheme(scheme, processed=method == "tm")
        out.append((method, scheme, check.positive_float(tau, "candidate tau")))
    if not out:
        raise ValueError("candidates must name at least one (method, scheme, tau)")
    return out


def default_pilot(t_end, taus):
    """The default pilot horizon T: the largest ≤ min(t_end, 100) with T/4 a
    multiple of every candidate step (the quarter of a pilot is one of its
    check times), so that any t_end works, not only multiples of 0.8."""
    taus = sorted(set(taus), reverse=True)
    unit = None
    for n in range(1, 10001):
        q = taus[0] * n
        if all(abs(q / t - round(q / t)) <= 1e-9 * q / t for t in taus):
            unit = q
            break
    if unit is None:
        raise ValueError(f"the candidate steps {taus} have no common multiple below "
                         f"{10000 * taus[0]:g}; give pilot_t (with pilot_t/4 a multiple of each)")
    pilot = math.floor(min(t_end, 100.0) / (4 * unit) + 1e-9) * 4 * unit
    if pilot == 0:
        raise ValueError(f"t_end = {t_end:g} is shorter than the shortest pilot, {4 * unit:g} "
                         "(4 steps of the largest candidate tau); shorten the candidate steps")
    return pilot


def _time_unit_cost(model, x0, method, scheme, tau, k, compensated=False):
    """Wall seconds per unit of time of a candidate carrying k vectors:
    the propagator alone (no run overhead), after one warm-up step (which
    also compiles), doubling the steps until it lasts long enough.

    A TM propagator is timed on the stepper the warm-up step took (its
    compact stepper unless the written-out one is compiled already): the
    doubling passes :attr:`TangentMapPropagator.COMPACT_WORK` orbit-steps
    within 0.05 s on a small model, where the propagator would take the
    written-out stepper and compile it inside a timed call (its seconds
    counted as the candidate's cost, and a compile per candidate). The
    compact stepper gives the same bits at 1.0–1.4× the time per step
    (``studies/results/suite18/compact_steps_quick.json``)."""
    options = {} if scheme is None else {"scheme": scheme}
    if compensated:
        options["compensated"] = compensated
    prop = make_propagator(method, model, tau, "qr" if k else "none", **options)
    if isinstance(prop, TangentMapPropagator):
        prop.COMPACT_WORK = math.inf
    W0 = initial_deviations(model.dim, k, 1, 0)
    state = RunState.start(np.asarray(x0, dtype=float)[None], W0)
    prop.advance(state, 1)
    n = 64
    while True:
        t0 = time.perf_counter()
        prop.advance(state, n)
        wall = time.perf_counter() - t0
        if wall >= _TIMING_SECONDS or (state.status != 0).any():
            return wall / (n * tau)
        n *= 2


def select_scheme(model: Model, x0: ArrayLike, target_error: float, metric: str = "energy",
                  t_end: float = 1e4, pilot_t: float | None = None,
                  candidates: Sequence[tuple[str, str | None, float]] | None = None,
                  k: int | None = None) -> SchemeChoice:
    """The cheapest (method, scheme, τ) whose error at t_end meets a target.

    Parameters
    ----------
    model : Model
    x0 : array_like, shape (2N,)
        The initial state of the job (errors depend on the orbit).
    target_error : float
        Largest acceptable error at t_end, in the metric's units.
    metric : {"energy", "tangent", "X1"}
        "energy": max relative energy error up to t; "tangent": relative
        error (Frobenius) of the tangent map applied to the 2N unit
        vectors; "X1": absolute error of the finite-time mLCE X1(t).
    t_end : float, default 1e4
        Horizon of the production run.
    pilot_t : float, optional
        Pilot horizon T. T/4 must be a multiple of every candidate τ; by
        default the largest such T ≤ min(t_end, 100) (:func:`default_pilot`).
    candidates : list of (method, scheme, tau), optional
        By default the TM method with :data:`DEFAULT_SCHEMES` ×
        :data:`DEFAULT_TAUS` and :data:`HIGH_ORDER_CANDIDATES`. ``scheme``
        is None for methods without one (e.g. ``("taylor", None, 0.05)``).
    k : int, optional
        Deviation vectors the production run carries, for the cost (0 for
        "energy", 1 for "X1", 2N for "tangent" by default).

    Returns
    -------
    SchemeChoice

    Raises
    ------
    ValueError
        For bad arguments, or when no candidate meets the target (the
        message gives the best error reached).

    Notes
    -----
    See the module docstring for how the pilot relates to t_end and when
    the choice can be wrong. References are computed once and cached.

    Examples
    --------
    The pilots run against the extended-precision Taylor reference, which
    takes a minute the first time (it is cached after that):

    >>> import varint
    >>> model, x0 = varint.paper_orbit("R1")
    >>> choice = varint.select_scheme(model, x0, 1e-8, metric="energy",
    ...                               t_end=1e6)                    # doctest: +SKIP
    >>> print(choice)                       # the table, cheapest first  # doctest: +SKIP
    >>> r = varint.lyapunov_spectrum(model, x0, 1e6, **choice.options())  # doctest: +SKIP
    """
    from .cache import reference
    from .api import integrate, lyapunov_spectrum

    t_end = check.positive_float(t_end, "t_end")
    # The orbit checked as every run's is (model, state, the kernels there).
    spec = specify(model, x0, "integrate", t_end, seed=None)
    model, x0 = spec.model, spec.one_state()
    target = check.positive_float(target_error, "target_error")
    known = {m.lower(): m for m in METRICS}.get(str(metric).lower())
    if known is None:
        raise ValueError(f"unknown metric {metric!r}; expected one of: "
                         f"{', '.join(METRICS)}")
    metric = known
    cands = _candidates(candidates)
    pilot = (default_pilot(t_end, [tau for _, _, tau in cands]) if pilot_t is None
             else min(check.positive_float(pilot_t, "pilot_t"), t_end))
    quarter = pilot / 4
    for method, scheme, tau in cands:
        if abs(quarter / tau - round(quarter / tau)) > 1e-9 * quarter / tau or quarter < tau:
            raise ValueError(f"pilot_t / 4 = {quarter:g} must be a multiple of every candidate "
                             f"tau; {method} {scheme or ''} has tau = {tau:g}")
    dim = model.dim
    if k is None:
        k = {"energy": 0, "X1": 1, "tangent": dim}[metric]
    else:
        k = check.n_vectors(k, dim, "k", minimum=0)
    checks = np.array([quarter, pilot])
    w1 = np.ones((dim, 1)) / math.sqrt(dim)

    if metric == "X1":
        ref = reference(model, x0, pilot, tau=quarter, kind="lyapunov_spectrum",
                        deviations=w1, t_out=checks).exponents[:, 0]
    elif metric == "tangent":
        ref = [reference(model, x0, t, tau=quarter, kind="integrate",
                         deviations=np.eye(dim)).deviations for t in checks]

    def errors(method, scheme, tau, compensated):
        # Candidates too coarse to trust are what the table is for: no
        # accuracy warnings from the pilots.
        opts = {"method": method, "tau": tau, "progress": False, "energy_tol": math.inf}
        if scheme is not None:
            opts["scheme"] = scheme
        if compensated:
            opts["compensated"] = compensated
        if metric == "energy":
            n = int(round(pilot / tau))
            r = integrate(model, x0, pilot, t_out=min(n, 400), **opts)
            return np.array([np.max(r.energy_error[r.t <= t * (1 + 1e-12)]) for t in checks])
        if metric == "X1":
            r = lyapunov_spectrum(model, x0, pilot, deviations=w1, t_out=checks, **opts)
            return np.abs(r.exponents[:, 0] - ref)
        return np.array([np.linalg.norm(integrate(model, x0, t, deviations=np.eye(dim), **opts)
                                        .deviations - W) / np.linalg.norm(W)
                         for t, W in zip(checks, ref, strict=True)])

    def row(method, scheme, tau, compensated=False):
        try:
            e = errors(method, scheme, tau, compensated)
        except IntegrationError:
            e = np.array([np.inf, np.inf])  # unstable at this τ
        tiny = np.finfo(float).tiny
        growth = max(0.0, math.log(max(e[1], tiny) / max(e[0], tiny)) / math.log(4.0)) \
            if np.isfinite(e).all() else math.inf
        predicted = e[1] * (t_end / pilot) ** growth if np.isfinite(growth) else math.inf
        seconds = (_time_unit_cost(model, x0, method, scheme, tau, k, compensated) * t_end
                   if np.isfinite(predicted) else math.inf)
        scheme_name = None if scheme is None else getattr(scheme, "name", scheme)
        return {"method": method, "scheme": scheme_name, "tau": tau, "compensated": compensated,
                "error_quarter": float(e[0]), "error_pilot": float(e[1]),
                "growth": float(growth), "error": float(predicted),
                "seconds": float(seconds), "meets": bool(predicted <= target),
                "unreliable": bool(growth > _UNRELIABLE)}

    table = [row(*c) for c in cands]
    # Near the plain floor: the same candidates compensated (module docstring),
    # where the TM method has a generated stepper to compensate.
    from .codegen.expressions import symbolic_fits

    if symbolic_fits(model, max(k, {"energy": 0, "X1": 1, "tangent": dim}[metric])):
        table += [row(method, scheme, tau, level)
                  for (method, scheme, tau), r in zip(cands, list(table), strict=True)
                  if method == "tm" and target < r["error"] <= COMPENSATION_RANGE * target
                  for level in ("step", "orbit", True)]
    table.sort(key=lambda r: (not r["meets"], r["seconds"], r["error"]))
    best = table[0]
    if not best["meets"]:
        closest = min(table, key=lambda r: r["error"])
        raise ValueError(
            f"no candidate meets {metric} error <= {target:g} at t_end = {t_end:g}; the best "
            f"predicted is {closest['error']:.3g} ({closest['method']} {closest['scheme'] or ''} "
            f"tau = {closest['tau']:g}); allow a larger error or add candidates with smaller "
            "tau or higher order")
    if best["unreliable"]:
        warnings.warn(f"the {metric} error of the choice grows like t^{best['growth']:.1f} over "
                      "the pilot (chaotic orbit?): its extrapolation to t_end is not reliable",
                      RuntimeWarning, stacklevel=2)
    return SchemeChoice(method=best["method"], scheme=best["scheme"], tau=best["tau"],
                        error=best["error"], seconds=best["seconds"], metric=metric,
                        target_error=target, pilot_t=pilot, t_end=t_end, table=table,
                        compensated=best["compensated"])

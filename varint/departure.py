"""Where an approximate tangent dynamics loses accuracy: the time at which
the indicators of a regular orbit depart from the reference behaviour.

For a regular orbit the deviation vectors grow linearly, so the finite-time
mLCE falls as X1(t) ∝ 1/t (up to a logarithm) and the GALIs follow power
laws (Skokos & Gerlach 2010, eqs. 12 and 17 of the LaTeX source). The TDH
methods (:mod:`varint.tdh`) follow these laws at first and then, when the
errors of their tangent map have built up, the vectors grow exponentially:
X1 levels off at a positive value and the GALIs fall exponentially, the
wrong verdict "chaotic" of the paper's Figs. 2–4. :func:`departure` measures
when that happens and where X1 levels off, for any method and τ, against a
reference run of the same orbit with the same initial vectors.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from . import _validate as check
from .methods import METHODS
from .models.base import Model
from .run import Run
from .runspec import specify
from .state import output_steps

__all__ = ["Departure", "departure", "departure_time", "DEFAULT_REFERENCE"]

#: The reference the indicators are compared with: the TM method with the
#: order-(8,6,4) scheme ABA864 at the same τ (the TM method keeps X1 ∝ 1/t
#: on the paper's regular orbits even at τ = 0.5; paper Table I).
DEFAULT_REFERENCE = {"method": "tm", "scheme": "ABA864"}


def departure_time(t, excess, threshold):
    """The earliest time from which ``excess`` stays above ``threshold``.

    Parameters
    ----------
    t : array_like, shape (n,)
        Increasing output times.
    excess : array_like, shape (n,)
        How far the method is from the reference at each time (NaN counts
        as not above).
    threshold : float

    Returns
    -------
    float or None
        ``t[j]`` for the smallest j with ``excess[i] > threshold`` for every
        i ≥ j; None if the last value is not above (no departure within the
        horizon). An excursion that comes back below does not count.
    """
    t = np.asarray(t, dtype=float)
    above = np.asarray(excess, dtype=float) > threshold
    if t.shape != above.shape or t.ndim != 1 or t.size == 0:
        raise ValueError(f"t and excess must be 1-d arrays of the same length, got shapes "
                         f"{t.shape} and {above.shape}")
    if not above[-1]:
        return None
    below = np.flatnonzero(~above)
    return float(t[0 if below.size == 0 else below[-1] + 1])


@dataclass
class Departure:
    """Where the indicators of a regular orbit leave the reference behaviour.

    Attributes
    ----------
    method : str
    tau : float
    t_x1 : float or None
        Departure time of X1 (criterion in :func:`departure`); None if X1
        follows the reference up to the horizon.
    level : float or None
        The value at which X1 levels off: the growth rate of
        Λ(t) = t·X1(t) from ``t_x1`` to the horizon; None without a
        departure or if the horizon is shorter than 2·``t_x1``.
    x1_end : float
        X1 at the horizon (what the paper reads off its plots).
    t_gali : dict of int -> float or None
        Departure time of each GALI_k.
    reference_slope : float
        Fitted slope of log X1_ref against log t over the last decade: about
        −1 for a regular orbit (a warning is given above −0.5).
    threshold, gali_threshold : float
        The thresholds used (natural logarithms).
    t : ndarray, shape (n,)
        Output times.
    x1, x1_reference : ndarray, shape (n,)
        X1 of the method and of the reference.
    gali, gali_reference : dict of int -> ndarray, shape (n,)
    runs : dict of str -> result
        The four runs ("x1", "x1_reference", "gali", "gali_reference"),
        with their provenance.
    """

    method: str
    tau: float
    t_x1: float | None
    level: float | None
    x1_end: float
    t_gali: dict
    reference_slope: float
    threshold: float
    gali_threshold: float
    t: np.ndarray
    x1: np.ndarray
    x1_reference: np.ndarray
    gali: dict = field(default_factory=dict)
    gali_reference: dict = field(default_factory=dict)
    runs: dict = field(default_factory=dict, repr=False)


def departure(model: Model, x0: ArrayLike, method: str, tau: float, t_end: float, *,
              scheme: str | None = None, reference: dict | None = None,
              gali_orders: Sequence[int] | None = None, threshold: float = math.log(10.0),
              gali_threshold: float = math.log(10.0), per_decade: int = 20, seed: int = 0,
              progress: bool | None = None, **method_options: Any) -> Departure:
    """When X1 and the GALIs of a regular orbit computed by ``method`` depart
    from a reference run, and where X1 levels off.

    The orbit is integrated twice for X1 (one deviation vector, QR every τ)
    and twice for the GALIs (2N vectors, normalised every τ): by ``method``
    and by the reference (:data:`DEFAULT_REFERENCE` unless given), from the
    same seeded initial vectors, at the same log-spaced output times.

    Criterion
    ---------
    Let Λ(t) = t·X1(t) = ln(‖w(t)‖/‖w(0)‖) be the accumulated logarithmic
    stretching of the first vector (paper eq. 10), and Λ_ref(t) that of the
    reference. X1 *departs* at the earliest output time t_d from which on
    Λ(t) − Λ_ref(t) > ``threshold`` at every later output time: by then the
    method has stretched the vector e^threshold times (10 times by default)
    more than the reference, for good. Since a regular orbit's reference
    grows like ln t, a method whose vectors grow as e^{Lt} departs near
    t_d ≈ threshold/L. The *level-off value* is the mean growth rate after
    departure, L = (Λ(t_end) − Λ(t_d))/(t_end − t_d), reported when
    t_end ≥ 2 t_d; X1 itself tends to L as t → ∞.

    GALI_k departs at the earliest output time from which on
    ln GALI_k,ref(t) − ln GALI_k(t) > ``gali_threshold``: the method's
    GALI_k has fallen, for good, that many e-folds (a decade by default)
    below the reference's power law.

    Parameters
    ----------
    model : Model
    x0 : array_like, shape (2N,)
        One regular orbit.
    method : str
        The method under test (e.g. "tdhcc"); see :data:`varint.METHODS`.
    tau : float
        Its renormalisation interval; the reference uses the same τ.
    t_end : float
        Horizon.
    scheme : str, optional
        The method's scheme.
    reference : dict, optional
        ``{"method": ..., **options}`` of the reference run;
        :data:`DEFAULT_REFERENCE` by default.
    gali_orders : sequence of int, optional
        GALI orders; 2..2N by default, () for none.
    threshold, gali_threshold : float, default ln 10
    per_decade : int, default 20
        Output times per decade of t (the resolution of the departure
        times: a factor 10^(1/per_decade)).
    seed : int, default 0
        Seed of the initial deviation vectors of both runs.
    progress : bool, optional
    **method_options
        Passed to ``method`` (e.g. ``eigensolver="analytic"``).

    Returns
    -------
    Departure

    Examples
    --------
    On R1 at τ = 0.05, TDHcc's X1 departs at t ≈ 6.4e3 and levels off at
    9.5e-4 (the paper's Table I: 9.4e-4). Four runs, each compiled on first
    use, so not run by the test suite (the documentation's gallery runs it):

    >>> import varint
    >>> model, x0 = varint.paper_orbit("R1")
    >>> d = varint.departure(model, x0, "tdhcc", tau=0.05, t_end=2e4)     # doctest: +SKIP
    >>> d.t_x1, d.level, d.t_gali                                         # doctest: +SKIP
    (6.4e3, 9.5e-4, {2: 5.7e3, 3: 3.2e3, 4: 3.2e3})
    """
    t_end, tau = check.horizon(t_end, tau)
    threshold = check.positive_float(threshold, "threshold")
    gali_threshold = check.positive_float(gali_threshold, "gali_threshold")
    if isinstance(per_decade, bool) or not isinstance(per_decade, (int, np.integer)) \
            or per_decade < 1:
        raise ValueError(f"per_decade must be a positive integer, got {per_decade!r}")
    if reference is not None and not isinstance(reference, dict):
        raise ValueError(f"reference must be a dict with a 'method' name, got {reference!r}")
    ref = dict(DEFAULT_REFERENCE if reference is None else reference)
    if not isinstance(ref.get("method"), str):
        raise ValueError(f"reference must be a dict with a 'method' name, got {reference!r}")
    ref_method = check.choice(ref.pop("method"), METHODS, "reference method")
    t_out = output_steps(t_end, tau, per_decade=per_decade) * tau

    def spec(indicator, method, **options):
        return specify(model, x0, indicator, t_end, tau, method=method, t_out=t_out, seed=seed,
                       **options)

    # Every run specified: every input checked once, as every run's are.
    specs = {"x1": spec("lyapunov", method, scheme=scheme, n_exponents=1, **method_options),
             "x1_reference": spec("lyapunov", ref_method, n_exponents=1, **ref)}
    specs["x1"].one_state()
    dim = specs["x1"].model.dim
    if gali_orders is not None and (isinstance(gali_orders, (str, bytes))
                                    or not hasattr(gali_orders, "__iter__")):
        raise ValueError(f"gali_orders must be a sequence of GALI orders in 2..{dim}, "
                         f"got {gali_orders!r}")
    orders = tuple(range(2, dim + 1)) if gali_orders is None else tuple(gali_orders)
    for k in orders:
        check.n_vectors(k, dim, "GALI order", minimum=2)
    if orders:
        specs["gali"] = spec("gali", method, k=orders, scheme=scheme, **method_options)
        specs["gali_reference"] = spec("gali", ref_method, k=orders, **ref)
    method = specs["x1"].method
    # Every run built (the methods check their options) before any runs;
    # Lyapunov and GALI results side by side.
    jobs = {name: Run(s, progress=progress) for name, s in specs.items()}
    runs: dict[str, Any] = {name: job.execute() for name, job in jobs.items()}
    t = runs["x1"].t
    x1, x1_ref = runs["x1"].exponents[:, 0], runs["x1_reference"].exponents[:, 0]
    t_x1 = departure_time(t, (x1 - x1_ref) * t, threshold)
    level = None
    if t_x1 is not None and t[-1] >= 2 * t_x1:
        j = np.searchsorted(t, t_x1)
        level = float((x1[-1] * t[-1] - x1[j] * t[j]) / (t[-1] - t[j]))
    late = (t >= t[-1] / 10) & (x1_ref > 0)
    slope = (float(np.polyfit(np.log(t[late]), np.log(x1_ref[late]), 1)[0])
             if late.sum() >= 2 else float("nan"))
    if not slope <= -0.5:
        warnings.warn(f"the reference X1 does not decay like 1/t over the last decade (fitted "
                      f"slope {slope:.2f}): the orbit may not be regular, and departures from "
                      f"a chaotic reference mean little", RuntimeWarning, stacklevel=2)

    g, g_ref, t_gali = {}, {}, {}
    if orders:
        tiny = np.finfo(float).tiny
        for k in runs["gali"].gali:
            g[k], g_ref[k] = runs["gali"].gali[k], runs["gali_reference"].gali[k]
            fall = np.log(np.maximum(g_ref[k], tiny)) - np.log(np.maximum(g[k], tiny))
            t_gali[k] = departure_time(t, fall, gali_threshold)

    return Departure(method=method, tau=tau, t_x1=t_x1, level=level, x1_end=float(x1[-1]),
                     t_gali=t_gali, reference_slope=slope, threshold=threshold,
                     gali_threshold=gali_threshold, t=t, x1=x1, x1_reference=x1_ref, gali=g,
                     gali_reference=g_ref, runs=runs)

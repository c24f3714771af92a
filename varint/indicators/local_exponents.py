"""Local (finite-time) Lyapunov exponents over windows of length Δ: the
"stretching numbers" of Voglis & Contopoulos, and their distribution.

The whole indicator is this file: one :class:`~varint.indicators.base.Indicator`
registered under ``"local_exponents"``. ``varint.run(model, x0,
"local_exponents", t_end, window=10.0)`` computes it with every method, and
``varint.chaos_map(model, grid, "local_exponents", ...)`` maps it, with no
other change to varint.

k deviation vectors are re-orthonormalised every τ (QR) as for the
Lyapunov spectrum, and ln R_jj of every interval is accumulated. At the
first grid time t ≥ t_start + Δ a window closes: its local exponent is

    λ_j = (S_j(t) − S_j(t_start)) / (t − t_start),   S_j = Σ ln R_jj,

(Voglis & Contopoulos 1994 for one vector and Δ = one period, Skokos &
Gerlach 2010 eq. 10 over the window instead of [0, t]), and a new window
starts. Running count, mean, standard deviation, minimum and maximum of the
λ_j of all closed windows are accumulated after every interval, so they
cover every window whatever the output times. A regular orbit's local
exponents scatter about a small positive value that falls as the window
grows (ln Δ / Δ from the linear growth of w); a chaotic orbit's scatter
about χ₁ with a spread set by its sticky and chaotic episodes, which the
time series at the output times shows (C2 of the paper: small values for
t ≲ 1e6, then a burst).

References
----------
N. Voglis & G. Contopoulos, J. Phys. A 27, 4899 (1994); G. Contopoulos,
Order and Chaos in Dynamical Astronomy (Springer, 2002), Sect. 2.10.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numba import njit

from .. import _validate as check
from ..protocol import Accumulator, Renorm
from ..results import _Result
from .base import Indicator, Option, register_indicator

__all__ = ["LOCAL_EXPONENTS", "LocalExponentsResult"]

LOG, START_LOG, START_T, WINDOW, LAST, COUNT, SUM, SUMSQ, LOW, HIGH = range(10)
#: Most output times of the default grid (one per window, or per several).
_MAX_OUTPUTS = 100_000
_STATISTICS = ("last", "mean", "std", "min", "max")


@njit(error_model="numpy")
def _update(aux, r, x, W, flow, t):
    for j in range(aux.shape[0]):
        s = aux[j, LOG] + math.log(r[j])
        aux[j, LOG] = s
        # A window closes at the first grid time past its end (Δ need not be
        # a multiple of τ; the exact length is used).
        if t >= aux[j, START_T] + aux[j, WINDOW] * (1.0 - 1e-12):
            v = (s - aux[j, START_LOG]) / (t - aux[j, START_T])
            aux[j, LAST] = v
            aux[j, COUNT] += 1.0
            aux[j, SUM] += v
            aux[j, SUMSQ] += v * v
            aux[j, LOW] = min(aux[j, LOW], v)
            aux[j, HIGH] = max(aux[j, HIGH], v)
            aux[j, START_LOG] = s
            aux[j, START_T] = t


def _accumulator(options):
    return Accumulator(
        name="local_exponents",
        columns=("log", "start_log", "start_t", "window", "last", "count", "sum", "sumsq",
                 "min", "max"),
        initial=(0.0, 0.0, 0.0, options["window"], math.nan, 0.0, 0.0, 0.0, math.inf,
                 -math.inf),
        update=_update)


def _window(model, value):
    if isinstance(value, bool) or not isinstance(value, numbers.Real) \
            or not (math.isfinite(value) and value > 0):
        raise ValueError(f"window must be a positive finite time (the length Δ of each "
                         f"window), got {value!r}")
    return float(value)


def _n_exponents(model, value):
    return check.n_vectors(value, model.dim, "n_exponents")


def _statistic(model, value):
    return check.choice(value, _STATISTICS, "statistic")


def _vectors(model, options, given):
    k = options["n_exponents"]
    if given is not None and given != k:
        raise ValueError(f"n_exponents = {k} but {given} deviation vectors were given")
    return k


def _read(rows, model, t, options):
    aux = rows.extra["acc_local_exponents"]
    count = aux[:, :, COUNT]
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = aux[:, :, SUM] / count
        var = np.maximum(aux[:, :, SUMSQ] / count - mean * mean, 0.0)
    none = count == 0
    low, high = aux[:, :, LOW].copy(), aux[:, :, HIGH].copy()
    low[none] = high[none] = np.nan
    return {"local": aux[:, :, LAST].copy(), "mean": mean, "std": np.sqrt(var),
            "minimum": low, "maximum": high, "windows": count.copy()}


def _finish(fields, options):
    return dict(fields, window=options["window"])


def _scalar(record, model, options):
    name = {"last": "local", "min": "minimum", "max": "maximum"}.get(options["statistic"],
                                                                     options["statistic"])
    return record[name][:, 0]


def _output_times(t_end, tau, options):
    # One output per window (the series whose distribution is wanted), or
    # per several windows on very long runs.
    n = int(t_end // options["window"])
    if n < 1:
        return None
    every = max(1, math.ceil(n / _MAX_OUTPUTS))
    return np.arange(every, n + 1, every) * options["window"]


@dataclass
class LocalExponentsResult(_Result):
    """Result of the ``"local_exponents"`` indicator.

    Attributes
    ----------
    local : ndarray, shape ([M,] n_out, k)
        Local exponent of the last window closed at each output time (NaN
        before the first); by default one output per window.
    mean, std, minimum, maximum : ndarray, shape ([M,] n_out, k)
        Statistics of the local exponents of every window closed so far.
    windows : ndarray, shape ([M,] n_out, k)
        How many windows were closed.
    window : float
        The window length Δ.
    deviations : ndarray, shape ([M,] 2N, k)
    """

    plot_kind: ClassVar[str] = "series"
    dims: ClassVar[dict] = dict.fromkeys(("local", "mean", "std", "minimum", "maximum",
                                          "windows"), ("exponent",))

    local: np.ndarray | None = None
    mean: np.ndarray | None = None
    std: np.ndarray | None = None
    minimum: np.ndarray | None = None
    maximum: np.ndarray | None = None
    windows: np.ndarray | None = None
    window: float = 0.0
    deviations: np.ndarray | None = None

    def distribution(self, bins=50, exponent=0, orbit=None, density=True):
        """Histogram of the local exponents in the time series.

        Parameters
        ----------
        bins : int or sequence
            As for :func:`numpy.histogram`.
        exponent : int
            Which exponent (0: the largest).
        orbit : int, optional
            Which orbit of a batch (all orbits together by default).
        density : bool
            Normalise to a probability density.

        Returns
        -------
        counts, edges : ndarray
        """
        values = np.asarray(self.local)[..., exponent]
        if orbit is not None:
            if values.ndim != 2:
                raise ValueError("orbit= selects an orbit of a batch; this result holds one")
            values = values[orbit]
        values = values[np.isfinite(values)]
        if values.size == 0:
            raise ValueError("no window has closed: run longer than the window length")
        return np.histogram(values, bins=bins, density=density)


LOCAL_EXPONENTS = register_indicator(Indicator(
    name="local_exponents",
    summary="local Lyapunov exponents over windows of length Δ (stretching numbers) and "
            "their distribution",
    renorm=Renorm.QR,
    vectors=_vectors,
    read=_read,
    result=LocalExponentsResult,
    require="orthonormal",
    options={"window": Option(10.0, _window, "window length Δ (time units)"),
             "n_exponents": Option(1, _n_exponents, "how many local exponents (vectors)"),
             "statistic": Option("max", _statistic,
                                 "the map value: last, mean, std, min or max over windows")},
    accumulator=_accumulator,
    finish=_finish,
    scalar=_scalar,
    below=False,
    log_scale=False,
    output_times=_output_times,
    count_option="n_exponents",
    laws="regular orbits: local exponents ≈ ln Δ / Δ, narrow distribution; chaotic: "
         "scattered about χ₁; sticky episodes show as long runs of small values",
    references=("Voglis & Contopoulos, J. Phys. A 27, 4899 (1994)",),
))

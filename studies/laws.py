"""Reading the paper's laws off time series: power-law slopes, exponential
rates, and how far a run is from a reference run or from a law.

The paper states its results as laws (X1 ∝ 1/t, GALI_k ∝ t^{−p},
exponential decay) and as times read off log-log plots ("levels off at
t ≈ 1e4"). These helpers turn a run's output into those numbers; whether a
number agrees with the paper's is decided by the rules of
:mod:`studies.claims`, which hold every tolerance.
"""

from __future__ import annotations

import numpy as np

__all__ = ["slope", "late_slope", "decade_slopes", "log_growth", "decay_rate",
           "local_exponents", "x1_law_excess", "stretch_excess", "growth_after", "law_deficit",
           "gali_deficit", "regular_gali_powers", "roundoff_time"]


def slope(t, y, t_lo, t_hi=np.inf):
    """Least-squares slope of log |y| against log t over t_lo ≤ t ≤ t_hi
    (NaN with fewer than three usable points)."""
    t, y = np.asarray(t, dtype=float), np.abs(np.asarray(y, dtype=float))
    use = (t >= t_lo) & (t <= t_hi) & (y > 0) & np.isfinite(y)
    if use.sum() < 3:
        return float("nan")
    return float(np.polyfit(np.log(t[use]), np.log(y[use]), 1)[0])


def decade_slopes(t, y, start):
    """The log-log slope of |y| over each whole decade [start·10^j,
    start·10^(j+1)] within the run, as (first time, last time, slope)."""
    out, lo = [], float(start)
    while lo * 10 <= t[-1] * (1 + 1e-9):
        out.append((lo, lo * 10, slope(t, y, lo, lo * 10)))
        lo *= 10
    return out


def roundoff_time(t, gali, vanishing, tau, margin):
    """The first output time at which GALI_k comes within a factor
    ``margin`` of its round-off floor in double precision (None if it
    never does).

    Each of the ``vanishing`` singular values that go to zero on a torus
    cannot fall below the rounding the unit vectors accumulate over t/τ
    renormalisations, ≈ √(t/τ)·ε; GALI_k, their product with the others
    (≈ 1), then floors at (√(t/τ)·ε)^vanishing and a power law fitted
    beyond that time measures rounding, not dynamics. That the floor is
    rounding, and of this size, is measured by :mod:`studies.roundoff_floor`.
    """
    if vanishing <= 0:
        return None
    t, gali = np.asarray(t, dtype=float), np.abs(np.asarray(gali, dtype=float))
    floor = margin * (np.sqrt(t / tau) * np.finfo(float).eps) ** vanishing
    hit = np.flatnonzero(gali <= floor)
    return float(t[hit[0]]) if hit.size else None


def late_slope(t, y, decades=2.0):
    """:func:`slope` over the last ``decades`` decades of t."""
    return slope(t, y, float(t[-1]) / 10 ** decades)


def log_growth(t, x, decades=3.0):
    """Coefficient A of Λ(t) = t·X(t) ≈ A ln t + B over the last ``decades``
    of t, for a finite-time Lyapunov exponent X.

    On a regular orbit the deviation vectors grow linearly in t (and the
    volume of all 2N is conserved), so Λ_i = ln‖w_i‖ ≈ ln t + c_i for
    i ≤ N and ≈ −ln t + c_i for i > N: A = ±1, i.e. X_i ≈ ±(ln t + c_i)/t,
    the paper's "X ∝ 1/t" (eq. 12) with its logarithmic factor. An
    exponentially growing vector gives A ≫ 1 (Λ ∝ t).
    """
    t, x = np.asarray(t, dtype=float), np.asarray(x, dtype=float)
    use = (t >= t[-1] / 10 ** decades) & np.isfinite(x)
    if use.sum() < 3:
        return float("nan")
    return float(np.polyfit(np.log(t[use]), x[use] * t[use], 1)[0])


def decay_rate(t, g, high=1e-2, low=1e-12):
    """Rate σ of an exponential decay g ∝ e^{−σt}, fitted to ln g against t
    while g falls from ``high`` to ``low`` (before the values reach the
    round-off floor).

    Returns
    -------
    rate : float
        NaN if fewer than three points lie in that band.
    window : tuple of float
        First and last time of the fit.
    """
    t, g = np.asarray(t, dtype=float), np.asarray(g, dtype=float)
    below = np.flatnonzero(g < low)
    end = below[0] if below.size else len(g)
    use = np.zeros(len(g), dtype=bool)
    use[:end] = (g[:end] < high) & (g[:end] > low)
    if use.sum() < 3:
        return float("nan"), (float("nan"), float("nan"))
    return (float(-np.polyfit(t[use], np.log(g[use]), 1)[0]),
            (float(t[use][0]), float(t[use][-1])))


def local_exponents(t, exponents, window):
    """Mean stretching rates σ_i = ΔΛ_i/Δt of the QR columns over
    ``window``, with Λ_i = t·X_i (linear interpolation in t): the
    approximations of the Lyapunov exponents that govern a GALI's decay
    over that time (the paper's eq. 14)."""
    t = np.asarray(t, dtype=float)
    lam = np.asarray(exponents, dtype=float) * t[:, None]
    a, b = window
    return np.array([(np.interp(b, t, lam[:, i]) - np.interp(a, t, lam[:, i])) / (b - a)
                     for i in range(lam.shape[1])])


def x1_law_excess(t, x1, fit=(1e2, 1e4)):
    """How much longer the vector of X1 is than linear growth predicts:
    Λ − (A ln t + B), with Λ = t·X1 and A, B fitted over ``fit`` (natural
    logarithm of the length ratio). A sticky chaotic orbit leaves the
    regular law X1 ∝ 1/t when this grows."""
    t, x1 = np.asarray(t, dtype=float), np.asarray(x1, dtype=float)
    lam = x1 * t
    w = (t >= fit[0]) & (t <= fit[1])
    a, b = np.polyfit(np.log(t[w]), lam[w], 1)
    return lam - (a * np.log(t) + b)


def stretch_excess(t, x1, t_ref, x1_ref):
    """How much more a method has stretched its vector than a reference run
    of the same orbit and initial vector: Λ − Λ_ref with Λ = t·X1 (the
    accumulated log-stretching, the criterion of :func:`varint.departure`).
    The reference is interpolated in log t, so it may have another τ.

    Returns
    -------
    t : ndarray
        The times of the method within the reference's horizon.
    excess : ndarray
    """
    t, x1 = np.asarray(t, dtype=float), np.asarray(x1, dtype=float)
    lam_ref = np.interp(np.log(t), np.log(t_ref), np.asarray(x1_ref) * np.asarray(t_ref))
    inside = t <= t_ref[-1] * (1 + 1e-12)
    return t[inside], (x1 * t - lam_ref)[inside]


def growth_after(t, x1, t_d):
    """The mean growth rate of Λ = t·X1 after ``t_d``: where X1 levels off
    once its vector grows exponentially. None if ``t_d`` is None or the run
    ends before 2·t_d."""
    t, x1 = np.asarray(t, dtype=float), np.asarray(x1, dtype=float)
    if t_d is None or t[-1] < 2 * t_d:
        return None
    j = int(np.searchsorted(t, t_d))
    return float((x1[-1] * t[-1] - x1[j] * t[j]) / (t[-1] - t[j]))


def gali_deficit(t, g, t_ref, g_ref):
    """How far GALI ``g`` is below a reference run's ``g_ref``
    (interpolated in log t, log g): ln g_ref − ln g.

    Returns
    -------
    t : ndarray
        The times within the reference's horizon.
    deficit : ndarray
    """
    tiny = np.finfo(float).tiny
    t = np.asarray(t, dtype=float)
    inside = t <= t_ref[-1] * (1 + 1e-12)
    log_ref = np.interp(np.log(t[inside]), np.log(t_ref), np.log(np.maximum(g_ref, tiny)))
    return t[inside], log_ref - np.log(np.maximum(np.asarray(g)[inside], tiny))


def law_deficit(t, g, power, fit=(1e2, 1e3)):
    """How far g is below the power law c·t^power, c fitted over the window
    ``fit``: ln(c·t^power) − ln g."""
    t, g = np.asarray(t, dtype=float), np.asarray(g, dtype=float)
    tiny = np.finfo(float).tiny
    w = (t >= fit[0]) & (t <= fit[1])
    log_c = float(np.mean(np.log(np.maximum(g[w], tiny)) - power * np.log(t[w])))
    return log_c + power * np.log(t) - np.log(np.maximum(g, tiny))


def regular_gali_powers(n_dof, torus_dim=None):
    """Exponents p of GALI_k ∝ t^p for a regular orbit on an s-torus of an
    N-dof system (Skokos, Bountis & Antonopoulos 2008; the paper's eq. 15
    for s = N): 0 for k ≤ s, −(k − s) for s < k ≤ 2N − s, −2(k − N) for
    2N − s < k ≤ 2N.

    Returns a dict k -> p for k = 2..2N.
    """
    s = n_dof if torus_dim is None else torus_dim
    out = {}
    for k in range(2, 2 * n_dof + 1):
        out[k] = 0 if k <= s else (-(k - s) if k <= 2 * n_dof - s else -2 * (k - n_dof))
    return out

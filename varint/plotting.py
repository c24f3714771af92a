"""Plots of results in the paper's style: log-log X_i(t) with a 1/t guide,
GALI_k(t) with the power laws of regular motion, surfaces of section
(Figs. 1 and 6) and chaos maps. :func:`plot` (``result.plot()``) picks the
right one for any result.

matplotlib is imported lazily, so the rest of varint never needs it.
"""

from __future__ import annotations

import numpy as np

__all__ = ["plot", "plot_lyapunov", "plot_gali", "plot_sali", "plot_megno",
           "plot_energy_error", "plot_series", "plot_section", "plot_chaos_map"]


def _axes(ax):
    if ax is None:
        import matplotlib.pyplot as plt

        _, ax = plt.subplots(figsize=(5, 3.6), layout="constrained")
    return ax


def _guide(ax, t, y_end, power, label=None, color="k", decades=3.0, span=None):
    """A power law t^power through the last point, over the last decades
    (where the asymptotic law should hold), and only where it stays within
    ``span`` = (low, high): a steep law over a short run would otherwise
    stretch the y-axis by many decades (t⁻⁴ over three decades is 1e12)."""
    t = np.asarray(t, dtype=float)
    t_end = t[-1]
    start = max(t[0], t_end * 10.0 ** -decades)
    if span is not None and power != 0:
        # The law leaves [low, high] at t_end (bound / y_end)^(1 / power);
        # only a crossing before t_end cuts the guide.
        for bound in span:
            crossing = t_end * (bound / y_end) ** (1.0 / power)
            if crossing < t_end:
                start = max(start, crossing)
    if not start < t_end:
        return
    t = np.geomspace(start, t_end, 50)
    ax.loglog(t, y_end * (t / t_end) ** power, "--", color=color, lw=0.8, label=label)


def _power_label(power):
    return rf"$\propto t^{{{power:g}}}$"


def plot_lyapunov(result, ax=None, which=None, guide=True):
    """log-log X_i(t) for the exponents ``which`` (default: the positive
    half, X_1 … X_N), with a 1/t line (paper eq. 12).

    Parameters
    ----------
    result : LyapunovResult
        A single-orbit result.
    ax : matplotlib Axes, optional
    which : sequence of int, optional
        Zero-based exponent indices.
    guide : bool
        Draw the ∝ 1/t law of regular orbits.
    """
    ax = _axes(ax)
    X = np.asarray(result.exponents)
    if X.ndim != 2:
        raise ValueError("plot_lyapunov takes a single-orbit result; index the batch first")
    which = range(max(1, X.shape[1] // 2)) if which is None else which
    for i in which:
        ax.loglog(result.t, np.abs(X[:, i]), label=f"$|X_{{{i + 1}}}|$")
    if guide:
        _guide(ax, result.t, abs(X[-1, 0]), -1.0, _power_label(-1))
    ax.set_xlabel("t")
    ax.set_ylabel("finite-time LCE")
    ax.legend(fontsize=8)
    return ax


def plot_gali(result, ax=None, n_dof=None, guide=True):
    """GALI_k(t) on log-log axes, with the regular-orbit laws
    GALI_k ∝ t^{−2(k−N)} for k > N (paper eq. 17) when ``guide``.

    ``n_dof`` (torus dimension N) defaults to half the phase-space
    dimension of the model in the result's provenance.
    """
    ax = _axes(ax)
    n = n_dof or result.provenance.model.get("n_dof")
    series = {k: np.asarray(g) for k, g in sorted(result.gali.items())}
    if any(g.ndim != 1 for g in series.values()):
        raise ValueError("plot_gali takes a single-orbit result; index the batch first")
    # The guides stay within the decades the GALIs themselves span.
    positive = np.concatenate([g[g > 0] for g in series.values()] + [np.empty(0)])
    span = (positive.min(), positive.max()) if positive.size else None
    for k, g in series.items():
        line, = ax.loglog(result.t, g, label=f"GALI$_{{{k}}}$")
        if guide and n is not None and k > n and g[-1] > 0:
            _guide(ax, result.t, g[-1], -2.0 * (k - n), _power_label(-2.0 * (k - n)),
                   color=line.get_color(), span=span)
    ax.set_xlabel("t")
    ax.set_ylabel("GALI")
    ax.legend(fontsize=8)
    return ax


def plot_sali(result, ax=None):
    """SALI(t) on log-log axes."""
    ax = _axes(ax)
    ax.loglog(result.t, np.asarray(result.sali), label="SALI")
    ax.set_xlabel("t")
    ax.set_ylabel("SALI")
    ax.legend(fontsize=8)
    return ax


def plot_megno(result, ax=None, which="megno"):
    """MEGNO Y(t) and its mean Ȳ(t) with the regular-orbit value 2
    (``which="megno"``), or FLI and OFLI (``which="fli"``), against log t.
    Chaotic orbits: Ȳ ≈ χ₁t/2, FLI ≈ χ₁t."""
    ax = _axes(ax)
    if np.ndim(result.megno) != 1:
        raise ValueError("plot_megno takes a single-orbit result; index the batch first")
    if which == "megno":
        ax.semilogx(result.t, result.megno, lw=0.6, alpha=0.6, label="$Y$")
        ax.semilogx(result.t, result.mean_megno, label=r"$\bar Y$")
        ax.axhline(2.0, ls="--", color="k", lw=0.8, label="2 (regular)")
        ax.set_ylabel("MEGNO")
    elif which == "fli":
        ax.semilogx(result.t, result.fli, label="FLI")
        ax.semilogx(result.t, result.ofli, label="OFLI")
        ax.set_ylabel("ln ‖w‖")
    else:
        raise ValueError(f"which must be 'megno' or 'fli', got {which!r}")
    ax.set_xlabel("t")
    ax.legend(fontsize=8)
    return ax


def plot_energy_error(result, ax=None):
    """Relative energy error against t on log-log axes (any time-series
    result of one orbit)."""
    ax = _axes(ax)
    err = np.asarray(result.energy_error)
    if err.ndim != 1:
        raise ValueError("plot_energy_error takes a single-orbit result; index the batch first")
    ax.loglog(result.t, np.maximum(err, np.finfo(float).tiny), label="|ΔH/H|")
    ax.set_xlabel("t")
    ax.set_ylabel("relative energy error")
    return ax


def plot_series(result, ax=None):
    """Every per-output field of a single-orbit result against log t (the
    plot of a user-registered indicator's :class:`~varint.results.IndicatorResult`
    and of local exponents): one line per field and trailing index."""
    import dataclasses

    ax = _axes(ax)
    t = np.asarray(result.t)
    skip = {"t", "energy_error", "state", "status", "deviations"}
    for f in dataclasses.fields(result):
        value = getattr(result, f.name)
        series = value if isinstance(value, dict) else {f.name: value}
        for name, arr in series.items():
            arr = np.asarray(arr) if f.name not in skip else None
            if arr is None or arr.dtype.kind != "f" or arr.ndim == 0 or arr.shape[0] != len(t):
                continue
            columns = arr.reshape(len(t), -1)
            for j in range(columns.shape[1]):
                label = str(name) if columns.shape[1] == 1 else f"{name}[{j}]"
                ax.semilogx(t, columns[:, j], label=label)
    ax.set_xlabel("t")
    ax.legend(fontsize=8)
    return ax


def _section_axes(plane, dim):
    n = dim // 2
    j = (plane + 1) % n
    return j, n + j


def _state_label(index, dim):
    n = dim // 2
    names = ("x", "y", "z") if n <= 3 else None
    base = names[index % n] if names else f"q_{{{index % n}}}"
    return f"${base}$" if index < n else f"$p_{{{base.strip('$')}}}$"


def plot_section(result, ax=None, axes=None, color="k", size=0.3, label=None):
    """The crossings of a :class:`~varint.results.SectionResult` (all its
    orbits) as points, by default in the plane (q_j, p_j) of the next
    coordinate after the section's (y, p_y for the x = 0 section of
    Hénon–Heiles, as in the paper's Figs. 1 and 6)."""
    ax = _axes(ax)
    pts = np.asarray(result.points)
    pts = pts.reshape(-1, pts.shape[-1])
    i, j = _section_axes(result.plane, pts.shape[-1]) if axes is None else axes
    ax.scatter(pts[:, i], pts[:, j], s=size, c=color, marker=".", linewidths=0, label=label)
    ax.set_xlabel(_state_label(i, pts.shape[-1]))
    ax.set_ylabel(_state_label(j, pts.shape[-1]))
    return ax


def plot_chaos_map(result, ax=None, log=None, cmap="viridis", colorbar=True):
    """A :class:`~varint.results.ChaosMapResult`: an image over the grid of
    a section map, else the values at the first two varying coordinates of
    the initial conditions. ``log`` (default: the indicator spans decades)
    shows log₁₀ of the values."""
    ax = _axes(ax)
    values = np.asarray(result.values, dtype=float)
    if log is None:  # indicators that fall exponentially on chaotic orbits
        log = result.indicator == "sali" or result.indicator.startswith("gali")
    label = result.indicator.upper().replace("_", " ")
    if log:
        with np.errstate(divide="ignore", invalid="ignore"):
            values = np.log10(values)
        label = f"log$_{{10}}$ {label}"
    dim = result.x0.shape[1]
    if result.axes is not None:
        image = np.full(result.mask.shape, np.nan)
        image[result.mask] = values
        u, v = result.u, result.v
        art = ax.pcolormesh(u, v, image, cmap=cmap, shading="nearest")
        i, j = result.axes
    else:
        varying = np.flatnonzero(np.ptp(result.x0, axis=0) > 0)
        if len(varying) < 2:
            raise ValueError("plot_chaos_map needs initial conditions that vary in two "
                             "coordinates")
        i, j = varying[:2]
        art = ax.scatter(result.x0[:, i], result.x0[:, j], c=values, s=4, cmap=cmap)
    ax.set_xlabel(_state_label(i, dim))
    ax.set_ylabel(_state_label(j, dim))
    if colorbar:
        ax.figure.colorbar(art, ax=ax, label=label)
    return ax


def _one_orbit(result, orbit):
    """The ``orbit``-th orbit of a batch result, as a single-orbit result."""
    import dataclasses

    m = len(result.status)
    if not 0 <= orbit < m:
        raise ValueError(f"orbit must be in 0..{m - 1}, got {orbit!r}")
    changes = {}
    for f in dataclasses.fields(result):
        value = getattr(result, f.name)
        if f.name == "t":
            continue
        if isinstance(value, dict):
            changes[f.name] = {k: np.asarray(v)[orbit] for k, v in value.items()}
        elif isinstance(value, np.ndarray) and value.ndim and value.shape[0] == m:
            changes[f.name] = value[orbit]
    return dataclasses.replace(result, **changes)


def plot(result, ax=None, orbit=None, **kwargs):
    """Plot any result in its natural form: X_i(t) with the 1/t guide,
    GALI_k(t) with the regular laws, SALI(t), MEGNO with its regular value
    2, the energy error of a plain integration, a surface of section, a
    chaos map.

    Parameters
    ----------
    result : any varint result
    ax : matplotlib Axes, optional
    orbit : int, optional
        Which orbit of a batch time-series result to show.
    **kwargs
        Passed to the specific function.
    """
    # Dispatch on the result class's plot_kind, so that this module needs
    # no result class (results.py imports it for result.plot()).
    kind = getattr(result, "plot_kind", None)
    if kind == "chaos_map":
        return plot_chaos_map(result, ax, **kwargs)
    if kind == "section":
        return plot_section(result, ax, **kwargs)
    functions = {"lyapunov": plot_lyapunov, "gali": plot_gali, "sali": plot_sali,
                 "megno": plot_megno, "energy_error": plot_energy_error,
                 "series": plot_series}
    if kind in functions:
        if np.ndim(result.status) == 1:
            if orbit is None:
                raise ValueError("this result holds a batch of orbits: pass orbit= to plot one")
            result = _one_orbit(result, orbit)
        return functions[kind](result, ax, **kwargs)
    raise ValueError(f"no plot for {type(result).__name__}")

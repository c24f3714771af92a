"""Plots of results in the paper's style: log-log X_i(t) with a 1/t guide,
GALI_k(t) with the power laws of regular motion, surfaces of section
(Figs. 1 and 6), chaos maps, lattices' spreading and chaos as log–log
panels, and ensembles as mean ± spread over realisations. :func:`plot` (``result.plot()``) picks the
right one for any result.

matplotlib is imported lazily, so the rest of varint never needs it.
"""

from __future__ import annotations

import numpy as np

from .models.registry import state_names

__all__ = ["plot", "plot_lyapunov", "plot_gali", "plot_sali", "plot_megno",
           "plot_energy_error", "plot_series", "plot_section", "plot_chaos_map",
           "plot_lattice", "plot_ensemble"]


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


def plot_megno(result, ax=None, which="megno", guide=True):
    """MEGNO Y(t) and its mean Ȳ(t) with the regular-orbit value 2
    (``which="megno"``; the line 2 when ``guide``), or FLI and OFLI
    (``which="fli"``), against log t. Chaotic orbits: Ȳ ≈ χ₁t/2,
    FLI ≈ χ₁t."""
    ax = _axes(ax)
    if np.ndim(result.megno) != 1:
        raise ValueError("plot_megno takes a single-orbit result; index the batch first")
    if which == "megno":
        ax.semilogx(result.t, result.megno, lw=0.6, alpha=0.6, label="$Y$")
        ax.semilogx(result.t, result.mean_megno, label=r"$\bar Y$")
        if guide:
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


def _state_label(index, dim, model=None):
    """The axis label of state component ``index``: the model's own name
    for it (:func:`varint.models.registry.state_names`: x, p_y, a map's
    x1 …, a SymPy model's symbols), in math type."""
    names = state_names(model or {}, dim)
    name = names[index]
    if name.startswith("p_"):
        return rf"$p_{{{_tex(name[2:])}}}$"
    return f"${_tex(name)}$"


def _tex(name):
    """x1 → x_{1}; q_2 → q_{2}; a longer name upright."""
    import re

    found = re.fullmatch(r"([A-Za-z])_?(\d+)", name)
    if found:
        return f"{found.group(1)}_{{{found.group(2)}}}"
    return name if len(name) == 1 else rf"\mathrm{{{name}}}"


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
    ax.set_xlabel(_state_label(i, pts.shape[-1], result.provenance.model))
    ax.set_ylabel(_state_label(j, pts.shape[-1], result.provenance.model))
    return ax


#: Colours of what a chaos map's colour scale cannot show.
OUTSIDE_COLOR = "0.85"      # not started: outside the energy surface's allowed region
ZERO_COLOR = "black"        # reached 0 (SALI or GALI below double round-off)
FAILED_COLOR = "magenta"    # the orbit failed (escaped, overflowed, ...)


def _spans_decades(values, decades=2.0):
    """Whether the positive values span more than ``decades`` decades
    between their 1st and 99th percentiles, all finite values being > 0."""
    finite = values[np.isfinite(values)]
    if not finite.size or np.any(finite <= 0):
        return False
    lo, hi = np.percentile(finite, [1, 99])
    return hi > lo * 10 ** decades


def plot_chaos_map(result, ax=None, log=None, cmap="viridis", colorbar=True):
    """A :class:`~varint.results.ChaosMapResult`: an image over the grid of
    a section map, else the values at the first two varying coordinates of
    the initial conditions, axes named after the model's coordinates.

    Three things the colour scale cannot show get colours of their own,
    named in a legend: grid points outside the allowed region (no orbit,
    light grey), values that reached 0 (SALI or GALI below double
    round-off, black; with ``log`` they have no logarithm) and failed
    orbits (magenta).

    Parameters
    ----------
    log : bool, optional
        Colour by log₁₀ of the values. By default when the indicator is
        read on a log scale (``result.log_scale``, which the map copied from
        ``Indicator.log_scale``: SALI, GALI) or its positive values span
        more than two decades (MEGNO or FLI with a few strongly chaotic
        orbits), so that outliers do not flatten the rest.
    """
    import matplotlib as mpl
    from matplotlib.patches import Patch

    ax = _axes(ax)
    values = np.asarray(result.values, dtype=float)
    failed = np.asarray(result.status) > 0
    zero = (values == 0) & ~failed
    if log is None:
        log = bool(result.log_scale) or _spans_decades(values[~zero])
    label = result.indicator.upper().replace("_", " ")
    shown = values.copy()
    if log:
        with np.errstate(divide="ignore", invalid="ignore"):
            shown = np.log10(values)
        label = f"log$_{{10}}$ {label}"
    finite = shown[np.isfinite(shown) & ~zero]
    lo, hi = ((finite.min(), finite.max()) if finite.size else (0.0, 1.0))
    if hi <= lo:
        hi = lo + 1.0
    # Zeros sit below the scale (the colour map's "under" colour); failed
    # orbits and grid points without one are masked ("bad", then drawn).
    shown[zero] = lo - 1.0
    shown[failed] = np.nan
    colours = (mpl.colormaps[cmap] if isinstance(cmap, str) else cmap).with_extremes(
        under=ZERO_COLOR, bad=OUTSIDE_COLOR)
    norm = mpl.colors.Normalize(lo, hi)
    dim = result.x0.shape[1]
    model = result.provenance.model
    if result.axes is not None:
        image = np.full(result.mask.shape, np.nan)
        image[result.mask] = shown
        art = ax.pcolormesh(result.u, result.v, np.ma.masked_invalid(image), cmap=colours,
                            norm=norm, shading="nearest")
        if failed.any():
            bad = np.zeros(result.mask.shape)
            bad[result.mask] = failed
            ax.pcolormesh(result.u, result.v, np.ma.masked_equal(bad, 0),
                          cmap=mpl.colors.ListedColormap([FAILED_COLOR]), shading="nearest")
        i, j = result.axes
        outside = not result.mask.all()
    else:
        varying = np.flatnonzero(np.ptp(result.x0, axis=0) > 0)
        if len(varying) < 2:
            raise ValueError("plot_chaos_map needs initial conditions that vary in two "
                             "coordinates")
        i, j = varying[:2]
        art = ax.scatter(result.x0[~failed, i], result.x0[~failed, j], c=shown[~failed], s=4,
                         cmap=colours, norm=norm)
        if failed.any():
            ax.scatter(result.x0[failed, i], result.x0[failed, j], c=FAILED_COLOR, s=4)
        outside = False
    ax.set_xlabel(_state_label(i, dim, model))
    ax.set_ylabel(_state_label(j, dim, model))
    if colorbar:
        ax.figure.colorbar(art, ax=ax, label=label, extend="min" if zero.any() else "neither")
    legend = ([Patch(color=OUTSIDE_COLOR, label="outside the allowed region")] if outside
              else []) + \
        ([Patch(color=ZERO_COLOR, label=f"{result.indicator.upper()} = 0")] if zero.any()
         else []) + \
        ([Patch(color=FAILED_COLOR, label="failed")] if failed.any() else [])
    if legend:
        ax.legend(handles=legend, fontsize=7, loc="upper right", framealpha=0.8)
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


#: The panels of a lattice result or ensemble: (title, y label, [(series,
#: legend)]); a panel is drawn when its first series is there.
LATTICE_PANELS = (
    ("finite-time mLCE", r"$\Lambda = X_1$", [("x1", None)]),
    ("second moment", r"$m_2$", [("m2", "packet"), ("dvd_m2", "DVD")]),
    ("participation number", r"$P$", [("participation", "packet"),
                                      ("dvd_participation", "DVD")]),
)


def _panels(ax, n):
    """``n`` axes side by side: new ones, or ``ax``'s place split in ``n``."""
    import matplotlib.pyplot as plt

    if ax is None:
        _, axes = plt.subplots(1, n, figsize=(3.4 * n, 3.2), layout="constrained",
                               squeeze=False)
        return list(axes[0])
    if np.ndim(ax):
        axes = list(np.ravel(ax))
        if len(axes) < n:
            raise ValueError(f"this plot has {n} panels; got {len(axes)} axes")
        return axes[:n]
    fig, spec = ax.figure, ax.get_subplotspec()
    if spec is None:
        raise ValueError(f"this plot has {n} panels: pass n axes, or an Axes of a grid")
    ax.remove()
    return [fig.add_subplot(cell) for cell in spec.subgridspec(1, n)]


def _lattice_series(names):
    return [panel for panel in LATTICE_PANELS if panel[2][0][0] in names]


def plot_lattice(result, ax=None):
    """A lattice result (``"spreading"``, ``"dvd"``) as panels on log–log
    axes: Λ = X₁ with the regular-motion law t⁻¹, the second moment m₂
    and the participation number P of the packet (and of the deviation
    vector distribution), each against t.

    Returns
    -------
    list of Axes
    """
    values = result.values
    panels = _lattice_series(values)
    if not panels:
        raise ValueError("plot_lattice takes the result of a lattice indicator ('spreading', "
                         f"'dvd'); this one holds {', '.join(values)}")
    axes = _panels(ax, len(panels))
    t = np.asarray(result.t)
    for axis, (title, ylabel, series) in zip(axes, panels, strict=True):
        for name, legend in series:
            if name in values:
                axis.loglog(t, np.abs(np.asarray(values[name])), label=legend)
        if series[0][0] == "x1" and len(t):
            _guide(axis, t, abs(float(np.asarray(values["x1"])[-1])), -1.0, _power_label(-1))
        _finish_panel(axis, title, ylabel)
    return axes


def _finish_panel(axis, title, ylabel):
    axis.set_xlabel("t")
    axis.set_ylabel(ylabel)
    axis.set_title(title, fontsize=9)
    if axis.get_legend_handles_labels()[0]:
        axis.legend(fontsize=7)


def plot_ensemble(result, ax=None, names=None):
    """An :class:`~varint.ensemble.EnsembleResult`: ⟨log₁₀ v⟩ over the
    realisations against t on log–log axes, shaded ± one standard
    deviation of log₁₀ v (the spread of the realisations), one panel per
    quantity: for a lattice ensemble Λ, m₂ and P as in :func:`plot_lattice`,
    otherwise every series of one value per output (or ``names``).

    Returns
    -------
    list of Axes
    """
    values = result.values
    if names is None:
        panels = _lattice_series(values)
        if not panels:
            singles = [n for n, v in values.items() if np.ndim(v) == 2]
            panels = [(n, n, [(n, None)]) for n in singles]
    else:
        unknown = [n for n in names if n not in values]
        if unknown:
            raise ValueError(f"this ensemble holds {', '.join(values)}; not {unknown[0]!r}")
        panels = [(n, n, [(n, None)]) for n in names]
    axes = _panels(ax, len(panels))
    t = np.asarray(result.t)
    realisations = len(result.seeds)
    for axis, (title, ylabel, series) in zip(axes, panels, strict=True):
        for name, legend in series:
            if name not in values:
                continue
            mean, std, _ = result.log_mean(name)
            line, = axis.loglog(t, 10 ** mean, label=legend)
            axis.fill_between(t, 10 ** (mean - std), 10 ** (mean + std), alpha=0.25,
                              color=line.get_color(), linewidth=0)
        if realisations > 1:
            _finish_panel(axis, f"{title}\n{realisations} realisations, mean ± 1σ",
                          rf"$\langle$ {ylabel} $\rangle$")
        else:
            _finish_panel(axis, title, ylabel)
    return axes


def _overlay(function, result, ax, **kwargs):
    """Every orbit of a batch on one axes: orbit m's lines labelled with m
    (the first few), the laws drawn once, through the most regular-looking
    orbit — the smallest final X₁, the largest final GALI of the highest
    order — so that a regular-motion law is not drawn through a chaotic
    orbit."""
    ax = _axes(ax)
    m = len(result.status)
    headline = result.headline()
    chosen = 0
    if headline:
        last = np.abs(np.asarray(headline[-1 if function is plot_gali else 0][1], dtype=float))
        if np.isfinite(last).any():
            chosen = int(np.nanargmax(last) if function is plot_gali else np.nanargmin(last))
    draws_guide = "guide" in function.__code__.co_varnames and kwargs.get("guide", True)
    for k in range(m):
        before = len(ax.lines)
        extra = {"guide": draws_guide and k == chosen} if draws_guide else {}
        function(_one_orbit(result, k), ax, **{**kwargs, **extra})
        for line in ax.lines[before:]:
            label = line.get_label()
            if label.startswith("_") or line.get_linestyle() == "--":
                continue
            line.set_label(f"orbit {k}: {label}" if k < 4 else "_")
            line.set_alpha(0.8 if m <= 8 else 0.4)
    handles, labels = ax.get_legend_handles_labels()
    if handles:
        ax.legend(handles, labels, fontsize=7 if m > 2 else 8)
    return ax


def plot(result, ax=None, orbit=None, **kwargs):
    """Plot any result in its natural form: X_i(t) with the 1/t guide,
    GALI_k(t) with the regular laws, SALI(t), MEGNO with its regular value
    2, the energy error of a plain integration, a surface of section, a
    chaos map, a lattice's spreading and chaos as log–log panels, an
    ensemble's mean ± spread. A batch of orbits is drawn overlaid (or one
    of them, with ``orbit=``).

    Parameters
    ----------
    result : any varint result
    ax : matplotlib Axes, optional
        For the panel plots (lattices, ensembles): an Axes whose place they
        share, or one Axes per panel.
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
    if kind == "ensemble":
        return plot_ensemble(result, ax, **kwargs)
    functions = {"lyapunov": plot_lyapunov, "gali": plot_gali, "sali": plot_sali,
                 "megno": plot_megno, "energy_error": plot_energy_error,
                 "series": plot_series}
    if kind in functions:
        function = functions[kind]
        if kind == "series" and _lattice_series(getattr(result, "values", None) or {}):
            function = plot_lattice
        if np.ndim(result.status) == 1:
            if orbit is None:
                if function is plot_lattice:
                    raise ValueError("a lattice result of several orbits: pass orbit= to "
                                     "plot one, or use varint.ensemble for realisations")
                return _overlay(function, result, ax, **kwargs)
            result = _one_orbit(result, orbit)
        return function(result, ax, **kwargs)
    raise ValueError(f"no plot for {type(result).__name__}")

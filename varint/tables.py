"""Results as pandas DataFrames (``result.to_dataframe()``).

Time series (Lyapunov exponents, GALIs, SALI, states, energy errors) become
one row per orbit and output time; a surface of section one row per
crossing; a chaos map one row per initial condition. Vector-valued series
get one column per component (X1 … Xk, q0 … p{N−1}), dict-valued ones one
per key (gali_2, gali_3, …). The provenance goes to ``df.attrs``. pandas is
optional: imported here only.
"""

from __future__ import annotations

import dataclasses

import numpy as np

__all__ = ["to_dataframe", "columns"]

#: Fields of every result that are not per-output data.
_SKIP = {"t", "state", "status", "provenance", "interrupted", "deviations"}


def _pandas():
    try:
        import pandas
    except ImportError as exc:
        raise ImportError("to_dataframe() needs pandas: pip install pandas "
                          "(or pip install 'varint[pandas]')") from exc
    return pandas


def _state_names(dim, variables=None):
    # A map model names its own variables (its state need not be (q, p)).
    if variables is not None and len(variables) == dim:
        return list(variables)
    n = dim // 2
    return [f"q{i}" for i in range(n)] + [f"p{i}" for i in range(n)]


def _component_names(name, width):
    if name == "exponents":
        return [f"X{i + 1}" for i in range(width)]
    if name in ("states", "points", "x0"):
        return _state_names(width)
    return [f"{name}_{i}" for i in range(width)]


def to_dataframe(result):
    """``result`` as a pandas DataFrame (see the module docstring)."""
    df = _pandas().DataFrame(columns(result))
    df.attrs["provenance"] = result.provenance.to_dict()
    return df


def columns(result):
    """The table of ``result`` as a dict of equally long 1-D arrays (what
    :func:`to_dataframe` and the command line's CSV files hold)."""
    from .results import ChaosMapResult, SectionResult

    if isinstance(result, ChaosMapResult):
        out = {"orbit": np.arange(len(result.values))}
        out.update(zip(_state_names(result.x0.shape[1],
                                    result.provenance.model.get("variables")), result.x0.T))
        out.update(value=result.values, t_stop=result.t_stop, status=result.status,
                   energy_error=result.energy_error)
        return out
    if isinstance(result, SectionResult):
        return _sections(result)
    return _time_series(result)


def _sections(result):
    points = np.asarray(result.points)
    times = np.asarray(result.times)
    energy = np.asarray(result.energy_error)
    if points.ndim == 2:
        points, times, energy = points[None], times[None], energy[None]
    keep = ~np.isnan(times)
    orbit = np.broadcast_to(np.arange(len(times))[:, None], times.shape)
    out = {"orbit": orbit[keep], "t": times[keep]}
    out.update(zip(_state_names(points.shape[-1]), points[keep].T))
    out["energy_error"] = energy[keep]
    return out


def _time_series(result):
    """One row per (orbit, output time) from every field laid out as
    ([M,] n_out[, c]); works for any result class that follows that layout."""
    t = np.asarray(result.t)
    batch = np.ndim(result.status) == 1
    m = len(result.status) if batch else 1
    series = {}
    for f in dataclasses.fields(result):
        if f.name in _SKIP:
            continue
        value = getattr(result, f.name)
        items = value.items() if isinstance(value, dict) else [(None, value)]
        for key, arr in items:
            if not isinstance(arr, np.ndarray):
                continue
            arr = arr if batch else arr[None]
            if arr.ndim < 2 or arr.shape[:2] != (m, len(t)):
                continue
            name = f.name if key is None else f"{f.name}_{key}"
            if arr.ndim == 2:
                series[name] = arr.reshape(-1)
            else:
                flat = arr.reshape(m * len(t), -1)
                series.update(zip(_component_names(name, flat.shape[1]), flat.T))
    out = {"orbit": np.repeat(np.arange(m), len(t))} if batch else {}
    out["t"] = np.tile(t, m)
    out.update(series)
    return out

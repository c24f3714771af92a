"""Results as labelled arrays and tables: ``result.to_xarray()`` and
``result.to_dataframe()``.

Both come from one description of a result (:func:`layout`): each array of
the result with the names of its dimensions, the coordinates of those
dimensions, and the attributes (the provenance). So a variable has the same
name, and a coordinate the same values, in the Dataset, the DataFrame and
the command line's CSV files.

Dimensions
----------
Time series
    (Lyapunov exponents, GALIs, SALI, MEGNO, local exponents, the orbit,
    any registered indicator's result) ``t`` (the output times), preceded
    by ``orbit`` for a batch, followed by the components of a
    vector-valued series: ``exponent`` (1 … k, the
    i of X_i), ``k`` (the GALI orders), ``component`` (the state labels
    q0 … q{N−1}, p0 … p{N−1}). The final ``state`` is ([orbit,]
    component), the final ``deviations`` ([orbit,] component, vector)
    with vector 1 … k, ``status`` ([orbit]).
Surfaces of section
    ``crossing`` (preceded by ``orbit`` for a batch): ``points``
    ([orbit,] crossing, component), ``times`` and ``energy_error``
    ([orbit,] crossing), NaN after each orbit's ``n_points``.
Chaos maps
    ``orbit`` for a map of an array of initial conditions; for a map of a
    :class:`~varint.sections.SectionGrid`, the grid itself: the two state
    labels of its axes (e.g. ``p1``, ``q1`` for Hénon–Heiles' (y, p_y)),
    with NaN where no orbit was started, ``allowed`` (the energetically
    allowed points) and ``orbit`` (the index of each point's orbit, −1
    where none). The check times of early stopping are the coordinate
    ``t_check``.

Tables
------
:func:`to_dataframe` has one row per orbit and output time (per crossing of
a section, per orbit of a map). Each variable over those dimensions is a
column; one with a component dimension gives a column per component,
named after it: ``X1`` … ``Xk`` for the exponents, ``q0`` … ``p{N−1}`` for
states, ``gali_2``, ``gali_3`` … for the GALIs, ``{name}_{i}`` otherwise.

Attributes
----------
``attrs`` hold the provenance as JSON text under ``"provenance"``
(``Provenance(**json.loads(ds.attrs["provenance"]))`` rebuilds it) and its
main entries as plain values (kind, model, method, scheme, tau, t_end,
seed, varint_version, …), so a Dataset writes to netCDF as it is. A
DataFrame's ``df.attrs["provenance"]`` is the provenance as a dict.

pandas and xarray are optional: each is imported here, when asked for.
"""

from __future__ import annotations

import dataclasses
import json
import numbers
from dataclasses import dataclass, field

import numpy as np

__all__ = ["to_xarray", "to_dataframe", "columns", "layout", "Layout"]

#: Dimension names of the trailing axes of fields, by field name (a result
#: class adds its own with the class attribute ``dims``).
DIMS = {"exponents": ("exponent",), "states": ("component",), "state": ("component",),
        "points": ("component",), "x0": ("component",), "deviations": ("component", "vector"),
        "gali": ("k",)}


@dataclass
class Layout:
    """What a result holds, in named dimensions.

    Attributes
    ----------
    coords : dict of str -> (tuple of str, ndarray)
        Coordinates: name -> (dimensions, values).
    data : dict of str -> (tuple of str, ndarray)
        Variables in the result's field order.
    attrs : dict
        Flat attributes (strings and numbers) including the provenance as
        JSON text.
    rows : tuple of str
        The dimensions of one table row.
    keep : ndarray of bool or None
        Which rows hold data (a section's real crossings); None: all.
    grid : dict or None
        For a map of a section grid: ``mask`` (n_v, n_u) and ``dims`` (the
        names of v and u) onto which the orbit dimension is unfolded.
    """

    coords: dict = field(default_factory=dict)
    data: dict = field(default_factory=dict)
    attrs: dict = field(default_factory=dict)
    rows: tuple = ()
    keep: np.ndarray | None = None
    grid: dict | None = None


def _pandas():
    try:
        import pandas
    except ImportError as exc:
        raise ImportError("to_dataframe() needs pandas: pip install pandas "
                          "(or pip install 'varint[pandas]')") from exc
    return pandas


def _xarray():
    try:
        import xarray
    except ImportError as exc:
        raise ImportError("to_xarray() needs xarray: pip install xarray "
                          "(or pip install 'varint[xarray]')") from exc
    return xarray


def state_labels(dim, variables=None):
    """q0 … q{N−1}, p0 … p{N−1} for a state of length ``dim`` = 2N, or a
    map model's own ``variables`` (its state need not be (q, p))."""
    if variables is not None and len(variables) == dim:
        return [str(v) for v in variables]
    n = dim // 2
    return [f"q{i}" for i in range(n)] + [f"p{i}" for i in range(n)]


def _coordinate(name, size, variables=None):
    if name == "component":
        return np.array(state_labels(size, variables))
    if name in ("exponent", "vector"):
        return np.arange(1, size + 1)
    return np.arange(size)


def _attrs(result):
    """Flat attributes: netCDF holds strings and numbers, not dicts or None."""
    p = result.provenance
    scheme = p.method_options.get("scheme") if isinstance(p.method_options, dict) else None
    if isinstance(scheme, dict):
        scheme = scheme.get("name")
    out = {"result": type(result).__name__, "kind": p.kind, "model": p.model.get("name"),
           "method": p.method, "scheme": scheme, "tau": p.tau, "t_end": p.t_end,
           "seed": p.seed, "varint_version": p.versions.get("varint"), "created": p.created,
           "wall_time": p.wall_time, "interrupted": int(bool(result.interrupted))}
    # Plain scalar fields (a window length, a map's indicator and threshold,
    # a section's plane); NumPy scalars are data (a single orbit's status).
    for f in dataclasses.fields(result):
        value = getattr(result, f.name)
        if isinstance(value, (str, int, float)) and not isinstance(value, (bool, np.generic)):
            out[f.name] = value
    out = {k: v for k, v in out.items() if v is not None}
    out["provenance"] = json.dumps(p.to_dict(), sort_keys=True)
    return out


class _Builder:
    """Collects variables and coordinates, naming unknown dimensions."""

    def __init__(self, result):
        self.result = result
        self.dims = {**DIMS, **getattr(type(result), "dims", {})}
        self.out = Layout(attrs=_attrs(result))
        model = getattr(result.provenance, "model", None)
        self.variables = model.get("variables") if isinstance(model, dict) else None

    def add(self, name, lead, array, trailing=None):
        array = np.asarray(array)
        extra = array.ndim - len(lead)
        if trailing is None:
            trailing = self.dims.get(name, ())
        trailing = tuple(trailing)[:extra]
        trailing += tuple(f"{name}_dim{i}" for i in range(len(trailing), extra))
        dims = tuple(lead) + trailing
        for d, size in zip(dims, array.shape, strict=True):
            if d not in self.out.coords:
                self.out.coords[d] = ((d,), _coordinate(d, size, self.variables))
        self.out.data[name] = (dims, array)


def layout(result):
    """The :class:`Layout` of any varint result (see the module docstring)."""
    # By the result class's layout, so that this module needs no result
    # class (results.py imports it for result.to_xarray()).
    kind = getattr(result, "layout", "series")
    if kind == "map":
        return _map(result)
    if kind == "section":
        return _section(result)
    return _series(result)


def _series(result):
    """Any result laid out as ([M,] n_out, ...) over the output times."""
    b = _Builder(result)
    t = np.asarray(result.t)
    batch = np.ndim(result.status) == 1
    lead = ("orbit",) if batch else ()
    m = len(result.status) if batch else None
    if batch:
        b.out.coords["orbit"] = (("orbit",), np.arange(m))
    b.out.coords["t"] = (("t",), t)
    series = tuple(lead) + ("t",)
    prefix = ((m,) if batch else ()) + (len(t),)
    for f in dataclasses.fields(result):
        name = f.name
        value = getattr(result, name)
        if name in ("t", "provenance", "interrupted") or value is None:
            continue
        if name in ("state", "deviations", "status"):
            b.add(name, lead, value)
        elif isinstance(value, dict) and value and all(
                isinstance(k, numbers.Integral) for k in value):
            # e.g. GALI_k by k: one variable along a dimension of the keys.
            keys = sorted(value)
            dim = b.dims.get(name, (f"{name}_key",))[0]
            b.add(name, series, np.stack([np.asarray(value[k]) for k in keys], axis=-1), (dim,))
            b.out.coords[dim] = ((dim,), np.array(keys))
        elif isinstance(value, dict):
            # e.g. IndicatorResult.values: each series its own variable.
            for key, arr in value.items():
                arr = np.asarray(arr)
                b.add(str(key), series if arr.shape[:len(prefix)] == prefix else lead, arr)
        elif isinstance(value, np.ndarray):
            b.add(name, series if value.shape[:len(prefix)] == prefix else lead, value)
    b.out.rows = series
    return b.out


def _section(result):
    b = _Builder(result)
    batch = np.ndim(result.status) == 1
    lead = ("orbit",) if batch else ()
    if batch:
        b.out.coords["orbit"] = (("orbit",), np.arange(len(result.status)))
    for name in ("times", "points", "energy_error"):
        b.add(name, lead + ("crossing",), getattr(result, name))
    b.add("n_points", lead, result.n_points)
    b.add("status", lead, result.status)
    b.add("state", lead, result.state)
    t = np.asarray(result.t)
    b.add("t_end", lead, t if batch else t.reshape(-1)[0])
    b.out.rows = lead + ("crossing",)
    b.out.keep = np.isfinite(np.asarray(result.times))
    return b.out


def _map(result):
    b = _Builder(result)
    b.out.coords["orbit"] = (("orbit",), np.arange(len(result.values)))
    b.out.coords["t_check"] = (("t_check",), np.asarray(result.t))
    b.add("x0", ("orbit",), result.x0)
    for name, value in (("value", result.values), ("t_stop", result.t_stop),
                        ("status", result.status), ("energy_error", result.energy_error),
                        ("state", result.state)):
        b.add(name, ("orbit",), value)
    b.out.rows = ("orbit",)
    if result.axes is not None:
        labels = state_labels(np.shape(result.x0)[1], b.variables)
        u, v = (labels[int(a)] for a in result.axes)
        b.out.grid = {"mask": np.asarray(result.mask, dtype=bool), "dims": (v, u),
                      "coords": {v: np.asarray(result.v), u: np.asarray(result.u)}}
        b.out.attrs["grid_axes"] = f"{u},{v}"
    return b.out


def _on_grid(lay):
    """The orbit dimension of a map unfolded onto its section grid: NaN (and
    orbit index −1) where no orbit was started."""
    mask = lay.grid["mask"]
    v, u = lay.grid["dims"]
    data = {}
    for name, (dims, arr) in lay.data.items():
        full = np.full(mask.shape + arr.shape[1:], np.nan)
        full[mask] = arr
        data[name] = ((v, u) + dims[1:], full)
    index = np.full(mask.shape, -1)
    index[mask] = lay.coords["orbit"][1]
    data["orbit"] = ((v, u), index)
    data["allowed"] = ((v, u), mask)
    coords = {name: c for name, c in lay.coords.items() if name != "orbit"}
    coords.update({name: ((name,), values) for name, values in lay.grid["coords"].items()})
    return coords, data


def to_xarray(result):
    """``result`` as an :class:`xarray.Dataset` (see the module docstring).
    Needs xarray (``pip install 'varint[xarray]'``)."""
    xr = _xarray()
    lay = layout(result)
    coords, data = (_on_grid(lay) if lay.grid is not None else (lay.coords, lay.data))
    return xr.Dataset(data_vars=data, coords=coords, attrs=lay.attrs)


#: Variables whose components are states: their columns are q0 … p{N−1}.
_STATES = ("states", "points", "x0")
#: Final values, not one per row: in the Dataset, not in the table.
_FINAL = ("state", "deviations")


def _column_names(name, dim, coords):
    if dim == "component" and name in _STATES:
        return [str(c) for c in coords]
    if name == "exponents" and dim == "exponent":
        return [f"X{c}" for c in coords]
    return [f"{name}_{c}" for c in coords]


def columns(result):
    """The table of ``result`` as a dict of equally long 1-D arrays (what
    :func:`to_dataframe` and the command line's CSV files hold): the
    variables of :func:`layout` over its row dimensions, flattened in
    row-major order."""
    lay = layout(result)
    rows = lay.rows
    shape = tuple(len(lay.coords[d][1]) for d in rows)
    keep = np.ones(shape, dtype=bool) if lay.keep is None else lay.keep.reshape(shape)
    index = np.indices(shape)
    out = {}
    if "orbit" in rows:
        out["orbit"] = lay.coords["orbit"][1][index[rows.index("orbit")][keep]]
    elif getattr(result, "layout", None) == "section":  # one orbit: still say which
        out["orbit"] = np.zeros(int(keep.sum()), dtype=int)
    if "t" in rows:
        out["t"] = lay.coords["t"][1][index[rows.index("t")][keep]]
    for name, (dims, arr) in lay.data.items():
        if dims[:len(rows)] != rows or len(dims) > len(rows) + 1 or name in _FINAL:
            continue
        column = "t" if (name == "times" and "t" not in rows) else name
        if len(dims) == len(rows):
            out[column] = arr[keep]
        else:
            flat = arr[keep]
            names = _column_names(name, dims[-1], lay.coords[dims[-1]][1])
            out.update(zip(names, flat.T, strict=True))
    return out


def to_dataframe(result):
    """``result`` as a pandas DataFrame (see the module docstring); the
    provenance is in ``df.attrs["provenance"]``. Needs pandas."""
    df = _pandas().DataFrame(columns(result))
    df.attrs["provenance"] = result.provenance.to_dict()
    return df

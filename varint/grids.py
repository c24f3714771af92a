"""Grids of initial conditions on a plane of phase space, for chaos maps of
map models (a 2D map's whole phase space) or of any slice through a higher
one; :func:`varint.section_grid` makes grids on a surface of section of a
flow at fixed energy instead. Both are :class:`SectionGrid` records (data
that models build too, so it lives here, below the runs and the models)."""

from __future__ import annotations

import numbers
from dataclasses import dataclass

import numpy as np

from . import _validate as check

__all__ = ["SectionGrid", "PhaseGrid", "phase_grid"]


@dataclass
class SectionGrid:
    """Initial conditions on a grid of a surface of section at fixed energy.

    Attributes
    ----------
    states : ndarray, shape (M, 2N)
        The valid grid points (row-major over ``mask``), with p_plane ≥ 0
        solved from the energy.
    mask : ndarray of bool, shape (n_v, n_u)
        Which grid points are energetically allowed.
    u, v : ndarray
        Grid values of the two coordinates that vary (``axes``).
    axes : tuple of int
        State indices of u and v (e.g. (1, 3) = (y, p_y) for Hénon–Heiles).
    plane : int
        q_plane = value on the section.
    value, energy : float
    """

    states: np.ndarray
    mask: np.ndarray
    u: np.ndarray
    v: np.ndarray
    axes: tuple
    plane: int
    value: float
    energy: float

    def __len__(self):
        return len(self.states)


@dataclass
class PhaseGrid(SectionGrid):
    """Initial conditions on a grid of the plane spanned by two state
    components (``axes``), the others fixed at ``base``; every point is
    used (``mask`` is all True), ``plane`` is None and ``value``,
    ``energy`` are NaN. :func:`varint.chaos_map` takes it like a
    :class:`~varint.sections.SectionGrid` (``image()`` of the result)."""


def phase_grid(model, u, v, axes=(0, 1), base=None):
    """A grid of initial conditions on the plane of two state components.

    Parameters
    ----------
    model : MapModel or Model
    u, v : array_like
        Values of the two components (e.g. ``np.linspace(0, 2*np.pi, 200)``
        for the standard map's x).
    axes : (int, int), default (0, 1)
        Their state indices: (x, p) of the standard map, (x1, x2) of
        :class:`~varint.models.CoupledStandardMaps`.
    base : array_like, shape (2N,), optional
        Values of the other components (zero by default).

    Returns
    -------
    PhaseGrid
        ``states`` (len(v)·len(u), 2N), row-major over (v, u).

    Examples
    --------
    >>> import numpy as np, varint
    >>> sm = varint.models.StandardMap(1.2)
    >>> g = varint.phase_grid(sm, np.linspace(0, 6, 3), np.linspace(-1, 1, 2))
    >>> g.states.shape
    (6, 2)
    """
    dim = model.dim
    axes = tuple(axes)
    if (len(axes) != 2 or len(set(axes)) != 2
            or any(isinstance(a, bool) or not isinstance(a, numbers.Integral)
                   or not 0 <= a < dim for a in axes)):
        raise ValueError(f"axes must be two distinct state indices in 0..{dim - 1}, "
                         f"got {axes!r}")
    grids = [check.real_array(a, name).reshape(-1) for a, name in ((u, "u"), (v, "v"))]
    for g, name in zip(grids, ("u", "v"), strict=True):
        if g.size == 0 or not np.isfinite(g).all():
            raise ValueError(f"{name} must be a non-empty array of finite values")
    check.check_memory(check.array_bytes((grids[0].size, grids[1].size, dim + 1)),
                       f"a phase grid of {grids[0].size} x {grids[1].size} points")
    base = np.zeros(dim) if base is None else check.real_array(base, "base").reshape(-1)
    if base.shape != (dim,) or not np.isfinite(base).all():
        raise ValueError(f"base must be {dim} finite values, got shape {base.shape}")
    U, V = np.meshgrid(*grids)
    X = np.broadcast_to(base, U.shape + (dim,)).copy()
    X[..., axes[0]], X[..., axes[1]] = U, V
    mask = np.ones(U.shape, dtype=bool)
    return PhaseGrid(states=np.ascontiguousarray(X.reshape(-1, dim)), mask=mask, u=grids[0],
                     v=grids[1], axes=tuple(int(a) for a in axes), plane=None,
                     value=float("nan"), energy=float("nan"))

"""Grids of planetary initial conditions over two orbital elements of one
planet — the stability maps of planetary dynamics (MEGNO over a planet's
(a, e), as in Goździewski et al. 2001 and REBOUND's MEGNO example) — for
:func:`varint.chaos_map`."""

from __future__ import annotations

import numbers

import numpy as np

from ._validate import real_array
from .grids import PhaseGrid

__all__ = ["element_grid"]


def element_grid(model, elements, planet, u, v, axes=("a", "e"), frame="jacobi"):
    """A grid of initial conditions over two orbital elements of one
    planet, the others fixed.

    Parameters
    ----------
    model : Planetary
    elements : sequence of mappings
        Every planet's elements (as :meth:`Planetary.from_elements`); those
        of ``planet`` on ``axes`` are replaced at every grid point.
    planet : int
        Which planet (1-based, inside out, as in ``masses``).
    u, v : array_like
        The values of the two elements (e.g. ``np.linspace(7, 10, 100)``
        for a).
    axes : (str, str), default ("a", "e")
        The two elements that vary, among a, e, inc, Omega, omega, M.
    frame : {"jacobi", "heliocentric"}
        What the elements refer to (:meth:`Planetary.from_elements`).

    Returns
    -------
    PhaseGrid
        ``states`` (len(v)·len(u), 2N) row-major over (v, u); its ``axes``
        are the element names, so ``image()`` of the map's result and
        :func:`varint.plotting.plot_chaos_map` show the elements.

    Raises
    ------
    ValueError
        For a model that is not :class:`Planetary`, a planet or axis that
        does not exist, or a grid point whose elements make no orbit (the
        message names the planet, the element and the value).

    Examples
    --------
    >>> import numpy as np, varint
    >>> model = varint.models.Planetary([1.0, 9.54e-4, 2.86e-4])
    >>> els = [dict(a=5.2, e=0.05), dict(a=9.5, e=0.05, M=1.0)]
    >>> g = varint.element_grid(model, els, 2, np.linspace(8, 10, 3), np.linspace(0, 0.3, 2))
    >>> g.states.shape, g.axes
    ((6, 12), ('a', 'e'))
    """
    # Imported here: ``import varint``'s first public name imports this
    # module, and a run of another model needs no planetary kernels.
    from .models.planetary import ELEMENTS, Planetary

    if not isinstance(model, Planetary):
        raise ValueError(f"element_grid needs a varint.models.Planetary, got {model!r}")
    if isinstance(planet, (bool, np.bool_)) or not isinstance(planet, numbers.Integral) \
            or not 1 <= planet <= model.n_planets:
        raise ValueError(f"planet must be an integer in 1..{model.n_planets}, got {planet!r}")
    axes = tuple(axes) if isinstance(axes, (tuple, list)) else (axes,)
    if len(axes) != 2 or axes[0] == axes[1] or any(a not in ELEMENTS for a in axes):
        raise ValueError(f"axes must be two different elements among {', '.join(ELEMENTS)}, "
                         f"got {axes!r}")
    grids = [real_array(w, name).reshape(-1) for w, name in ((u, "u"), (v, "v"))]
    for g, name in zip(grids, ("u", "v"), strict=True):
        if g.size == 0 or not np.isfinite(g).all():
            raise ValueError(f"{name} must be a non-empty array of finite values")
    if isinstance(elements, dict) or len(elements) != model.n_planets:
        raise ValueError(f"elements must be a sequence of {model.n_planets} mappings (one per "
                         f"planet), got {elements!r}")
    base = [dict(el) for el in elements]
    states = np.empty((grids[1].size, grids[0].size, model.dim))
    for b, vb in enumerate(grids[1]):
        for a, ua in enumerate(grids[0]):
            els = [dict(el) for el in base]
            els[planet - 1].update({axes[0]: float(ua), axes[1]: float(vb)})
            states[b, a] = model.from_elements(els, frame)
    return PhaseGrid(states=states.reshape(-1, model.dim), mask=np.ones(states.shape[:2], bool),
                     u=grids[0], v=grids[1], axes=axes, plane=None, value=float("nan"),
                     energy=float("nan"))

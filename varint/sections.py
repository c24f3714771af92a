"""Poincaré surfaces of section: crossings found to round-off, and grids of
initial conditions on a section at a given energy.

The section is the hyperplane q_i = c crossed in one direction (for
Hénon–Heiles, the paper's x = 0 with p_x ≥ 0, Figs. 1 and 6). Orbits are
integrated by a splitting scheme with the compiled orbit stepper of the TM
method (no deviation vectors). When q_i − c changes sign over a step of
length τ, the crossing is found by *re-integrating* that step from its start
with a shorter step δ ∈ (0, τ] of the same scheme, solving
q_i(Φ_δ(x)) = c by Newton's method on δ (derivative q̇_i = (M⁻¹p)_i)
safeguarded by bisection. So every crossing is a point of the numerical
orbit, with the scheme's own accuracy and energy error, and lies on the
plane to round-off (|q_i − c| ~ 1e-16), not to the O(τ²) of an
interpolation.

References
----------
Skokos & Gerlach, Phys. Rev. E 82, 036704 (2010), Sect. VI.A, Figs. 1 and 6;
M. Hénon, Physica D 5, 412 (1982) (on computing crossings accurately).
"""

from __future__ import annotations

import numbers
import time
from collections import namedtuple
from functools import cache

import numpy as np
import numba
from numba import njit
from numpy.typing import ArrayLike

from .kernels import tm as K
from .kernels.closures import cache_on_disk
from .kernels.interval import Call
from .models.base import Model
from .protocol import COUNTERS, STATUS_OK, Renorm, Status
from . import _validate as check
from . import identity
from .accuracy import assess, warn
from .results import Provenance, SectionResult, package_versions
from .runspec import specify
from .schemes import SplittingScheme, get_scheme, stage_arrays
from .threads import in_threads
# The grid of initial conditions is data of the grids layer (models build it
# too, below this module); imported here, where it has always been named.
from .grids import SectionGrid

__all__ = ["surface_of_section", "section_grid", "SectionGrid"]

_OK = int(Status.OK)
_NONE = int(Renorm.NONE)
#: Newton iterations at most per crossing (it converges in 3–5).
_MAX_NEWTON = 60
#: Crossings stored per orbit and kernel call; an orbit with more pauses
#: and continues in the next call, so memory stays bounded.
_BUFFER = 4096


#: What the section finder reads besides the orbits and the scheme: the
#: steps to go, the squared escape radius, the section q_plane = value and
#: its direction, the crossings wanted per orbit, τ.
_Section = namedtuple("_Section", ("n_steps", "escape_r2", "plane", "value", "direction",
                                   "max_points", "tau"))


@njit
def _scaled_step(orbit, state, frac, setup, scaled):
    """One step of length frac·τ of the orbit record ``state`` (in place) by
    ``orbit``: drifts and kicks scale with the step, the corrector with its
    cube (see :func:`varint.schemes.stage_arrays`); ``scaled`` is the
    TMSetup whose ``h`` and ``hc`` receive them."""
    for i in range(setup.h.shape[0]):
        scaled.h[i] = setup.h[i] * frac
        scaled.hc[i] = setup.hc[i] * frac ** 3
    return orbit(state, scaled, Call(1, 0, 0.0, _NONE, np.inf))


@cache
def _section_kernel(n, bw, kernels):
    """The batch section finder for N = ``n`` and bandwidth ``bw`` (−1:
    sizes read at run time) of the model ``kernels``: the serial kernel
    (:func:`_serial_sections`) on threads over slices of the orbits
    (:func:`varint.threads.in_threads`; every argument but the last two
    has a leading axis of orbits), each orbit's bits the serial ones."""
    sections = _serial_sections(n, bw, kernels)

    def threaded(X, done, status, counts, n_found, points, setup, find):
        def work(lo, hi):
            sections(X[lo:hi], done[lo:hi], status[lo:hi], counts[lo:hi], n_found[lo:hi],
                     points[lo:hi], setup, find)

        in_threads(work, X.shape[0])

    return threaded


def _serial_sections(n, bw, kernels):
    """The section finder of :func:`_section_kernel` over its orbits one
    after the other, compiled with ``nogil=True`` and cached on disk."""
    orbit = K.orbit_kernel(n, bw, kernels)

    @njit(nogil=True)
    def sections(X, done, status, counts, n_found, points, setup, find):
        """Advance orbit m from step done[m] towards n_steps in blocks of
        steps, writing each crossing into a free row of points[m] as
        (state, time in steps); a row with a NaN time is free. Returns to
        the caller when the buffer could overflow or max_points are found."""
        d = X.shape[1]
        nd = d // 2
        block = 256
        n_steps, plane, value, direction = find.n_steps, find.plane, find.value, find.direction
        max_points = find.max_points
        for m in range(X.shape[0]):
            points[m, :, d] = np.nan
            if status[m] != _OK:
                continue
            x = X[m]
            start = np.empty(d)
            y = np.empty(d)
            # No vectors, no accumulator (k = 0): the orbit through a block,
            # and the one step of Newton's iteration from y.
            no_W, no_m, no_e = np.empty((d, 0)), np.ones(0), np.zeros(0, dtype=np.int64)
            record = K.TMOrbit(x, no_W, no_m, no_e, np.empty((0, 0)), counts[m], np.empty(0),
                               np.empty((block, d)))
            newton = K.TMOrbit(y, no_W, no_m, no_e, np.empty((0, 0)), counts[m], np.empty(0),
                               np.empty((1, d)))
            scaled = K.TMSetup(setup.kinds, np.empty(setup.h.shape[0]),
                               np.empty(setup.h.shape[0]), setup.minv, setup.par, setup.bw,
                               setup.ctime)
            rec = record.record
            minv = setup.minv
            found = 0
            while (done[m] < n_steps and n_found[m] < max_points
                   and points.shape[1] - found >= block):
                nb = min(block, n_steps - done[m])
                for i in range(d):
                    start[i] = x[i]
                st, ok = orbit(record, setup, Call(nb, 0, 0.0, _NONE, find.escape_r2))
                for j in range(ok):
                    prev = start if j == 0 else rec[j - 1]
                    f0 = prev[plane] - value
                    f1 = rec[j, plane] - value
                    if direction > 0:
                        crossing = f0 < 0.0 <= f1
                    elif direction < 0:
                        crossing = f0 > 0.0 >= f1
                    else:
                        crossing = (f0 < 0.0 <= f1) or (f0 > 0.0 >= f1)
                    if not crossing or n_found[m] >= max_points:
                        continue
                    # Safeguarded Newton on the fraction s of the step:
                    # g(s) = q_plane(Φ_{sτ}(prev)) − c, bracketed by [lo, hi].
                    lo, hi, glo = 0.0, 1.0, f0
                    s = f0 / (f0 - f1)
                    tol = 1e-15 * max(1.0, abs(value))
                    for _ in range(_MAX_NEWTON):
                        for i in range(d):
                            y[i] = prev[i]
                        _scaled_step(orbit, newton, s, setup, scaled)
                        g = y[plane] - value
                        if abs(g) <= tol or hi - lo <= 1e-16:
                            break
                        if (g < 0.0) == (glo < 0.0):
                            lo, glo = s, g
                        else:
                            hi = s
                        rate = minv[plane] * y[nd + plane] * find.tau
                        s_new = s - g / rate if rate != 0.0 else -1.0
                        # Outside the bracket Newton is not to be trusted: bisect.
                        s = s_new if lo < s_new < hi else 0.5 * (lo + hi)
                    for i in range(d):
                        points[m, found, i] = y[i]
                    points[m, found, d] = done[m] + j + s
                    found += 1
                    n_found[m] += 1
                done[m] += ok
                if st != _OK:
                    status[m] = st
                    break
        return 0

    return cache_on_disk(sections)


def surface_of_section(model: Model, x0: ArrayLike, t_end: float, tau: float = 0.01,
                       scheme: str | SplittingScheme = "ABA864", plane: int = 0,
                       value: float = 0.0, direction: int = 1, max_points: int | None = None,
                       escape_radius: float | None = None,
                       energy_tol: float | None = None) -> SectionResult:
    """Crossings of orbits with the section q_plane = value.

    Parameters
    ----------
    model : Model
    x0 : array_like, shape (2N,) or (M, 2N)
        Initial states; several orbits run in parallel.
    t_end : float
        Integrate each orbit to this time (or until ``max_points`` crossings).
    tau : float, default 0.01
        Step of the scheme.
    scheme : str or SplittingScheme, default "ABA864"
        Any registered splitting scheme (4th order ABA864 is accurate to
        ~1e-13 in energy on Hénon–Heiles at τ = 0.01).
    plane : int, default 0
        Index i of the coordinate q_i that defines the section.
    value : float, default 0
        The section is q_i = value.
    direction : {1, -1, 0}
        Crossings with q_i increasing (1: p_i > 0 for a positive mass, the
        paper's x = 0, p_x ≥ 0), decreasing (−1), or both (0).
    max_points : int, optional
        Stop an orbit after this many crossings.
    escape_radius : float, optional
        Stop an orbit whose |q| exceeds this (status ESCAPED).
    energy_tol : float, optional
        As for :func:`varint.run`: above this relative energy error at the
        crossings, ``result.accuracy`` says the section is not to be
        trusted and an :class:`~varint.accuracy.AccuracyWarning` says so.

    Returns
    -------
    SectionResult
        ``points`` ([M,] n, 2N) NaN-padded states at the crossings,
        ``times`` ([M,] n), ``n_points``, the relative energy error of every
        crossing, and the provenance.

    Examples
    --------
    The paper's regular orbit R1 crosses x = 0 (p_x ≥ 0) about once per
    6.6 time units, on the plane to round-off:

    >>> import numpy as np, varint
    >>> model, x0 = varint.paper_orbit("R1")
    >>> s = varint.surface_of_section(model, x0, 200.0, tau=0.01)
    >>> int(s.n_points), s.points.shape
    (30, (30, 4))
    >>> bool(np.abs(s.points[:, 0]).max() < 1e-15)
    True
    """
    # The run's inputs checked as every run's are (model, states and the
    # kernels there, times, escape radius, energy tolerance), into the
    # specification of the orbits' integration.
    spec = specify(model, x0, "integrate", t_end, tau, scheme=scheme, seed=None,
                   escape_radius=escape_radius, energy_tol=energy_tol)
    spec = spec.with_step(spec.tau)
    model, X, single, t_end, tau = spec.model, spec.x0, spec.single, spec.t_end, spec.tau
    _autonomous_flow(model)
    if isinstance(plane, bool) or not isinstance(plane, (int, np.integer)) \
            or not 0 <= plane < model.n_dof:
        raise ValueError(f"plane must be a coordinate index in 0..{model.n_dof - 1}, got {plane!r}")
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not np.isfinite(value):
        raise ValueError(f"value must be a finite number, got {value!r}")
    if direction not in (1, -1, 0):
        raise ValueError(f"direction must be 1, -1 or 0, got {direction!r}")
    limit = np.iinfo(np.int64).max
    if max_points is not None:
        if isinstance(max_points, bool) or not isinstance(max_points, (int, np.integer)) \
                or max_points < 1:
            raise ValueError(f"max_points must be a positive integer, got {max_points!r}")
        limit = int(max_points)
    radius = model.escape_radius
    sch = get_scheme(scheme, n_parts=2)
    kinds, h, hc = stage_arrays(sch, tau)
    n_steps = check.step_count(t_end, tau)
    m, d = X.shape
    # The crossing buffer of every orbit, and the states, times and errors
    # of the crossings (at least one row each), before allocating them.
    check.check_memory(check.array_bytes((m, _BUFFER, d + 1), (m, 2 * d + 4)),
                       f"surface_of_section of {m} orbits of {model.name}")
    reference = spec.reference
    x = X.copy()
    small = model.n_dof <= K.SPECIALISE_N
    kernel = _section_kernel(model.n_dof if small else -1, model.bandwidth if small else -1,
                             K.model_kernels(model))
    done = np.zeros(m, dtype=np.int64)
    n_found = np.zeros(m, dtype=np.int64)
    status = np.zeros(m, dtype=np.int64)
    counts = np.zeros((m, len(COUNTERS)), dtype=np.int64)
    buf = np.empty((m, _BUFFER, d + 1))
    found = [[] for _ in range(m)]
    start, machine, code = time.perf_counter(), identity.machine(), identity.code_identity()
    while True:
        kernel(x, done, status, counts, n_found, buf,
               K.TMSetup(kinds, h, hc, model.inverse_mass, model.params, model.bandwidth,
                         np.empty(0)),
               _Section(n_steps, np.inf if radius is None else float(radius) ** 2, int(plane),
                        float(value), int(direction), limit, float(tau)))
        for j in range(m):
            rows = buf[j][~np.isnan(buf[j, :, d])]
            if len(rows):
                found[j].append(rows.copy())
        active = (status == STATUS_OK) & (done < n_steps) & (n_found < limit)
        if not active.any():
            break
    n_max = max(1, int(n_found.max()))
    points = np.full((m, n_max, d), np.nan)
    times = np.full((m, n_max), np.nan)
    for j in range(m):
        if found[j]:
            rows = np.concatenate(found[j])
            points[j, :len(rows)] = rows[:, :d]
            times[j, :len(rows)] = rows[:, d] * tau
    # Relative to |T| + |V| at the start (varint.accuracy), as for runs.
    with np.errstate(invalid="ignore", over="ignore"):
        energy_error = (np.abs(model.energy(points) - reference.values["energy"][:, None])
                        / reference.scales["energy"][:, None])
    total = counts.sum(axis=0)
    prov = Provenance(
        kind="surface_of_section", model=model.describe(),
        x0=(X[0] if single else X).tolist(), method="tm",
        method_options={"scheme": sch.describe()}, tau=tau, t_end=t_end, seed=None,
        options={"plane": int(plane), "value": float(value), "direction": int(direction),
                 "max_points": max_points, "escape_radius": radius},
        versions=dict(package_versions(), numba=numba.__version__),
        counts=dict(steps=int(done.sum()), **dict(zip(COUNTERS, map(int, total), strict=True))),
        wall_time=time.perf_counter() - start, code=code, machine=machine)
    sq = (lambda a: a[0]) if single else (lambda a: a)
    verdict = assess(times, {"energy_error": energy_error}, status, spec.energy_tol, tau,
                     single)
    warn(verdict, "tm", what="the surface of section")
    return SectionResult(t=done * tau if not single else np.array([done[0] * tau]),
                         energy_error=sq(energy_error), state=sq(x), provenance=prov,
                         status=sq(status), interrupted=False, accuracy=verdict,
                         points=sq(points),
                         times=sq(times), n_points=sq(n_found), plane=int(plane),
                         value=float(value))


def _autonomous_flow(model):
    """Sections at fixed energy need an autonomous flow: refuse a map or a
    time-dependent V (whose energy is not conserved), naming the remedy."""
    if getattr(model, "kind", "flow") == "map":
        raise ValueError(f"{model.name} is a map: its orbits are already a section; grid its "
                         "phase space with varint.phase_grid")
    if model.time_dependent:
        raise ValueError(f"{model.name} depends on time, so its energy is not conserved and has "
                         "no section at fixed energy; grid its phase space with "
                         "varint.phase_grid (a stroboscopic section: t_out at multiples of the "
                         "period)")


def section_grid(model: Model, energy: float, u: ArrayLike, v: ArrayLike,
                 axes: tuple[int, int] | None = None, plane: int = 0, value: float = 0.0,
                 base: ArrayLike | None = None) -> SectionGrid:
    """A grid of initial conditions on the section q_plane = value at the
    given energy, with p_plane ≥ 0 solved from H = energy (the paper's
    x = 0, p_x ≥ 0 section of Hénon–Heiles for the defaults).

    Parameters
    ----------
    model : Model
    energy : float
    u, v : array_like
        Values of the two coordinates that vary (e.g. ``np.linspace(-0.5,
        0.7, 200)``).
    axes : (int, int), optional
        Their state indices (positions 0..N−1, momenta N..2N−1); by default
        the next coordinate after ``plane`` and its momentum, (1, N + 1).
    plane : int, default 0
    value : float, default 0
    base : array_like, shape (2N,), optional
        Values of the coordinates that are neither on the axes nor solved
        (zero by default; relevant for N > 2).

    Returns
    -------
    SectionGrid
        Points where no real p_plane solves the energy are masked out.

    Examples
    --------
    The Hénon–Heiles section x = 0 at H = 0.125, on a 6 × 5 grid of
    (y, p_y); p_x ≥ 0 is solved from the energy:

    >>> import numpy as np, varint
    >>> model = varint.models.HenonHeiles()
    >>> grid = varint.section_grid(model, 0.125, np.linspace(-0.4, 0.6, 6),
    ...                            np.linspace(-0.3, 0.3, 5))
    >>> len(grid), grid.mask.shape, grid.axes
    (26, (5, 6), (1, 3))
    >>> bool(np.allclose(model.energy(grid.states), 0.125))
    True
    """
    model = check.model(model)
    _autonomous_flow(model)
    n = model.n_dof
    if isinstance(plane, bool) or not isinstance(plane, (int, np.integer)) or not 0 <= plane < n:
        raise ValueError(f"plane must be a coordinate index in 0..{n - 1}, got {plane!r}")
    pair = ((plane + 1) % n, n + (plane + 1) % n) if axes is None else tuple(axes)
    if (len(pair) != 2 or len(set(pair)) != 2
            or any(not isinstance(a, (int, np.integer)) or not 0 <= a < 2 * n for a in pair)
            or plane in pair or plane + n in pair):
        raise ValueError(f"axes must be two distinct state indices in 0..{2 * n - 1} other than "
                         f"the plane's q and p ({plane}, {plane + n}), got {axes!r}")
    if isinstance(energy, bool) or not isinstance(energy, numbers.Real) or not np.isfinite(energy):
        raise ValueError(f"energy must be a finite number, got {energy!r}")
    energy = float(energy)
    grids = [check.real_array(a, name).reshape(-1) for a, name in ((u, "u"), (v, "v"))]
    for g, name in zip(grids, ("u", "v"), strict=True):
        if g.size == 0 or not np.isfinite(g).all():
            raise ValueError(f"{name} must be a non-empty array of finite values")
    base = np.zeros(2 * n) if base is None else check.real_array(base, "base").reshape(-1)
    if base.shape != (2 * n,):
        raise ValueError(f"base must have shape ({2 * n},), got {base.shape}")
    if not np.isfinite(base).all():
        raise ValueError(f"base must be finite, got {base.tolist()}")
    # The grid's states, the potential's temporaries and the mask.
    points = len(grids[0]) * len(grids[1])
    check.check_memory(check.array_bytes((points, 6 * n + 4)),
                       f"a section grid of {len(grids[0])} x {len(grids[1])} = {points} points")
    U, V = np.meshgrid(*grids)
    X = np.broadcast_to(base, U.shape + (2 * n,)).copy()
    X[..., pair[0]], X[..., pair[1]] = U, V
    X[..., plane], X[..., n + plane] = value, 0.0
    # p_plane² / 2 · m⁻¹ = E − V(q) − (other kinetic terms).
    rest = energy - model.potential(X[..., :n]) - model.kinetic(X[..., n:])
    mask = rest >= 0
    X[..., n + plane] = np.sqrt(np.where(mask, 2.0 * rest / model.inverse_mass[plane], 0.0))
    return SectionGrid(states=np.ascontiguousarray(X[mask]), mask=mask, u=grids[0], v=grids[1],
                       axes=tuple(int(a) for a in pair), plane=int(plane), value=float(value),
                       energy=energy)

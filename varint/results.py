"""Results: plain dataclasses of NumPy arrays that carry their provenance.

Every result records what determines it (model, initial states, method,
scheme, τ, seed, options) and what produced it (package versions, wall
time, evaluation counts), and saves to / loads from a single ``.npz`` file.
Single-orbit calls give arrays without the leading orbit axis; batch calls
(``x0`` of shape (M, 2N)) keep it.
"""

from __future__ import annotations

import dataclasses
import functools
import datetime
import json
import math
import os
import pickle
import platform
import sys
import time
from dataclasses import dataclass, field
from typing import IO, ClassVar

import numpy as np

from .accuracy import Accuracy
from .files import jsonable

__all__ = ["Provenance", "IntegrationResult", "LyapunovResult", "GALIResult", "SALIResult",
           "MEGNOResult", "IndicatorResult", "SectionResult", "ChaosMapResult",
           "load_result", "package_versions"]

#: Result classes by name, for :func:`load_result` (every subclass of
#: ``_Result`` is added when it is defined, wherever that is).
_CLASSES: dict = {}


@functools.cache
def package_versions(*extra):
    """Versions of Python, varint and the numerical packages a run used
    (cached).

    NumPy, SciPy and numba give the ``__version__`` of the copy imported,
    the code that ran (a run has imported all three: numba loads SciPy's
    BLAS with its registries), for free; one not imported yet, and every
    name of ``extra`` (a distribution's name, e.g. "scikit-sundae"), is read
    from the installed package metadata, which takes ~15 ms to import and
    milliseconds a name.
    """
    from . import __version__

    # varint's own version as varint reports it (a source checkout's, not
    # that of an older installed copy).
    out = {"python": platform.python_version(), "varint": __version__}
    for name in ("numpy", "scipy", "numba"):
        version = getattr(sys.modules.get(name), "__version__", None)
        out[name] = version if isinstance(version, str) else _installed_version(name)
    for name in extra:
        out[name] = _installed_version(name)
    return out


def _installed_version(distribution):
    """The version of an installed distribution (None if not installed)."""
    from importlib import metadata

    try:
        return metadata.version(distribution)
    except metadata.PackageNotFoundError:
        return None


#: (second, its ISO 8601 text) of the last :func:`_utc_now`.
_LAST_NOW = (None, "")


def _utc_now():
    """The time now in UTC, ISO 8601 to the second: the text is made once a
    second (datetime's ~4 µs would be a tenth of a prepared run's short
    call), from ``time.time()`` truncated to the second, as
    ``datetime.now(timezone.utc).isoformat(timespec="seconds")`` truncates
    it."""
    global _LAST_NOW
    second = int(time.time())
    last = _LAST_NOW
    if last[0] != second:
        text = datetime.datetime.fromtimestamp(second, datetime.timezone.utc).isoformat(
            timespec="seconds")
        _LAST_NOW = last = (second, text)    # one assignment: safe across threads
    return last[1]


@dataclass
class Provenance:
    """What determines a result and what produced it.

    Attributes
    ----------
    kind : str
        "integrate", "lyapunov_spectrum", "gali", "sali", ...
    model : dict
        :meth:`Model.describe` of the model.
    x0 : list
        The initial state(s).
    method : str
        The ``method=`` used.
    method_options : dict
        The propagator's settings (scheme, tolerances, ...).
    tau : float
        Step / renormalisation interval.
    t_end : float
    seed : int or None
        Seed of the random initial deviation vectors (None if given).
    options : dict
        Other arguments of the call.
    versions : dict
    counts : dict
        Work done (steps; force, Hessian or right-hand-side evaluations).
    wall_time : float
        Seconds.
    created : str
        ISO 8601 time at which the run finished.
    tau_choice : dict
        How τ was chosen: ``{"rule": "given"}``, or the pilot that chose it
        (:mod:`varint.stepsize`: ``rule``, ``scheme``, ``tolerance``,
        ``tried`` steps and their errors, ``counts`` of the pilot's work).
    code : dict
        The code that ran (:func:`varint.identity.code_identity`): the
        digest of varint's sources, and the git commit where run from a
        checkout. Empty in results saved before it was recorded.
    machine : dict
        The machine when the run started (:func:`varint.identity.machine`:
        CPU model, cores, load average). Empty in results saved before it
        was recorded.
    timing : dict
        Seconds of this session by part, each without the numba
        compilations inside it: ``compile`` (their sum), ``pilot`` (the
        automatic step's pilot), ``setup`` and ``run``
        (:mod:`varint.compiling`). ``wall_time`` holds them all: compare
        methods by ``timing["run"]``, which a first call's compilation does
        not inflate.
    cpu_time : float or None
        CPU seconds (:func:`time.process_time`, every thread of the process)
        the integration took: measured in every session of a resumed run
        and summed (kept in its checkpoint), never extrapolated; None where
        a session's was not measured (a checkpoint from before varint
        recorded it) or cannot be told apart from other work (a chaos map
        on a cluster).
    """

    kind: str
    model: dict
    x0: list
    method: str
    method_options: dict
    tau: float
    t_end: float
    seed: int | None
    options: dict
    versions: dict
    counts: dict
    wall_time: float
    created: str = field(default_factory=_utc_now)
    tau_choice: dict = field(default_factory=dict)
    # Not filled in by default: a result loaded from an older file must not
    # be stamped with the code that loads it.
    code: dict = field(default_factory=dict)
    machine: dict = field(default_factory=dict)
    timing: dict = field(default_factory=dict)
    cpu_time: float | None = None

    #: The fields a prepared run's short call may leave pickled
    #: (:meth:`with_pickled`): those no state changes.
    PICKLED: ClassVar[frozenset] = frozenset(
        ("model", "method_options", "options", "versions", "seed", "tau_choice", "code"))

    @classmethod
    def with_pickled(cls, pickled, **fields):
        """A provenance whose fields of :data:`PICKLED` are ``pickled``
        (:func:`pickle.dumps` of a dict of them), unpickled at the first
        access of any of them, and whose other fields are ``fields`` (all
        of them; ``created``, where not given, now, as :meth:`__init__`
        stamps it).

        A prepared run's short call (:mod:`varint.prepared`) makes one per
        result: each result then has its own copies of the dicts and lists
        that no state changes, as with :meth:`__init__`, but makes them
        only if they are read (unpickling them took ~10 µs of a ~100 µs
        call). Attribute access, ``==``, :func:`dataclasses.asdict`,
        :meth:`to_dict`, :func:`copy.copy` and pickling see the same
        provenance as one built by :meth:`__init__`.
        """
        new = object.__new__(cls)
        if "created" not in fields:
            fields["created"] = _utc_now()
        new.__dict__.update(fields, _pickled=pickled)
        return new

    def __getattr__(self, name):
        # Called only for a name not in the instance's __dict__: a field of
        # PICKLED still pickled (with_pickled). The fields are set before
        # the pickle is dropped, so another thread finds either.
        d = self.__dict__
        pickled = d.get("_pickled")
        if pickled is not None and name in self.PICKLED:
            for key, value in pickle.loads(pickled).items():
                d.setdefault(key, value)
            d.pop("_pickled", None)
        if name in self.PICKLED and name in d:
            return d[name]
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

    def __getstate__(self):
        # Every field, unpickled where it was left pickled (with_pickled).
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}

    def to_dict(self):
        return jsonable(dataclasses.asdict(self))


@dataclass
class _Result:
    """Fields every result has; subclasses add their indicator arrays.

    Every result has ``t``, ``energy_error`` (the relative energy error at
    each output, see :mod:`varint.accuracy`), the final ``state``,
    ``provenance``, ``status``, ``interrupted`` and its ``accuracy``
    verdict (:class:`~varint.accuracy.Accuracy`: the largest errors of the
    conserved quantities and whether they are within the tolerance at which
    indicators can be trusted).

    ``layout`` says how the arrays are laid out (``"series"``: ([M,] n_out,
    ...) over the output times; ``"map"``: one value per initial
    condition; ``"section"``: crossings), and ``plot_kind`` which plot of
    :mod:`varint.plotting` shows it.
    """

    layout: ClassVar[str] = "series"
    plot_kind: ClassVar[str] = "energy_error"
    #: Labels of series in summaries (field or key → label).
    _labels: ClassVar[dict] = {"mean_megno": "mean MEGNO", "megno": "MEGNO", "sali": "SALI",
                               "fli": "FLI", "ofli": "OFLI", "participation": "P",
                               "dvd_participation": "DVD P", "dvd_m2": "DVD m2"}
    #: Names of the trailing dimensions of fields, for :meth:`to_xarray`
    #: (beyond those of :data:`varint.tables.DIMS`), e.g.
    #: ``{"local": ("exponent",)}``; unnamed ones are ``{field}_dim{i}``.
    dims: ClassVar[dict] = {}

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        _CLASSES[cls.__name__] = cls
        # The summary below, not the dataclass's dump of every array: set
        # in the class itself before @dataclass runs, which then keeps it.
        if "__repr__" not in cls.__dict__:
            cls.__repr__ = _Result.__repr__

    t: np.ndarray
    energy_error: np.ndarray
    state: np.ndarray
    provenance: Provenance
    status: np.ndarray
    interrupted: bool
    accuracy: Accuracy | None = None

    def save(self, path):
        """Write the result to ``path`` (``.npz``): arrays plus provenance JSON."""
        arrays, meta = {}, {"class": type(self).__name__}
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if f.name == "provenance":
                meta["provenance"] = value.to_dict()
            elif f.name == "accuracy":
                meta["accuracy"] = None if value is None else jsonable(value.to_dict())
            elif isinstance(value, dict):
                meta.setdefault("dict_fields", {})[f.name] = [str(k) for k in value]
                for key, arr in value.items():
                    arrays[f"{f.name}__{key}"] = np.asarray(arr)
            elif isinstance(value, np.ndarray):
                arrays[f.name] = value
            else:
                meta[f.name] = jsonable(value)
        np.savez(path, __meta__=np.array(json.dumps(meta)), **arrays)

    def to_xarray(self):
        """The result as an :class:`xarray.Dataset`: every array with named
        dimensions and coordinates (``orbit``, ``t``, ``exponent``,
        ``component``, … ; a map of a section grid on the grid itself), the
        provenance in ``ds.attrs`` (see :mod:`varint.tables`). Needs xarray
        (``pip install "varint[xarray]"``).

        Examples
        --------
        >>> import varint
        >>> model, x0 = varint.paper_orbit("C1")
        >>> ds = varint.lyapunov_spectrum(model, x0, 100.0, t_out=5).to_xarray()
        >>> ds.exponents.dims, ds.attrs["method"]
        (('t', 'exponent'), 'tm')
        """
        from .tables import to_xarray

        return to_xarray(self)

    def to_dataframe(self):
        """The result as a pandas DataFrame, one row per orbit and time (or
        per crossing, per map point): the variables of :meth:`to_xarray`,
        one column per component; the provenance is in ``df.attrs``.
        Needs pandas (``pip install "varint[pandas]"``).

        Examples
        --------
        >>> import varint
        >>> model, x0 = varint.paper_orbit("R1")
        >>> varint.gali(model, x0, 10.0, k=(2, 4), t_out=3).to_dataframe().columns.tolist()
        ['t', 'energy_error', 'gali_2', 'gali_4']
        """
        from .tables import to_dataframe

        return to_dataframe(self)

    def plot(self, ax=None, **kwargs):
        """Plot in the paper's style (see :mod:`varint.plotting`)."""
        from .plotting import plot

        return plot(self, ax=ax, **kwargs)

    def summary(self):
        """One-line description for logs and the command line."""
        p = self.provenance
        scheme = p.method_options.get("scheme")
        scheme = f" ({scheme.get('name', '')})" if isinstance(scheme, dict) else ""
        t = np.asarray(self.t, dtype=float)
        end = f" to t={float(np.nanmax(t)):g}" if t.size and np.isfinite(t).any() else ""
        return (f"{p.kind} of {p.model.get('name')} by {p.method}{scheme} tau={p.tau:g}"
                f"{end} in {p.wall_time:.3g} s")

    def headline(self):
        """The values a reader looks at first, as (label, value) pairs: the
        last output of each series (per orbit for a batch: median and
        range)."""
        out = []
        for name, value in self._series():
            v = np.asarray(value, dtype=float)
            if v.ndim == 0 or v.shape[-1 if self._batch() else 0] == 0:
                continue
            last = v[..., -1] if self._batch() else v[-1]
            out.append((name, last))
        return out

    def _batch(self):
        return np.ndim(self.status) == 1

    def _series(self):
        """(name, array ([M,] n_out)) of every per-output series with one
        value per output time (columns of wider ones are named name[i])."""
        skip = {"t", "energy_error", "state", "status", "deviations", "provenance", "accuracy",
                "interrupted", "states"}
        n_out = len(np.atleast_1d(self.t))
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if f.name in skip or value is None:
                continue
            items = value.items() if isinstance(value, dict) else [(f.name, value)]
            for key, arr in items:
                arr = np.asarray(arr)
                if arr.dtype.kind != "f" or arr.ndim == 0:
                    continue
                lead = 1 if self._batch() else 0
                if arr.ndim <= lead or arr.shape[lead] != n_out:
                    continue
                label = f"GALI_{key}" if f.name == "gali" else self._labels.get(key, str(key))
                if arr.ndim == lead + 1:
                    yield label, arr
                elif arr.ndim == lead + 2 and arr.shape[-1] <= 8:
                    for j in range(arr.shape[-1]):
                        yield (f"X{j + 1}" if label == "exponents" else f"{label}[{j}]"), \
                            arr[..., j]

    def __repr__(self):
        """A summary, not the arrays: what ran, the headline values, the
        accuracy verdict, and the fields that hold the rest."""
        p = self.provenance
        lines = [f"{type(self).__name__}: {self.summary()}"]
        t = np.atleast_1d(np.asarray(self.t, dtype=float))
        orbits = (f"{len(self.status)} orbits" if self._batch()
                  else f"x0 = {_short(p.x0)}" if p.x0 else "")
        if self.layout != "series":     # a map's t holds check times; a section's, ends
            times = f"t_end = {p.t_end:g}"
        elif t.size > 1 and np.isfinite(t).all():
            times = f"{t.size} outputs, t = {t[0]:g} … {t[-1]:g}"
        else:
            times = f"{t.size} output(s)"
        lines.append(f"  {orbits}; {times}" if orbits else f"  {times}")
        pairs = self.headline()
        if pairs:
            at = f"at t = {t[-1]:g}" if self.layout == "series" and t.size else "values"
            shown = ", ".join(f"{name} = {_value(v)}" for name, v in pairs[:8])
            more = f" (+{len(pairs) - 8} more)" if len(pairs) > 8 else ""
            lines.append(f"  {at}: {shown}{more}")
        if self.accuracy is not None:
            lines.append(f"  accuracy: {self.accuracy.verdict}")
        if np.any(np.asarray(self.status) > 0):
            lines.append(f"  failed: {int(np.sum(np.asarray(self.status) > 0))} orbit(s) "
                         "(status > 0)")
        if self.interrupted:
            lines.append("  interrupted: the outputs so far")
        arrays = [f"{f.name} {np.shape(getattr(self, f.name))}" for f in dataclasses.fields(self)
                  if isinstance(getattr(self, f.name), np.ndarray)]
        dicts = [f"{f.name}[{', '.join(map(repr, getattr(self, f.name)))}]"
                 for f in dataclasses.fields(self) if isinstance(getattr(self, f.name), dict)]
        lines.append("  fields: " + ", ".join(arrays + dicts) + "; .provenance, .accuracy")
        return "\n".join(lines)


def _value(v):
    """A headline value: one number, or median and range over orbits."""
    v = np.asarray(v, dtype=float)
    if v.ndim == 0:
        return f"{float(v):.4g}"
    finite = v[np.isfinite(v)]
    if not finite.size:
        return "nan"
    return (f"{np.median(finite):.4g} (median of {v.size}; {finite.min():.3g} … "
            f"{finite.max():.3g})")


def _short(x0):
    x = np.asarray(x0, dtype=float).ravel()
    if x.size <= 6:
        return "[" + ", ".join(f"{v:.6g}" for v in x) + "]"
    return f"[{', '.join(f'{v:.6g}' for v in x[:3])}, … ({x.size} values)]"


@dataclass
class IntegrationResult(_Result):
    """Result of :func:`varint.integrate`.

    The trajectory is ``states``; ``state`` is only where it ended.

    Attributes
    ----------
    t : ndarray, shape (n_out,)
        The output times (only t_end by default: pass ``t_out`` for a
        trajectory).
    states : ndarray, shape ([M,] n_out, 2N)
        The trajectory: the orbit at each output time.
    state : ndarray, shape ([M,] 2N)
        The final state only (as in every result): ``states[..., -1, :]``
        for a run that finished.
    deviations : ndarray, shape ([M,] 2N, k)
        Final deviation vectors, never renormalised: the tangent map of the
        whole run applied to the initial vectors.
    energy_error : ndarray, shape ([M,] n_out)
        |H(t) − H(0)| / (|T| + |V|)(0): relative to the kinetic plus the
        absolute potential energy at t = 0, which stays meaningful when
        H(0) = 0 (:mod:`varint.accuracy`).
    accuracy : Accuracy
        The largest errors and the verdict.
    """

    states: np.ndarray | None = None
    deviations: np.ndarray | None = None


@dataclass
class LyapunovResult(_Result):
    """Result of :func:`varint.lyapunov_spectrum`.

    Attributes
    ----------
    exponents : ndarray, shape ([M,] n_out, k)
        Finite-time Lyapunov exponents X_i(t) (paper eq. 10), column i in QR
        column order: X_1 ≥ X_2 ≥ … once the vectors have aligned.
    deviations : ndarray, shape ([M,] 2N, k)
        Final orthonormal deviation vectors (the Q factor).
    """

    plot_kind: ClassVar[str] = "lyapunov"

    exponents: np.ndarray | None = None
    deviations: np.ndarray | None = None

    def pair_sums(self):
        """|X_i + X_{2N−i+1}|, i = 1..N, shape ([M,] n_out, N); zero in theory
        for autonomous Hamiltonians (paper eq. 13). Needs the full spectrum."""
        k = self.exponents.shape[-1]
        if k % 2:
            raise ValueError(f"pair sums need the full spectrum (2N exponents), have {k}")
        return np.abs(self.exponents[..., : k // 2] + self.exponents[..., ::-1][..., : k // 2])


@dataclass
class GALIResult(_Result):
    """Result of :func:`varint.gali`.

    Attributes
    ----------
    gali : dict of int -> ndarray, shape ([M,] n_out)
        GALI_k(t) for each requested k: the product of the singular values
        of the first k unit deviation vectors (paper eq. 18).
    deviations : ndarray, shape ([M,] 2N, max k)
        Final unit deviation vectors.
    """

    plot_kind: ClassVar[str] = "gali"

    gali: dict | None = None
    deviations: np.ndarray | None = None


@dataclass
class SALIResult(_Result):
    """Result of :func:`varint.sali`.

    Attributes
    ----------
    sali : ndarray, shape ([M,] n_out)
        SALI(t) = min(‖ŵ₁ + ŵ₂‖, ‖ŵ₁ − ŵ₂‖).
    deviations : ndarray, shape ([M,] 2N, 2)
    """

    plot_kind: ClassVar[str] = "sali"

    sali: np.ndarray | None = None
    deviations: np.ndarray | None = None


@dataclass
class MEGNOResult(_Result):
    """Result of :func:`varint.megno`.

    Attributes
    ----------
    megno : ndarray, shape ([M,] n_out)
        MEGNO Y(t) = (2/t) ∫₀ᵗ s δ̇(s)/δ(s) ds of one deviation vector,
        in its discrete form (2/t) Σ t_i ln r_i over the steps.
    mean_megno : ndarray, shape ([M,] n_out)
        Its running average Ȳ(t) over the steps: → 2 on quasi-periodic
        orbits, ≈ χ₁ t / 2 on chaotic ones.
    fli, ofli : ndarray, shape ([M,] n_out)
        Fast Lyapunov indicator sup_{s≤t} ln‖w(s)‖ and its orthogonal
        variant sup ln‖w_⊥(s)‖ (w_⊥: the part of w orthogonal to the flow),
        for a unit initial vector.
    deviations : ndarray, shape ([M,] 2N, 1)
    """

    plot_kind: ClassVar[str] = "megno"

    megno: np.ndarray | None = None
    mean_megno: np.ndarray | None = None
    fli: np.ndarray | None = None
    ofli: np.ndarray | None = None
    deviations: np.ndarray | None = None


@dataclass
class IndicatorResult(_Result):
    """Result of an indicator that has no result class of its own (FLI,
    OFLI, indicators registered by users): its series by name.

    Attributes
    ----------
    values : dict of str -> ndarray, shape ([M,] n_out, ...)
        Each quantity the indicator reads at the output times; also
        reachable as ``result[name]``.
    deviations : ndarray, shape ([M,] 2N, k)
        Final deviation vectors.
    """

    plot_kind: ClassVar[str] = "series"

    values: dict | None = None
    deviations: np.ndarray | None = None

    def __getitem__(self, name):
        try:
            return self.values[name]
        except KeyError:
            raise KeyError(f"this result holds {', '.join(self.values)}; not {name!r}") from None


@dataclass
class SectionResult(_Result):
    """Result of :func:`varint.surface_of_section`.

    Attributes
    ----------
    points : ndarray, shape ([M,] n, 2N)
        States at the crossings of the section, NaN-padded after each
        orbit's ``n_points``.
    times : ndarray, shape ([M,] n)
        Crossing times (NaN-padded).
    n_points : ndarray of int, shape ([M,])
    energy_error : ndarray, shape ([M,] n)
        Relative energy error of each crossing.
    t : ndarray, shape (M,) or (1,)
        Time each orbit was integrated to.
    plane, value :
        The section q_plane = value.
    """

    layout: ClassVar[str] = "section"
    plot_kind: ClassVar[str] = "section"

    def headline(self):
        return [("crossings", np.asarray(self.n_points))]

    points: np.ndarray | None = None
    times: np.ndarray | None = None
    n_points: np.ndarray | None = None
    plane: int = 0
    value: float = 0.0


@dataclass
class ChaosMapResult(_Result):
    """Result of :func:`varint.chaos_map`: one indicator value per initial
    condition.

    Attributes
    ----------
    indicator : str
        Its name ("sali", "gali_3", "x1", …).
    values : ndarray, shape (M,)
        The indicator at ``t_stop`` (NaN for failed orbits).
    t_stop : ndarray, shape (M,)
        When it was read: t_end, the check time at which early stopping
        decided the orbit, or the failure time.
    threshold : float or None
        Early-stopping threshold (None: every orbit ran to t_end).
    x0 : ndarray, shape (M, 2N)
    status : ndarray of int, shape (M,)
        0: ran to t_end; −1 (``DECIDED``): stopped early; > 0: failed.
    energy_error : ndarray, shape (M,)
        Relative energy error at ``t_stop``.
    t : ndarray
        The check times at which early stopping was decided.
    axes, u, v, mask :
        For a map of a :class:`~varint.sections.SectionGrid`: the state
        indices of the grid axes, their values and which grid points are
        allowed (``values`` holds the allowed ones in row-major order);
        None and empty arrays otherwise.
    log_scale : bool or None
        Whether the indicator is read on a log scale
        (:attr:`Indicator.log_scale <varint.indicators.Indicator>`), as the
        map recorded it, for :func:`~varint.plotting.plot_chaos_map`; None
        in maps saved before it was recorded. The map holds it so that
        drawing a result needs nothing of the indicator registry above it.
    """

    layout: ClassVar[str] = "map"
    plot_kind: ClassVar[str] = "chaos_map"

    indicator: str = ""
    values: np.ndarray | None = None
    t_stop: np.ndarray | None = None
    threshold: float | None = None
    x0: np.ndarray | None = None
    axes: list | None = None
    u: np.ndarray | None = None
    v: np.ndarray | None = None
    mask: np.ndarray | None = None
    log_scale: bool | None = None

    def headline(self):
        values = np.asarray(self.values, dtype=float)
        out = [(self.indicator.upper(), values)]
        if self.threshold is not None:
            below = int(np.sum(self.decided))
            out.append(("decided early", np.asarray(float(below))))
        return out

    def _batch(self):
        return True

    def image(self):
        """``values`` on the grid, shape (len(v), len(u)), NaN where no
        orbit was started (a grid map only)."""
        if self.axes is None:
            raise ValueError("this map was not made on a grid; its values are per orbit")
        out = np.full(self.mask.shape, np.nan)
        out[self.mask] = self.values
        return out

    @property
    def decided(self):
        """Which orbits early stopping froze (bool, shape (M,))."""
        return self.status == -1


def load_result(path: str | os.PathLike[str] | IO[bytes]) -> _Result:
    """Read a result written by ``save``: the same class, arrays and
    provenance.

    Everything is checked before a result is built (:func:`_validated`):
    the archive holds numeric arrays only (no pickles), every field belongs
    to the result class and has its type, the provenance and accuracy
    verdict have theirs, the arrays' shapes agree with each other, and the
    verdict agrees with the errors it is drawn from.

    Raises
    ------
    ValueError
        Naming the file and the field, for a file that is not a varint
        result or whose content is inconsistent (a damaged or edited file).

    Examples
    --------
    >>> import io, varint
    >>> model, x0 = varint.paper_orbit("R1")
    >>> r = varint.sali(model, x0, 10.0)
    >>> buffer = io.BytesIO()         # or a path such as "r1.npz"
    >>> r.save(buffer)
    >>> back = varint.load_result(io.BytesIO(buffer.getvalue()))
    >>> type(back).__name__, bool((back.sali == r.sali).all()), back.provenance == r.provenance
    ('SALIResult', True, True)
    """
    where = (f"result file {os.fspath(path)}" if isinstance(path, (str, os.PathLike))
             else "the result")
    try:
        if isinstance(path, (str, os.PathLike)):
            with open(path, "rb") as f:
                head = f.read(4)
        else:
            head = path.read(4)
            path.seek(-len(head), 1)
        if head != b"PK\x03\x04":
            raise _Invalid(None, "it is not an .npz archive")
        with np.load(path, allow_pickle=False) as data:
            if "__meta__" not in data.files:
                raise _Invalid(None, "it has no __meta__ entry")
            meta = json.loads(str(data["__meta__"][()]))
            arrays = {k: data[k] for k in data.files if k != "__meta__"}
    except _Invalid as exc:
        raise ValueError(f"{where} is not a varint result: {exc}") from None
    except FileNotFoundError:
        raise
    except Exception as exc:     # not an .npz, a pickle, truncated, bad JSON
        raise ValueError(f"{where} is not a varint result ({type(exc).__name__}: {exc})"
                         ) from None
    try:
        return _validated(meta, arrays)
    except _Invalid as exc:
        raise ValueError(f"{where} is damaged or was edited: {exc}") from None


class _Invalid(Exception):
    """A field of a stored result that is not what ``save`` writes."""

    def __init__(self, field, why):
        super().__init__(why if field is None else f"field {field!r}: {why}")


#: Provenance fields and the JSON types they hold.
_PROVENANCE_TYPES = {"kind": str, "model": dict, "x0": list, "method": str,
                     "method_options": dict, "tau": (int, float), "t_end": (int, float),
                     "seed": (int, type(None)), "options": dict, "versions": dict,
                     "counts": dict, "wall_time": (int, float), "created": str,
                     "tau_choice": dict, "code": dict, "machine": dict, "timing": dict,
                     "cpu_time": (int, float, type(None))}


def _provenance(d):
    if not isinstance(d, dict):
        raise _Invalid("provenance", f"expected a dict, got {type(d).__name__}")
    names = {f.name for f in dataclasses.fields(Provenance)}
    for key, value in d.items():
        if key not in names:
            raise _Invalid(f"provenance.{key}", "not a field of Provenance (written by another "
                           "varint version?)")
        want = _PROVENANCE_TYPES.get(key)
        if want is not None and (isinstance(value, bool) or not isinstance(value, want)):
            raise _Invalid(f"provenance.{key}", f"expected {_type_names(want)}, got "
                           f"{type(value).__name__} {value!r:.60}")
    missing = [f.name for f in dataclasses.fields(Provenance)
               if f.name not in d and f.default is dataclasses.MISSING
               and f.default_factory is dataclasses.MISSING]
    if missing:
        raise _Invalid(f"provenance.{missing[0]}", "it is missing")
    counts = d.get("counts", {})
    bad = [k for k, v in counts.items() if isinstance(v, bool) or not isinstance(v, int) or v < 0]
    if bad:
        raise _Invalid(f"provenance.counts.{bad[0]}", f"expected a count >= 0, got "
                       f"{counts[bad[0]]!r}")
    timing = d.get("timing", {})
    bad = [k for k, v in timing.items() if isinstance(v, bool) or not isinstance(v, (int, float))
           or not 0 <= v < math.inf]
    if bad:
        raise _Invalid(f"provenance.timing.{bad[0]}", f"expected seconds >= 0, got "
                       f"{timing[bad[0]]!r:.60}")
    return Provenance(**d)


def _type_names(types):
    types = types if isinstance(types, tuple) else (types,)
    return " or ".join("None" if t is type(None) else t.__name__ for t in types)


def _accuracy(d, status):
    if d is None:
        return None
    try:
        acc = Accuracy.from_dict(d)
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        raise _Invalid("accuracy", f"not a verdict ({type(exc).__name__}: {exc})") from None
    worst = np.asarray(acc.worst, dtype=float)
    accurate = np.asarray(acc.accurate)
    if accurate.shape != worst.shape:
        raise _Invalid("accuracy.accurate", f"shape {accurate.shape}, its errors' "
                       f"{worst.shape}")
    with np.errstate(invalid="ignore"):
        ok = worst <= acc.energy_tol
    failed = np.asarray(status) > 0
    if failed.shape != accurate.shape:
        failed = np.zeros(accurate.shape, dtype=bool)
    # The verdict is drawn from the errors: it cannot say accurate where
    # they exceed the tolerance or the orbit failed.
    if np.any(accurate & ~(ok & ~failed)):
        raise _Invalid("accuracy.accurate", "says accurate where the stored errors exceed the "
                       "tolerance or the orbit failed")
    return acc


def _validated(meta, arrays):
    """The result ``meta`` and ``arrays`` stand for (see :func:`load_result`)."""
    if not isinstance(meta, dict):
        raise _Invalid("__meta__", f"expected a JSON object, got {type(meta).__name__}")
    meta = dict(meta)
    name = meta.pop("class", None)
    if name not in _CLASSES:
        raise _Invalid("class", f"{name!r} is not a varint result class")
    cls = _CLASSES[name]
    fields = {f.name: f for f in dataclasses.fields(cls)}
    for key, a in arrays.items():
        if a.dtype.kind not in "biuf":
            raise _Invalid(key, f"dtype {a.dtype} is not numeric")
    kwargs = {"provenance": _provenance(meta.pop("provenance", None))}
    acc = meta.pop("accuracy", None)
    dict_fields = meta.pop("dict_fields", {})
    if not isinstance(dict_fields, dict):
        raise _Invalid("dict_fields", "expected a dict")
    for field_name, keys in dict_fields.items():
        if field_name not in fields or not isinstance(keys, list) \
                or not all(isinstance(k, str) for k in keys):
            raise _Invalid(f"dict_fields.{field_name}", "not a dict field of " + name)
        try:
            kwargs[field_name] = {int(k) if k.isdigit() else k: arrays.pop(f"{field_name}__{k}")
                                  for k in keys}
        except KeyError as exc:
            raise _Invalid(exc.args[0], "it is missing") from None
    for key in arrays:
        if key not in fields or key in ("provenance", "accuracy"):
            raise _Invalid(key, f"not an array field of {name}")
    kwargs.update(arrays)
    for key, value in meta.items():
        if key not in fields or key in kwargs:
            raise _Invalid(key, f"not a field of {name}")
        if isinstance(value, dict) or (isinstance(value, list) and key != "axes"):
            raise _Invalid(key, f"expected a number, a string or None, got "
                           f"{type(value).__name__}")
    kwargs.update(meta)
    required = [f for f in fields.values() if f.init and f.default is dataclasses.MISSING
                and f.default_factory is dataclasses.MISSING and f.name not in kwargs
                and f.name != "accuracy"]
    if required:
        raise _Invalid(required[0].name, "it is missing")
    _check_shapes(cls, kwargs)
    kwargs["accuracy"] = _accuracy(acc, kwargs.get("status"))
    try:
        return cls(**kwargs)
    except (TypeError, ValueError) as exc:
        raise _Invalid(name, str(exc)) from None


def _check_shapes(cls, f):
    """The shapes every result shares: ``t`` a vector of finite times, the
    status integer per orbit, the final state (…, 2N) with a status per
    orbit, and a series' energy errors one per output time."""
    t = np.asarray(f.get("t"))
    if t.ndim != 1 or t.dtype.kind not in "iuf" or not np.isfinite(t).all():
        raise _Invalid("t", f"expected a vector of finite times, got shape {t.shape}")
    status = np.asarray(f.get("status"))
    if status.dtype.kind not in "iu":
        raise _Invalid("status", f"expected integer codes, got dtype {status.dtype}")
    state = np.asarray(f.get("state"))
    if state.ndim < 1 or state.shape[:-1] != status.shape:
        raise _Invalid("state", f"shape {state.shape} does not match status {status.shape}")
    if cls.layout == "series":
        e = np.asarray(f.get("energy_error"))
        if e.shape != status.shape + t.shape:
            raise _Invalid("energy_error", f"shape {e.shape}, expected "
                           f"{status.shape + t.shape} (orbits, output times)")
        # A series starts with (orbits, output times); a per-orbit array
        # (an ensemble's seeds and wall times) is one value per orbit.
        for key, value in f.items():
            series = value.values() if isinstance(value, dict) else [value]
            for v in series:
                if isinstance(v, np.ndarray) and key not in ("t", "state", "status",
                                                            "deviations", "energy_error") \
                        and v.shape[:len(status.shape) + 1] != status.shape + t.shape \
                        and v.shape != status.shape:
                    raise _Invalid(key, f"shape {v.shape} does not start with (orbits, output "
                                   f"times) {status.shape + t.shape}")
    elif cls.layout == "map":
        m = status.shape
        for key in ("values", "t_stop", "energy_error"):
            v = np.asarray(f.get(key))
            if v.shape != m:
                raise _Invalid(key, f"shape {v.shape}, expected {m} (one per orbit)")

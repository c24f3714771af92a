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
import os
import platform
from dataclasses import dataclass, field
from importlib import metadata
from typing import IO, ClassVar

import numpy as np

from .accuracy import Accuracy
from .files import jsonable

__all__ = ["Provenance", "IntegrationResult", "LyapunovResult", "GALIResult", "SALIResult",
           "MEGNOResult", "IndicatorResult", "SectionResult", "ChaosMapResult",
           "load_result", "package_versions"]

#: Result classes by name, for :func:`load_result` (every subclass of
#: ``_Result`` is added when it is defined, wherever that is).
_CLASSES = {}


@functools.lru_cache(maxsize=None)
def package_versions(*extra):
    """Versions of Python, varint and the numerical packages a run used
    (cached: reading package metadata takes milliseconds)."""
    from . import __version__

    names = ("numpy", "scipy", "numba") + tuple(extra)
    # varint's own version as varint reports it (a source checkout's, not
    # that of an older installed copy).
    out = {"python": platform.python_version(), "varint": __version__}
    for name in names:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = None
    return out


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
    created: str = field(default_factory=lambda: datetime.datetime.now(
        datetime.timezone.utc).isoformat(timespec="seconds"))
    tau_choice: dict = field(default_factory=dict)
    # Not filled in by default: a result loaded from an older file must not
    # be stamped with the code that loads it.
    code: dict = field(default_factory=dict)
    machine: dict = field(default_factory=dict)

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
    #: Names of the trailing dimensions of fields, for :meth:`to_xarray`
    #: (beyond those of :data:`varint.tables.DIMS`), e.g.
    #: ``{"local": ("exponent",)}``; unnamed ones are ``{field}_dim{i}``.
    dims: ClassVar[dict] = {}

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        _CLASSES[cls.__name__] = cls

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
        return (f"{p.kind} of {p.model.get('name')} by {p.method} "
                f"({p.method_options.get('scheme', {}).get('name', '')}) tau={p.tau:g} "
                f"to t={float(np.max(self.t)):g} in {p.wall_time:.3g} s")


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

    states: np.ndarray = None
    deviations: np.ndarray = None


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

    exponents: np.ndarray = None
    deviations: np.ndarray = None

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

    gali: dict = None
    deviations: np.ndarray = None


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

    sali: np.ndarray = None
    deviations: np.ndarray = None


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

    megno: np.ndarray = None
    mean_megno: np.ndarray = None
    fli: np.ndarray = None
    ofli: np.ndarray = None
    deviations: np.ndarray = None


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

    values: dict = None
    deviations: np.ndarray = None

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

    points: np.ndarray = None
    times: np.ndarray = None
    n_points: np.ndarray = None
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
    """

    layout: ClassVar[str] = "map"
    plot_kind: ClassVar[str] = "chaos_map"

    indicator: str = ""
    values: np.ndarray = None
    t_stop: np.ndarray = None
    threshold: float | None = None
    x0: np.ndarray = None
    axes: list | None = None
    u: np.ndarray = None
    v: np.ndarray = None
    mask: np.ndarray = None

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
    with np.load(path, allow_pickle=False) as data:
        meta = json.loads(str(data["__meta__"]))
        arrays = {k: data[k] for k in data.files if k != "__meta__"}
    cls = _CLASSES[meta.pop("class")]
    kwargs = {"provenance": Provenance(**meta.pop("provenance"))}
    acc = meta.pop("accuracy", None)
    kwargs["accuracy"] = None if acc is None else Accuracy.from_dict(acc)
    for name, keys in meta.pop("dict_fields", {}).items():
        kwargs[name] = {int(k) if k.isdigit() else k: arrays.pop(f"{name}__{k}") for k in keys}
    kwargs.update(arrays)
    kwargs.update(meta)
    return cls(**kwargs)

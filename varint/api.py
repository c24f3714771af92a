"""The public run functions: thin wrappers over :func:`varint.run`, one per
built-in indicator, with the indicator's own parameters spelled out.

Every other parameter (``method``, ``scheme``, ``t_out``, ``seed``,
``deviations``, ``progress``, ``errors``, ``escape_radius``,
``checkpoint``, ``checkpoint_interval`` and the method's options) is that
of :func:`varint.run`, documented there once.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, cast

from numpy.typing import ArrayLike

from .models.base import Model
from .results import GALIResult, IntegrationResult, LyapunovResult, MEGNOResult, SALIResult
from .run import run

__all__ = ["lyapunov_spectrum", "gali", "sali", "megno", "integrate"]


def lyapunov_spectrum(model: Model, x0: ArrayLike, t_end: float, tau: float | None = None,
                      n_exponents: int | None = None, **options: Any) -> LyapunovResult:
    """Finite-time Lyapunov exponents X_1(t), …, X_k(t) of one or many orbits.

    Every τ the deviation vectors are re-orthonormalised by QR
    decomposition and the logarithms of the diagonal of R are accumulated:
    X_i(t) = (1/t) Σ ln R_ii (the discrete QR technique; Skokos & Gerlach
    2010, Sect. III, eq. 10). For regular orbits X_1 ∝ ln t / t (eq. 12);
    for autonomous Hamiltonians X_i + X_{2N−i+1} → 0 (eq. 13).

    Parameters
    ----------
    model : Model
    x0 : array_like, shape (2N,) or (M, 2N)
    t_end : float
    tau : float, optional
        Renormalisation interval (= integration step for ``"tm"``).
    n_exponents : int, optional
        How many exponents (k ≤ 2N deviation vectors); all 2N by default,
        or as many as ``deviations`` has columns.
    **options
        As for :func:`varint.run` (``method``, ``scheme``, ``t_out``,
        ``seed``, ``deviations`` (orthonormal), ``checkpoint``, …).

    Returns
    -------
    LyapunovResult
        ``t`` (n_out,), ``exponents`` ([M,] n_out, k), ``energy_error``.

    Examples
    --------
    >>> import varint
    >>> model, x0 = varint.paper_orbit("C1")
    >>> r = varint.lyapunov_spectrum(model, x0, t_end=100.0, tau=0.05)
    >>> r.exponents.shape[1]
    4
    """
    return cast(LyapunovResult, run(model, x0, "lyapunov", t_end, tau, n_exponents=n_exponents,
                                    **options))


def gali(model: Model, x0: ArrayLike, t_end: float, tau: float | None = None,
         k: int | Sequence[int] | None = None, **options: Any) -> GALIResult:
    """Generalised alignment indices GALI_k(t) (paper Sect. IV, eqs. 15–18).

    max(k) deviation vectors are evolved and normalised to unit length every
    τ; GALI_k is the volume spanned by the first k of them, computed at the
    output times from the singular values. Regular motion on an N-torus:
    GALI_k ≈ const for k ≤ N and ∝ t^{−2(k−N)} for k > N (eq. 17); chaotic
    motion: exponential decay (eq. 16).

    Parameters
    ----------
    model, x0, t_end, tau
        As in :func:`lyapunov_spectrum`.
    k : int or sequence of int, optional
        GALI orders, each in 2..2N; by default 2, 3, 4 (those up to 2N).
    **options
        As for :func:`varint.run`; ``deviations`` of shape ([M,] 2N, max k)
        must be linearly independent (they are normalised before use).

    Returns
    -------
    GALIResult
        ``t``, ``gali`` (dict k -> ([M,] n_out)), ``energy_error``.

    Examples
    --------
    >>> import varint
    >>> model, x0 = varint.paper_orbit("R1")
    >>> g = varint.gali(model, x0, 100.0, tau=0.05, k=(2, 4))
    >>> sorted(g.gali)
    [2, 4]
    """
    return cast(GALIResult, run(model, x0, "gali", t_end, tau, k=k, **options))


def sali(model: Model, x0: ArrayLike, t_end: float, tau: float | None = None,
         **options: Any) -> SALIResult:
    """Smaller alignment index SALI(t) = min(‖ŵ₁ + ŵ₂‖, ‖ŵ₁ − ŵ₂‖).

    Two deviation vectors normalised every τ. SALI → 0 exponentially for
    chaotic orbits and stays away from 0 for regular ones in 2-dof systems
    (Skokos 2001). Parameters as in :func:`gali`.

    Returns
    -------
    SALIResult

    Examples
    --------
    >>> import varint
    >>> model, x0 = varint.paper_orbit("C1")
    >>> bool(varint.sali(model, x0, 2000.0, tau=0.05).sali[-1] < 1e-8)
    True
    """
    return cast(SALIResult, run(model, x0, "sali", t_end, tau, **options))


def megno(model: Model, x0: ArrayLike, t_end: float, tau: float | None = None,
          **options: Any) -> MEGNOResult:
    """MEGNO Y(t), its mean Ȳ(t), FLI and OFLI of one or many orbits, with
    any method (the quadrature of MEGNO's integral is the same on every
    method's renormalisation grid; see :mod:`varint.indicators.megno`).

    One deviation vector (``deviations`` of shape ([M,] 2N) or ([M,] 2N, 1),
    normalised before use; seeded random by default). Other parameters as
    in :func:`lyapunov_spectrum`.

    Returns
    -------
    MEGNOResult
        ``t``, ``megno``, ``mean_megno``, ``fli``, ``ofli`` ([M,] n_out).

    Examples
    --------
    >>> import varint
    >>> model, x0 = varint.paper_orbit("R1")
    >>> m = varint.megno(model, x0, 2000.0, tau=0.05)
    >>> 1.5 < float(m.mean_megno[-1]) < 2.5
    True
    """
    return cast(MEGNOResult, run(model, x0, "megno", t_end, tau, **options))


def integrate(model: Model, x0: ArrayLike, t_end: float, tau: float | None = None,
              deviations: ArrayLike | None = None, **options: Any) -> IntegrationResult:
    """Integrate orbits, and deviation vectors if given, from 0 to ``t_end``.

    The deviation vectors are never renormalised: ``deviations`` of the
    result is the numerical tangent map of the whole run applied to the
    initial vectors (for ``"tm"``, exactly the derivative of the numerical
    orbit map; paper Sect. V.C). Without ``deviations`` no tangent work is
    done at all.

    Parameters
    ----------
    model, x0, t_end
        As in :func:`lyapunov_spectrum`.
    tau : float, optional
        Integration step (``"tm"``) or output grid spacing.
    deviations : array_like, shape ([M,] 2N, k), optional
        Initial deviation vectors to carry along.
    **options
        As for :func:`varint.run`; ``t_out`` is only t_end by default.

    Returns
    -------
    IntegrationResult
        ``states`` ([M,] n_out, 2N) at the output times; the final
        ``state`` ([M,] 2N) and ``deviations`` ([M,] 2N, k);
        ``energy_error``.

    Raises
    ------
    IntegrationError
        If an orbit becomes non-finite or escapes, or the deviation vectors
        overflow (it says at what time; the partial result is attached).
        The raw deviation vectors are checked for overflow every 16 steps.

    Examples
    --------
    >>> import varint
    >>> model, x0 = varint.paper_orbit("R1")
    >>> out = varint.integrate(model, x0, 10.0, tau=0.01, scheme="ABA864", t_out=5)
    >>> out.states.shape
    (5, 4)
    """
    return cast(IntegrationResult, run(model, x0, "integrate", t_end, tau, deviations=deviations,
                                       **options))

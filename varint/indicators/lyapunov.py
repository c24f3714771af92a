"""The Lyapunov spectrum: finite-time Lyapunov exponents X_1(t) … X_k(t).

Every τ the deviation vectors are re-orthonormalised by QR decomposition and
the logarithms of the diagonal of R are accumulated: X_i(t) = (1/t) Σ ln R_ii
(the discrete QR technique; Skokos & Gerlach 2010, Sect. III, eq. 10).

References
----------
G. Benettin, L. Galgani, A. Giorgilli & J.-M. Strelcyn, Meccanica 15, 9 and
21 (1980); Ch. Skokos & E. Gerlach, Phys. Rev. E 82, 036704 (2010).
"""

from __future__ import annotations

from .. import _validate as check
from ..protocol import Renorm
from ..results import LyapunovResult
from .base import Indicator, Option, register_indicator

__all__ = ["LYAPUNOV"]


def _n_exponents(model, value):
    return None if value is None else check.n_vectors(value, model.dim, "n_exponents")


def _vectors(model, options, given):
    k = options["n_exponents"]
    if k is None:
        return model.dim if given is None else given
    if given is not None and given != k:
        raise ValueError(f"n_exponents = {k} but {given} deviation vectors were given")
    return k


def _read(rows, model, t, options):
    return {"exponents": rows.log_growth() / t[:, None]}


def _x1(record, model, options):
    return record["exponents"][:, 0]


LYAPUNOV = register_indicator(Indicator(
    name="lyapunov",
    summary="finite-time Lyapunov exponents X_1(t) … X_k(t) by QR every τ (paper eq. 10)",
    renorm=Renorm.QR,
    vectors=_vectors,
    read=_read,
    result=LyapunovResult,
    require="orthonormal",
    options={"n_exponents": Option(None, _n_exponents,
                                   "how many exponents (k ≤ 2N vectors); all 2N by default")},
    count_option="n_exponents",
    scalar=_x1,
    log_scale=False,
    laws="regular orbits: X_1 ∝ ln t / t → 0 (paper eq. 12); chaotic orbits: X_1 → χ_1 > 0; "
         "autonomous Hamiltonians: X_i + X_{2N−i+1} → 0 (eq. 13)",
    references=("Benettin, Galgani, Giorgilli & Strelcyn, Meccanica 15, 9 and 21 (1980)",
                "Skokos & Gerlach, Phys. Rev. E 82, 036704 (2010), eq. 10"),
), aliases={"x1": {"n_exponents": 1}, "lyapunov_spectrum": {}})

"""Observables of many-body lattices: how a wave packet spreads and where
its chaos lives.

Two indicators, for the lattice models of :mod:`varint.models`
(:class:`~varint.models.DisorderedKG`, :class:`~varint.models.FPUT`,
:class:`~varint.models.DDNLS`, in 1D and 2D):

``"spreading"``
    The distribution z_l = h_l / Σh of the conserved quantity over sites —
    the energy (KG, FPUT: ``model.densities``) or the norm (DDNLS) — at the
    output times, through its second moment and participation number

        m₂ = Σ_l |r_l − r̄|² z_l,   r̄ = Σ_l r_l z_l,   P = 1 / Σ_l z_l²,

    (r_l the site's coordinates: l in 1D, (i, j) in 2D). The orbit alone,
    no deviation vectors. Sub-diffusive spreading is m₂ ∝ t^a: a = 1/3
    (weak chaos) and 1/2 (strong chaos) in 1D, 1/5 and 1/3 in 2D (Flach,
    Krimer & Skokos 2009; Laptyeva et al. 2010; Many Manda, Senyange &
    Skokos 2020).
``"dvd"``
    One deviation vector, normalised every τ: the finite-time maximum
    Lyapunov exponent Λ(t) = X₁(t) (Skokos & Gerlach 2010, eq. 10), the
    deviation vector distribution (DVD) ξ_l = (δq_l² + δp_l²)/‖w‖² with its
    own m₂ and P (Skokos, Gkolias & Flach 2013; Senyange, Many Manda &
    Skokos 2018), and the m₂ and P of the packet, so that one run gives
    both laws: Λ ∝ t^{−0.25} (weak) and t^{−0.3} (strong chaos) in 1D,
    t^{−0.37} and t^{−0.46} in 2D; t^{−1} for regular motion.

With ``profiles=True`` both also keep the whole site distributions at the
output times (shape ([M,] n_out, N): mind the size for long runs of big
lattices).
"""

from __future__ import annotations

import numpy as np

from .. import _validate as check
from ..protocol import Renorm
from ..results import IndicatorResult
from .base import Field, Indicator, Option, as_values, register_indicator

__all__ = ["SPREADING", "DVD", "moments"]


def moments(z, positions):
    """Centre, second moment and participation number of distributions.

    Parameters
    ----------
    z : ndarray, shape (..., N)
        Non-negative weights per site (normalised here).
    positions : ndarray, shape (N, d)
        Site coordinates.

    Returns
    -------
    centre : ndarray, shape (..., d)
    m2 : ndarray, shape (...)
        Σ |r_l − r̄|² z_l.
    participation : ndarray, shape (...)
        1 / Σ z_l².
    """
    z = np.asarray(z, dtype=float)
    lead = z.shape[:-1]
    # One row per distribution, so that a single one (shape (N,)) is
    # handled by the same masked recomputation below.
    z = z.reshape(-1, z.shape[-1])
    with np.errstate(invalid="ignore", divide="ignore"):
        z = z / np.sum(z, axis=-1, keepdims=True)
        centre = z @ positions
        r2 = np.sum(positions * positions, axis=-1)
        m2 = z @ r2 - np.sum(centre * centre, axis=-1)
        # Centring after the fact loses digits when the packet is narrow
        # and far from the origin: recompute about the centre there.
        narrow = m2 < 1e-6 * (1.0 + np.sum(centre * centre, axis=-1))
        if np.any(narrow):
            d = positions[None, :, :] - centre[narrow][:, None, :]
            m2[narrow] = np.sum(z[narrow] * np.sum(d * d, axis=-1), axis=-1)
        participation = 1.0 / np.sum(z * z, axis=-1)
    return (centre.reshape(lead + centre.shape[-1:]), m2.reshape(lead),
            participation.reshape(lead))


def _lattice(model):
    from ..models.lattice import LatticeModel

    if not isinstance(model, LatticeModel):
        raise ValueError(f"lattice observables need a lattice model (varint.models.DisorderedKG, "
                         f"FPUT, DDNLS), got {model.name}")
    return model


def _profiles(model, value):
    return check.flag(value, "profiles") or False


def _packet(state, model, options):
    z = model.densities(state.x)
    centre, m2, part = moments(z, model.positions())
    out = {"m2": m2, "participation": part, "centre": centre,
           "total": np.sum(z, axis=-1)}
    if options["profiles"]:
        out["profile"] = z / np.sum(z, axis=-1, keepdims=True)
    return out


def _packet_defined(model, x0, options):
    """Refuse initial states whose conserved quantity sums to zero (or is not
    finite) over the sites: z_l = h_l / Σh, hence m₂ and P, are 0/0 there
    (e.g. a Klein–Gordon lattice at rest), and would be NaN at every output."""
    total = np.sum(_lattice(model).densities(x0), axis=-1)
    bad = np.flatnonzero(~(np.isfinite(total) & (total > 0)))
    if bad.size:
        m = int(bad[0])
        where = "" if len(x0) == 1 else f" of orbit {m}"
        quantity = getattr(model, "density_of", "energy")
        raise ValueError(
            f"the total {quantity} of the initial state{where} over the lattice's sites is "
            f"{float(total[m])!r}: its distribution z_l = h_l / Σh (and so m₂ and P) is "
            f"undefined; start from a state with a positive {quantity} (e.g. "
            "model.initial_block(...))")


def _spreading_vectors(model, options, given):
    _lattice(model)
    return 0 if given is None else given


def _spreading_read(state, model, t, options):
    return _packet(state, model, options)


SPREADING = register_indicator(Indicator(
    name="spreading",
    summary="second moment m₂ and participation number P of the energy (or norm) "
            "distribution over the lattice's sites",
    renorm=Renorm.NONE,
    vectors=_spreading_vectors,
    read=_spreading_read,
    result=IndicatorResult,
    options={"profiles": Option(False, _profiles,
                                "also keep the site distribution z_l at every output time")},
    finish=as_values,
    scalar=Field("m2"),
    states=_packet_defined,
    log_scale=True,
    laws="sub-diffusion m₂ ∝ t^a: a = 1/3 (weak chaos), 1/2 (strong chaos) in 1D; 1/5 and 1/3 "
         "in 2D; P ∝ √m₂ for a thermalised packet",
    references=("S. Flach, D. O. Krimer & Ch. Skokos, Phys. Rev. Lett. 102, 024101 (2009)",
                "T. V. Laptyeva et al., EPL 91, 30001 (2010)",
                "B. Many Manda, B. Senyange & Ch. Skokos, Phys. Rev. E 101, 032206 (2020)"),
))


def _dvd_vectors(model, options, given):
    _lattice(model)
    if given is not None and given != 1:
        raise ValueError(f"the 'dvd' indicator follows one deviation vector, got {given}")
    return 1


def _dvd_read(state, model, t, options):
    out = _packet(state, model, options)
    xi = model.deviation_distribution(state.W)[:, 0, :]
    _, dm2, dpart = moments(xi, model.positions())
    out.update(x1=state.log_growth()[:, 0] / t, dvd_m2=dm2, dvd_participation=dpart)
    if options["profiles"]:
        out["dvd"] = xi
    return out


DVD = register_indicator(Indicator(
    name="dvd",
    summary="finite-time mLCE Λ(t), the deviation vector distribution over sites (its m₂ "
            "and P) and the packet's m₂ and P",
    renorm=Renorm.QR,
    vectors=_dvd_vectors,
    read=_dvd_read,
    result=IndicatorResult,
    require="unit",
    options={"profiles": Option(False, _profiles,
                                "also keep the DVD ξ_l and the packet's z_l at every output "
                                "time")},
    finish=as_values,
    scalar=Field("x1"),
    states=_packet_defined,
    log_scale=True,
    laws="Λ ∝ t^{−0.25} (weak) and t^{−0.3} (strong chaos) in 1D, t^{−0.37} and t^{−0.46} in "
         "2D; Λ ∝ t^{−1} for regular motion; the DVD is localised in meandering chaotic spots",
    references=("Ch. Skokos, I. Gkolias & S. Flach, Phys. Rev. Lett. 111, 064101 (2013)",
                "B. Senyange, B. Many Manda & Ch. Skokos, Phys. Rev. E 98, 052229 (2018)",
                "B. Many Manda, B. Senyange & Ch. Skokos, Phys. Rev. E 101, 032206 (2020)"),
))

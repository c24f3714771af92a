"""MEGNO and the fast Lyapunov indicators FLI and OFLI.

With one deviation vector renormalised every τ and r_i its stretching over
the interval ending at t_i = iτ:

* MEGNO (Cincotta & Simó 2000): Y(t) = (2/t) ∫₀ᵗ s δ̇/δ ds, and its mean
  Ȳ(t) = (1/t) ∫₀ᵗ Y(s) ds. On quasi-periodic orbits Ȳ → 2 (Y oscillates
  about 2; → 0 on stable periodic orbits); on chaotic orbits Ȳ ≈ χ₁ t / 2.
* FLI (Froeschlé, Lega & Gonczi 1997): sup_{s≤t} ln‖w(s)‖ of the never
  renormalised vector — grows like ln t on regular orbits, like χ₁ t on
  chaotic ones.
* OFLI (Fouchard, Lega, Froeschlé & Froeschlé 2002): the same for the part
  of w orthogonal to the flow f = ẋ, which removes the linear shear along
  the flow and separates periodic from quasi-periodic orbits. A map has no
  flow: OFLI refuses map models, and MEGNO's ``ofli`` is NaN for them.

Quadrature
----------
All three need the stretching of every interval, so they are accumulated
after every renormalisation by :data:`MEGNO_ACCUMULATOR`, the same compiled
code for every method (rule 9 of :class:`varint.protocol.Propagator`). With
ln δ(t_i) = Σ_{j≤i} ln r_j exact at the grid times, the integral is the
Riemann–Stieltjes sum on the renormalisation grid,

    ∫₀^{t_n} s d(ln δ) ≈ Σ_{i≤n} t_i ln r_i,   Y(t_n) = (2/t_n) Σ_{i≤n} t_i ln r_i,

(right end points, exact for a stretching that is constant over each
interval) and the mean is the average over the grid,
Ȳ(t_n) = (1/n) Σ_{i≤n} Y(t_i). The grid is the τ of the run for every
method: the TM step, the TDH methods' interval, the output grid of the
Taylor, CVODE and DOP853 baselines (which step adaptively inside it). So the
discretisation error is the same O(τ) in the weights t_i for every method,
and methods agree to the accuracy of their tangent dynamics. FLI and OFLI
are suprema over the same grid.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..protocol import Accumulator, Renorm
from ..results import IndicatorResult, MEGNOResult
from .base import Field, Indicator, as_values, register_indicator

__all__ = ["MEGNO", "FLI", "OFLI", "MEGNO_ACCUMULATOR", "FLI_ACCUMULATOR"]

#: Columns of the accumulator array of each vector.
LOG, WEIGHTED, MEGNO_SUM, FLI_MAX, OFLI_MAX = range(5)


@njit(error_model="numpy")
def _update_megno(aux, r, x, W, flow, t):
    ff = 0.0
    for i in range(flow.shape[0]):
        ff += flow[i] * flow[i]
    for j in range(aux.shape[0]):
        lr = math.log(r[j])
        s = aux[j, LOG] + lr
        aux[j, LOG] = s
        aux[j, WEIGHTED] += t * lr
        aux[j, MEGNO_SUM] += 2.0 * aux[j, WEIGHTED] / t
        if s > aux[j, FLI_MAX]:
            aux[j, FLI_MAX] = s
        # ‖w_⊥‖ = ‖w‖ ‖ŵ_⊥‖ with ŵ the renormalised vector: ln‖w_⊥‖ = S + ½ ln‖ŵ_⊥‖².
        wf = 0.0
        for i in range(flow.shape[0]):
            wf += W[i, j] * flow[i]
        perp = 1.0 - wf * wf / ff if ff > 0.0 else 1.0
        if perp > 0.0:
            o = s + 0.5 * math.log(perp)
            if o > aux[j, OFLI_MAX]:
                aux[j, OFLI_MAX] = o


@njit(error_model="numpy")
def _update_fli(aux, r, x, W, flow, t):
    for j in range(aux.shape[0]):
        s = aux[j, 0] + math.log(r[j])
        aux[j, 0] = s
        if s > aux[j, 1]:
            aux[j, 1] = s


#: MEGNO's sums, FLI and OFLI of each vector (see the module docstring).
#: At t = 0: ln‖w‖ = 0, so FLI = 0; OFLI is a maximum over t ≥ τ.
MEGNO_ACCUMULATOR = Accumulator(
    name="megno", columns=("log", "weighted", "megno_sum", "fli", "ofli"),
    initial=(0.0, 0.0, 0.0, 0.0, -math.inf), update=_update_megno, needs_flow=True)

#: FLI alone: ln‖w‖ and its supremum; needs no flow (so no extra force
#: evaluation in schemes that end on a drift). ``update`` keeps them as a
#: running sum of ln r; the generated stepper
#: (:mod:`varint.kernels.generate`) keeps instead the largest ‖w‖ as a
#: mantissa and exponent ("peak", "peak_exp": the product of the stretchings
#: at the step of the supremum) and takes one logarithm when the state is
#: copied out, which lets its loop over orbits vectorise. The two agree to
#: round-off; each is deterministic.
FLI_ACCUMULATOR = Accumulator(name="fli", columns=("log", "fli", "peak", "peak_exp"),
                              initial=(0.0, 0.0, 1.0, 0.0), update=_update_fli)


def _one_vector(model, options, given):
    if given is not None and given != 1:
        raise ValueError(f"this indicator follows one deviation vector, {given} were given")
    return 1


def _is_map(model):
    return getattr(model, "kind", "flow") == "map"


def _one_vector_of_a_flow(model, options, given):
    # OFLI removes the component along the flow ẋ: a map has no flow.
    if _is_map(model):
        raise ValueError(f"OFLI needs the flow (the phase-space velocity) and {model.name} is a "
                         "map, which has none; use 'fli' or 'megno'")
    return _one_vector(model, options, given)


def _read_megno(rows, model, t, options):
    aux = rows.extra[MEGNO_ACCUMULATOR.key][:, 0]  # (R, columns) of the one vector
    # A map has no flow to be orthogonal to: no OFLI (NaN), see _one_vector_of_a_flow.
    ofli = np.full(len(aux), np.nan) if _is_map(model) else aux[:, OFLI_MAX].copy()
    return {"megno": 2.0 * aux[:, WEIGHTED] / t, "mean_megno": aux[:, MEGNO_SUM] / rows.step,
            "fli": aux[:, FLI_MAX].copy(), "ofli": ofli}


def _read_fli(rows, model, t, options):
    return {"fli": rows.extra[FLI_ACCUMULATOR.key][:, 0, 1].copy()}


def _read_ofli(rows, model, t, options):
    return {"ofli": rows.extra[MEGNO_ACCUMULATOR.key][:, 0, OFLI_MAX].copy()}


_REFERENCES_MEGNO = ("Cincotta & Simó, Astron. Astrophys. Suppl. 147, 205 (2000)",
                     "Cincotta, Giordano & Simó, Physica D 182, 151 (2003)")
_REFERENCES_FLI = ("Froeschlé, Lega & Gonczi, Celest. Mech. Dyn. Astron. 67, 41 (1997)",)
_REFERENCES_OFLI = ("Fouchard, Lega, Froeschlé & Froeschlé, Celest. Mech. Dyn. Astron. 83, "
                    "205 (2002)",)

MEGNO = register_indicator(Indicator(
    name="megno",
    summary="MEGNO Y(t), its mean Ȳ(t), FLI and OFLI of one deviation vector",
    renorm=Renorm.NORMALIZE,
    vectors=_one_vector,
    read=_read_megno,
    result=MEGNOResult,
    require="unit",
    accumulator=MEGNO_ACCUMULATOR,
    scalar=Field("mean_megno"),
    below=False,
    log_scale=False,
    laws="quasi-periodic orbits: Ȳ → 2; stable periodic: Ȳ → 0; chaotic: Ȳ ≈ χ₁ t / 2",
    references=_REFERENCES_MEGNO + _REFERENCES_FLI + _REFERENCES_OFLI,
))

FLI = register_indicator(Indicator(
    name="fli",
    summary="fast Lyapunov indicator FLI(t) = sup_{s≤t} ln‖w(s)‖ of one deviation vector",
    renorm=Renorm.NORMALIZE,
    vectors=_one_vector,
    read=_read_fli,
    result=IndicatorResult,
    require="unit",
    accumulator=FLI_ACCUMULATOR,
    finish=as_values,
    scalar=Field("fli"),
    below=False,
    log_scale=False,
    laws="regular orbits: FLI ≈ ln t (linear growth of w); chaotic: FLI ≈ χ₁ t",
    references=_REFERENCES_FLI,
))

OFLI = register_indicator(Indicator(
    name="ofli",
    summary="orthogonal FLI: sup_{s≤t} ln‖w_⊥(s)‖, w_⊥ the part of w orthogonal to the flow",
    renorm=Renorm.NORMALIZE,
    vectors=_one_vector_of_a_flow,
    read=_read_ofli,
    result=IndicatorResult,
    require="unit",
    accumulator=MEGNO_ACCUMULATOR,
    finish=as_values,
    scalar=Field("ofli"),
    below=False,
    log_scale=False,
    laws="periodic orbits: OFLI stays bounded; quasi-periodic: ≈ ln t; chaotic: ≈ χ₁ t",
    references=_REFERENCES_OFLI,
))

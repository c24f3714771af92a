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
after every renormalisation by :data:`MEGNO_ACCUMULATOR`, whose update is
written once (:data:`MEGNO_RULE`) and is the same arithmetic in every method
(rule 9 of :class:`varint.protocol.Propagator`). With
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

from ..codegen.accumulators import compile_update
from ..protocol import Accumulator, Renorm, UpdateRule
from ..results import IndicatorResult, MEGNOResult
from .base import Field, Indicator, as_values, register_indicator

__all__ = ["MEGNO", "FLI", "OFLI", "MEGNO_ACCUMULATOR", "FLI_ACCUMULATOR", "MEGNO_RULE",
           "FLI_RULE"]

#: Columns of the accumulator array of each vector.
LOG, WEIGHTED, MEGNO_SUM, FLI_MAX, OFLI_MAX = range(5)


#: MEGNO's update, written once: generated steppers write it into their
#: loops, and every other stepper calls it compiled (:func:`compile_update`),
#: with the same operations in the same order. ‖w_⊥‖ = ‖w‖ ‖ŵ_⊥‖ with ŵ
#: the renormalised vector: ln‖w_⊥‖ = S + ½ ln‖ŵ_⊥‖².
MEGNO_RULE = UpdateRule(
    live=("log", "weighted", "megno_sum", "fli", "ofli"),
    step=("lr = math.log(r)",
          "log = log + lr",
          "weighted = weighted + t * lr",
          "megno_sum = megno_sum + 2.0 * weighted / t",
          "fli = log if log > fli else fli",
          "wf = dot(w, f)",
          "ff = dot(f, f)",
          "perp = 1.0 - wf * wf / ff if ff > 0.0 else 1.0",
          "o = log + 0.5 * math.log(perp)",
          "ofli = o if perp > 0.0 and o > ofli else ofli"))

@njit(error_model="numpy")
def _update_fli(aux, r, x, W, flow, t):
    for j in range(aux.shape[0]):
        s = aux[j, 0] + math.log(r[j])
        aux[j, 0] = s
        if s > aux[j, 1]:
            aux[j, 1] = s


_MEGNO_COLUMNS = ("log", "weighted", "megno_sum", "fli", "ofli")

#: MEGNO's sums, FLI and OFLI of each vector (see the module docstring).
#: At t = 0: ln‖w‖ = 0, so FLI = 0; OFLI is a maximum over t ≥ τ.
MEGNO_ACCUMULATOR = Accumulator(
    name="megno", columns=_MEGNO_COLUMNS, initial=(0.0, 0.0, 0.0, 0.0, -math.inf),
    update=compile_update(MEGNO_RULE, _MEGNO_COLUMNS), needs_flow=True, rule=MEGNO_RULE)

#: FLI in a generated stepper: the largest ‖w‖ kept as a mantissa and
#: exponent ("peak", "peak_exp": the accumulated stretching at the step of
#: the supremum), compared exactly with the current (am, ae): the exponents
#: are multiples of 500, so am · 2^(ae − peak_exp) is exact where it matters
#: and otherwise decides by its exponent alone. FLI = ln peak + peak_exp ln 2
#: is taken only when the state is copied out — no logarithm per step, so
#: the loop over SIMD lanes vectorises (the arithmetic of Froeschlé et al.'s
#: sup, not of :func:`_update_fli`'s running sum).
FLI_RULE = UpdateRule(
    live=("peak", "peak_exp"),
    step=("d = ae - peak_exp",
          "v = am if d == 0.0 else (am * ACC_BIG if d == 500.0 else (am * ACC_SMALL if "
          "d == -500.0 else (np.inf if d > 0.0 else 0.0)))",
          "up = v > peak",
          "peak = am if up else peak",
          "peak_exp = float(ae) if up else peak_exp"),
    readout=("log = math.log(am) + ae * LN2",
             "fli = math.log(peak) + peak_exp * LN2"))

#: FLI alone: ln‖w‖ and its supremum; needs no flow (so no extra force
#: evaluation in schemes that end on a drift). ``update`` keeps them as a
#: running sum of ln r; a generated stepper follows :data:`FLI_RULE`. The
#: two agree to round-off; each is deterministic.
FLI_ACCUMULATOR = Accumulator(name="fli", columns=("log", "fli", "peak", "peak_exp"),
                              initial=(0.0, 0.0, 1.0, 0.0), update=_update_fli, rule=FLI_RULE)


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

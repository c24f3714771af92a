"""Symplectic correctors of Wisdom, Holman & Touma (1996) for the
Wisdom–Holman map, as data: words of Kepler drifts and interaction kicks.

The Wisdom–Holman map W(τ) = e^{τ/2 L_A} e^{τ L_B} e^{τ/2 L_A} of
H = A + εB (A integrable, B the perturbation) is conjugate to the exact
flow of H up to terms of second order in ε: a near-identity symplectic map
C with W(τ) = C⁻¹ ∘ φ_H(τ) ∘ C + O(ε²) removes every error term of first
order in ε up to the corrector's order p, so the energy error of the
corrected outputs falls from O(ετ²) to O(ετ^{p+1} + ε²τ²) at no cost per
step: the map runs on the mapped state C⁻¹(x) and C is applied only where
an output is needed (the kernel and processor of a processed method).

C is a product of operators Z(a, b) = X(a, −b) X(−a, b), each built from
the flows of the split, X(a, b) = e^{aτ L_A} e^{bτ L_B} e^{−aτ L_A}::

    C = Π_{k=K…1} Z(−a_k, −b_k) · Π_{k=1…K} Z(a_k, b_k),   a_k = k √(7/40)

(Wisdom, Holman & Touma 1996, with α = √(7/40); the b_k of orders 3, 5, 7,
11 and 17 as tabulated at full precision by Rein & Tamayo 2015, whose
implementation in REBOUND's WHFast orders the factors of order 3 the other
way round; the sign of its b here fits this ordering, which the measured
error scaling in the tests confirms). Since Z(a, b)⁻¹ = Z(−a, b), C⁻¹ is
the same word with every b negated.

The tangent of C is the product of the flows' tangent maps, like any
other word of flows (:mod:`varint.kernels.nbody`).

References
----------
J. Wisdom, M. Holman & J. Touma, Fields Inst. Commun. 10, 217 (1996);
H. Rein & D. Tamayo, Mon. Not. R. Astron. Soc. 452, 376 (2015).
"""

from __future__ import annotations

import math

__all__ = ["WHT_ORDERS", "corrector_word", "ALPHA"]

#: The spacing of the corrector's drift lengths, α = √(7/40).
ALPHA = math.sqrt(7.0 / 40.0)

#: b_k of the corrector of each order, for a_k = k α (k = 1 … K).
_B = {
    3: (0.024900596027799867499350357910273437184309981229127,),
    5: (0.041500993379666445832250596517122395307183302048545,
        -0.0083001986759332891664501193034244790614366604097090),
    7: (0.053964399093127498721765893493510877532452806339655,
        -0.018270923246702131478062356884535264841652263842597,
        0.0024926811426922105779030593952776964450539008582219),
    11: (0.072593394748842738674253180742744961827622366521517,
         -0.038121613681288650508647613260247372125243616270670,
         0.012309078592019946317544564763237909911330686448336,
         -0.0023487215292295354188307328851055489876255097419754,
         0.00020361579647854651301632818774633716473696537436847),
    17: (0.093056103771425958591541059067553547100903397724386,
         -0.065192863576377893658290760803725762027864651086787,
         0.032422198864713580293681523029577130832258806467604,
         -0.012071760822342291062449751726959664253913904872527,
         0.0033132577069380655655490196833451994080066801611459,
         -0.00063599983075817658983166881625078545864140848560259,
         0.000076436355227935738363241846979413475106795392377415,
         -0.0000043347415473373580190650223498124944896789841432241),
}

#: The orders available.
WHT_ORDERS = tuple(sorted(_B))

#: Slots of a corrector word: the integrable part A (the Kepler drift) and
#: the perturbation B (the interaction kick).
DRIFT, KICK = 0, 1


def corrector_word(order, inverse=False):
    """The corrector C of ``order`` (or C⁻¹) as a word of flows.

    Parameters
    ----------
    order : int
        One of :data:`WHT_ORDERS`.
    inverse : bool
        C⁻¹ (real state → the map's state) instead of C (map's state →
        real state).

    Returns
    -------
    tuple of (slot, coefficient)
        Flows e^{c τ L_slot} in order of application, slot :data:`DRIFT` or
        :data:`KICK`; adjacent flows of one slot merged, zero lengths
        dropped.

    Raises
    ------
    ValueError
        For an order without coefficients (the message lists the orders).
    """
    if order not in _B:
        raise ValueError(f"no Wisdom-Holman-Touma corrector of order {order!r}; available: "
                         f"{', '.join(map(str, WHT_ORDERS))}")
    sign = 1.0 if inverse else -1.0
    b = _B[order]
    factors = [(-(k + 1) * ALPHA, -sign * b[k]) for k in reversed(range(len(b)))]
    factors += [((k + 1) * ALPHA, sign * b[k]) for k in range(len(b))]
    word = []
    for a, bk in factors:
        # Z(a, b) = X(a, −b) X(−a, b) = e^{aA} e^{−bB} e^{−2aA} e^{bB} e^{aA}.
        word += [(DRIFT, a), (KICK, -bk), (DRIFT, -2.0 * a), (KICK, bk), (DRIFT, a)]
    merged = []
    for slot, c in word:
        if merged and merged[-1][0] == slot:
            merged[-1] = (slot, merged[-1][1] + c)
        else:
            merged.append((slot, c))
    return tuple((s, c) for s, c in merged if c != 0.0)

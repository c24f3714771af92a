"""A galaxy's disc and bulge, compiled: the gradient and Hessian of a
Miyamoto–Nagai disc and a Plummer sphere, written out with their shared
subexpressions.

The disc (Miyamoto & Nagai 1975, eq. 4) is Φ_D = −G M_D / √s_D with
s_D = x² + y² + S², S = A + ζ and ζ = √(z² + B²); the bulge (Plummer 1911;
Binney & Tremaine 2008, eq. 2.44a) Φ_S = −G M_S / √s_S, s_S = r² + ε².
With k = G M / s^{3/2} and e = 3k/s (either part),

    ∂_iΦ = k x_i (x, y; every coordinate of the bulge),   ∂_zΦ_D = k m z,
    ∂_ijΦ = k δ_ij − e x_i x_j,   ∂_izΦ_D = −e x_i (m z),
    ∂_zzΦ_D = k (m − A z²/ζ³) − e (m z)²,

m = S/ζ = 1 + A/ζ (from ∂_z s_D = 2 S z/ζ and ∂_z m = −A z/ζ³). Three
square roots and five divisions for both parts, gradient and Hessian
together: the SymPy forms they replace in the bar's generated stepper
(:mod:`varint.models.bar`) took nine and ten, the gradient and the
Hessian simplified apart (17 against 22 ns an evaluation in a compiled
loop over the regular bar orbit's positions, bar25). Against the SymPy
forms in 30 digits: ≤ 6e-16 of the largest entry
(``tests/models/test_bar_galactic.py``).

References
----------
M. Miyamoto & R. Nagai, Publ. Astron. Soc. Japan 27, 533 (1975);
H. C. Plummer, MNRAS 71, 460 (1911); J. Binney & S. Tremaine, *Galactic
Dynamics*, 2nd ed., Princeton (2008), Sect. 2.2–2.3.
"""

from __future__ import annotations

import math

from numba import njit

__all__ = ["disc_bulge_force"]


@njit(cache=True, error_model="numpy", inline="always")
def disc_bulge_force(q, g, D, hessian, disc_mass, disc_a, disc_b, bulge_mass, bulge_radius):
    """The gradient of Φ_D + Φ_S (module docstring; G·M_D = ``disc_mass``,
    scale lengths ``disc_a``, ``disc_b``; G·M_S = ``bulge_mass``, radius
    ``bulge_radius``) at the position ``q`` (3,) added to ``g`` (3,) and,
    if ``hessian``, its Hessian to ``D`` (3, 3). Inlined into its caller
    (four arrays passed to a call cost about as much as its arithmetic)."""
    x, y, z = q[0], q[1], q[2]
    R2 = x * x + y * y
    z2 = z * z
    # The bulge.
    s = R2 + z2 + bulge_radius * bulge_radius
    inv = 1.0 / s
    kb = bulge_mass * inv / math.sqrt(s)
    eb = 3.0 * kb * inv
    # The disc.
    zeta = math.sqrt(z2 + disc_b * disc_b)
    izeta = 1.0 / zeta
    S = disc_a + zeta
    s = R2 + S * S
    inv = 1.0 / s
    kd = disc_mass * inv / math.sqrt(s)
    ed = 3.0 * kd * inv
    mz = S * izeta * z
    k = kb + kd
    g[0] += k * x
    g[1] += k * y
    g[2] += kb * z + kd * mz
    if hessian:
        e = eb + ed
        v = -(e * (x * y))
        D[0, 1] += v
        D[1, 0] += v
        v = -(x * (eb * z + ed * mz))
        D[0, 2] += v
        D[2, 0] += v
        v = -(y * (eb * z + ed * mz))
        D[1, 2] += v
        D[2, 1] += v
        D[0, 0] += k - e * (x * x)
        D[1, 1] += k - e * (y * y)
        D[2, 2] += (kb - eb * z2) + (kd * (S * izeta - disc_a * z2 * (izeta * izeta * izeta))
                                     - ed * (mz * mz))

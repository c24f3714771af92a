"""The paper's TDH methods: the tangent dynamics Hamiltonian integrated
along an orbit known only at the grid times t_i = iΔt.

``method="tdhcc"``, ``"tdhes"`` and ``"tdheps"`` select them in every run
function (:data:`varint.METHODS`), for every model. They exist to reproduce
Skokos & Gerlach (2010), Sect. V.B, and to measure where they lose accuracy
(:mod:`varint.departure`); for production runs the TM method (``"tm"``) is
both faster and accurate.

Equation numbers count the equations of the paper's LaTeX source (its
preprint): the TDH is eq. (9), the TDHes diagonalisation eqs.
(28)–(29), the extended phase space eqs. (30)–(37), the schemes usable there
eqs. (38)–(40), and Appendix A eqs. (A.10) and (A.15)–(A.18) for
Hénon–Heiles.

References
----------
Ch. Skokos & E. Gerlach, Phys. Rev. E 82, 036704 (2010).
"""

from .frozen import henon_heiles_transform, oscillator
from .propagators import TDHccPropagator, TDHepsPropagator, TDHesPropagator, eps_grid

__all__ = ["TDHccPropagator", "TDHesPropagator", "TDHepsPropagator", "eps_grid",
           "henon_heiles_transform", "oscillator"]

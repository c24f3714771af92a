"""varint: variational equations of Hamiltonian systems, integrated fast and
accurately, and the chaos indicators built on them.

The tangent map (TM) method of Skokos & Gerlach (Phys. Rev. E 82, 036704,
2010) turns any symplectic splitting scheme for H = ½pᵀM⁻¹p + V(q) into an
integrator of the orbit and its deviation vectors.

>>> import varint
>>> model, x0 = varint.paper_orbit("C1")
>>> r = varint.lyapunov_spectrum(model, x0, t_end=100.0, tau=0.05)
>>> r.exponents.shape[1]
4
"""

from . import models
from .checkpoint import CheckpointError
from .departure import Departure, departure
from .driver import IntegrationError
from .indicators import gali, lyapunov_spectrum, sali
from .integrate import integrate
from .maps import MAP_INDICATORS, chaos_map
from .megno import megno
from .methods import METHODS
from .models import paper_orbit, solve_momentum
from .results import (ChaosMapResult, GALIResult, IntegrationResult, LyapunovResult,
                      MEGNOResult, SALIResult, SectionResult, load_result)
from .schemes import SCHEMES, SplittingScheme, get_scheme, register_scheme
from .sections import section_grid, surface_of_section
from .selection import select_scheme

__all__ = [
    "models", "paper_orbit", "solve_momentum",
    "SCHEMES", "SplittingScheme", "get_scheme", "register_scheme", "METHODS",
    "integrate", "lyapunov_spectrum", "gali", "sali", "megno",
    "IntegrationResult", "LyapunovResult", "GALIResult", "SALIResult", "MEGNOResult",
    "load_result",
    "IntegrationError", "CheckpointError", "departure", "Departure",
    "chaos_map", "MAP_INDICATORS", "ChaosMapResult", "surface_of_section", "section_grid",
    "SectionResult", "select_scheme",
]

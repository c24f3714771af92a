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

import importlib.util as _util
import re as _re
import sys as _sys
from importlib import metadata as _metadata
from pathlib import Path as _Path


def _version():
    """The version in pyproject.toml, the one place it is written.

    Run from a source checkout (pyproject.toml of the project "varint" beside
    the package) it is read from that file, so a checkout that sits beside an
    older installed copy reports its own version; otherwise from the
    installed distribution's metadata. "0+unknown" if neither is found.
    """
    pyproject = _Path(__file__).resolve().parent.parent / "pyproject.toml"
    try:
        text = pyproject.read_text(encoding="utf-8")
    except OSError:
        text = ""
    # [project] holds name and version; no TOML parser is needed for two
    # plain strings (tomllib is Python >= 3.11 only).
    project = _re.search(r"^\[project\]\s*$(.*?)(?=^\[|\Z)", text, _re.M | _re.S)
    if project and _re.search(r'^name\s*=\s*"varint"', project.group(1), _re.M):
        found = _re.search(r'^version\s*=\s*"([^"]+)"', project.group(1), _re.M)
        if found:
            return found.group(1)
    try:
        return _metadata.version("varint")
    except _metadata.PackageNotFoundError:
        return "0+unknown"


#: The version of varint (PEP 440), e.g. "0.1.0"; results record it in
#: their provenance.
__version__ = _version()


def _source_checkout_baselines():
    # The reference integrators live in the repository's top-level
    # baselines/ folder (the layout is fixed) and are installed as
    # varint.baselines (pyproject's package-dir). Run from a source
    # checkout, the same name must find that folder.
    installed = _Path(__file__).with_name("baselines")
    folder = _Path(__file__).resolve().parent.parent / "baselines"
    name = __name__ + ".baselines"
    if installed.is_dir() or name in _sys.modules or not (folder / "__init__.py").is_file():
        return
    spec = _util.spec_from_file_location(name, folder / "__init__.py",
                                         submodule_search_locations=[str(folder)])
    module = _util.module_from_spec(spec)
    _sys.modules[name] = module
    spec.loader.exec_module(module)
    globals()["baselines"] = module


_source_checkout_baselines()

from . import models  # noqa: E402
from .accuracy import Accuracy, AccuracyWarning  # noqa: E402
from .api import gali, integrate, lyapunov_spectrum, megno, sali  # noqa: E402
from .checkpoint import CheckpointError  # noqa: E402
from .departure import Departure, departure  # noqa: E402
from .driver import IntegrationError  # noqa: E402
from .element_grid import element_grid  # noqa: E402
from .grids import PhaseGrid, phase_grid  # noqa: E402
from .ensemble import EnsembleResult, ensemble  # noqa: E402
from .indicators import INDICATORS, Indicator, Option, get_indicator, register_indicator  # noqa: E402
from .maps import chaos_map  # noqa: E402
from .methods import METHODS, register_method  # noqa: E402
from .models import paper_orbit, solve_momentum  # noqa: E402
from .protocol import Renorm, Status  # noqa: E402
from .results import (ChaosMapResult, GALIResult, IndicatorResult,  # noqa: E402
                      IntegrationResult, LyapunovResult, MEGNOResult, SALIResult, SectionResult,
                      load_result)
from .run import run  # noqa: E402
from .schemes import SCHEMES, SplittingScheme, get_scheme, register_scheme  # noqa: E402
from .sections import section_grid, surface_of_section  # noqa: E402
from .selection import select_scheme  # noqa: E402
from .codecache import tolerate_full_disks  # noqa: E402

# A full disk when numba caches a kernel costs a warning, not the run.
tolerate_full_disks()

__all__ = [
    "models", "paper_orbit", "solve_momentum",
    "SCHEMES", "SplittingScheme", "get_scheme", "register_scheme",
    "METHODS", "register_method",
    "INDICATORS", "Indicator", "Option", "get_indicator", "register_indicator",
    "run", "integrate", "lyapunov_spectrum", "gali", "sali", "megno",
    "IntegrationResult", "LyapunovResult", "GALIResult", "SALIResult", "MEGNOResult",
    "IndicatorResult", "load_result", "Status", "Renorm",
    "IntegrationError", "CheckpointError", "departure", "Departure",
    "chaos_map", "ChaosMapResult", "surface_of_section", "section_grid", "ensemble",
    "EnsembleResult", "phase_grid", "PhaseGrid", "element_grid", "SectionResult",
    "select_scheme",
    "Accuracy", "AccuracyWarning",
]

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

import importlib as _importlib
import importlib.util as _util
import re as _re
import sys as _sys
import types as _types
from pathlib import Path as _Path
from typing import TYPE_CHECKING as _TYPE_CHECKING


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
    # importlib.metadata takes ~15 ms to import (email parsing): only an
    # installed copy, which has no pyproject.toml beside it, pays it.
    from importlib import metadata

    try:
        return metadata.version("varint")
    except metadata.PackageNotFoundError:
        return "0+unknown"


#: The version of varint (PEP 440), e.g. "0.1.0"; results record it in
#: their provenance. Worked out on first use (:func:`__getattr__`), so that
#: ``import varint`` reads no file.
__version__: str


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

#: Every public name and the submodule that defines it. ``import varint``
#: imports none of them: numba, SymPy and SciPy take a second or more to
#: import, and a process that only asks for ``varint.__version__`` (or a
#: CLI's ``--help``) should not pay it. A public name asked for imports its
#: own submodule (and what that needs), see :func:`__getattr__`: a first
#: R1 spectrum does not import the maps, ensembles, grids and sections
#: (≈ 14 ms of CPU of its start-up).
_EXPORTS = {
    "models": "models",
    "Accuracy": "accuracy", "AccuracyWarning": "accuracy",
    "gali": "api", "integrate": "api", "lyapunov_spectrum": "api", "megno": "api",
    "sali": "api",
    "CheckpointError": "checkpoint",
    "Departure": "departure", "departure": "departure",
    "IntegrationError": "driver",
    "element_grid": "element_grid",
    "PhaseGrid": "grids", "phase_grid": "grids",
    "EnsembleResult": "ensemble", "ensemble": "ensemble",
    "INDICATORS": "indicators", "Indicator": "indicators", "Option": "indicators",
    "get_indicator": "indicators", "register_indicator": "indicators",
    "chaos_map": "maps",
    "METHODS": "methods", "register_method": "methods",
    "paper_orbit": "models", "solve_momentum": "models",
    "Renorm": "protocol", "Status": "protocol",
    "ChaosMapResult": "results", "GALIResult": "results", "IndicatorResult": "results",
    "IntegrationResult": "results", "LyapunovResult": "results", "MEGNOResult": "results",
    "SALIResult": "results", "SectionResult": "results", "load_result": "results",
    "run": "run",
    "PreparedRun": "prepared", "prepare": "prepared",
    "SCHEMES": "schemes", "SplittingScheme": "schemes", "get_scheme": "schemes",
    "register_scheme": "schemes",
    "section_grid": "sections", "surface_of_section": "sections",
    "select_scheme": "selection",
}

__all__ = list(_EXPORTS)

if _TYPE_CHECKING:
    # What a type checker sees (the same names, statically): at run time
    # they arrive through __getattr__ below. ``X as X`` marks a re-export.
    from . import models as models
    from .accuracy import Accuracy as Accuracy, AccuracyWarning as AccuracyWarning
    from .api import (
        gali as gali,
        integrate as integrate,
        lyapunov_spectrum as lyapunov_spectrum,
        megno as megno,
        sali as sali,
    )
    from .checkpoint import CheckpointError as CheckpointError
    from .departure import Departure as Departure, departure as departure
    from .driver import IntegrationError as IntegrationError
    from .element_grid import element_grid as element_grid
    from .grids import PhaseGrid as PhaseGrid, phase_grid as phase_grid
    from .ensemble import EnsembleResult as EnsembleResult, ensemble as ensemble
    from .indicators import (
        INDICATORS as INDICATORS,
        Indicator as Indicator,
        Option as Option,
        get_indicator as get_indicator,
        register_indicator as register_indicator,
    )
    from .maps import chaos_map as chaos_map
    from .methods import METHODS as METHODS, register_method as register_method
    from .models import paper_orbit as paper_orbit, solve_momentum as solve_momentum
    from .protocol import Renorm as Renorm, Status as Status
    from .prepared import PreparedRun as PreparedRun, prepare as prepare
    from .results import (
        ChaosMapResult as ChaosMapResult,
        GALIResult as GALIResult,
        IndicatorResult as IndicatorResult,
        IntegrationResult as IntegrationResult,
        LyapunovResult as LyapunovResult,
        MEGNOResult as MEGNOResult,
        SALIResult as SALIResult,
        SectionResult as SectionResult,
        load_result as load_result,
    )
    from .run import run as run
    from .schemes import (
        SCHEMES as SCHEMES,
        SplittingScheme as SplittingScheme,
        get_scheme as get_scheme,
        register_scheme as register_scheme,
    )
    from .sections import section_grid as section_grid, surface_of_section as surface_of_section
    from .selection import select_scheme as select_scheme


class _Package(_types.ModuleType):
    """varint's module object: the import system binds every submodule it
    imports to its package, and four submodules are named after the
    function they define (``run``, ``departure``, ``ensemble``,
    ``element_grid``). The function keeps the name, as it did when
    ``import varint`` imported everything at once."""

    def __setattr__(self, name, value):
        if isinstance(value, _types.ModuleType) and _EXPORTS.get(name) == name != "models":
            return
        super().__setattr__(name, value)


_sys.modules[__name__].__class__ = _Package


def _load(module):
    """Import submodule ``module`` and the public names it defines
    (:data:`_EXPORTS`) into the package."""
    # Importing is loading code: the collector's full passes over the
    # objects of numpy and numba it would make meanwhile free nothing.
    with _importlib.import_module(".collector", __name__).held():
        value = _importlib.import_module(f".{module}", __name__)
    names = globals()
    for name, where in _EXPORTS.items():
        if where == module:
            names[name] = value if name == module == "models" else getattr(value, name)
    # A full disk when numba caches a kernel costs a warning, not the run
    # (each load wraps the kernels of the modules imported since the last).
    _importlib.import_module(".codecache", __name__).tolerate_full_disks()


def __getattr__(name):
    # Called only for names not yet in the package (PEP 562).
    if name == "__version__":
        globals()[name] = _version()
        return globals()[name]
    if name not in _EXPORTS:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    _load(_EXPORTS[name])
    return globals()[name]


def __dir__():
    return sorted(set(globals()) | set(_EXPORTS) | {"__version__"})

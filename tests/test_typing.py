"""The public API is typed (PEP 561): the package ships py.typed, and every
parameter and return value of the public functions is annotated with types
that resolve."""

import importlib
import inspect
import typing
from pathlib import Path

import pytest

import varint
from varint import maps, models
from varint.indicators import base as indicators
from varint.methods import register_method
from varint.models import symbolic

ROOT = Path(__file__).resolve().parent.parent
# The module, not the function varint.run that shadows it.
run_module = importlib.import_module("varint.run")

PUBLIC = {
    "varint.run": varint.run, "varint.run.prepare": run_module.prepare,
    "varint.lyapunov_spectrum": varint.lyapunov_spectrum, "varint.gali": varint.gali,
    "varint.sali": varint.sali, "varint.megno": varint.megno,
    "varint.integrate": varint.integrate, "varint.chaos_map": maps.chaos_map,
    "varint.section_grid": varint.section_grid,
    "varint.surface_of_section": varint.surface_of_section,
    "varint.paper_orbit": varint.paper_orbit, "varint.solve_momentum": varint.solve_momentum,
    "varint.models.from_potential": symbolic.from_potential,
    "varint.select_scheme": varint.select_scheme, "varint.departure": varint.departure,
    "varint.load_result": varint.load_result,
    "varint.register_method": register_method,
    "varint.register_indicator": indicators.register_indicator,
    "varint.get_indicator": indicators.get_indicator,
    "varint.register_scheme": varint.register_scheme,
    "varint.get_scheme": varint.get_scheme,
    "Model.__init__": models.Model.__init__,
    "HenonHeiles.__init__": models.HenonHeiles.__init__,
    "ThreeDof.__init__": models.ThreeDof.__init__,
    "FPUBeta.__init__": models.FPUBeta.__init__,
}


@pytest.mark.parametrize("name", sorted(PUBLIC))
def test_fully_annotated_and_resolvable(name):
    function = PUBLIC[name]
    hints = typing.get_type_hints(function)  # raises NameError for a name that does not resolve
    signature = inspect.signature(function)
    missing = [p for p in signature.parameters if p != "self" and p not in hints]
    assert not missing, f"{name}: parameters without a type: {missing}"
    assert "return" in hints, f"{name}: no return type"


def test_the_result_types_are_the_result_classes():
    hints = typing.get_type_hints(varint.lyapunov_spectrum)
    assert hints["return"] is varint.LyapunovResult
    assert typing.get_type_hints(maps.chaos_map)["return"] is varint.ChaosMapResult


def test_py_typed_is_shipped():
    assert (Path(varint.__file__).parent / "py.typed").is_file()
    text = (ROOT / "pyproject.toml").read_text()
    assert '[tool.setuptools.package-data]\nvarint = ["py.typed"]' in text

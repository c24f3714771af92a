"""One version, written once (pyproject.toml), reported by varint, recorded
in results, cited and described in the changelog."""

import re
from importlib import metadata
from pathlib import Path

import pytest

import varint

ROOT = Path(__file__).resolve().parent.parent
PYPROJECT = (ROOT / "pyproject.toml").read_text()
VERSION = re.search(r'^version = "([^"]+)"', PYPROJECT, re.M).group(1)


def test_version_is_pyprojects():
    assert varint.__version__ == VERSION


def test_an_installed_copy_agrees():
    try:
        installed = metadata.version("varint")
    except metadata.PackageNotFoundError:
        pytest.skip("varint is not installed (run from the source tree)")
    assert installed == VERSION


def test_results_record_it(r1):
    model, x0 = r1
    r = varint.integrate(model, x0, 0.1, tau=0.05)
    assert r.provenance.versions["varint"] == varint.__version__


def test_citation_file():
    cff = (ROOT / "CITATION.cff").read_text()
    assert "cff-version: 1.2.0" in cff
    assert re.search(r"^version: (\S+)$", cff, re.M).group(1) == VERSION
    assert "doi: 10.1103/PhysRevE.82.036704" in cff and "Skokos" in cff


def test_changelog_names_this_version():
    changelog = (ROOT / "CHANGELOG.md").read_text()
    released = VERSION.split(".dev")[0]
    assert re.search(rf"^## {re.escape(released)}\b", changelog, re.M) or \
        f"## {VERSION}" in changelog

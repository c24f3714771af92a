"""The package stays lint- and type-clean, and its public API type-checks in
a user's code: ``ruff check`` (rules in pyproject's ``[tool.ruff.lint]``)
over the whole repository and ``mypy`` (``[tool.mypy]``) over ``varint``
report nothing, and mypy, run on a snippet that uses the API, accepts the
right uses and rejects a wrong one."""

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


def _run(*args, cwd=ROOT):
    # MYPYPATH: the source tree, as an editable install's import hook is
    # invisible to mypy.
    env = {**os.environ, "MYPYPATH": str(ROOT)}
    return subprocess.run([sys.executable, "-m", *args], cwd=cwd, capture_output=True,
                          text=True, timeout=600, env=env)


@pytest.fixture(scope="module")
def mypy_cache(tmp_path_factory):
    # One cache per module run: the second mypy call reuses the package's
    # analysis instead of redoing it.
    return tmp_path_factory.mktemp("mypy_cache")


def test_ruff_reports_nothing():
    out = _run("ruff", "check", "--no-cache", ".")
    assert out.returncode == 0, out.stdout + out.stderr


def test_mypy_reports_nothing_on_the_package(mypy_cache):
    out = _run("mypy", "--cache-dir", str(mypy_cache))
    assert out.returncode == 0, out.stdout + out.stderr


USES = """
import numpy as np
import varint
from varint.maps import ChaosMapResult
from varint.results import LyapunovResult

model = varint.models.HenonHeiles()
x0 = np.array([0.0, 0.1, 0.35, 0.1])
r: LyapunovResult = varint.lyapunov_spectrum(model, x0, 10.0, tau=0.05)
exponents: np.ndarray | None = r.exponents
m: ChaosMapResult = varint.chaos_map(model, np.array([x0, x0]), "fli", t_end=10.0)
"""


@pytest.mark.parametrize("wrong, expected", [
    ("", None),
    ('n: int = varint.lyapunov_spectrum(model, x0, 10.0)', "Incompatible types in assignment"),
    ("model.no_such_attribute", "has no attribute"),
])
def test_mypy_checks_the_public_api_in_user_code(tmp_path, mypy_cache, wrong, expected):
    snippet = tmp_path / "user.py"
    snippet.write_text(textwrap.dedent(USES) + wrong + "\n")
    out = _run("mypy", "--config-file", str(ROOT / "pyproject.toml"), "--cache-dir",
               str(mypy_cache), str(snippet), cwd=tmp_path)
    if expected is None:
        assert out.returncode == 0, out.stdout + out.stderr
    else:
        assert out.returncode == 1 and expected in out.stdout, out.stdout + out.stderr

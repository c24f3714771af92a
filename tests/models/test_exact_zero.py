"""The exact zero tests of :mod:`varint.models.exact_zero`, and the
structures :func:`~varint.models.from_hamiltonian` finds with them: the
same as ``sympy.simplify`` found, hidden identities included, without
importing what ``simplify`` imports on the common path."""

import subprocess
import sys

import pytest
import sympy as sp

from varint.models.exact_zero import is_zero, without
from varint.models.hamiltonian import recognise

q, r, p, s, t = sp.symbols("q r p s t")


@pytest.mark.parametrize("e", [
    sp.Integer(0), (q + p) ** 2 - q ** 2 - 2 * q * p - p ** 2,
    1 / (q - 1) - 1 / (q + 1) - 2 / (q ** 2 - 1),
    (q ** 2 - 1) / (q - 1) - q - 1,
    sp.sin(q) ** 2 + sp.cos(q) ** 2 - 1,
    sp.cos(2 * q) - sp.cos(q) ** 2 + sp.sin(q) ** 2,
    sp.exp(q) * sp.exp(-q) - 1])
def test_identities_are_zero(e):
    assert is_zero(e)


@pytest.mark.parametrize("e", [
    sp.Integer(-1), q * p - p * r, 1 / (q - 1) - 1 / (q + 1),
    sp.sin(q) ** 2 + sp.cos(q) ** 2 - 1 + 10 ** -25 * q,  # tiny, still not zero
    sp.sqrt(q ** 2) - q, sp.exp(q) - 1 - q, sp.Float(0.1) * q * p])
def test_non_identities_are_not_zero(e):
    assert not is_zero(e)


def test_without_removes_symbols_that_cancel():
    assert without((p + q) ** 2 - 2 * p * q - q ** 2, [q]) == p ** 2
    assert without(p ** 2 * (sp.sin(q) ** 2 + sp.cos(q) ** 2), [q]) == p ** 2
    assert without(p * q, [q]) is None


@pytest.mark.parametrize("H, kind", [
    # ½p²(sin²q + cos²q) + V: the kinetic energy ½p², hidden.
    (p ** 2 * (sp.sin(q) ** 2 + sp.cos(q) ** 2) / 2 + q ** 4, "potential"),
    # A mixed term that cancels only through sin² + cos² = 1.
    (p ** 2 / 2 + q * p * (sp.sin(q) ** 2 + sp.cos(q) ** 2) - q * p + q ** 2, "potential"),
    # A rational form of ½p²: (q + 1)² p² / (2 (q + 1)²).
    (p ** 2 * (q ** 2 + 2 * q + 1) / (2 * (q + 1) ** 2) + q ** 4, "potential"),
    # T(p) written with q inside, cancelling: (p + q)² − 2pq − q² + V.
    ((p + q) ** 2 - 2 * p * q + sp.cos(q), "potential"),
    # A rational, non-quadratic T(p) with a rational V.
    (p ** 4 / (1 + p ** 2) + 1 / (1 + q ** 2), "separable"),
    # Mixed terms that do not cancel: the general form.
    (p ** 2 / 2 + q ** 2 / 2 + sp.sin(q) * p, "general"),
    ((p ** 2 + 1) * (q ** 2 + 1) / 2, "general")])
def test_hidden_structures_are_found(H, kind):
    assert recognise(H, (q,), (p,)).kind == kind


def test_making_a_model_does_not_import_simplify():
    # sympy.simplify imports sympy.physics.units at its first call (~0.1 s
    # of a fresh process's first model, issue 28); the common structures
    # are decided without it.
    code = ("import sys, sympy as sp\n"
            "from varint.models.hamiltonian import recognise\n"
            "from varint.models import CR3BP\n"
            "x, y, px, py = sp.symbols('x y p_x p_y')\n"
            "H = (px**2 + py**2) / 2 + sp.Rational(1, 10) * x * px * py + x**2 * y\n"
            "assert recognise(H, (x, y), (px, py)).kind == 'general'\n"
            "assert recognise(sp.sqrt(1 + px**2) + x**4, (x,), (px,)).kind == 'separable'\n"
            "CR3BP(0.01)\n"
            "assert 'sympy.physics.units' not in sys.modules\n")
    subprocess.run([sys.executable, "-c", code], check=True)

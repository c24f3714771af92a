"""The TDHeps study's quick mode: a second implementation of TDHeps, written
from the paper's Appendix eqs. A.15–A.18, reproduces varint's."""

import inspect

import pytest

from studies import tdheps_variants


@pytest.fixture
def compiled_once(monkeypatch):
    """The study's ``make_tdheps``, each (model, variant) made once. The
    study makes a new compiled closure per run, and numba compiles each
    anew: R1's "half" variant three times (the first claim and two τ),
    "full" twice, the same code (about 12 CPU s cold). A run's numbers are
    those of the closure made for it: the closures differ only in being
    made again."""
    made = {}
    make = tdheps_variants.make_tdheps

    def once(model, **variant):
        given = inspect.signature(make).bind(model, **variant)
        given.apply_defaults()      # "half" given or by default: one closure
        key = (id(model),) + tuple(v for k, v in given.arguments.items() if k != "model")
        if key not in made:
            made[key] = (model, make(model, **variant))   # the model kept: its id stays its
        return made[key][1]

    monkeypatch.setattr(tdheps_variants, "make_tdheps", once)
    return made


def test_an_independent_tdheps_gives_varints_numbers(tmp_path, compiled_once):
    res = tdheps_variants.main(["--quick", "--out", str(tmp_path)])
    assert len(compiled_once) == 4     # R1 half and full, R2 with M⁻¹ and unit mass
    (check,) = [c for c in res["claims"] if c["claim"].startswith("A second TDHeps")]
    assert check["holds"], check["ours"]
    # The variants run and give finite, positive levels on R1 and R2.
    assert {(r["orbit"], r["orbit_step"], r["corrector"]) for r in res["rows"]} >= {
        ("R1", "half", "M^-1"), ("R1", "full", "M^-1"), ("R2", "half", "unit mass (eq. 36)")}
    assert all(r["X1"] > 0 for r in res["rows"])
    assert (tmp_path / "tdheps_variants.csv").exists()

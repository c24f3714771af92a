"""The TDHeps study's quick mode: a second implementation of TDHeps, written
from the paper's Appendix eqs. A.15–A.18, reproduces varint's."""

from studies import tdheps_variants


def test_an_independent_tdheps_gives_varints_numbers(tmp_path):
    res = tdheps_variants.main(["--quick", "--out", str(tmp_path)])
    (check,) = [c for c in res["claims"] if c["claim"].startswith("A second TDHeps")]
    assert check["holds"], check["ours"]
    # The variants run and give finite, positive levels on R1 and R2.
    assert {(r["orbit"], r["orbit_step"], r["corrector"]) for r in res["rows"]} >= {
        ("R1", "half", "M^-1"), ("R1", "full", "M^-1"), ("R2", "half", "unit mass (eq. 36)")}
    assert all(r["X1"] > 0 for r in res["rows"])
    assert (tmp_path / "tdheps_variants.csv").exists()

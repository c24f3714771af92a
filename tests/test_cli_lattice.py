"""``varint lattice``: the clean linear chain's ballistic law through the
command line, its CSV the API's numbers, and one-line refusals."""

import csv

import numpy as np
import pytest

import varint
from varint import cli


def _run(capsys, argv):
    code = cli.main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def test_clean_linear_chain_spreads_ballistically(capsys, tmp_path):
    """W = 0, β = 0: m₂ = 2t² exactly (Bessel solution), so the printed
    exponent is 2 and the CSV holds log₁₀(2t²)."""
    path = tmp_path / "m2.csv"
    code, out, err = _run(capsys, ["lattice", "spreading", "--model", "ddnls", "--sites", "201",
                                   "--W", "0", "--beta", "0", "--t-end", "40", "--tau", "0.02",
                                   "--scheme", "s11ABC6", "--csv", str(path)])
    assert code == 0, err
    assert "m2 ~ t^2.000 over t = 0.4..40" in out
    with open(path) as f:
        rows = list(csv.DictReader(f))
    t = np.array([float(r["t"]) for r in rows])
    m2 = np.array([float(r["<log10 m2>"]) for r in rows])
    assert np.allclose(m2, np.log10(2 * t ** 2), atol=1e-9, rtol=0)


def test_an_ensemble_is_the_api_ensemble(capsys, tmp_path):
    path = tmp_path / "kg.csv"
    argv = ["lattice", "dvd", "--model", "kg", "--sites", "6x6", "--W", "10", "--block", "2",
            "--density", "0.2", "--seeds", "1:3", "--t-end", "20", "--t-out", "5",
            "--csv", str(path), "--checkpoint", str(tmp_path / "ck")]
    code, out, err = _run(capsys, argv)
    assert code == 0, err
    e = varint.ensemble(varint.models.DisorderedKG, [1, 2, 3],
                        lambda m, s: m.initial_block(2, 0.2, seed=s), "dvd", 20.0, 0.1,
                        params={"shape": (6, 6), "W": 10.0, "boundary": "fixed"},
                        scheme="ABA864", t_out=5, progress=False)
    with open(path) as f:
        rows = list(csv.DictReader(f))
    for name in ("x1", "m2"):
        mean, std, _ = e.log_mean(name)
        assert np.allclose([float(r[f"<log10 {name}>"]) for r in rows], mean, rtol=1e-5)
        assert np.allclose([float(r[f"std {name}"]) for r in rows], std, rtol=1e-5, atol=1e-9)
    # Run again: every realisation comes from the checkpoint, same table.
    code, again, _ = _run(capsys, argv)
    assert code == 0 and again.splitlines()[1:-1] == out.splitlines()[1:-1]


@pytest.mark.parametrize("argv, message", [
    (["--model", "fput", "--sites", "8x8"], "--sites must be one integer, got 8x8"),
    (["--model", "kg", "--sites", "16", "--beta", "1"], "--beta does not apply to --model kg"),
    (["--model", "kg", "--sites", "1x2x3"], "expected N or NXxNY, got '1x2x3'"),
    (["--model", "ddnls", "--sites", "16", "--seeds", "3:1"], "LAST >= FIRST"),
    (["--model", "ddnls", "--sites", "16", "--block", "40"], "width 40 exceeds the lattice"),
    (["--model", "fput", "--sites", "16", "--seeds", "1,2"], "fput has no disorder"),
    (["--model", "ddnls", "--sites", "16", "--scheme", "SABA2C"], "needs the corrector flow"),
    (["--model", "ddnls", "--sites", "16", "--W", "-1"], "W must be >= 0"),
    (["--model", "kg", "--sites", "16", "--t-out", "50", "--t-end", "1"],
     "more output times than the run has steps"),
])
def test_bad_lattice_arguments_are_one_line(capsys, argv, message):
    code, out, err = _run(capsys, ["lattice", "dvd", *argv])
    assert code == 2 and message in err and len(err.strip().splitlines()) == 1, err

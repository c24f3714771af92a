"""``varint run --hamiltonian``: any H(q, p) from the command line, its
structure recognised, its momentum solved from the energy, and bad
arguments refused in one line."""

import numpy as np
import pytest

from varint import cli

CR3BP = ("(px**2+py**2)/2 + y*px - x*py - 0.999046/sqrt((x+0.000954)**2+y**2)"
         " - 0.000954/sqrt((x-0.999046)**2+y**2)")


def _run(capsys, argv):
    code = cli.main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def test_run_a_rotating_frame(capsys, tmp_path):
    """The Sun–Jupiter problem by formula: recognised as a rotating frame
    plus V (the TM method with SRKN14a), p_x solved from H = −1.525 on the
    branch ẋ ≥ 0; the energy is conserved to 1e-5 (its close approaches to
    the Sun set that at the CLI's τ = 0.05)."""
    csv_path = tmp_path / "fli.csv"
    code, out, err = _run(capsys, ["run", "fli", "--hamiltonian", CR3BP, "--coords", "x,y",
                                   "--momenta", "px,py", "--energy", "-1.525", "--q", "0.4,0",
                                   "--p", "0,1.18", "--t-end", "50", "--csv", str(csv_path)])
    assert code == 0, err
    assert "by tm (SRKN14a)" in out
    rows = np.genfromtxt(csv_path, delimiter=",", names=True)
    assert rows["energy_error"].max() < 1e-5
    assert rows["fli"][-1] > 0


@pytest.mark.parametrize("argv, message", [
    (["--hamiltonian", "px**2/2 + x**4", "--coords", "x"], "--hamiltonian needs --momenta"),
    (["--hamiltonian", "px**2/2 + x**4", "--coords", "x", "--momenta", "px,py"],
     "--momenta names 2 momenta for 1 --coords"),
    (["--hamiltonian", "x**2/2 + x**4", "--coords", "x", "--momenta", "x"],
     "x is both a momentum and a coordinate"),
    (["--hamiltonian", "px**2/2 + k*x**4", "--coords", "x", "--momenta", "px"], "k"),
    (["--potential", "x**4", "--coords", "x", "--momenta", "px"],
     "--momenta applies to --hamiltonian only"),
    (["--hamiltonian", "px**2/2 + x**4", "--coords", "x", "--momenta", "px",
      "--inverse-mass", "2"], "--inverse-mass applies to --potential only"),
    (["--hamiltonian", "px**2/2 + x**4", "--momenta", "px"], "--hamiltonian needs --coords"),
])
def test_bad_arguments_are_refused_in_one_line(capsys, argv, message):
    code, out, err = _run(capsys, ["run", "x1", *argv, "--x0", "0.1,0.2", "--t-end", "1"])
    assert code == 2
    assert message in err and len(err.strip().splitlines()) == 1


def test_energy_without_a_real_momentum_is_refused(capsys):
    code, _, err = _run(capsys, ["run", "x1", "--hamiltonian", "px**2/2 + x**2*py**2/2 + y**2",
                                 "--coords", "x,y", "--momenta", "px,py", "--energy", "-1",
                                 "--t-end", "1"])
    assert code == 2
    assert "no real momentum p[0] gives energy -1" in err

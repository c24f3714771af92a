"""The ``varint`` command line: complete help, one-line errors, and each
job writing its table and plot."""

import argparse
import csv
import shutil
import subprocess
import sys

import numpy as np
import pytest

import varint
from varint import cli


def _run(capsys, argv):
    try:
        code = cli.main(argv)
    except SystemExit as exc:  # argparse
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


def _rows(path):
    with open(path) as f:
        return list(csv.reader(f))


def test_help_is_complete():
    parser = cli.build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    assert set(sub.choices) == {"schemes", "run", "map", "select", "study", "demo"}
    for name, p in sub.choices.items():
        assert p.description, name
        text = p.format_help()
        for action in p._actions:
            assert action.help, (name, action.dest)  # every option explained
            for flag in action.option_strings:
                assert flag in text
    for name in sub.choices:
        assert name in parser.format_help()


def test_console_script_and_module_entry_points():
    exe = shutil.which("varint")
    if exe is not None:
        out = subprocess.run([exe, "--help"], capture_output=True, text=True, timeout=60)
        assert out.returncode == 0 and "varint map" in out.stdout
    # python -m varint stays the demo (the README's first command).
    out = subprocess.run([sys.executable, "-m", "varint", "--help"], capture_output=True,
                         text=True, timeout=60)
    assert out.returncode == 0 and "--t-end" in out.stdout and "R1" in out.stdout


@pytest.mark.parametrize("argv, status, match", [
    (["run", "bogus"], 2, "invalid choice: 'bogus'"),
    (["run", "sali", "--orbit", "R9"], 2, "unknown paper orbit 'R9'"),
    (["run", "sali", "--orbit", "R1", "--tau", "-1"], 2, "tau must be a positive"),
    (["run", "sali", "--orbit", "R1", "--model", "three-dof"], 2, "give exactly one of"),
    (["run", "sali", "--model", "henon-heiles"], 2, "give the initial state"),
    (["run", "sali", "--model", "henon-heiles", "--x0", "1,2"], 2, "--x0 needs 4 numbers"),
    (["run", "sali", "--potential", "x**2/2 +", "--coords", "x"], 2, "cannot read --potential"),
    (["map", "--model", "henon-heiles"], 2, "--energy is required"),
    (["map", "--model", "henon-heiles", "--energy", "0.125", "--u", "1:0:3"], 2,
     "--u must be START:STOP:NUM"),
    (["map", "--model", "henon-heiles", "--energy", "0.125", "--indicator", "nope"], 2,
     "unknown indicator 'nope'"),
    (["select", "--orbit", "R1"], 2, "required: --target"),
    (["study", "nosuch"], 2, "unknown study 'nosuch'"),
    (["run", "sali", "--model", "henon-heiles", "--energy", "0.3", "--t-end", "300"], 1,
     "run failed: the orbit failed"),
])
def test_bad_arguments_give_one_line(capsys, argv, status, match):
    code, out, err = _run(capsys, argv)
    assert code == status
    lines = err.strip().splitlines()
    assert len(lines) == 1 and match in lines[0]


def test_schemes(capsys, tmp_path):
    code, out, err = _run(capsys, ["schemes", "--csv", str(tmp_path / "s.csv")])
    assert code == 0
    for name in varint.SCHEMES:
        assert varint.SCHEMES[name].name in out
    rows = _rows(tmp_path / "s.csv")
    assert rows[0][:4] == ["name", "order", "nominal", "forces/step"]
    assert {r[0] for r in rows[1:]} == {s.name for s in varint.SCHEMES.values()}


def test_run_an_indicator_of_a_potential(capsys, tmp_path):
    argv = ["run", "sali", "--potential", "(x**2+y**2)/2 + x**2*y - y**3/3", "--coords", "x,y",
            "--energy", "0.125", "--q", "0,0.558", "--t-end", "5", "--csv",
            str(tmp_path / "r.csv"), "--png", str(tmp_path / "r.png")]
    code, out, err = _run(capsys, argv)
    assert code == 0, err
    rows = _rows(tmp_path / "r.csv")
    assert rows[0] == ["t", "energy_error", "sali"]
    # The same run through the API, on the built-in model: same values.
    model, x0 = varint.paper_orbit("R1")
    ref = varint.sali(model, x0, 5.0)
    assert np.allclose([float(r[2]) for r in rows[1:]], ref.sali, rtol=1e-12)
    assert (tmp_path / "r.png").stat().st_size > 1000


def test_run_lyapunov_of_a_paper_orbit(capsys):
    code, out, err = _run(capsys, ["run", "lyapunov", "--orbit", "C1", "--t-end", "10",
                                   "--k", "2", "--scheme", "ABA864"])
    assert code == 0, err
    assert "X1" in out and "X2" in out and "X3" not in out and "ABA864" in out


def test_map(capsys, tmp_path):
    argv = ["map", "--model", "henon-heiles", "--energy", "0.125", "--u=-0.4:0.6:5",
            "--v=-0.3:0.3:4", "--t-end", "5", "--csv", str(tmp_path / "m.csv"),
            "--png", str(tmp_path / "m.png"), "--checkpoint", str(tmp_path / "ck")]
    code, out, err = _run(capsys, argv)
    assert code == 0, err
    assert "sali map of HenonHeiles" in out
    rows = _rows(tmp_path / "m.csv")
    assert rows[0][:5] == ["orbit", "q0", "q1", "p0", "p1"] and len(rows) > 10
    assert (tmp_path / "m.png").exists() and (tmp_path / "ck" / "map.json").exists()


def test_study_list(capsys):
    code, out, err = _run(capsys, ["study", "--list"])
    assert code == 0
    assert "sections" in out and "bench_chaos_map" in out

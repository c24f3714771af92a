"""The ``varint`` command line: complete help, the installed console script,
every command run once (quickly), and every failure ending in one line:
a table of bad arguments (each refused before any integration step), each
kind of exception a command can raise, Ctrl-C, and hostile potentials."""

import argparse
import csv
import importlib.metadata
import os
import shutil
import signal
import subprocess
import sys
import sysconfig
from pathlib import Path

import numpy as np
import pytest
from numba.core.errors import TypingError

import varint
from varint import cli
from varint.driver import IntegrationError
from tests.helpers import hook_advance

ROOT = Path(__file__).resolve().parent.parent


def _run(capsys, argv):
    code = cli.main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def _rows(path):
    with open(path) as f:
        return list(csv.reader(f))


def _one_line(err):
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert "Traceback" not in err
    return lines[0]


def _env():
    """The environment of a subprocess that imports this tree's varint."""
    path = os.environ.get("PYTHONPATH")
    return dict(os.environ, PYTHONPATH=str(ROOT) + (os.pathsep + path if path else ""))


def test_help_is_complete():
    parser = cli.build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    assert set(sub.choices) == {"schemes", "run", "map", "select", "lattice", "study", "demo"}
    for name, p in sub.choices.items():
        assert p.description, name
        text = p.format_help()
        for action in p._actions:
            assert action.help, (name, action.dest)  # every option explained
            for flag in action.option_strings:
                assert flag in text
    for name in sub.choices:
        assert name in parser.format_help()


def test_console_script_is_installed_and_runs_this_main():
    """The installed package declares the ``varint`` script as
    varint.cli:main, the script exists and runs (importing this tree), and
    ``python -m varint.cli`` works from the source tree."""
    scripts = [ep for ep in importlib.metadata.entry_points(group="console_scripts")
               if ep.name == "varint"]
    assert scripts, "no 'varint' console script is installed: pip install -e ."
    assert scripts[0].value == "varint.cli:main"
    assert scripts[0].load() is cli.main
    exe = Path(sysconfig.get_path("scripts")) / "varint"
    exe = str(exe) if exe.exists() else shutil.which("varint")
    assert exe, "the 'varint' script is declared but missing from the scripts directory"
    out = subprocess.run([exe, "--help"], capture_output=True, text=True, timeout=120,
                         env=_env(), cwd=ROOT)
    assert out.returncode == 0, out.stderr
    assert "varint map" in out.stdout and "--traceback" in out.stdout
    out = subprocess.run([sys.executable, "-m", "varint.cli", "schemes"], capture_output=True,
                         text=True, timeout=120, cwd=ROOT)
    assert out.returncode == 0 and "SBAB2C" in out.stdout, out.stderr
    # python -m varint stays the demo (the README's first command).
    out = subprocess.run([sys.executable, "-m", "varint", "--help"], capture_output=True,
                         text=True, timeout=120, cwd=ROOT)
    assert out.returncode == 0 and "--t-end" in out.stdout and "R1" in out.stdout


HH = ["--model", "henon-heiles"]
R1 = ["--orbit", "R1"]
POT = ["--coords", "x,y", "--x0", "0,0.1,0.1,0"]
MAP = ["map", *HH, "--energy", "0.125"]

# (argv, exit status, text the one line must contain). Every row with
# status 2 is refused before the first integration step.
BAD_ARGUMENTS = [
    (["run", "bogus"], 2, "invalid choice: 'bogus'"),
    (["run", "sali", "--orbit", "R9"], 2, "unknown paper orbit 'R9'"),
    (["run", "sali", *R1, "--tau", "-1"], 2, "--tau: expected a positive finite number, got '-1'"),
    (["run", "sali", *R1, "--model", "three-dof"], 2, "give exactly one of"),
    (["run", "sali", *HH], 2, "give the initial state"),
    (["run", "sali", *HH, "--x0", "1,2"], 2, "--x0 needs 4 numbers"),
    (["run", "sali", "--potential", "x**2/2 +", "--coords", "x", "--x0", "0,0"], 2,
     "--potential: cannot read 'x**2/2 +'"),
    (["map", *HH], 2, "--energy is required"),
    ([*MAP, "--u", "1:0:3"], 2, "--u must be START:STOP:NUM with STOP > START"),
    ([*MAP, "--indicator", "nope"], 2, "unknown indicator 'nope'"),
    (["select", "--orbit", "R1"], 2, "required: --target"),
    (["study", "nosuch"], 2, "unknown study 'nosuch'"),
    (["run", "sali", *HH, "--energy", "0.3", "--t-end", "300"], 1,
     "run failed: the orbit failed"),
    # -- the issues' cases: a singular potential, absurd grids, output paths, counts
    (["run", "sali", "--potential", "1/x + y**2/2", "--coords", "x,y", "--x0", "0,0.1,0.1,0"],
     2, "are not finite at the initial state, q = [0.0, 0.1]"),
    ([*MAP, "--u=0:1:1000000000"], 2, "needs about"),
    ([*MAP, "--u=0:1:100000", "--v=0:1:100000"], 2, "= 10000000000 points (--u, --v) needs about"),
    (["run", "lyapunov", *R1, "--csv", "/nonexistent/dir/x.csv"], 2,
     "--csv /nonexistent/dir/x.csv: directory /nonexistent/dir does not exist"),
    (["run", "lyapunov", *R1, "--png", "/nonexistent/dir/x.png"], 2, "does not exist"),
    (["run", "lyapunov", *R1, "--csv", "/proc/version"], 2,
     "cannot write --csv /proc/version: it is a file of a virtual file system"),
    (["run", "lyapunov", *R1, "--png", "/tmp"], 2, "--png /tmp is a directory"),
    (["run", "lyapunov", *R1, "--csv", "/etc/passwd/x.csv"], 2, "/etc/passwd is not a directory"),
    (["run", "lyapunov", *R1, "--csv", ""], 2, "--csv must name a file, got ''"),
    (["run", "lyapunov", *R1, "--png", "plot.xyz"], 2, "matplotlib cannot write .xyz files"),
    (["run", "lyapunov", *R1, "--csv", "same.png", "--png", "same.png"], 2,
     "--csv and --png name the same file"),
    (["run", "lyapunov", *R1, "--csv", "x" * 300], 2, "File name too long"),
    (["schemes", "--csv", "/nonexistent/s.csv"], 2, "directory /nonexistent does not exist"),
    (["demo", "--out", "/nonexistent/d.png"], 2, "--out /nonexistent/d.png: directory"),
    (["run", "lyapunov", *R1, "--k", "2.5"], 2, "--k must be an integer in 1..4, got '2.5'"),
    (["run", "lyapunov", *R1, "--k", "0"], 2, "--k must be an integer in 1..4, got '0'"),
    (["run", "lyapunov", *R1, "--k", ""], 2, "--k is empty"),
    (["run", "gali", *R1, "--k", "2,3.5"], 2, "--k must be integers in 1..4, got '3.5'"),
    (["run", "gali", *R1, "--k", "1,2"], 2, "--k: GALI order"),
    (["run", "sali", *R1, "--k", "2"], 2, "--k applies to gali, local_exponents, lyapunov, not sali"),
    (["run", "sali", *R1, "--t-out", "2.5"], 2, "--t-out: expected a positive integer, got '2.5'"),
    (["run", "sali", *R1, "--t-out", "0"], 2, "--t-out: expected a positive integer, got '0'"),
    (["run", "sali", *R1, "--t-end", "1", "--t-out", "1000", "--tau", "0.05"], 2,
     "--t-out 1000 asks for more output times than the run has steps"),
    # With the automatic step, the run refuses them once the step is chosen.
    (["run", "sali", *R1, "--t-end", "1", "--t-out", "1000"], 2,
     "t_out = 1000 output times, more than the 8 steps of the run (t_end / tau = 1 / 0.125)"),
    (["run", "sali", *R1, "--seed", "1.5"], 2, "--seed: expected an integer >= 0, got '1.5'"),
    (["run", "sali", *R1, "--seed", "-1"], 2, "--seed: expected an integer >= 0, got '-1'"),
    (["run", "sali", "--model", "fpu-beta", "--fpu-n", "3.7"], 2,
     "--fpu-n: expected a positive integer, got '3.7'"),
    (["run", "sali", "--model", "fpu-beta", "--fpu-n", "1000000000000", "--x0", "0"], 2,
     "model FPUBeta(n=1000000000000, beta=1.5) (1000000000000 degrees of freedom) needs about"),
    (["run", "lyapunov", "--model", "fpu-beta", "--fpu-n", "100000", "--energy", "1"], 2,
     "a run of 200000 vectors of FPUBeta(n=100000, beta=1.5) with 70 outputs needs about"),
    ([*MAP, "--u=-0.4:0.6:5.5"], 2, "--u: NUM must be a positive integer (the number of points)"),
    ([*MAP, "--v=-0.4:0.6:1e3.5"], 2, "--v: NUM must be a positive integer"),
    ([*MAP, "--u=-0.4:nan:5"], 2, "--u: START and STOP must be finite"),
    ([*MAP, "--u=-0.4:0.6"], 2, "--u must be START:STOP:NUM (e.g. --u=-0.45:0.7:200)"),
    ([*MAP, "--u=a:b:3"], 2, "--u must be START:STOP:NUM with numbers START and STOP"),
    ([*MAP, "--u", "-0.4:0.6:0"], 2, "NUM must be a positive integer"),
    # -- non-finite, tiny and huge numbers
    (["run", "sali", *R1, "--tau", "nan"], 2,
     "--tau: expected a positive finite number, got 'nan'"),
    (["run", "sali", *R1, "--tau", "0"], 2, "--tau: expected a positive finite number, got '0'"),
    (["run", "sali", *R1, "--t-end", "inf"], 2, "--t-end: expected a positive finite number"),
    (["run", "sali", *R1, "--t-end", "-inf"], 2, "--t-end: expected a positive finite number"),
    (["run", "sali", *R1, "--tau", "1e-300"], 2,
     "--t-end 10000 / --tau 1e-300 is 1e+304 steps, more than the 1e+11 a command runs"),
    (["run", "sali", *R1, "--t-end", "1e300"], 2, "--t-end 1e+300 takes more than the 1e+11 "
     "steps a command runs even at the largest automatic step (1)"),
    (["run", "sali", *R1, "--t-end", "1e300", "--tau", "0.05"], 2,
     "is 2e+301 steps, more than the 1e+11"),
    (["run", "sali", *R1, "--tau", "1", "--t-end", "0.5"], 2,
     "t_end = 0.5 is shorter than one step tau = 1.0"),
    (["run", "sali", *R1, "--tau", "0.05abc"], 2, "--tau: expected a positive finite number"),
    (["run", "sali", *HH, "--energy", "nan"], 2, "--energy: expected a finite number, got 'nan'"),
    (["run", "sali", *HH, "--energy", "inf"], 2, "--energy: expected a finite number, got 'inf'"),
    (["run", "sali", *HH, "--x0", "0,0,nan,0"], 2, "--x0 must hold finite numbers, got 'nan'"),
    (["run", "sali", *HH, "--x0", "0,0,1e999,0"], 2, "--x0 must hold finite numbers"),
    (["run", "sali", *HH, "--x0", "0,0,1,0,0"], 2, "--x0 needs 4 numbers, got 5"),
    (["run", "sali", *HH, "--x0", "a,b,c,d"], 2, "--x0 must be comma-separated numbers, got 'a'"),
    (["run", "sali", *HH, "--x0", ""], 2, "--x0 is empty"),
    (["run", "sali", *HH, "--energy", "-0.5", "--q", "-0.1,0.1"], 2,
     "no real momentum p[0] gives energy -0.5 at q = [-0.1, 0.1]"),
    (["run", "sali", *HH, "--energy", "0.125", "--q", "0,0.1,3"], 2, "--q needs 2 numbers, got 3"),
    (["run", "sali", *HH, "--x0", "0,0,0.1,0", "--energy", "0.1"], 2,
     "give either --x0 or --energy"),
    (["run", "sali", *HH, "--q", "-1,0.1", "--x0", "0,0,0,0"], 2, "--q goes with --energy"),
    # A paper orbit is its initial state: another is refused, not silently used.
    (["run", "sali", *R1, "--energy", "0.1"], 2, "--energy does not apply to --orbit R1"),
    (["run", "sali", *R1, "--x0", "0,0.1,0.1,0"], 2, "--x0 does not apply to --orbit R1"),
    (["run", "sali", "--model", "fpu-beta", "--beta", "nan", "--x0", "0"], 2,
     "--beta: expected a finite number, got 'nan'"),
    (["run", "sali", *HH, "--fpu-n", "4", "--x0", "0,0,0,0"], 2,
     "--fpu-n applies to --model fpu-beta only"),
    (["run", "sali", *R1, "--inverse-mass", "1,1"], 2, "--inverse-mass applies to --potential"),
    (["run", "sali", *R1, "--coords", "x,y"], 2, "--coords applies to --potential and --hamiltonian only"),
    # -- names: empty, unknown, unicode
    (["run", "sali", "--orbit", ""], 2, "unknown paper orbit ''"),
    (["run", "sali", *R1, "--scheme", ""], 2, "unknown scheme ''; expected one of: SABA1"),
    (["run", "sali", *R1, "--scheme", "SBAB2C\u200b"], 2, "unknown scheme"),
    (["run", "sali", *R1, "--method", ""], 2, "unknown method ''; expected one of: tm"),
    (["run", "sali", *R1, "--method", "taylor", "--scheme", "ABA864"], 2,
     "method 'taylor' takes no scheme"),
    (["run", "sali", "--orbit", "R\u00b9"], 2, "unknown paper orbit"),
    # -- --potential and --coords
    (["run", "sali", "--potential", "", *POT], 2, "--potential is empty"),
    (["run", "sali", "--potential", "x**2", "--x0", "0,0"], 2, "--potential needs --coords"),
    (["run", "sali", "--potential", "x**2", "--coords", "", "--x0", "0,0"], 2,
     "--coords: coordinate 1 must be a name"),
    (["run", "sali", "--potential", "x**2", "--coords", "x,,y", "--x0", "0,0"], 2,
     "--coords: coordinate 2 must be a name"),
    (["run", "sali", "--potential", "x**2", "--coords", "x,x", "--x0", "0,0"], 2,
     "--coords names 'x' twice"),
    (["run", "sali", "--potential", "x**2", "--coords", "sin", "--x0", "0,0"], 2,
     "--coords: 'sin' is reserved"),
    (["run", "sali", "--potential", "x**2", "--coords", "lambda", "--x0", "0,0"], 2,
     "--coords: 'lambda' is reserved"),
    (["run", "sali", "--potential", "x**2", "--coords", ",".join(f"q{i}" for i in range(101)),
      "--x0", "0"], 2, "--coords names 101 coordinates; at most 100"),
    (["run", "sali", "--potential", "x**2+y**2", *POT[:2], "--inverse-mass", "1,-1",
      "--x0", "0,0,0,0"], 2, "--inverse-mass must be positive, got -1"),
    (["run", "sali", "--potential", "x**2+y**2", *POT[:2], "--inverse-mass", "1,nan",
      "--x0", "0,0,0,0"], 2, "--inverse-mass must hold finite numbers, got 'nan'"),
    (["run", "sali", "--potential", "x**2 + z", *POT], 2,
     "--potential: 'z' is not a coordinate, constant or function"),
    (["run", "sali", "--potential", "x \u2212 y", *POT], 2,
     "invalid character '\u2212' (U+2212)"),
    (["run", "sali", "--potential", "9**9**9**9", *POT], 2, "exponent of magnitude above 1000"),
    (["run", "sali", "--potential", "x/0", *POT], 2, "'0' is a divisor that is zero"),
    (["run", "sali", "--potential", "x**2 + abs(y)", *POT], 2,
     "'abs' is not an allowed function"),
    (["run", "sali", "--potential", "x**2 + 1e400", *POT], 2, "'1e400' is not a finite number"),
    # 2**100 is a double now (it runs); 10**400 is beyond the range of one.
    (["run", "sali", "--potential", "(10**200*x)**2 + y**2", *POT], 2,
     "beyond the range of a double"),
    (["run", "sali", "--potential", "x**2/2 + y**2/2 + sqrt(x)", "--coords", "x,y", "--x0",
      "-1,0,0,0"], 2, "are not finite at the initial state"),
    (["run", "sali", "--potential", "x**2 + 1j*y", *POT], 2, "'1j' is an imaginary number"),
    # -- map options
    ([*MAP, "--axes", "1,9"], 2, "--axes must be integers in 0..3, got '9'"),
    ([*MAP, "--axes", "1.5,3"], 2, "--axes must be integers in 0..3, got '1.5'"),
    ([*MAP, "--axes", "1"], 2, "--axes needs 2 integers, got 1"),
    ([*MAP, "--plane", "5"], 2, "plane must be a coordinate index in 0..1, got 5"),
    ([*MAP, "--plane", "-1"], 2, "--plane: expected an integer >= 0, got '-1'"),
    ([*MAP, "--threshold", "nan"], 2, "--threshold must hold finite numbers"),
    ([*MAP, "--threshold", "abc"], 2, "--threshold must be comma-separated numbers"),
    ([*MAP, "--checkpoint", ""], 2, "--checkpoint must name a directory, got ''"),
    ([*MAP, "--checkpoint", "/etc/passwd"], 2, "--checkpoint /etc/passwd is a file"),
    ([*MAP, "--checkpoint", "/nonexistent/ck"], 2, "directory /nonexistent does not exist"),
    ([*MAP, "--chunk-size", "0"], 2, "--chunk-size: expected a positive integer, got '0'"),
    ([*MAP, "--scheduler", ""], 2, "--scheduler must be an address"),
    ([*MAP, "--energy", "-1", "--u=0:0.1:2", "--v=0:0.1:2"], 2,
     "the section grid holds no allowed point"),
    ([*MAP, "--t-end", "1e300"], 2, "takes more than the 1e+11 steps a command runs"),
    # -- select, demo, study
    (["select", *R1, "--target", "0"], 2, "--target: expected a positive finite number"),
    (["select", *R1, "--target", "-1e-8"], 2, "--target: expected a positive finite number"),
    (["select", *R1, "--target", "1e-8", "--pilot-t", "nan"], 2,
     "--pilot-t: expected a positive finite number"),
    (["select", *R1, "--target", "1e-8", "--t-end", "0.5"], 2,
     "--t-end 0.5 is shorter than the shortest pilot, 0.8"),
    (["select", *R1, "--target", "1e-8", "--metric", "nope"], 2, "invalid choice: 'nope'"),
    (["demo", "--t-end", "nan"], 2, "t_end must be a finite number, got nan"),
    (["demo", "--t-end", "1e300"], 2, "is 2e+301 steps, more than the 1e+11"),
    (["demo", "--out", "d.xyz"], 2, "--out d.xyz: matplotlib cannot write .xyz files"),
    (["study", "../../etc/passwd"], 2, "unknown study '../../etc/passwd'"),
    # -- more found by trying
    (["run", "sali", *R1, "--t-end", "1", "--csv", "/dev/full"], 1,
     "error: cannot write --csv /dev/full: No space left on device"),
    (["run", "sali", *R1, "--csv", "/tmp/no such dir/x.csv"], 2,
     "directory /tmp/no such dir does not exist"),
    (["run", "lyapunov", *R1, "--k", "-1"], 2, "--k must be an integer in 1..4, got '-1'"),
    (["run", "lyapunov", *R1, "--t-end", "1", "--t-out", "99999999999999999999", "--tau",
      "0.05"], 2, "asks for more output times than the run has steps (--t-end / --tau = 20)"),
    (["run", "lyapunov", *R1, "--t-end", "1", "--t-out", "99999999999999999999"], 2,
     "with 99999999999999999999 outputs needs about"),
    (["run", "sali", *R1, "--t-end", "0.0499999", "--tau", "0.05"], 2,
     "is shorter than one step tau = 0.05"),
    (["run", "sali", *HH, "--energy", "1e308"], 2,
     "--energy 1e+308 gives a momentum p[0] = inf beyond the range of a double"),
    (["run", "sali", *HH, "--x0", "1e200,0,0,0"], 2,
     "are not finite at the initial state, q = [1e+200, 0.0]"),
    (["run", "sali", "--potential", "exp(1000*x)", "--coords", "x", "--x0", "1,0"], 2,
     "are not finite at the initial state"),
    (["run", "sali", "--potential", "x**2", "--coords", "x", "--x0", "0,0", "--inverse-mass",
      "0"], 2, "--inverse-mass must be positive, got 0"),
    (["run", "sali", "--potential", "x**2", "--coords", "x", "--x0", "0,0", "--inverse-mass",
      "1e400"], 2, "--inverse-mass must hold finite numbers, got '1e400'"),
    (["run", "sali", "--potential", "x**2", "--coords", "x y", "--x0", "0,0"], 2,
     "--coords: coordinate 1 must be a name"),
    (["run", "sali", "--orbit", "\uff321"], 2, "unknown paper orbit '\uff321'"),
    (["run", "sali", *R1, "--scheme", "SBAB2C "], 2, "unknown scheme 'SBAB2C '"),
    (["run"], 2, "the following arguments are required: indicator"),
    ([*MAP, "--u=-1e308:1e308:3"], 2, "--u: STOP - START must be finite"),
    ([*MAP, "--u=1e308:1.7e308:3"], 2, "the section grid holds no allowed point"),
    ([*MAP, "--scheduler", "nonsense"], 2, "cannot connect to --scheduler nonsense"),
    ([*MAP, "--indicator", "gali_9"], 2, "GALI order k must be in 2..4"),
    ([*MAP, "--threshold", "1,2"], 2, "--threshold needs 1 numbers, got 2"),
    (["--traceback"], 0, None),
    (["run", "sali", *R1, "--nosuch"], 2, "unrecognized arguments: --nosuch"),
    # Maps and time-dependent potentials.
    (["run", "x1", "--map", "standard", "--energy", "1"], 2, "is a map, which has no energy"),
    (["run", "x1", "--map", "standard", "--x0", "1,0", "--method", "dop853"], 2,
     "maps take: tm, two-particle"),
    (["run", "x1", "--map", "standard", "--x0", "1,0", "--tau", "0.5"], 2, "whole iterations"),
    (["run", "x1", "--map", "coupled", "--x0", "1,0,0,0", "--K", "2"], 2,
     "--K applies to --map standard only"),
    (["run", "x1", *HH, "--x0", "0,0,0,0", "--K1", "2"], 2, "--K1 applies to --map coupled"),
    (["run", "sali", *R1, "--beta", "2"], 2, "--beta applies to --model fpu-beta and --map"),
    (["run", "sali", *R1, "--time", "t"], 2, "--time applies to --potential and --hamiltonian only"),
    (["run", "sali", "--potential", "-cos(q)*cos(t)", "--coords", "q", "--time", "q", "--x0",
      "0,1"], 2, "--time q is also one of the --coords"),
    (["map", "--map", "standard", "--energy", "1"], 2, "does not apply to a map"),
    (["map", "--potential", "-cos(q)*cos(t)", "--coords", "q", "--time", "t"], 2,
     "give --u and --v"),
    # The two-particle method's options.
    (["run", "x1", *R1, "--d0", "1e-6"], 2, "--d0 applies to --method two-particle only"),
    ([*MAP, "--method", "dop853", "--d-max", "1e-3"], 2,
     "--d-max applies to --method two-particle only, not dop853"),
    (["run", "x1", *R1, "--method", "two-particle", "--d0", "0"], 2,
     "--d0: expected a positive finite number"),
    # With --tau: the method checks d_max when it is built, which the
    # automatic step's pilot (a compiled run) would come before.
    (["run", "x1", *R1, "--method", "two-particle", "--d0", "1e-6", "--d-max", "1e-7",
      "--tau", "0.05"], 2, "d_max must exceed d0"),
    # The TM method's compensated summation.
    (["run", "x1", *R1, "--method", "dop853", "--compensated"], 2,
     "--compensated applies to --method tm only, not dop853"),
    (["run", "x1", *R1, "--tau", "0.05", "--compensated", "kahan"], 2,
     "--compensated: expected 'orbit' or 'step'"),
]


@pytest.mark.parametrize("argv, status, match", BAD_ARGUMENTS,
                         ids=[" ".join(row[0])[:60] for row in BAD_ARGUMENTS])
def test_bad_arguments_give_one_line(capsys, monkeypatch, tmp_path, argv, status, match):
    monkeypatch.chdir(tmp_path)
    steps = hook_advance(monkeypatch, "tm", 10 ** 9, lambda: None)
    code, out, err = _run(capsys, argv)
    assert code == status, err
    if match is None:
        assert not err
        return
    assert match in _one_line(err)
    if status == 2:
        assert not steps, "an integration ran before the argument was refused"
        assert not list(tmp_path.iterdir())


def test_the_bad_argument_table_has_distinct_rows():
    keys = [tuple(argv) for argv, *_ in BAD_ARGUMENTS]
    assert len(set(keys)) == len(keys) >= 120


HOSTILE_POTENTIALS = [
    "__import__('os').system('touch PWNED')",
    "().__class__.__bases__[0].__subclasses__()",
    "x.__class__",
    "__builtins__",
    "eval('1')",
    "exec('import os')",
    "open('PWNED', 'w')",
    "(lambda: 1)()",
    "[x for x in (1, 2)]",
    "{x: 1}",
    "x if y else 1",
    "sin.__globals__",
    "x[0]",
    "x; import os",
    "import os",
    "f'{x}'",
    "'PWNED'",
    "sin(x)(y)",
    "x := 1",
    "sympy.sin(x)",
    "Symbol('z')",
    "9**9**9**9",
    "(x**2)**9999999",
    "2**10**100",
    "x" + "+x" * 5000,
    "-(" * 120 + "x" + ")" * 120,
    "x**(" * 110 + "2" + ")" * 110,
    "-" * 120 + "x",
    "sin(" * 110 + "x" + ")" * 110,
    "x\0",
    "",
]


@pytest.mark.parametrize("formula", HOSTILE_POTENTIALS, ids=range(len(HOSTILE_POTENTIALS)))
def test_hostile_potentials_are_refused_without_running(capsys, monkeypatch, tmp_path, formula):
    monkeypatch.chdir(tmp_path)
    code, out, err = _run(capsys, ["run", "sali", "--potential", formula, *POT])
    assert code == 2
    assert "--potential" in _one_line(err)
    assert not list(tmp_path.iterdir())


# -- every command, quickly ------------------------------------------------------------
def test_schemes(capsys, tmp_path):
    code, out, err = _run(capsys, ["schemes", "--csv", str(tmp_path / "s.csv")])
    assert code == 0
    two_part = varint.schemes.registered(2)
    for s in two_part:
        assert s.name in out
    rows = _rows(tmp_path / "s.csv")
    assert rows[0][:4] == ["name", "order", "nominal", "forces/step"]
    assert {r[0] for r in rows[1:]} == {s.name for s in two_part}


def test_run_an_indicator_of_a_potential(capsys, tmp_path):
    argv = ["run", "sali", "--potential", "(x**2+y**2)/2 + x^2*y - y**3/3", "--coords", "x,y",
            "--energy", "0.125", "--q", "0,0.558", "--t-end", "5", "--csv",
            str(tmp_path / "r.csv"), "--png", str(tmp_path / "r.png")]
    code, out, err = _run(capsys, argv)
    assert code == 0, err
    rows = _rows(tmp_path / "r.csv")
    assert rows[0] == ["t", "energy_error", "sali", "method", "scheme", "tau", "seed"]
    # The same run through the API, on the built-in model: same values.
    model, x0 = varint.paper_orbit("R1")
    ref = varint.sali(model, x0, 5.0)  # the automatic step, as the command's
    assert np.allclose([float(r[2]) for r in rows[1:]], ref.sali, rtol=1e-12)
    # The CSV says what ran: the step the pilot chose, not a default.
    assert {tuple(r[3:]) for r in rows[1:]} == {("tm", "SBAB2C", repr(ref.provenance.tau), "0")}
    assert (tmp_path / "r.png").stat().st_size > 1000


def test_run_lyapunov_of_a_paper_orbit(capsys):
    """--k and --scheme reach the run. One exponent of SABA2 at a given
    step: the plain kernel test_run_compensated compares with (k = 2 of
    ABA864, a kernel of its own, cost ~8 CPU s cold)."""
    code, out, err = _run(capsys, ["run", "lyapunov", "--orbit", "C1", "--t-end", "10",
                                   "--k", "1", "--scheme", "SABA2", "--tau", "0.05"])
    assert code == 0, err
    assert "X1" in out and "X2 " not in out and "(SABA2)" in out


def test_run_compensated(capsys, tmp_path):
    """--compensated and --scheme reach the TM method: the exponent the
    command writes is the API's with that scheme and compensated=True, bit
    for bit, and not the plain one's."""
    code, out, err = _run(capsys, ["run", "lyapunov", "--orbit", "C1", "--t-end", "10",
                                   "--tau", "0.05", "--k", "1", "--scheme", "SABA2",
                                   "--compensated", "--csv", str(tmp_path / "r.csv")])
    assert code == 0, err
    written = np.array([float(r[2]) for r in _rows(tmp_path / "r.csv")[1:]])
    model, x0 = varint.paper_orbit("C1")
    runs = {c: np.asarray(varint.lyapunov_spectrum(model, x0, 10.0, tau=0.05, n_exponents=1,
                                                   scheme="SABA2", compensated=c).exponents)[:, 0]
            for c in (False, True)}
    assert np.array_equal(written, runs[True]) and not np.array_equal(written, runs[False])


@pytest.mark.parametrize("flag, level", [([], None), (["--compensated"], True),
                                         (["--compensated", "orbit"], "orbit"),
                                         (["--compensated", "step"], "step")])
def test_compensated_levels_reach_the_method_options(flag, level):
    """--compensated alone asks for every drift and kick compensated, with
    a value for the partial levels the TM method takes (its test:
    tests/test_compensated.py); no flag leaves the method's default."""
    args = cli.build_parser().parse_args(["run", "x1", *R1, "--tau", "0.05", *flag])
    assert cli._method_options(args).get("compensated") == level


@pytest.mark.parametrize("indicator, column", [("gali", "gali_4"), ("megno", "megno"),
                                               ("integrate", "q0")])
def test_run_every_other_indicator(capsys, tmp_path, indicator, column):
    """Negative numbers as values (--x0 -0.1,..., --q, --p) parse too."""
    state = (["--x0", "-0.1,0.2,-0.05,0.1"] if indicator != "megno" else
             ["--energy", "0.1", "--q", "0,-0.1", "--p", "0,-0.05"])
    argv = ["run", indicator, *HH, *state, "--t-end", "2", "--t-out", "4", "--csv",
            str(tmp_path / "r.csv")]
    if indicator == "gali":
        argv += ["--k", "2,3,4"]
    code, out, err = _run(capsys, argv)
    assert code == 0, err
    rows = _rows(tmp_path / "r.csv")
    assert column in rows[0] and len(rows) == 5
    if indicator == "integrate":
        ref = varint.integrate(varint.models.HenonHeiles(), [-0.1, 0.2, -0.05, 0.1], 2.0,
                               t_out=4)
        assert np.allclose([float(v) for v in rows[-1][2:6]], ref.states[-1], rtol=1e-14)


def test_map(capsys, tmp_path):
    argv = ["map", "--model", "henon-heiles", "--energy", "0.125", "--u", "-0.4:0.6:5",
            "--v=-0.3:0.3:4", "--t-end", "5", "--csv", str(tmp_path / "m.csv"),
            "--png", str(tmp_path / "m.png"), "--checkpoint", str(tmp_path / "ck")]
    code, out, err = _run(capsys, argv)
    assert code == 0, err
    assert "sali map of HenonHeiles" in out
    rows = _rows(tmp_path / "m.csv")
    assert rows[0][:5] == ["orbit", "q0", "q1", "p0", "p1"] and len(rows) > 10
    assert (tmp_path / "m.png").exists() and (tmp_path / "ck" / "map.json").exists()


def test_a_map_says_which_scheme_and_step_ran(capsys, tmp_path):
    """Issue 32: the help named SBAB2C while the map ran SRKN14a at the
    pilot's step, and neither the summary nor the CSV said so."""
    from varint.maps import MAP_SCHEME

    help_text = " ".join(cli.build_parser()._subparsers._group_actions[0].choices["map"]
                         .format_help().split())
    assert f"default {MAP_SCHEME} when the step is chosen automatically" in help_text
    argv = ["map", *HH, "--energy", "0.125", "--u", "-0.4:0.6:4", "--v=-0.3:0.3:3",
            "--t-end", "5", "--csv", str(tmp_path / "m.csv")]
    code, out, err = _run(capsys, argv)
    assert code == 0, err
    rows = _rows(tmp_path / "m.csv")
    head = rows[0]
    scheme, tau = {r[head.index("scheme")] for r in rows[1:]}, {r[head.index("tau")]
                                                              for r in rows[1:]}
    assert scheme == {MAP_SCHEME} and len(tau) == 1
    assert f"scheme {MAP_SCHEME}, tau = {float(tau.pop()):g} (chosen by a pilot" in out
    # A given step and --scheme: the scheme named, not the default of given
    # steps (SBAB2C, as the help says); SRKN14a, whose map kernel of this
    # model the run above compiled (a kernel of its own is ~12 CPU s cold).
    code, out, err = _run(capsys, [*argv, "--tau", "0.05", "--scheme", MAP_SCHEME])
    assert code == 0, err
    assert f"scheme {MAP_SCHEME}, tau = 0.05 (given)" in out


def test_run_resumes_from_its_checkpoint(capsys, monkeypatch, tmp_path):
    """--checkpoint: the run is saved, and the same command again returns
    the same values (bitwise) from the file."""
    argv = ["run", "lyapunov", *R1, "--t-end", "20", "--tau", "0.05", "--checkpoint",
            str(tmp_path / "r.ckpt"), "--csv", str(tmp_path / "a.csv")]
    code, _, err = _run(capsys, argv)
    assert code == 0, err
    assert (tmp_path / "r.ckpt").stat().st_size > 0
    first = (tmp_path / "a.csv").read_text()
    steps = hook_advance(monkeypatch, "tm", 10 ** 9, lambda: None)
    code, _, err = _run(capsys, argv)
    assert code == 0, err
    assert steps == [] and (tmp_path / "a.csv").read_text() == first
    code, _, err = _run(capsys, [*argv[:-4], "--tau", "0.1", *argv[-4:]])
    assert code == 2 and "checkpoint" in _one_line(err)


def test_run_and_map_a_symplectic_map(capsys, tmp_path):
    """--map: t counts iterations (τ = 1), X1 of the standard map at K = 10
    near ln(K/2), and a chaos map of its phase space."""
    code, out, err = _run(capsys, ["run", "x1", "--map", "standard", "--K", "10", "--x0",
                                   "1,0.5", "--t-end", "20000", "--csv",
                                   str(tmp_path / "x1.csv")])
    assert code == 0, err
    assert "StandardMap(K=10)" in out and "tau=1 " in out
    rows = _rows(tmp_path / "x1.csv")
    assert float(rows[-1][0]) == 20000 and float(rows[-1][1]) == 0.0
    assert abs(float(rows[-1][2]) - np.log(5)) < 0.05
    code, out, err = _run(capsys, ["map", "--map", "coupled", "--u", "0:1:4", "--v", "0:1:3",
                                   "--t-end", "200", "--csv", str(tmp_path / "m.csv")])
    assert code == 0, err
    assert "sali map of CoupledStandardMaps" in out and "12 orbits" in out
    assert _rows(tmp_path / "m.csv")[0][:5] == ["orbit", "x1", "x2", "x3", "x4"]


def test_run_and_map_a_driven_pendulum(capsys, tmp_path):
    """--time: the chaotic layer of the parametrically driven pendulum (SALI
    → 0), the extended energy K conserved, and a map of its phase space."""
    pot = ["--potential", "-cos(q)*(1+0.2*cos(1.5*t))", "--coords", "q", "--time", "t"]
    code, out, err = _run(capsys, ["run", "sali", *pot, "--x0", "0,2", "--t-end", "300",
                                   "--csv", str(tmp_path / "s.csv")])
    assert code == 0, err
    rows = _rows(tmp_path / "s.csv")
    # The automatic step keeps the pilot's energy error within 1e-5.
    assert float(rows[-1][2]) < 1e-8 and float(rows[-1][1]) < 1e-4
    code, out, err = _run(capsys, ["map", *pot, "--u", "-3:3:3", "--v", "-2.5:2.5:3",
                                   "--indicator", "sali", "--t-end", "100"])
    assert code == 0, err
    assert "on the plane of state components 0, 1: 9 orbits" in out


def test_two_particle_method_with_its_separation(capsys, tmp_path):
    """--method two-particle --d0: X1 of a chaotic orbit of the standard map
    (K = 10, t = 2000) within the method's error of the TM method's (both
    on the same orbit, tests/test_two_particle.py; measured 2.7e-7 at
    d0 = 1e-8), and further from it at a d0 where the curvature error
    dominates (6.1e-5 at d0 = 4e-4); a chaos map of the standard map with
    neighbours put back only beyond --d-max. The TM run is the kernel of
    test_run_and_map_a_symplectic_map; a flow's (C1 of Hénon–Heiles)
    two-particle kernel costs ~19 CPU s cold, the map's ~7."""
    def x1(*extra):
        code, _, err = _run(capsys, ["run", "x1", "--map", "standard", "--K", "10", "--x0",
                                     "1,0.5", "--t-end", "2000", "--t-out", "1", "--csv",
                                     str(tmp_path / "x.csv"), *extra])
        assert code == 0, err
        return float(_rows(tmp_path / "x.csv")[-1][2])

    tm = x1()
    assert abs(x1("--method", "two-particle", "--d0", "1e-8") - tm) < 1e-6
    assert abs(x1("--method", "two-particle", "--d0", "4e-4") - tm) > 1e-5
    code, out, err = _run(capsys, ["map", "--map", "standard", "--K", "1.2", "--u", "0:6:4",
                                   "--v", "-3:3:3", "--t-end", "500", "--method",
                                   "two-particle", "--d0", "1e-9", "--d-max", "1e-6"])
    assert code == 0, err
    assert "sali map of StandardMap(K=1.2)" in out and "12 orbits" in out


def test_select(capsys, monkeypatch, tmp_path):
    """The command prints select_scheme's table with what its columns mean,
    its choice, and writes the table: every candidate. (Two default
    schemes and no compensated pilots: the command's plumbing, not the
    selection, is tested here, and every default candidate is a kernel of
    its own, each compensated level two more, compact and written out: 27
    CPU s cold for the three levels of one scheme;
    tests/test_selection.py tests the choice and the compensated pilots,
    test_a_table_of_mixed_values_is_written_as_text below their column.)"""
    # Named by path: imports varint.selection where no earlier test has.
    monkeypatch.setattr("varint.selection.DEFAULT_SCHEMES", ("SBAB2C", "ABA864"))
    monkeypatch.setattr("varint.selection.HIGH_ORDER_CANDIDATES", ())
    # A candidate is piloted compensated where target < error <= range × target.
    monkeypatch.setattr("varint.selection.COMPENSATION_RANGE", 1.0)
    code, out, err = _run(capsys, ["select", "--orbit", "R1", "--target", "1e-6", "--t-end",
                                   "1", "--csv", str(tmp_path / "s.csv")])
    assert code == 0, err
    assert "growth a" in out and "the error grows as t^a" in out
    assert "chosen: method=tm" in out
    rows = _rows(tmp_path / "s.csv")
    assert {r[rows[0].index("compensated")] for r in rows[1:]} == {"False"}
    assert len(rows) - 1 == 2 * len(varint.selection.DEFAULT_TAUS)
    assert {r[rows[0].index("scheme")] for r in rows[1:]} == {"SBAB2C", "ABA864"}


def test_a_table_of_mixed_values_is_written_as_text(capsys, tmp_path):
    """A column of select's table mixes values (compensated: False, True,
    "orbit", "step"): the CSV holds each as written, in the table's order."""
    path = tmp_path / "t.csv"
    cli._write_csv(path, {"scheme": ["SBAB2C", "SBAB2C", "SBAB2C", "ABA864"],
                          "compensated": [False, "step", True, "orbit"],
                          "tau": [0.1, 0.1, 0.1, 0.05]})
    assert "table written to" in capsys.readouterr().out
    assert _rows(path) == [["scheme", "compensated", "tau"], ["SBAB2C", "False", "0.1"],
                           ["SBAB2C", "step", "0.1"], ["SBAB2C", "True", "0.1"],
                           ["ABA864", "orbit", "0.05"]]


def test_demo(capsys, tmp_path):
    code, out, err = _run(capsys, ["demo", "--t-end", "1", "--out", str(tmp_path / "d.png")])
    assert code == 0, err
    assert "R1" in out and "C1" in out and (tmp_path / "d.png").stat().st_size > 1000


def test_study_list(capsys):
    code, out, err = _run(capsys, ["study", "--list"])
    assert code == 0
    assert "sections" in out and "bench_chaos_map" in out
    # Each description is a whole sentence, not a docstring's first line.
    described = cli._study_names(ROOT)
    assert len(described) >= 20
    for name, doc in described.items():
        assert doc.endswith((".", "?", "!")) and "``" not in doc and ":mod:" not in doc, name


@pytest.mark.parametrize("returned, status", [({"rows": []}, 0), (None, 0), (0, 0), (1, 1),
                                              (3, 3), (True, 0), ("done", 0)])
def test_a_study_that_returns_its_results_exits_0(capsys, monkeypatch, tmp_path, returned,
                                                  status):
    """Issue 32: most studies' main() returns their results (a dict), which
    the command took for an exit status (1); only an integer is one."""
    root = _checkout(tmp_path / "repo")
    (root / "studies" / "gives.py").write_text(
        f'"""Returns something."""\n\n\ndef main(argv=None):\n    return {returned!r}\n')
    monkeypatch.chdir(root)
    monkeypatch.delitem(sys.modules, "studies", raising=False)
    monkeypatch.delitem(sys.modules, "studies.gives", raising=False)
    monkeypatch.setattr(sys, "path", [str(root), *sys.path])
    assert _run(capsys, ["study", "gives", "--quick"])[0] == status


STUDIES = sorted(cli._study_names(ROOT))


@pytest.mark.parametrize("name", STUDIES)
def test_every_study_answers_help_through_the_command(capsys, monkeypatch, name):
    """Every study of studies/ is found, imports and parses its options
    when run as 'varint study NAME' (exit 0)."""
    monkeypatch.chdir(ROOT)
    code, out, err = _run(capsys, ["study", name, "--help"])
    assert code == 0, err
    assert out.startswith("usage:")


def test_the_readme_study_command_exits_0(tmp_path):
    """README's 'varint study sections --quick', as a user runs it."""
    out = subprocess.run([sys.executable, "-m", "varint.cli", "study", "sections", "--quick",
                          "--out", str(tmp_path)], capture_output=True, text=True, timeout=600,
                         cwd=ROOT, env=_env())
    assert out.returncode == 0, out.stdout[-2000:] + out.stderr[-2000:]


@pytest.mark.slow  # every study's quick mode: tens of minutes
@pytest.mark.parametrize("name", [s for s in STUDIES if s not in ("sections", "fingerprints")])
def test_every_study_quick_mode_exits_0_through_the_command(tmp_path, name):
    out = subprocess.run([sys.executable, "-m", "varint.cli", "study", name, "--quick",
                          "--out", str(tmp_path)], capture_output=True, text=True,
                         timeout=3600, cwd=ROOT, env=_env())
    assert out.returncode == 0, out.stdout[-2000:] + out.stderr[-2000:]


def _checkout(folder):
    (folder / "studies").mkdir(parents=True)
    (folder / "pyproject.toml").write_text('[project]\nname = "varint"\nversion = "0"\n')
    (folder / "studies" / "__init__.py").write_text("")
    (folder / "studies" / "hello.py").write_text(
        '"""Says hello."""\n\n\ndef main(argv=None):\n    import varint\n'
        '    print("hello", argv, varint.__file__)\n')
    return folder


def test_study_runs_from_the_checkout_above_the_current_directory(tmp_path):
    root = _checkout(tmp_path / "repo")
    (root / "deep" / "er").mkdir(parents=True)
    out = subprocess.run([sys.executable, "-m", "varint.cli", "study", "hello", "--quick"],
                         capture_output=True, text=True, timeout=120, env=_env(),
                         cwd=root / "deep" / "er")
    assert out.returncode == 0, out.stderr
    assert f"hello ['--quick'] {ROOT / 'varint' / '__init__.py'}" in out.stdout
    listed = subprocess.run([sys.executable, "-m", "varint.cli", "study", "--list"],
                            capture_output=True, text=True, timeout=120, env=_env(), cwd=root)
    assert listed.stdout.split() == ["hello", "Says", "hello."]


def test_study_without_a_checkout_says_how_to_get_one(capsys, monkeypatch, tmp_path):
    # A non-editable install: the package is not inside a checkout either.
    installed = tmp_path / "site-packages" / "varint" / "cli.py"
    monkeypatch.setattr(cli, "__file__", str(installed))
    monkeypatch.chdir(tmp_path)
    (tmp_path / "pyproject.toml").write_text('[project]\nname = "other"\n')
    (tmp_path / "studies").mkdir()
    code, out, err = _run(capsys, ["study", "sections"])
    assert code == 2
    line = _one_line(err)
    assert "no varint source checkout here" in line and "clone the varint repository" in line
    assert "run 'varint study' from inside it" in line


# -- every kind of failure ends in one line -------------------------------------------------
def _numba_error():
    return TypingError("Failed in nopython mode pipeline (step: nopython frontend)\n"
                       "No implementation of function abs(array)\n\nDuring: typing")


def _wrapped_numba_error():
    try:
        raise _numba_error()
    except TypingError as exc:
        try:
            raise TypeError("the kernels of model 'm' could not be compiled") from exc
        except TypeError as wrapped:
            return wrapped


FAILURES = [
    (ZeroDivisionError("division by zero"), 1,
     "run failed: ZeroDivisionError in the model's kernels or the indicator (division by zero)"),
    (FloatingPointError("overflow encountered in multiply"), 1,
     "run failed: FloatingPointError"),
    (OverflowError("math range error"), 1, "run failed: OverflowError"),
    (MemoryError("Unable to allocate 74.5 GiB for an array"), 1,
     "run failed: out of memory (Unable to allocate 74.5 GiB for an array)"),
    (_numba_error(), 1, "numba could not compile the integrator: No implementation of function"),
    (_wrapped_numba_error(), 1, "numba could not compile the integrator: the kernels of model"),
    (IntegrationError("the orbit failed at t = 3", t=3.0, step=60, orbit=0, reason="nan"), 1,
     "run failed: the orbit failed at t = 3"),
    (KeyboardInterrupt(), 130, "varint run: interrupted"),
    (ModuleNotFoundError("No module named 'heyoka'", name="heyoka"), 2,
     "error: this needs the package heyoka, which is not installed"),
    (ImportError("--scheduler needs dask.distributed"), 2, "error: --scheduler needs dask"),
    (OSError(28, "No space left on device"), 1, "error: [Errno 28] No space left on device"),
    (ValueError("two\nlines"), 2, "varint run: error: two lines"),
    (varint.CheckpointError("c.ckpt is truncated"), 2, "error: c.ckpt is truncated"),
    (TypeError("unsupported operand type(s)"), 1,
     "internal error: TypeError: unsupported operand type(s); rerun with 'varint --traceback"),
    (RuntimeError("boom"), 1, "internal error: RuntimeError: boom"),
    (RecursionError("maximum recursion depth exceeded"), 1, "internal error: RecursionError"),
    (AttributeError("'function' object has no attribute 'integrate'"), 1,
     "internal error: AttributeError"),
]


@pytest.mark.parametrize("exc, status, match", FAILURES,
                         ids=[type(f[0]).__name__ + str(i) for i, f in enumerate(FAILURES)])
def test_every_failure_ends_in_one_line(capsys, monkeypatch, exc, status, match):
    def fail(args):
        raise exc

    monkeypatch.setattr(cli, "_cmd_run", fail)
    code, out, err = _run(capsys, ["run", "sali", "--orbit", "R1"])
    assert code == status
    assert match in _one_line(err)


def test_traceback_flag_shows_the_traceback_then_the_line(capsys, monkeypatch):
    def fail(args):
        raise RuntimeError("boom")

    monkeypatch.setattr(cli, "_cmd_run", fail)
    for argv in (["--traceback", "run", "sali"], ["run", "sali", "--traceback"]):
        code, out, err = _run(capsys, argv)
        lines = err.strip().splitlines()
        assert code == 1 and lines[0] == "Traceback (most recent call last):"
        assert "in fail" in err and lines[-1].startswith("varint run: internal error:")


def test_a_broken_pipe_and_a_study_exit_status_are_not_errors(capsys, monkeypatch):
    def pipe(args):
        raise BrokenPipeError

    def study(args):
        raise SystemExit(3)

    monkeypatch.setattr(cli, "_cmd_run", pipe)
    assert _run(capsys, ["run", "sali"]) == (0, "", "")
    monkeypatch.setattr(cli, "_cmd_study", study)
    assert _run(capsys, ["study", "x"])[0] == 3


def test_warnings_are_one_line_each(capsys, monkeypatch):
    import warnings

    def warn(args):
        warnings.warn("three\nline\nwarning", RuntimeWarning, stacklevel=2)

    monkeypatch.setattr(cli, "_cmd_run", warn)
    code, out, err = _run(capsys, ["run", "sali"])
    assert code == 0 and err == "varint run: warning: three line warning\n"


def test_ctrl_c_prints_the_outputs_so_far_then_one_line(capsys, monkeypatch, tmp_path):
    hook_advance(monkeypatch, "tm", 2, lambda: os.kill(os.getpid(), signal.SIGINT))
    code, out, err = _run(capsys, ["run", "lyapunov", "--orbit", "C1", "--t-end", "200",
                                   "--csv", str(tmp_path / "r.csv")])
    assert code == 130
    line = _one_line(err)
    assert line.startswith("varint run: interrupted at t = ") and "shown and written" in line
    rows = _rows(tmp_path / "r.csv")
    assert len(rows) > 1 and float(rows[-1][0]) < 200

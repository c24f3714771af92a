"""Bad inputs of round 3, tried as a hostile user would (each a row of the
table below): every one is refused before any work with a one-line
``ValueError`` (or a clean ``IntegrationError`` where the run itself
overflows) naming the value and what was expected — never a raw
``TypeError`` from NumPy or numba, and never evaluated as code."""

import os

import numpy as np
import pytest
import sympy as sp

import varint
from varint import cli
from varint.models import (FPUT, DDNLS, CoupledStandardMaps, DisorderedKG, FPUBeta,
                           HenonHeiles, StandardMap, from_map, from_potential)

R1 = [0.0, 0.558, 0.23337397, 0.0]
q0, q1 = sp.symbols("q0 q1")
X, P = sp.symbols("x p")


def hh():
    return HenonHeiles()


def block(m, s):
    return m.initial_block(3, 1.0)


#: (name, call, expected exception, message regex).
CASES = [
    # Numbers given as text are refused everywhere, never parsed.
    ("FPUT alpha text", lambda: FPUT(8, alpha="1"), ValueError, "alpha must be"),
    ("FPUT n text", lambda: FPUT("8"), ValueError, "n must be an integer"),
    ("FPUT n fractional", lambda: FPUT(8.5), ValueError, "n must be an integer"),
    ("FPUT beta NaN", lambda: FPUT(8, beta=float("nan")), ValueError, "beta must be"),
    ("KG W text", lambda: DisorderedKG(16, W="4"), ValueError, "W must be"),
    ("KG W infinite", lambda: DisorderedKG(16, W=float("inf")), ValueError, "W must be"),
    ("KG seed text", lambda: DisorderedKG(16, seed="1"), ValueError, "seed must be"),
    ("DDNLS beta text", lambda: DDNLS(16, beta="1"), ValueError, "beta must be"),
    ("standard map K text", lambda: StandardMap("1.2"), ValueError, "K must be"),
    ("standard map K NaN", lambda: StandardMap(float("nan")), ValueError, "K must be"),
    ("coupled maps K1 text", lambda: CoupledStandardMaps("1", 1, 0.1), ValueError, "K1 must"),
    ("FPU-beta n text", lambda: FPUBeta("8"), ValueError, "n must be an integer"),
    ("inverse mass text", lambda: from_potential(q0 ** 2 + q1 ** 2, [q0, q1],
                                                 inverse_mass=["1", "1"]),
     ValueError, r"inverse_mass\[0\] must be a number"),
    ("potential as text", lambda: from_potential("q0**2", [q0]), ValueError,
     "V must be a SymPy expression"),
    ("escape radius text", lambda: from_potential(q0 ** 2, [q0], escape_radius="3"),
     ValueError, "escape_radius must be positive"),
    ("escape radius True", lambda: from_potential(q0 ** 2, [q0], escape_radius=True),
     ValueError, "escape_radius must be positive"),
    ("period as code", lambda: from_map([X + P, P], [X, P],
                                        periods={X: "__import__('os').getcwd()"}),
     ValueError, "period of x must be a number"),
    ("period list text", lambda: from_map([X + P, P], [X, P], periods=["6.28", 0]),
     ValueError, "period of x must be a number"),
    ("period imaginary", lambda: from_map([X + P, P], [X, P], periods={X: sp.I}),
     ValueError, "period of x must be a number"),
    ("period symbolic", lambda: from_map([X + P, P], [X, P], periods={X: q0}),
     ValueError, "period of x must be a number"),
    ("map expressions as text", lambda: from_map(["x+p", "p"], [X, P]), ValueError,
     r"exprs\[0\] must be a SymPy expression"),
    ("tau text", lambda: varint.lyapunov_spectrum(hh(), R1, 10.0, tau="0.05"), ValueError,
     "tau must be"),
    ("t_end text", lambda: varint.lyapunov_spectrum(hh(), R1, "10"), ValueError,
     "t_end must be"),
    ("seed text", lambda: varint.lyapunov_spectrum(hh(), R1, 10.0, seed="1"), ValueError,
     "seed must be"),
    ("seed fractional", lambda: varint.lyapunov_spectrum(hh(), R1, 10.0, seed=1.5),
     ValueError, "seed must be"),
    ("t_out text", lambda: varint.lyapunov_spectrum(hh(), R1, 10.0, t_out="5"), ValueError,
     "t_out"),
    ("t_out list of text", lambda: varint.lyapunov_spectrum(hh(), R1, 10.0, t_out=["5", "10"]),
     ValueError, "t_out must be an array of real numbers"),
    ("x0 text", lambda: varint.lyapunov_spectrum(hh(), ["0", "0.5", "0.2", "0"], 10.0),
     ValueError, "x0 must be an array of real numbers"),
    ("energy_tol text", lambda: varint.lyapunov_spectrum(hh(), R1, 10.0, energy_tol="1e-3"),
     ValueError, "energy_tol must be"),
    ("escape_radius text (run)", lambda: varint.lyapunov_spectrum(hh(), R1, 10.0,
                                                                  escape_radius="3"),
     ValueError, "escape_radius must be"),
    ("renormalize_every text", lambda: varint.lyapunov_spectrum(hh(), R1, 10.0,
                                                                renormalize_every="4"),
     ValueError, "renormalize_every must be"),
    ("n_exponents text", lambda: varint.lyapunov_spectrum(hh(), R1, 10.0, n_exponents="2"),
     ValueError, "n_exponents must be"),
    ("GALI k text", lambda: varint.gali(hh(), R1, 10.0, k="2"), ValueError, "k must be"),
    ("GALI k list of text", lambda: varint.gali(hh(), R1, 10.0, k=["2", "3"]), ValueError,
     "k must be"),
    ("d0 text", lambda: varint.run(hh(), R1, "x1", 10.0, method="two-particle", d0="1e-8"),
     ValueError, "d0 must be"),
    ("d_max text", lambda: varint.sali(hh(), R1, 10.0, method="two-particle", d_max="1e-6"),
     ValueError, "d_max must be"),
    ("d0 huge", lambda: varint.run(hh(), R1, "x1", 10.0, method="two-particle", d0=1e10),
     ValueError, "d0 = 1e\\+10 is outside"),
    ("d0 tiny", lambda: varint.run(hh(), R1, "x1", 10.0, method="two-particle", d0=1e-300),
     ValueError, "is outside"),
    ("d0 of a map too large", lambda: varint.run(StandardMap(1.2), [1.0, 0.5], "x1", 10,
                                                 method="two-particle", d0=0.1),
     ValueError, "is outside"),
    ("window text", lambda: varint.run(hh(), R1, "local_exponents", 10.0, window="5"),
     ValueError, "window must be"),
    ("rtol text", lambda: varint.lyapunov_spectrum(hh(), R1, 10.0, method="cvode",
                                                   rtol="1e-10"),
     ValueError, "rtol must be"),
    ("deviations of text", lambda: varint.lyapunov_spectrum(
        hh(), R1, 10.0, deviations=[["1", "0"], ["0", "1"], ["0", "0"], ["0", "0"]]),
     ValueError, "deviations must be an array of real numbers"),
    ("map threshold text", lambda: varint.chaos_map(hh(), np.array([R1]), "sali", t_end=10.0,
                                                    threshold="1e-8"),
     ValueError, "threshold must be"),
    ("map chunk_size text", lambda: varint.chaos_map(hh(), np.array([R1]), "sali",
                                                     t_end=10.0, chunk_size="4"),
     ValueError, "chunk_size must be"),
    ("map seed text", lambda: varint.chaos_map(hh(), np.array([R1]), "sali", t_end=10.0,
                                               seed="1"),
     ValueError, "seed must be"),
    ("map t_check text", lambda: varint.chaos_map(hh(), np.array([R1]), "sali", t_end=10.0,
                                                  t_check="5"),
     ValueError, "t_check"),
    ("section energy text", lambda: varint.section_grid(hh(), "0.125", np.linspace(-.4, .4, 4),
                                                        np.linspace(-.4, .4, 4)),
     ValueError, "energy must be"),
    ("ensemble seeds of text", lambda: varint.ensemble(DDNLS, ["1"], block, "dvd", 1.0, 0.1,
                                                       params={"shape": 16}),
     ValueError, "seeds must be"),
    ("ensemble parameter text", lambda: varint.ensemble(DDNLS, [1], block, "dvd", 1.0, 0.1,
                                                        params={"shape": 16, "W": "4"}),
     ValueError, "W must be"),
    ("select target text", lambda: varint.select_scheme(hh(), R1, "1e-8", t_end=10.0),
     ValueError, "target_error must be"),
    ("reference kind eval", lambda: __import__("varint.cache").cache.reference(
        hh(), R1, 1.0, kind="eval"), ValueError, "unknown kind"),
    # Observables undefined at zero energy, and huge parameters.
    ("KG at rest, dvd", lambda: varint.run(DisorderedKG(16, seed=1), np.zeros(32), "dvd", 1.0,
                                           0.1), ValueError, "total energy"),
    ("KG at rest, spreading", lambda: varint.run(DisorderedKG(16, seed=1), np.zeros(32),
                                                 "spreading", 1.0, 0.1),
     ValueError, "total energy"),
    ("KG at rest, map", lambda: varint.chaos_map(DisorderedKG(16, seed=1), np.zeros((2, 32)),
                                                 "dvd", t_end=1.0, tau=0.1),
     ValueError, "orbit 0"),
    ("DDNLS without norm", lambda: varint.run(DDNLS(16, seed=1), np.zeros(32), "dvd", 1.0, 0.1),
     ValueError, "total norm"),
    ("FPUT at rest", lambda: varint.run(FPUT(16), np.zeros(32), "spreading", 1.0, 0.1),
     ValueError, "total energy"),
    ("KG with a NaN site", lambda: varint.run(DisorderedKG(4, seed=1),
                                              [np.nan] + [0.0] * 7, "dvd", 1.0, 0.1),
     ValueError, "must be finite"),
    # SABA1, the scheme of fewest stages: the coefficients compile all the
    # same, in a smaller kernel than ABA864's (the same run as
    # tests/test_options_in_verdict.py, hence one compilation).
    ("FPUT alpha=beta=1e300", lambda: varint.run(FPUT(4, alpha=1e300, beta=1e300),
                                                 FPUT(4).initial_block(2, 0.4), "x1", 3.0, 0.1,
                                                 scheme="SABA1"),
     varint.IntegrationError, "non-finite"),
    # SBAB2C's corrector (an FPUT chain's own default, ABA864, has none).
    ("FPUT alpha=1e200 (corrector 1e401)", lambda: varint.run(
        FPUT(4, alpha=1e200, beta=0.0), FPUT(4).initial_block(2, 0.4), "x1", 3.0, 0.1,
        scheme="SBAB2C"),
     ValueError, "beyond the range of a double"),
    ("potential coefficient 1e400", lambda: from_potential(sp.Integer(10) ** 400 * q0 ** 2,
                                                           [q0]),
     ValueError, "beyond the range of a double"),
    ("rational coefficient beyond int64", lambda: from_potential(
        sp.Rational(10 ** 400, 3) * q0 ** 2, [q0]), ValueError, "beyond the range of a double"),
    ("load_result of a text file", lambda: varint.load_result(__file__), ValueError,
     "not an .npz archive"),
    ("tau of 1e300", lambda: varint.lyapunov_spectrum(hh(), R1, 10.0, tau=1e300), ValueError,
     "shorter than one step"),
]


@pytest.mark.parametrize("name, call, exc, match", CASES, ids=[c[0] for c in CASES])
def test_a_bad_input_is_refused_cleanly(name, call, exc, match):
    with pytest.raises(exc, match=match) as err:
        call()
    assert type(err.value) is exc or exc is ValueError and isinstance(err.value, ValueError)
    assert len(str(err.value).strip().splitlines()) == 1, str(err.value)


def test_the_table_holds_at_least_sixty_cases():
    assert len(CASES) >= 60 and len({c[0] for c in CASES}) == len(CASES)


# -- the command line's output files ----------------------------------------------

def test_csv_and_png_never_write_through_a_planted_link(tmp_path, capsys):
    """A symbolic link planted at an output path made --csv and --png
    overwrite its target: such a path is refused before the run, and a
    link planted during the run is replaced, never followed."""
    victim = tmp_path / "victim"
    victim.write_text("precious\n")
    for flag, name in (("--csv", "out.csv"), ("--png", "out.png")):
        link = tmp_path / name
        link.symlink_to(victim)
        code = cli.main(["run", "x1", "--orbit", "R1", "--t-end", "2", flag, str(link)])
        err = capsys.readouterr().err
        assert code == 2 and "symbolic link" in err and victim.read_text() == "precious\n"
        link.unlink()
    # Planted after the check: the writer replaces the link.
    link = tmp_path / "late.csv"
    link.symlink_to(victim)
    cli._write_csv(str(link), {"t": [1.0, 2.0], "x1": [0.5, 0.25]})
    assert victim.read_text() == "precious\n" and not link.is_symlink()
    assert link.read_text().splitlines()[0] == "t,x1"
    assert oct(link.stat().st_mode & 0o777) == oct(0o666 & ~_umask())


def test_the_demo_plot_never_writes_through_a_planted_link(tmp_path, capsys):
    """``varint demo --out`` as --png: a link at the path is refused before
    the run, and one planted during it is replaced, never followed."""
    from varint import demo

    victim = tmp_path / "victim"
    victim.write_text("precious\n")
    link = tmp_path / "demo.png"
    link.symlink_to(victim)
    code = cli.main(["demo", "--t-end", "1", "--out", str(link)])
    assert code == 2 and "symbolic link" in capsys.readouterr().err
    demo.run(t_end=1.0, out=str(link))
    assert victim.read_text() == "precious\n" and not link.is_symlink()
    assert link.read_bytes().startswith(b"\x89PNG")


def _umask():
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def test_devices_are_still_written_directly(capsys):
    code = cli.main(["run", "x1", "--orbit", "R1", "--t-end", "2", "--csv", "/dev/null"])
    assert code == 0 and os.path.exists("/dev/null") and not os.path.isfile("/dev/null")

"""Bad input, tried: a table of wrong arguments across the public API. Each
must raise the stated exception with a message naming the problem, before
any compiled kernel runs (so no numba typing error, segfault or traceback
from inside a kernel can reach the user). Damaged checkpoint and cache
files are tried at more length in test_faults.py."""

import os

import numpy as np
import pytest
import sympy as sp
from numba import njit

import varint
from varint import _validate as check
from varint.formula import parse_formula
from varint.models import FPUBeta, HenonHeiles, Model, paper_orbit, solve_momentum
from varint.models.henon_heiles import _grad, _hess, _potential, _third
from tests.helpers import hook_advance

HH = HenonHeiles()
X0 = paper_orbit("C1")[1]
x, y, k = sp.symbols("x y k")
HH_V = (x**2 + y**2) / 2 + x**2 * y - y**3 / 3


def run(fn=varint.lyapunov_spectrum, **kw):
    args = dict(model=HH, x0=X0, t_end=10.0)
    args.update(kw)
    return fn(**args)


def scheme(**kw):
    """SplittingScheme with one field changed from a valid leapfrog."""
    args = dict(name="LF", drift_first=True, drifts=(0.5,), kicks=(1.0,), order=2)
    args.update(kw)
    return varint.SplittingScheme(**args)


def formula(text, coords=("x", "y")):
    return parse_formula(text, coords, "--potential")


def written_by_another_run(path):
    run(fn=varint.sali, checkpoint=path / "c.ckpt")
    return run(checkpoint=path / "c.ckpt")


def not_a_checkpoint(path):
    (path / "c.ckpt").write_text("t,x,y\n0,0.1,0.2\n")
    return run(checkpoint=path / "c.ckpt")


def truncated_checkpoint(path):
    run(checkpoint=path / "c.ckpt")
    data = (path / "c.ckpt").read_bytes()
    (path / "c.ckpt").write_bytes(data[: len(data) * 2 // 3])
    return run(checkpoint=path / "c.ckpt")


def _sym(expr, name):
    return varint.models.from_potential(expr, [x, y], name=name)


INVERSE_X = _sym(1 / x + y**2 / 2, "1/x")
LOG_X = _sym(sp.log(x) + y**2 / 2, "log x")
SQRT_X = _sym(sp.sqrt(x) + y**2 / 2, "sqrt x")
EXP_X = _sym(sp.exp(1000 * x) + y**2 / 2, "exp 1000x")
HH_GRID = varint.section_grid(HH, 0.125, np.linspace(-0.4, 0.6, 3), np.linspace(-0.4, 0.4, 3))


@njit
def _grad_two_args(q, g):
    g[0] = q[0]


def map_into_a_file(path):
    (path / "taken").write_text("a file, not a directory")
    return varint.chaos_map(HH, [X0, X0], t_end=10.0, tau=0.05, checkpoint=path / "taken")


ORTHO_NOT = np.array([[1.0, 0.5], [0.0, 1.0], [0.0, 0.0], [0.0, 0.0]])
RANK_2_OF_3 = np.array([[1.0, 0.0, 1.0], [0.0, 1.0, 1.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])

# (what is wrong, call(tmp_path), exception, regex the message must match)
CASES = [
    # -- initial states: shapes, dtypes, NaN/inf
    ("x0 of the wrong length", lambda p: run(x0=[0.0, 0.1, 0.2]), ValueError,
     r"x0 must have shape \(4,\) or \(M, 4\) for HenonHeiles .* got shape \(3,\)"),
    ("x0 of rank 3", lambda p: run(x0=np.zeros((1, 1, 4))), ValueError,
     r"x0 must have shape .* got shape \(1, 1, 4\)"),
    ("x0 with no orbit", lambda p: run(x0=np.zeros((0, 4))), ValueError, "x0 holds no orbit"),
    ("x0 with NaN", lambda p: run(x0=[0.0, np.nan, 0.1, 0.0]), ValueError,
     "x0 must be finite; component 1 is nan"),
    ("x0 with inf in a batch", lambda p: run(x0=[X0, [np.inf, 0, 0, 0]]), ValueError,
     "x0 must be finite; orbit 1, component 0 is inf"),
    ("x0 complex", lambda p: run(x0=X0 + 0j), ValueError, "x0 must be real, got complex"),
    ("x0 of text", lambda p: run(x0=["0", "0.1", "0.2", "0"]), ValueError,
     "x0 must be an array of real numbers, got dtype <U"),
    ("x0 with None", lambda p: run(x0=[None, 0.1, 0.2, 0.0]), ValueError,
     "x0 must hold real numbers, got None"),
    ("x0 ragged", lambda p: run(x0=[X0, [0.0, 0.1]]), ValueError,
     "x0 must be a rectangular array"),
    ("x0 boolean", lambda p: run(x0=[True, False, True, False]), ValueError,
     "x0 must be an array of real numbers, got dtype bool"),
    # -- step and horizon
    ("tau zero", lambda p: run(tau=0.0), ValueError,
     "tau must be a positive finite number, got 0.0"),
    ("tau negative", lambda p: run(tau=-0.05), ValueError, "tau must be a positive .* got -0.05"),
    ("tau NaN", lambda p: run(tau=np.nan), ValueError, "tau must be a positive .* got nan"),
    ("tau inf", lambda p: run(tau=np.inf), ValueError, "tau must be a positive .* got inf"),
    ("tau as text", lambda p: run(tau="0.05"), ValueError, "tau must be a positive .* got '0.05'"),
    ("tau complex", lambda p: run(tau=0.05 + 0j), ValueError,
     r"tau must be a positive .* \(0.05\+0j\)"),
    ("tau larger than t_end", lambda p: run(t_end=0.01, tau=0.05), ValueError,
     "t_end = 0.01 is shorter than one step tau = 0.05"),
    ("t_end NaN", lambda p: run(t_end=np.nan), ValueError,
     "t_end must be a finite number, got nan"),
    ("t_end negative", lambda p: run(t_end=-10.0), ValueError, "t_end must be >= 0, got -10.0"),
    # -- unknown names
    ("unknown method", lambda p: run(method="rk4"), ValueError,
     "unknown method 'rk4'; expected one of: tm"),
    ("unknown scheme", lambda p: run(scheme="SABA9"), ValueError,
     "unknown scheme 'SABA9'; expected one of: SABA1"),
    ("unknown errors mode", lambda p: run(errors="ignore"), ValueError,
     "unknown errors 'ignore'; expected one of: raise, flag"),
    ("unknown paper orbit", lambda p: paper_orbit("R9"), ValueError, "unknown paper orbit 'R9'"),
    ("misspelt method option", lambda p: run(checkpiont="c.ckpt"), TypeError, "checkpiont"),
    # -- numbers of vectors: k outside 1..2N
    ("n_exponents 0", lambda p: run(n_exponents=0), ValueError, r"n_exponents must be in 1\.\.4"),
    ("n_exponents above 2N", lambda p: run(n_exponents=5), ValueError,
     r"n_exponents must be in 1\.\.4 \(2N for this model\), got 5"),
    ("n_exponents not an integer", lambda p: run(n_exponents=2.0), ValueError,
     "n_exponents must be an integer"),
    ("n_exponents boolean", lambda p: run(n_exponents=True), ValueError,
     "n_exponents must be an integer"),
    ("GALI order 1", lambda p: run(fn=varint.gali, k=1), ValueError,
     r"GALI order k must be in 2\.\.4"),
    ("GALI order above 2N", lambda p: run(fn=varint.gali, k=(2, 5)), ValueError,
     r"GALI order k must be in 2\.\.4 .* got 5"),
    ("no GALI order", lambda p: run(fn=varint.gali, k=()), ValueError,
     "k must name at least one GALI order"),
    ("repeated GALI order", lambda p: run(fn=varint.gali, k=(2, 2)), ValueError,
     "GALI orders must be distinct"),
    ("deviations with no column", lambda p: run(deviations=np.zeros((4, 0))), ValueError,
     r"number of deviation vectors \(columns of deviations\) must be in 1\.\.4 .* got 0"),
    ("more deviations than 2N", lambda p: run(fn=varint.gali, deviations=np.ones((4, 5))),
     ValueError, r"number of deviation vectors .* must be in 1\.\.4 .* got 5"),
    ("n_exponents and deviations disagree",
     lambda p: run(n_exponents=2, deviations=np.eye(4)[:, :3]), ValueError,
     "n_exponents = 2 but 3 deviation vectors were given"),
    ("SALI with three vectors", lambda p: run(fn=varint.sali, deviations=np.eye(4)[:, :3]),
     ValueError, "SALI needs exactly 2 deviation vectors, 3 were given"),
    # -- deviation vectors: shapes, values
    ("deviations of rank 4", lambda p: run(deviations=np.zeros((1, 1, 4, 2))), ValueError,
     r"deviations must have shape \(4, k\) or \(1, 4, k\)"),
    ("deviations of the wrong dimension", lambda p: run(deviations=np.eye(3)), ValueError,
     r"deviations must have shape \(4, k\) .* got shape \(1, 3, 3\)"),
    ("deviations not orthonormal", lambda p: run(deviations=ORTHO_NOT), ValueError,
     "deviations of orbit 0 are not orthonormal"),
    ("deviations rank-deficient", lambda p: run(fn=varint.gali, k=3, deviations=RANK_2_OF_3),
     ValueError, "deviations of orbit 0 are linearly dependent"),
    ("deviations with NaN", lambda p: run(deviations=np.full((4, 1), np.nan)), ValueError,
     "deviations must be finite"),
    ("deviations complex", lambda p: run(deviations=np.eye(4) * 1j), ValueError,
     "deviations must be real"),
    # -- seeds and output times
    ("negative seed", lambda p: run(seed=-1), ValueError,
     "seed must be a non-negative integer or None, got -1"),
    ("fractional seed", lambda p: run(seed=1.5), ValueError, "seed must be .* got 1.5"),
    ("t_out decreasing", lambda p: run(t_out=[5.0, 1.0]), ValueError,
     "t_out must be strictly increasing"),
    ("t_out beyond t_end", lambda p: run(t_out=[1.0, 20.0]), ValueError,
     r"t_out must lie in \[tau, t_end\]"),
    ("t_out count 0", lambda p: run(t_out=0), ValueError,
     "t_out as a count must be a positive integer, got 0"),
    ("t_out of rank 2", lambda p: run(t_out=[[1.0, 2.0]]), ValueError,
     "t_out must be a 1-D array of times, got shape"),
    ("t_out complex", lambda p: run(t_out=[1.0 + 1j]), ValueError, "t_out must be real"),
    # -- other options
    ("progress not a flag", lambda p: run(progress="yes"), ValueError,
     "progress must be True, False or None, got 'yes'"),
    ("escape radius negative", lambda p: run(escape_radius=-1.0), ValueError,
     "escape_radius must be a positive finite number, got -1.0"),
    ("checkpoint interval negative", lambda p: run(checkpoint=p / "c", checkpoint_interval=-1),
     ValueError, "checkpoint_interval must be a finite number of seconds >= 0, got -1"),
    ("checkpoint path a directory", lambda p: run(checkpoint=p), varint.CheckpointError,
     "is a directory"),
    ("checkpoint not a path", lambda p: run(checkpoint=3.5), varint.CheckpointError,
     "checkpoint must be a file path, got 3.5"),
    # -- damaged or foreign checkpoints
    ("checkpoint of another file", not_a_checkpoint, varint.CheckpointError,
     "is not a varint checkpoint"),
    ("checkpoint truncated", truncated_checkpoint, varint.CheckpointError,
     "is truncated or corrupt"),
    ("checkpoint of another run", written_by_another_run, varint.CheckpointError,
     "kind .checkpoint: 'sali', this call: 'lyapunov'"),
    # -- models: masses, parameters, kernels, symbolic potentials
    ("inverse mass zero", lambda p: Model(2, _potential, _grad, _hess, _third, 1,
                                          inverse_mass=[1.0, 0.0]), ValueError,
     "inverse_mass must be positive and finite; got 0.0 at index 1"),
    ("inverse mass negative (symbolic)",
     lambda p: varint.models.from_potential(HH_V, [x, y], inverse_mass=[1, -2]), ValueError,
     r"inverse_mass\[1\] must be positive and finite, got -2"),
    ("model parameter NaN", lambda p: Model(2, _potential, _grad, _hess, _third, 1,
                                            params=[np.nan]), ValueError,
     r"params must be finite, got \[nan\]"),
    ("model kernel not compiled", lambda p: Model(2, _potential, _potential, _hess, _third, 1),
     ValueError, "grad kernel must be a numba-compiled function"),
    ("FPU chain too short", lambda p: FPUBeta(1), ValueError, "n must be an integer >= 2"),
    ("escape radius of a model", lambda p: HenonHeiles(escape_radius=0.0), ValueError,
     "escape_radius must be positive and finite, got 0.0"),
    ("potential with a free parameter",
     lambda p: varint.models.from_potential(HH_V + k * x**4, [x, y]), ValueError,
     "V contains symbols that are not coordinates: k"),
    ("potential not differentiable",
     lambda p: varint.models.from_potential(HH_V + sp.Abs(x) ** 3, [x, y]), ValueError,
     "V must be three times differentiable"),
    ("potential complex",
     lambda p: varint.models.from_potential(HH_V + sp.I * x, [x, y]), ValueError,
     "V must be real"),
    ("energy out of reach", lambda p: solve_momentum(HH, [0.0, 0.9], [0.0, 0.0], 0.125),
     ValueError, "no real momentum p\\[0\\] gives energy 0.125"),
    ("FPU beta as text", lambda p: FPUBeta(4, beta="1"), ValueError,
     "beta must be a finite real number, got str '1'"),
    ("FPU beta complex", lambda p: FPUBeta(4, beta=1j), ValueError,
     "beta must be a finite real number, got complex 1j"),
    ("FPU beta infinite", lambda p: FPUBeta(4, beta=np.inf), ValueError,
     "beta must be a finite real number, got float inf"),
    ("FPU size fractional", lambda p: FPUBeta(3.7), ValueError,
     "n must be an integer >= 2 .* got 3.7"),
    ("FPU size NaN", lambda p: FPUBeta(np.nan), ValueError, "n must be an integer >= 2 .* got nan"),
    ("FPU size as text", lambda p: FPUBeta("8"), ValueError,
     "n must be an integer >= 2 .* got '8'"),
    ("FPU size beyond memory", lambda p: FPUBeta(10 ** 12), ValueError,
     r"model FPUBeta\(n=1000000000000, beta=1.5\) \(1000000000000 degrees of freedom\) needs "
     r"about 43.7 TiB of memory, but .* is available"),
    ("model n_dof fractional", lambda p: Model(2.5, _potential, _grad, _hess, _third, 1),
     ValueError, "n_dof must be a positive integer, got 2.5"),
    ("model n_dof as text", lambda p: Model("2", _potential, _grad, _hess, _third, 1),
     ValueError, "n_dof must be a positive integer, got '2'"),
    ("model bandwidth negative", lambda p: Model(2, _potential, _grad, _hess, _third, -1),
     ValueError, "bandwidth must be an integer >= 0, got -1"),
    # -- splitting schemes
    ("register a name, not a scheme", lambda p: varint.register_scheme("SBAB9"), ValueError,
     "register_scheme needs a SplittingScheme or CompositionScheme, got str 'SBAB9'; build one with"),
    ("register a registered name", lambda p: varint.register_scheme("sbab2c"), ValueError,
     "'sbab2c' is already registered, get it with get_scheme"),
    ("register None", lambda p: varint.register_scheme(None), ValueError,
     "register_scheme needs a SplittingScheme or CompositionScheme, got NoneType None"),
    ("scheme coefficient NaN", lambda p: scheme(drifts=(np.nan,)), ValueError,
     r"scheme 'LF': drifts\[0\] must be a finite real number, got nan"),
    ("scheme coefficients NaN summing to NaN",
     lambda p: scheme(drifts=(0.5, np.nan, -np.nan), kicks=(0.5, 0.0)), ValueError,
     r"scheme 'LF': drifts\[1\] must be a finite real number, got nan"),
    ("scheme coefficient infinite", lambda p: scheme(kicks=(np.inf,)), ValueError,
     r"scheme 'LF': kicks\[0\] must be a finite real number, got inf"),
    ("scheme coefficient as text", lambda p: scheme(kicks=("1",)), ValueError,
     r"scheme 'LF': kicks\[0\] must be a finite real number, got '1'"),
    ("scheme coefficients not a sequence", lambda p: scheme(kicks=1.0), ValueError,
     "scheme 'LF': kicks must be a sequence of numbers, got 1.0"),
    ("scheme order NaN", lambda p: scheme(order=np.nan), ValueError,
     "scheme 'LF': order must be a positive integer, got nan"),
    ("scheme order fractional", lambda p: scheme(order=2.5), ValueError,
     "scheme 'LF': order must be a positive integer, got 2.5"),
    ("scheme order zero", lambda p: scheme(order=0), ValueError,
     "scheme 'LF': order must be a positive integer, got 0"),
    ("scheme corrector as text", lambda p: scheme(corrector="abc"), ValueError,
     "scheme 'LF': corrector must be a finite number .* got 'abc'"),
    ("scheme corrector NaN", lambda p: scheme(corrector=np.nan), ValueError,
     "scheme 'LF': corrector must be a finite number .* got nan"),
    ("scheme layout flag as text", lambda p: scheme(drift_first="yes"), ValueError,
     "scheme 'LF': drift_first must be True .* got 'yes'"),
    ("scheme without a name", lambda p: scheme(name=""), ValueError,
     "a scheme's name must be a non-empty string, got ''"),
    # -- formulas (the command line's --potential): hostile and malformed text
    ("formula calling __import__", lambda p: formula("__import__('os').system('touch x')"),
     ValueError, "--potential: .*__import__\\('os'\\).system. is attribute access"),
    ("formula with a dunder name", lambda p: formula("__builtins__"), ValueError,
     "'__builtins__' is not a coordinate, constant or function"),
    ("formula with attribute access", lambda p: formula("x.real"), ValueError,
     "'x.real' is attribute access, which is not allowed; allowed: numbers, x, y"),
    ("formula with a lambda", lambda p: formula("(lambda: 0)()"), ValueError,
     "'lambda: 0' is a lambda"),
    ("formula with a comprehension", lambda p: formula("[x for x in (1,)]"), ValueError,
     "is a comprehension"),
    ("formula with a generator", lambda p: formula("sum(x for x in (1,))"), ValueError,
     "'sum' is not an allowed function"),
    ("formula calling a non-whitelisted name", lambda p: formula("eval('1')"), ValueError,
     "'eval' is not an allowed function"),
    ("formula with a keyword argument", lambda p: formula("sin(x=1)"), ValueError,
     "'sin\\(x=1\\)' passes keyword arguments"),
    ("formula with the wrong arity", lambda p: formula("atan2(x)"), ValueError,
     "gives atan2 1 argument; it takes 2"),
    ("formula with a subscript", lambda p: formula("x[0]"), ValueError, "'x\\[0\\]' is indexing"),
    ("formula with text", lambda p: formula("'abc'"), ValueError, "is text, not a real number"),
    ("formula with a comparison", lambda p: formula("x < y"), ValueError, "is a comparison"),
    ("formula with floor division", lambda p: formula("x // 2"), ValueError, "uses '//'"),
    ("formula with a huge tower of powers", lambda p: formula("9**9**9**9"), ValueError,
     "'9\\*\\*9\\*\\*9' has an exponent of magnitude above 1000"),
    ("formula with a huge exponent", lambda p: formula("x**100000"), ValueError,
     "exponent of magnitude above 1000"),
    ("formula with a power beyond a double", lambda p: formula("10**309"), ValueError,
     "'10\\*\\*309' is a number beyond the range of a double"),
    ("formula with an infinite literal", lambda p: formula("1e999*x"), ValueError,
     "'1e999' is not a finite number"),
    ("formula with a huge integer", lambda p: formula("1" + "0" * 400), ValueError,
     "is a number beyond the range of a double"),
    ("formula dividing by zero", lambda p: formula("x/(y-y)"), ValueError,
     "'y-y' is a divisor that is zero"),
    ("formula that is not finite", lambda p: formula("x + 0**-1"), ValueError,
     "is not finite"),
    ("formula very long", lambda p: formula("x+" * 6000 + "x"), ValueError,
     "--potential is 12001 characters long; at most 10000 are read"),
    ("formula nested too deeply", lambda p: formula("sin(" * 110 + "x" + ")" * 110), ValueError,
     "is nested more than 100 levels deep"),
    ("formula with too many nested parentheses", lambda p: formula("(" * 250 + "x" + ")" * 250),
     ValueError, "too many nested parentheses"),
    ("formula with a chain too long to parse", lambda p: formula("x-" * 3000 + "x"), ValueError,
     "too deeply nested or has too many operators in one chain"),
    ("formula with a unicode minus", lambda p: formula("x \u2212 y"), ValueError,
     "invalid character '\u2212' \\(U\\+2212\\)"),
    ("formula with a NUL byte", lambda p: formula("x\0"), ValueError, "null bytes"),
    ("formula empty", lambda p: formula("  "), ValueError, "--potential is empty"),
    ("formula not a string", lambda p: formula(3), ValueError,
     "--potential must be a string, got int 3"),
    ("formula with a near-miss name", lambda p: formula("e**x"), ValueError,
     "'e' is not a coordinate, constant or function \\(did you mean 'E'\\?\\)"),
    ("formula coordinate a keyword", lambda p: formula("x", ("x", "lambda")), ValueError,
     "'lambda' is reserved"),
    ("formula coordinate twice", lambda p: formula("x", ("x", "x")), ValueError,
     "names 'x' twice"),
    ("formula coordinates as one string", lambda p: formula("x", "xy"), ValueError,
     "must be a sequence of names, got the string 'xy'"),
    # -- output files, sizes and the arguments of runs (validators for the run loop)
    ("output file in a missing directory", lambda p: check.output_file(p / "no" / "x.csv", "--csv"),
     ValueError, "--csv .*x.csv: directory .*no does not exist"),
    ("output file a directory", lambda p: check.output_file(p, "--csv"), ValueError,
     "is a directory; expected a file path"),
    ("output file under a file", lambda p: check.output_file("/etc/passwd/x.csv", "--csv"),
     ValueError, "/etc/passwd is not a directory"),
    ("output file in /proc", lambda p: check.output_file("/proc/version", "--csv"), ValueError,
     "cannot write --csv /proc/version: it is a file of a virtual file system"),
    ("output file empty", lambda p: check.output_file("", "--csv"), ValueError,
     "--csv must name a file, got ''"),
    ("output file with a NUL", lambda p: check.output_file("a\0b", "--csv"), ValueError,
     "contains a NUL byte"),
    ("output file as bytes", lambda p: check.output_file(b"x.csv", "--csv"), ValueError,
     "--csv must be a file path, got bytes"),
    ("output file named too long", lambda p: check.output_file(p / ("x" * 300), "--csv"),
     ValueError, "cannot write --csv .*: File name too long"),
    ("memory beyond the machine", lambda p: check.check_memory(2 ** 80, "a grid of 2**40 points"),
     ValueError, "a grid of 2\\*\\*40 points needs about .* PiB of memory, but .* is available"),
    ("steps beyond the counter", lambda p: check.step_count(1e300, 0.05), ValueError,
     "t_end / tau = 1e\\+300 / 0.05 = 2e\\+301 steps, more than"),
    ("a name as the model", lambda p: check.model("henon-heiles"), ValueError,
     "model must be a varint model \\(e.g. varint.models.HenonHeiles\\(\\), .* got str "
     "'henon-heiles'"),
    ("a name as the Dask client", lambda p: check.dask_client("local"), ValueError,
     "client must be a dask.distributed.Client or None, got str 'local'"),
    ("an option of another method", lambda p: check.method_options(
        "tm", {"rtol": 1e-9}, ("scheme", "parallel", "fast_indicators"),
        {"cvode": ("rtol", "atol"), "dop853": ("delta", "rtol", "atol")}), TypeError,
     "unknown option 'rtol' for method 'tm'; valid options: scheme, parallel, fast_indicators "
     "\\('rtol' is an option of cvode, dop853\\)"),
    # -- round 2: step counts, sizes and memory, before any allocation
    ("t_end beyond the step counter", lambda p: run(t_end=1e300, tau=0.05), ValueError,
     r"t_end / tau = 1e\+300 / 0.05 = 2e\+301 steps, more than the 4.61e\+18 a run can take"),
    ("t_end beyond the counter with the automatic step", lambda p: run(t_end=1e300),
     ValueError, r"t_end / tau = 1e\+300 / 1 = 1e\+300 steps, more than"),
    ("tau too small for the counter", lambda p: run(tau=1e-300), ValueError,
     r"t_end / tau = 10 / 1e-300 = 1e\+301 steps"),
    ("tau the smallest double", lambda p: run(tau=5e-324), ValueError,
     r"t_end / tau = 10 / 4.94066e-324 = inf steps, more than"),
    ("three outputs of a run beyond the counter", lambda p: run(t_end=1e300, tau=0.05, t_out=3),
     ValueError, "steps, more than the 4.61e\\+18 a run can take"),
    ("more outputs than steps", lambda p: run(t_out=10 ** 9, tau=0.05), ValueError,
     "t_out = 1000000000 output times, more than the 200 steps of the run "
     r"\(t_end / tau = 10 / 0.05\); give at most 200"),
    ("output count as a huge float", lambda p: run(t_out=1e20, tau=0.05), ValueError,
     "t_out = 100000000000000000000 output times, more than the 200 steps"),
    ("output count boolean", lambda p: run(t_out=True), ValueError,
     "t_out as a count must be a positive integer, got True"),
    ("records beyond memory", lambda p: run(x0=np.tile(X0, (10 ** 4, 1)), t_end=1e5, tau=0.05,
                                            t_out=10 ** 6), ValueError,
     r"a run of 10000 orbit\(s\) of HenonHeiles with 4 deviation vectors and 1000000 output "
     "times needs about .* of memory, but .* is available"),
    ("deviation vectors beyond memory", lambda p: run(model=FPUBeta(10 ** 5), x0=np.zeros(
        2 * 10 ** 5)), ValueError,
     r"a run of 1 orbit\(s\) of FPUBeta\(n=100000, beta=1.5\) with 200000 deviation vectors "
     "needs about 1.16 TiB of memory"),
    ("a section grid beyond memory", lambda p: varint.section_grid(
        HH, 0.125, np.linspace(0, 1, 10 ** 6), np.linspace(0, 1, 10 ** 6)), ValueError,
     r"a section grid of 1000000 x 1000000 = 1000000000000 points needs about"),
    ("a surface of section of too many orbits", lambda p: varint.surface_of_section(
        HH, np.broadcast_to(X0, (10 ** 6, 4)), 10.0), ValueError,
     "surface_of_section of 1000000 orbits of HenonHeiles needs about"),
    ("a map beyond memory", lambda p: varint.chaos_map(
        HH, np.broadcast_to(X0, (2 * 10 ** 10, 4)), t_end=10.0), ValueError,
     r"initial_conditions of shape \(20000000000, 4\) \(as float64\) needs about 596 GiB"),
    ("a section of more steps than the counter", lambda p: varint.surface_of_section(
        HH, X0, 1e300), ValueError, "steps, more than the 4.61e\\+18"),
    ("a map of more steps than the counter", lambda p: varint.chaos_map(
        HH, [X0, X0], t_end=1e300, tau=0.05), ValueError, "steps, more than"),
    # -- round 2: types of the run arguments
    ("model None", lambda p: run(model=None), ValueError, "model must be a varint model"),
    ("model a name in a map", lambda p: varint.chaos_map("henon-heiles", [X0], t_end=10.0),
     ValueError, "model must be a varint model .* got str 'henon-heiles'"),
    ("model a name in a section", lambda p: varint.surface_of_section("hh", X0, 10.0),
     ValueError, "model must be a varint model"),
    ("model a name in select_scheme", lambda p: varint.select_scheme("hh", X0, 1e-6),
     ValueError, "model must be a varint model"),
    ("model a name in departure", lambda p: varint.departure("hh", X0, "tm", 0.05, 100.0),
     ValueError, "model must be a varint model"),
    ("Dask client a name", lambda p: varint.chaos_map(HH, [X0, X0], t_end=10.0, client="local"),
     ValueError, "client must be a dask.distributed.Client or None, got str 'local'"),
    ("Dask client an address", lambda p: varint.chaos_map(
        HH, [X0, X0], t_end=10.0, client=("tcp://localhost", 8786)), ValueError,
     "client must be a dask.distributed.Client or None, got tuple"),
    ("indicator a number", lambda p: varint.run(HH, X0, 3, 10.0), ValueError,
     "unknown indicator 3; expected one of"),
    ("indicator None", lambda p: varint.run(HH, X0, None, 10.0), ValueError,
     "unknown indicator None"),
    ("method None", lambda p: run(method=None), ValueError, "unknown method None; expected"),
    ("method a number", lambda p: run(method=3), ValueError, "unknown method 3"),
    ("scheme a number", lambda p: run(scheme=3), ValueError, "unknown scheme 3; expected one of"),
    ("scheme unknown with the automatic step", lambda p: run(fn=varint.sali, scheme="RK4"),
     ValueError, "unknown scheme 'RK4'"),
    ("seed as text", lambda p: run(seed="1"), ValueError,
     "seed must be a non-negative integer or None, got '1'"),
    ("seed NaN", lambda p: run(seed=np.nan), ValueError, "seed must be .* got nan"),
    ("errors None", lambda p: run(errors=None), ValueError,
     "unknown errors None; expected one of: raise, flag"),
    ("energy_tol zero", lambda p: run(energy_tol=0.0), ValueError,
     "energy_tol must be a positive number .* got 0.0"),
    ("energy_tol negative", lambda p: run(energy_tol=-1e-3), ValueError,
     "energy_tol must be a positive number .* got -0.001"),
    ("energy_tol NaN", lambda p: run(energy_tol=np.nan), ValueError,
     "energy_tol must be a positive number .* got nan"),
    ("energy_tol as text", lambda p: run(energy_tol="1e-3"), ValueError,
     "energy_tol must be a positive number .* got '1e-3'"),
    ("energy_tol of a map boolean", lambda p: varint.chaos_map(HH, [X0, X0], t_end=10.0,
                                                               energy_tol=True), ValueError,
     "energy_tol must be a positive number .* got True"),
    ("t_end as text", lambda p: run(t_end="100"), ValueError,
     "t_end must be a finite number, got '100'"),
    ("t_end infinite with the automatic step", lambda p: run(t_end=np.inf), ValueError,
     "t_end must be a finite number, got inf"),
    ("t_end zero with the automatic step", lambda p: run(t_end=0.0), ValueError,
     "t_end must be > 0 \\(a run takes at least one step\\), got 0.0"),
    ("t_end boolean", lambda p: run(t_end=True, tau=0.05), ValueError,
     "t_end must be a finite number, got True"),
    ("tau an array", lambda p: run(tau=np.array([0.05, 0.1])), ValueError,
     "tau must be a positive finite number, got array"),
    ("x0 as a dict", lambda p: run(x0={"x": 0.0}), ValueError,
     r"x0 must hold real numbers, got \{'x': 0.0\} \(dict\)"),
    ("x0 as one string", lambda p: run(x0="0,0.1,0.2,0"), ValueError,
     "x0 must be an array of real numbers, got dtype <U"),
    ("n_exponents a NumPy integer above 2N", lambda p: run(n_exponents=np.int64(5)),
     ValueError, r"n_exponents must be in 1\.\.4 \(2N for this model\), got 5"),
    ("GALI order fractional", lambda p: run(fn=varint.gali, k=(2.5,)), ValueError,
     "GALI order"),
    ("local-exponent window NaN", lambda p: varint.run(HH, X0, "local_exponents", 10.0,
                                                        window=np.nan), ValueError,
     "window must be a positive finite time"),
    ("zero deviation vectors", lambda p: run(fn=varint.gali, k=2, deviations=np.zeros((4, 2))),
     ValueError, "deviations of orbit 0 are linearly dependent"),
    ("checkpoint interval as text", lambda p: run(checkpoint=p / "c", checkpoint_interval="60"),
     ValueError, "checkpoint_interval must be a finite number of seconds >= 0, got '60'"),
    ("t_out times beyond t_end with the automatic step", lambda p: run(t_out=[1.0, 20.0]),
     ValueError, r"t_out must lie in \[tau, t_end\] = \(0, 10.0\], got 1.0..20.0"),
    ("t_out times with NaN", lambda p: run(t_out=[1.0, np.nan]), ValueError,
     "t_out must be a non-empty array of finite times"),
    ("t_out empty", lambda p: run(t_out=[]), ValueError,
     "t_out must be a non-empty array of finite times"),
    # -- round 2: initial states where V or its derivatives are singular
    ("a state on the singularity of 1/x", lambda p: run(model=INVERSE_X, x0=[0.0, 0.1, 0.1, 0.0]),
     ValueError, r"the derivatives of V \(1/x\) are not finite at the initial state, "
     r"q = \[0.0, 0.1\]: the gradient ∇V is \[-inf, 0.1\]"),
    ("a batch with one singular state", lambda p: run(model=INVERSE_X, x0=[[1.0, 0.1, 0.1, 0.0],
                                                                          [0.0, 0.1, 0.1, 0.0]]),
     ValueError, "not finite at the initial state of orbit 1, q = \\[0.0, 0.1\\]"),
    ("log x at x < 0", lambda p: run(model=LOG_X, x0=[-1.0, 0.1, 0.0, 0.0]), ValueError,
     r"the potential of log x is not finite at the initial state, q = \[-1.0, 0.1\] "
     r"\(energy = nan\)"),
    ("sqrt x at x < 0", lambda p: run(model=SQRT_X, x0=[-1.0, 0.1, 0.0, 0.0]), ValueError,
     r"are not finite at the initial state, q = \[-1.0, 0.1\]: the gradient ∇V is \[nan"),
    ("an overflowing exponential", lambda p: run(model=EXP_X, x0=[1.0, 0.1, 0.0, 0.0]),
     ValueError, "the gradient ∇V is \\[inf"),
    ("a singular point in a map", lambda p: varint.chaos_map(
        INVERSE_X, [[1.0, 0.1, 0.1, 0.0], [0.5, 0.0, 0.0, 0.0], [0.0, 0.2, 0.0, 0.1]],
        t_end=10.0), ValueError,
     "not finite at initial condition of orbit 2, q = \\[0.0, 0.2\\]"),
    ("a singular state in select_scheme", lambda p: varint.select_scheme(
        INVERSE_X, [0.0, 0.1, 0.1, 0.0], 1e-6), ValueError, "are not finite at the initial state"),
    ("a singular state in a section", lambda p: varint.surface_of_section(
        INVERSE_X, [0.0, 0.1, 0.1, 0.0], 10.0), ValueError, "are not finite at the initial state"),
    ("a singular state in departure", lambda p: varint.departure(
        INVERSE_X, [0.0, 0.1, 0.1, 0.0], "tm", 0.05, 100.0), ValueError,
     "are not finite at the initial state"),
    ("a model whose kernels fail to compile", lambda p: run(model=Model(
        2, _potential, _grad_two_args, _hess, _third, 1, name="two-args")), TypeError,
     "the kernels of model 'two-args' could not be compiled"),
    ("inverse mass infinite", lambda p: Model(2, _potential, _grad, _hess, _third, 1,
                                              inverse_mass=[1.0, np.inf]), ValueError,
     "inverse_mass must be positive and finite; got inf at index 1"),
    # -- round 2: maps
    ("map chunk size zero", lambda p: varint.chaos_map(HH, [X0, X0], t_end=10.0, chunk_size=0),
     ValueError, "chunk_size must be a positive integer, got 0"),
    ("map chunk size fractional", lambda p: varint.chaos_map(HH, [X0, X0], t_end=10.0,
                                                             chunk_size=2.5), ValueError,
     "chunk_size must be a positive integer, got 2.5"),
    ("map threshold as text", lambda p: varint.chaos_map(HH, [X0, X0], t_end=10.0,
                                                         threshold="none"), ValueError,
     "threshold must be a finite number, None or 'default', got 'none'"),
    ("map threshold NaN", lambda p: varint.chaos_map(HH, [X0, X0], t_end=10.0,
                                                     threshold=np.nan), ValueError,
     "threshold must be a finite number"),
    ("map check times empty", lambda p: varint.chaos_map(HH, [X0, X0], t_end=10.0, t_check=[]),
     ValueError, "t_check must be a non-empty array of finite times"),
    ("map check times beyond t_end", lambda p: varint.chaos_map(HH, [X0, X0], t_end=10.0,
                                                                t_check=[5.0, 50.0]), ValueError,
     r"t_check must lie in \[tau, t_end\]"),
    ("map progress as text", lambda p: varint.chaos_map(HH, [X0, X0], t_end=10.0,
                                                        progress="yes"), ValueError,
     "progress must be True, False or None, got 'yes'"),
    ("map option misspelt", lambda p: varint.chaos_map(HH, [X0, X0], t_end=10.0, shceme="ABA864"),
     TypeError, "unknown option 'shceme' for method 'tm'"),
    ("map seed negative", lambda p: varint.chaos_map(HH, [X0, X0], t_end=10.0, seed=-3),
     ValueError, "seed must be a non-negative integer, got -3"),
    ("map of a grid of another model", lambda p: varint.chaos_map(
        varint.models.ThreeDof(), HH_GRID, t_end=10.0), ValueError,
     r"the section grid's states must have shape \(6,\) or \(M, 6\) for ThreeDof"),
    ("map escape radius infinite", lambda p: varint.chaos_map(HH, [X0, X0], t_end=10.0,
                                                              escape_radius=np.inf), ValueError,
     "escape_radius must be a positive finite number, got inf"),
    # -- round 2: sections and grids
    ("section plane out of range", lambda p: varint.surface_of_section(HH, X0, 10.0, plane=5),
     ValueError, r"plane must be a coordinate index in 0\.\.1, got 5"),
    ("section direction 2", lambda p: varint.surface_of_section(HH, X0, 10.0, direction=2),
     ValueError, "direction must be 1, -1 or 0, got 2"),
    ("section max_points zero", lambda p: varint.surface_of_section(HH, X0, 10.0, max_points=0),
     ValueError, "max_points must be a positive integer, got 0"),
    ("section value NaN", lambda p: varint.surface_of_section(HH, X0, 10.0, value=np.nan),
     ValueError, "value must be a finite number, got nan"),
    ("section energy_tol negative", lambda p: varint.surface_of_section(HH, X0, 10.0,
                                                                        energy_tol=-1.0),
     ValueError, "energy_tol must be a positive number"),
    ("grid energy NaN", lambda p: varint.section_grid(HH, np.nan, [0.1], [0.1]), ValueError,
     "energy must be a finite number, got nan"),
    ("grid axis with NaN", lambda p: varint.section_grid(HH, 0.125, [0.1, np.nan], [0.1]),
     ValueError, "u must be a non-empty array of finite values"),
    ("grid base infinite", lambda p: varint.section_grid(HH, 0.125, [0.1], [0.1],
                                                         base=[0, 0, np.inf, 0]), ValueError,
     "base must be finite, got"),
    ("momentum for an infinite energy", lambda p: solve_momentum(HH, [0.0, 0.1], [0.0, 0.0],
                                                                np.inf), ValueError,
     "energy must be finite, got inf"),
    # -- round 2: select_scheme and departure
    ("candidate of an unknown method", lambda p: varint.select_scheme(
        HH, X0, 1e-6, candidates=[("rk4", None, 0.1)]), ValueError,
     "unknown method 'rk4'; expected one of"),
    ("candidate of an unknown scheme", lambda p: varint.select_scheme(
        HH, X0, 1e-6, candidates=[("tm", "SABA9", 0.1)]), ValueError, "unknown scheme 'SABA9'"),
    ("candidates a string", lambda p: varint.select_scheme(HH, X0, 1e-6, candidates="tm"),
     ValueError, "candidates must be a list of \\(method, scheme or None, tau\\), got 'tm'"),
    ("select t_end shorter than a pilot", lambda p: varint.select_scheme(HH, X0, 1e-6, t_end=0.5),
     ValueError, "t_end = 0.5 is shorter than the shortest pilot, 0.8"),
    ("select target zero", lambda p: varint.select_scheme(HH, X0, 0.0), ValueError,
     "target_error must be a positive finite number, got 0.0"),
    ("select k above 2N", lambda p: varint.select_scheme(HH, X0, 1e-6, k=9), ValueError,
     r"k must be in 0\.\.4"),
    ("select a batch", lambda p: varint.select_scheme(HH, [X0, X0], 1e-6), ValueError,
     r"x0 must be one state of shape \(4,\)"),
    ("departure of an unknown method", lambda p: varint.departure(HH, X0, "rk4", 0.05, 100.0),
     ValueError, "unknown method 'rk4'"),
    ("departure reference not a dict", lambda p: varint.departure(HH, X0, "tm", 0.05, 100.0,
                                                                  reference="tm"), ValueError,
     "reference must be a dict with a 'method' name, got 'tm'"),
    ("departure reference of an unknown method", lambda p: varint.departure(
        HH, X0, "tm", 0.05, 100.0, reference={"method": "nope"}), ValueError,
     "unknown reference method 'nope'"),
    ("departure GALI order 1", lambda p: varint.departure(HH, X0, "tm", 0.05, 100.0,
                                                          gali_orders=(1,)), ValueError,
     r"GALI order must be in 2\.\.4"),
    ("departure GALI orders a number", lambda p: varint.departure(HH, X0, "tm", 0.05, 100.0,
                                                                  gali_orders=5), ValueError,
     "gali_orders must be a sequence of GALI orders"),
    ("departure per_decade zero", lambda p: varint.departure(HH, X0, "tm", 0.05, 100.0,
                                                             per_decade=0), ValueError,
     "per_decade must be a positive integer, got 0"),
    ("departure of a batch", lambda p: varint.departure(HH, [X0, X0], "tm", 0.05, 100.0),
     ValueError, r"x0 must be one state of shape \(4,\)"),
    ("departure steps beyond the counter", lambda p: varint.departure(HH, X0, "tm", 1e-300,
                                                                      100.0), ValueError,
     "steps, more than"),
    # -- round 2: paths
    ("checkpoint in a missing directory", lambda p: run(checkpoint=p / "no" / "c.ckpt"),
     varint.CheckpointError, "does not exist"),
    ("checkpoint in /proc", lambda p: run(checkpoint="/proc/version"), varint.CheckpointError,
     "/proc/version"),
    ("map checkpoint a file", lambda p: map_into_a_file(p), varint.CheckpointError,
     "cannot use .* as a chaos map checkpoint directory"),
]


def test_the_table_has_at_least_25_distinct_cases():
    assert len({name for name, *_ in CASES}) == len(CASES) >= 25


@pytest.mark.parametrize("call, exception, message", [case[1:] for case in CASES],
                         ids=[case[0] for case in CASES])
def test_bad_input_is_refused_before_any_kernel_runs(call, exception, message, tmp_path,
                                                     monkeypatch):
    # Cases that write a checkpoint first run once; count only the last call.
    calls = hook_advance(monkeypatch, "tm", 10 ** 9, lambda: None)
    with pytest.raises(exception, match=message) as err:
        call(tmp_path)
    assert type(err.value).__module__.split(".")[0] in ("builtins", "varint")
    if calls and not isinstance(err.value, varint.CheckpointError):
        pytest.fail(f"a kernel ran before the input was refused ({len(calls)} calls)")


def test_available_memory_reads_meminfo_else_sysconf(monkeypatch):
    with open("/proc/meminfo") as f:
        total = next(int(line.split()[1]) * 1024 for line in f if line.startswith("MemTotal:"))
    free = check.available_memory()
    assert isinstance(free, int) and 0 < free <= total

    def unreadable(*args, **kwargs):
        raise OSError("no /proc here")

    # Without /proc/meminfo (nor cgroup files): the free physical pages.
    monkeypatch.setattr(check, "open", unreadable, raising=False)
    pages = os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    assert abs(check.available_memory() - pages) < 2 ** 30


def test_check_memory_names_what_and_how_much(monkeypatch):
    monkeypatch.setattr(check, "available_memory", lambda: 3 * 2 ** 30)
    check.check_memory(2 ** 30, "a small run")
    with pytest.raises(ValueError, match=r"^a big run needs about 7.28 TiB of memory, but 3 GiB "
                                         r"is available$"):
        check.check_memory(check.array_bytes((10 ** 12,)), "a big run")
    monkeypatch.setattr(check, "available_memory", lambda: None)
    check.check_memory(2 ** 80, "anything, when the memory is unknown")


def test_the_tables_hold_at_least_150_bad_api_inputs():
    # This table, plus the concurrent uses below.
    assert len(CASES) >= 150


def test_maps_sharing_a_checkpoint_directory_from_two_threads_agree(tmp_path):
    """Two threads run the same map into one checkpoint directory at once:
    chunk files are written atomically, so each map is complete and both
    equal a map computed alone; the directory then resumes the map."""
    import threading

    grid = varint.section_grid(HH, 0.125, np.linspace(-0.4, 0.6, 12), np.linspace(-0.4, 0.4, 12))
    kw = dict(t_end=50.0, tau=0.05, chunk_size=16, progress=False)
    alone = varint.chaos_map(HH, grid, "sali", **kw)
    out, errors = {}, []

    def work(i):
        try:
            out[i] = varint.chaos_map(HH, grid, "sali", checkpoint=tmp_path / "map", **kw)
        except Exception as exc:  # reported below, with the thread
            errors.append((i, exc))

    threads = [threading.Thread(target=work, args=(i,)) for i in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors
    for r in out.values():
        assert r.values.tobytes() == alone.values.tobytes()
    again = varint.chaos_map(HH, grid, "sali", checkpoint=tmp_path / "map", **kw)
    assert again.provenance.options["chunks_resumed"] == again.provenance.options["chunks"]
    assert again.values.tobytes() == alone.values.tobytes()


def test_runs_in_threads_give_the_results_of_runs_alone():
    """The run loop shares nothing between calls: runs with and without
    the automatic step, in four threads at once, give bitwise the serial
    results. (The two indicators whose kernels this file's checkpoint
    cases compile: what the loop shares or not is the same for all.)"""
    from concurrent.futures import ThreadPoolExecutor

    r1 = paper_orbit("R1")
    jobs = [(varint.sali, HH, X0, {"tau": 0.05}), (varint.lyapunov_spectrum, *r1, {}),
            (varint.sali, *r1, {}), (varint.lyapunov_spectrum, HH, X0, {"tau": 0.1})]
    serial = [fn(m, x0, 200.0, **kw) for fn, m, x0, kw in jobs]
    with ThreadPoolExecutor(4) as pool:
        threaded = list(pool.map(lambda j: j[0](j[1], j[2], 200.0, **j[3]), jobs))
    for a, b in zip(serial, threaded, strict=True):
        assert a.provenance.tau == b.provenance.tau
        assert a.energy_error.tobytes() == b.energy_error.tobytes()


def test_a_map_refuses_a_directory_holding_another_map_even_when_resuming(tmp_path):
    """A map at a given τ, then the same map with the automatic step (whose
    pilot chooses another τ) into its directory: refused, naming τ. The
    scheme given to both, as the default map's (SBAB2C): the pilot then
    runs the SIMD lanes of the map above's stepper, not those of the maps'
    pilot scheme (SRKN14a, 17 CPU s cold; test_cli's map, in this file's
    xdist unit, compiles those anyway)."""
    grid = varint.section_grid(HH, 0.125, np.linspace(-0.4, 0.6, 4), np.linspace(-0.4, 0.4, 4))
    kw = dict(t_end=20.0, checkpoint=tmp_path / "m", progress=False, scheme="SBAB2C")
    varint.chaos_map(HH, grid, "sali", tau=0.05, **kw)
    with pytest.raises(varint.CheckpointError, match=r"holds a chaos map with other "
                                                     r"parameters: .*tau \(checkpoint: 0.05,"):
        varint.chaos_map(HH, grid, "sali", **kw)


def test_one_vector_is_independent_where_svd_says_so():
    # One column: its length stands for its singular value (no SVD); the
    # verdicts are the SVD's, a subnormal column included.
    W = np.ones((4, 4, 1))
    W[2] = 0.0
    W[3] = 1e-310
    with pytest.raises(ValueError, match="deviations of orbit 2 are linearly dependent"):
        check.full_rank(W)
    s = np.linalg.svd(W, compute_uv=False)
    assert list(s[:, -1] / np.maximum(s[:, 0], np.finfo(float).tiny) > 1e-12) == \
        [True, True, False, True]
    check.full_rank(W[[0, 1, 3]])


@pytest.mark.parametrize("value", [0.0, 5e-324, 1e-320, 1e-310, 2.3e-308, 1.0, 1e300, 1e305,
                                   1.7e308, np.inf, np.nan])
def test_one_vector_verdict_is_the_svds_in_every_range_of_its_largest_entry(value):
    # The one-column check skips the length where the largest entry lies in
    # [tiny, 1e300]; at and beyond both ends it computes it: either way
    # the verdict is the SVD's (NaN and inf refused, as there), whichever
    # orbit of the batch holds the column.
    col = np.array([value, -value / 3, 0.0, value / 7])
    W = np.ones((3, 4, 1))
    W[1, :, 0] = col
    with np.errstate(all="ignore"):
        s = np.linalg.svd(W[1:2], compute_uv=False) if np.isfinite(col).all() else \
            np.full((1, 1), np.nan)
        independent = bool(s[0, -1] / max(s[0, 0], np.finfo(float).tiny) > 1e-12)
    if independent:
        check.full_rank(W)
        check.full_rank(W[1:2])
    else:
        with pytest.raises(ValueError, match="deviations of orbit 1 are linearly dependent"):
            check.full_rank(W)


def test_one_vector_with_one_nan_entry_is_refused_like_an_all_nan_one():
    # The largest entry propagates NaN (as max does): no pass for a column
    # whose other entries are fine.
    W = np.ones((2, 4, 1))
    W[1, 1, 0] = np.nan
    with pytest.raises(ValueError, match="deviations of orbit 1 are linearly dependent"):
        check.full_rank(W)


@pytest.mark.parametrize("power, kernel", [(0.5, "the gradient"), (1.5, "the Hessian"),
                                           (2.5, "the third derivatives")])
def test_the_compiled_pass_finds_the_first_state_where_one_kernel_is_not_finite(power, kernel):
    # x^p at x = 0: only ∇V (p = 1/2), only D²V (3/2) or only the third
    # derivatives (5/2) are infinite; the pass over 1000 states (beyond
    # those checked from Python) stops at the first of two such states.
    xs, ys = sp.symbols("x y")
    model = varint.models.from_potential(xs**power + ys**2, [xs, ys],
                                         name=f"x^{power} + y^2")
    X = np.tile([1.0, 0.1, 0.0, 0.0], (1000, 1))
    X[:, 0] += np.linspace(0.0, 0.5, 1000)
    X[[700, 900], 0] = 0.0
    with pytest.raises(ValueError, match=f"orbit 700, q = \\[0.0, 0.1\\]: {kernel}"):
        check.kernels(model, X)
    check.kernels(model, X[:700])

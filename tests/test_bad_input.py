"""Bad input, tried: a table of wrong arguments across the public API. Each
must raise the stated exception with a message naming the problem, before
any compiled kernel runs (so no numba typing error, segfault or traceback
from inside a kernel can reach the user). Damaged checkpoint and cache
files are tried at more length in test_faults.py."""

import numpy as np
import pytest
import sympy as sp

import varint
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

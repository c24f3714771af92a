"""The stepping skeleton's closure kernels are cached on disk under a key
that names what they are compiled from: the same key in every process, a
new one when anything compiled in changes, none for a user's own function
(varint.kernels.closures, issue 28)."""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from numba import njit
from numba.core import caching

from varint.kernels import parts as P
from varint.kernels.closures import _ClosureCache, closure_key
from varint.models import fput, kg

ROOT = Path(__file__).resolve().parent.parent

KEY_OF_KG = ("from varint.kernels.parts import parts_batch; "
             "from varint.kernels.closures import closure_key; from varint.models import kg; "
             "print(closure_key(parts_batch(kg._apply, kg._field, 2, False)))")


def fresh(code):
    """Run ``code`` in a new interpreter on this source tree; its last line."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    done = subprocess.run([sys.executable, "-c", code], env=env, check=True,
                          capture_output=True, text=True)
    return done.stdout.strip().splitlines()[-1]


def test_a_kernel_has_the_same_key_in_every_process():
    here = closure_key(P.parts_batch(kg._apply, kg._field, 2, False))
    assert fresh(KEY_OF_KG) == fresh(KEY_OF_KG) == here


def test_the_key_changes_with_what_is_compiled_in():
    def key(apply=kg._apply, field=kg._field, k=2, parallel=False, flow=False):
        return closure_key(P.parts_batch(apply, field, k, parallel, flow=flow))

    keys = [key(), key(k=1), key(flow=True), key(apply=fput._apply, field=fput._field)]
    assert len(set(keys)) == len(keys)
    # In parallel the same kernel runs on threads: nothing else is compiled.
    assert P.parts_batch(kg._apply, kg._field, 2, True).kernel is P.parts_batch(
        kg._apply, kg._field, 2, False)


@njit
def _users_update(aux, r, x, W, flow, t):
    aux[0, 0] += r[0]


def test_a_users_function_keeps_the_kernel_in_memory():
    ours = P.parts_batch(kg._apply, kg._field, 1, False)
    theirs = P.parts_batch(kg._apply, kg._field, 1, False, accumulate=_users_update)
    assert isinstance(ours._cache, _ClosureCache)
    assert isinstance(theirs._cache, caching.NullCache)


def test_a_second_process_runs_a_lattice_without_compiling():
    """The part stepper of a lattice, compiled by one process, is loaded by
    the next, which compiles nothing and gets the same bits."""
    code = ("import json, varint; from varint import compiling; "
            "m = varint.models.DisorderedKG(16, seed=1); x = m.initial_block(width=4, seed=1); "
            "r = varint.lyapunov_spectrum(m, x, t_end=2.0, tau=0.1, progress=False); "
            "print(json.dumps([compiling.compile_seconds(), r.exponents.tobytes().hex()]))")
    _, first = json.loads(fresh(code))
    compiled, second = json.loads(fresh(code))
    assert compiled == 0.0
    assert second == first


def test_a_generated_modules_function_is_named_by_its_module(tmp_path, monkeypatch):
    """A function of a generated module read from its verified file is
    named by the module (a hash of its source's inputs) and its code; one
    compiled in memory, named for this process only, is not."""
    from varint import codecache
    from varint.kernels.closures import Unnamed, _describe

    monkeypatch.setenv("VARINT_CACHE_DIR", str(tmp_path))

    def source():
        return "from numba import njit\n@njit\ndef f(x):\n    return 2 * x\n"

    on_disk = codecache.load_module("varint_test_named_0123", "kernels", source)
    in_memory = codecache.load_module("varint_test_named_4567", "kernels", source,
                                      on_disk=False)
    if not codecache.named_by_file(on_disk.f.py_func):
        pytest.skip("no usable cache directory here")
    description = _describe(on_disk.f)
    assert "varint_test_named_0123" in repr(description)
    assert not codecache.named_by_file(in_memory.f.py_func)
    with pytest.raises(Unnamed):
        _describe(lambda x: x)                                  # a function of the user's


def test_a_second_process_runs_tdh_without_compiling():
    """The TDH kernels close over the generated stepper of their orbit (a
    module in the cache directory): compiled by one process, they are
    loaded by the next, which compiles nothing and gets the same bits."""
    code = ("import json, varint; from varint import compiling; "
            "m, x = varint.paper_orbit('R1'); "
            "r = varint.megno(m, x, t_end=1.0, tau=0.05, method='tdhes', progress=False); "
            "print(json.dumps([compiling.compile_seconds(), r.megno.tobytes().hex()]))")
    _, first = json.loads(fresh(code))
    compiled, second = json.loads(fresh(code))
    assert compiled == 0.0
    assert second == first


def test_arrays_over_immutable_bytes_are_named_by_content():
    """An array whose memory is a bytes object (a compiled right-hand
    side's parameters) is named by its content; any other array could
    change after it is named, and is not."""
    from varint.kernels.closures import Unnamed, _describe

    def frozen(values):
        return np.frombuffer(np.asarray(values, dtype=np.float64).tobytes())

    assert _describe(frozen([1.0, 2.0])) == _describe(frozen([1.0, 2.0]))
    assert _describe(frozen([1.0, 2.0])) != _describe(frozen([1.0, 3.0]))
    assert _describe(frozen([1.0, 2.0])) != _describe(frozen([1.0, 2.0]).reshape(2, 1))
    writable = np.array([1.0, 2.0])
    with pytest.raises(Unnamed):
        _describe(writable)
    writable.flags.writeable = False        # read-only now, writable again at will
    with pytest.raises(Unnamed):
        _describe(writable)


def test_a_second_process_runs_dop853_without_compiling():
    """The DOP853 engine is compiled into its orbit kernel with the model's
    right-hand side: the generated one (Hénon–Heiles) and the one from a
    model's kernels and parameters (a time-dependent potential). Compiled
    by one process, both are loaded by the next, which compiles nothing and
    gets the same bits."""
    code = ("import json, sympy as sp, varint; from varint import compiling; "
            "from varint.models import from_potential; "
            "m, x = varint.paper_orbit('R1'); q, t = sp.symbols('q t'); "
            "forced = from_potential(-sp.cos(q) * (1 + sp.cos(t) / 5), [q], time=t); "
            "kw = dict(t_end=1.0, tau=0.05, method='dop853', progress=False); "
            "a = varint.lyapunov_spectrum(m, x, **kw).exponents; "
            "b = varint.lyapunov_spectrum(forced, [0.0, 2.0], **kw).exponents; "
            "print(json.dumps([compiling.compile_seconds(), a.tobytes().hex(), "
            "b.tobytes().hex()]))")
    first = json.loads(fresh(code))
    second = json.loads(fresh(code))
    assert second[0] == 0.0
    assert second[1:] == first[1:]

"""A kernel called through the compiled version its first call selected
(:class:`varint.kernels.resolved.Resolved`) gives the dispatcher's bits,
and keeps the dispatch where that call converted its arguments."""

import numpy as np
from numba import njit

import varint
from varint.kernels.resolved import Resolved


@njit(cache=False)
def _scaled_sum(x, factor, out):
    total = 0.0
    for v in x:
        total += v * factor
    out[0] = total


# Compiled for arrays of any layout only: C-contiguous arguments are
# converted to it, no version has their exact types.
@njit("void(float64[:], float64, float64[:])", cache=False)
def _any_layout(x, factor, out):
    out[0] = x.sum() * factor


def test_later_calls_run_the_compiled_version_of_the_first_with_the_same_bits():
    x = np.random.default_rng(0).standard_normal(17)
    out, expected = np.zeros(1), np.zeros(1)
    call = Resolved(_scaled_sum)
    call(x, 0.1, out)
    assert call._entry is _scaled_sum.overloads[_scaled_sum.signatures[0]].entry_point
    for factor in (0.3, -2.5):
        call(x, factor, out)
        _scaled_sum(x, factor, expected)
        assert out.tobytes() == expected.tobytes()


def test_a_converting_first_call_keeps_the_dispatch():
    x, out = np.arange(5.0), np.zeros(1)
    call = Resolved(_any_layout)
    call(x, 2.0, out)
    call(x, 2.0, out)
    assert call._entry is None and out[0] == 20.0


def test_a_plain_function_is_called_as_it_is():
    def plain(x):
        return x

    assert Resolved.of(plain) is plain
    assert isinstance(Resolved.of(_scaled_sum), Resolved)


def test_a_prepared_runs_short_calls_skip_the_dispatch():
    # The stepper, the kernel check and the energy errors of a prepared
    # one-step call run their compiled versions after the first short call
    # (the results are the one-shot call's, bitwise:
    # tests/test_prepared_short.py).
    model, x0 = varint.paper_orbit("R1")
    run = varint.prepare(model, "integrate", 0.05, tau=0.05, scheme="s15odr8",
                         deviations=np.eye(4)[:, :1])
    run(x0)
    run(x0)
    a = run(x0 + [0.0, 0.0, 1e-3, 0.0])
    assert run._again.short._run()._kernel._entry is not None
    # Hénon–Heiles' T is the base model's over 2 degrees of freedom: the
    # energy errors are the kernel that computes T with them.
    assert run._again.short.state_kernel is not None
    assert run._again.short.state_kernel._entry is not None
    assert all(r._entry is not None for r in run._again.kernel_check._resolved)
    b = varint.integrate(model, x0 + [0.0, 0.0, 1e-3, 0.0], 0.05, tau=0.05, scheme="s15odr8",
                         deviations=np.eye(4)[:, :1])
    assert a.state.tobytes() == b.state.tobytes()
    assert a.deviations.tobytes() == b.deviations.tobytes()

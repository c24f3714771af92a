"""varint.floating_errors: the handling inside is np.errstate(all="ignore")'s
from any handling outside, and the handling outside comes back."""

import threading
import warnings

import numpy as np
import pytest

from varint import floating_errors


def _inside_errstate():
    with np.errstate(all="ignore"):
        return np.geterr(), np.geterrcall(), np.getbufsize()


def _inside_ignoring():
    token = floating_errors.ignoring()
    try:
        return np.geterr(), np.geterrcall(), np.getbufsize()
    finally:
        floating_errors.restore(token)


def _outside():
    return np.geterr(), np.geterrcall(), np.getbufsize()


def _call(*args):
    pass


@pytest.mark.parametrize("outside", [
    {},
    {"all": "raise"},
    {"over": "warn", "invalid": "raise", "under": "print"},
    {"all": "call", "call": _call},
])
def test_the_handling_inside_is_errstates_and_outside_comes_back(outside):
    with np.errstate(**outside):
        before = _outside()
        # Twice: the second from the object the first made.
        assert _inside_ignoring() == _inside_errstate()
        assert _inside_ignoring() == _inside_errstate()
        assert _outside() == before


def test_the_buffer_size_of_the_moment_is_kept():
    old = np.setbufsize(16384)
    try:
        assert _inside_ignoring() == _inside_errstate()
        assert _inside_ignoring()[2] == 16384
    finally:
        np.setbufsize(old)
    assert _inside_ignoring()[2] == old


def test_errors_inside_raise_and_warn_nothing_and_outside_they_do_again():
    big = np.array([1e308])
    with np.errstate(all="raise"):
        token = floating_errors.ignoring()
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("error")
                assert np.isinf(big * 10.0)[0] and np.isnan(np.array([np.inf]) - np.inf)[0]
        finally:
            floating_errors.restore(token)
        with pytest.raises(FloatingPointError):
            big * 10.0


def test_each_thread_has_its_own_handling():
    # A thread that ignores errors leaves another thread's handling alone.
    entered, checked = threading.Event(), threading.Event()
    seen = {}

    def quiet():
        token = floating_errors.ignoring()
        entered.set()
        checked.wait(10)
        seen["quiet"] = np.geterr()
        floating_errors.restore(token)

    thread = threading.Thread(target=quiet)
    with np.errstate(all="raise"):
        thread.start()
        entered.wait(10)
        seen["main"] = np.geterr()
        checked.set()
        thread.join()
    assert set(seen["main"].values()) == {"raise"}
    assert set(seen["quiet"].values()) == {"ignore"}

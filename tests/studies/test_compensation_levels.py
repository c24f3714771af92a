"""The compensation levels' quick mode (C2 to t = 1e3, s35odr10 at τ = 0.25
and 0.2, prepared runs, heyoka beside them)."""

import pytest

from studies import compensation_levels as cl


@pytest.fixture(scope="module")
def result(tmp_path_factory):
    return cl.main(["--quick", "--out", str(tmp_path_factory.mktemp("levels"))])


def test_orbit_level_is_full_compensation_s_orbit_and_reaches_1e_10(result):
    """compensated="orbit" computes full compensation's orbit bit for bit,
    so the state's error is the same number; at τ = 0.2 the vector's error
    is within a factor 2 of full compensation's and below 1e-10, which
    plain summation misses (round-off: 1.5e-10)."""
    rows = {(r["level"], r["tau"]): r for r in result["rows"] if r["contender"] == "varint"}
    for tau in cl.QUICK_TAUS:
        assert rows["+co", tau]["error_state"] == rows["+c", tau]["error_state"]
    assert rows["+co", 0.2]["error"] < min(1e-10, 2 * rows["+c", 0.2]["error"])
    assert rows["plain", 0.2]["error"] > 1e-10
    assert {r["contender"] for r in result["costs"]} == {"plain", "+co", "+cs", "+c", "heyoka"}


def test_step_level_reaches_1e_10_where_plain_summation_does_not(result):
    """compensated="step" (the orbit's displacement over each step added
    compensated, the stages and the vector plain) at τ = 0.2 reaches a
    global error below 1e-10 (measured 4.0e-11; "orbit" 1.7e-11), which
    plain summation misses (round-off: 1.5e-10), with another orbit than
    full compensation's (other roundings)."""
    rows = {(r["level"], r["tau"]): r for r in result["rows"] if r["contender"] == "varint"}
    assert rows["+cs", 0.2]["error"] < 1e-10 < rows["plain", 0.2]["error"]
    assert rows["+cs", 0.2]["error_state"] != rows["+c", 0.2]["error_state"]

"""Shared fixtures: the paper's orbits, built once per session."""

import pytest

import varint


@pytest.fixture(scope="session")
def r1():
    return varint.paper_orbit("R1")


@pytest.fixture(scope="session")
def c1():
    return varint.paper_orbit("C1")

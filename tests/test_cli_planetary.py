"""``varint map --model planetary``: the registered two-planet model and
its grid of the outer planet's orbital elements (no integration here; the
maps themselves are tested in test_planetary_runs.py)."""

import numpy as np
import pytest

from varint import cli
from varint.models import Planetary
from varint.models.planetary import JUPITER_SATURN
from varint.models.registry import get_model


def _grid(argv):
    args = cli.build_parser().parse_args(["map", "--model", "planetary", *argv])
    model, _ = cli._model(args)
    return model, cli._grid(args, model)


def test_registry_builds_the_star_and_two_planets_with_the_given_masses():
    model = get_model("planetary").build(m2=1e-3)
    assert isinstance(model, Planetary)
    assert model.masses.tolist() == [1.0, 9.54e-4, 1e-3]


def test_grid_points_have_the_outer_planets_elements_they_name():
    """Round trip: the elements read back from every grid state are the
    grid's values (outer planet) and Jupiter's (inner planet)."""
    model, grid = _grid(["--m1", "1e-3", "--u", "7:10:4", "--v", "0:0.4:3"])
    assert model.masses[1] == 1e-3
    assert grid.axes == ("a", "e") and grid.states.shape == (12, 12)
    for k, x in enumerate(grid.states):
        inner, outer = model.to_elements(x)
        assert outer[:2] == pytest.approx([grid.u[k % 4], grid.v[k // 4]], abs=1e-12)
        assert inner[:2] == pytest.approx([JUPITER_SATURN[0]["a"], JUPITER_SATURN[0]["e"]],
                                          abs=1e-12)
    np.testing.assert_allclose(grid.u, np.linspace(7, 10, 4))


def test_grid_over_other_elements():
    _, grid = _grid(["--axes", "a,inc", "--u", "8:9:2", "--v", "0:0.2:2"])
    assert grid.axes == ("a", "inc")
    model = get_model("planetary").build()
    assert model.to_elements(grid.states[-1])[1][2] == pytest.approx(0.2, abs=1e-12)


@pytest.mark.parametrize("argv, words", [
    (["--energy", "-1"], "--energy does not apply to --model planetary"),
    (["--plane", "1"], "--plane does not apply to --model planetary"),
    (["--axes", "a,x"], "--axes: two different orbital elements"),
    (["--axes", "e,e"], "--axes: two different orbital elements"),
])
def test_bad_planetary_grid_options_are_refused_in_one_line(capsys, argv, words):
    code = cli.main(["map", "--model", "planetary", "--indicator", "megno", *argv])
    err = capsys.readouterr().err
    assert code != 0 and words in err and len(err.strip().splitlines()) == 1, err

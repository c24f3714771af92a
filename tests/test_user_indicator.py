"""An indicator registered by a user (README's worked example) works in
single runs, in chaos maps and with another method, with no other change."""

import numpy as np
import pytest

import varint
from varint.indicators import INDICATORS, Indicator
from varint.results import IndicatorResult


def _read_angle(rows, model, t, options):
    w1, w2 = rows.W[:, :, 0], rows.W[:, :, 1]
    chord = np.minimum(np.linalg.norm(w1 - w2, axis=1), np.linalg.norm(w1 + w2, axis=1))
    return {"angle": 2 * np.arcsin(chord / 2)}


@pytest.fixture(scope="module")
def angle():
    name = "user_angle"
    if name not in INDICATORS:
        varint.register_indicator(Indicator(
            name=name, summary="smaller angle between two unit deviation vectors",
            renorm="normalize", vectors=lambda model, options, given: 2, read=_read_angle,
            result=IndicatorResult, require="unit",
            scalar=lambda record, model, options: record["angle"], threshold=1e-8))
    return name


def test_laws_in_a_single_run(angle):
    """The angle closes like SALI, ∝ exp(−(χ1 − χ2) t), on the chaotic C1,
    and stays open on the regular R1 (a 2-torus: two tangent directions)."""
    model, c1 = varint.paper_orbit("C1")
    _, r1 = varint.paper_orbit("R1")
    chaotic = varint.run(model, c1, angle, t_end=2e3, t_out=np.array([1e3, 2e3]))
    regular = varint.run(model, r1, angle, t_end=2e3, t_out=np.array([1e3, 2e3]))
    assert isinstance(chaotic, IndicatorResult)
    assert chaotic["angle"][-1] < 1e-8
    assert regular["angle"].min() > 1e-3
    # SALI of the same vectors: min(|w1 ± w2|) = 2 sin(angle / 2).
    sali = varint.sali(model, r1, t_end=2e3, t_out=np.array([1e3, 2e3]))
    np.testing.assert_allclose(2 * np.sin(regular["angle"] / 2), sali.sali, rtol=1e-12)


def test_in_a_chaos_map_as_in_single_runs(angle):
    """The map's value of each orbit is the single run's last value, bit
    for bit (same seeds: orbit m draws from default_rng([seed, m]); the
    same step, given: a map's automatic step has defaults of its own)."""
    model = varint.models.HenonHeiles()
    x0 = np.array([varint.paper_orbit("R1")[1], varint.paper_orbit("C1")[1]])
    m = varint.chaos_map(model, x0, angle, t_end=300.0, tau=0.05, threshold=None)
    one = varint.run(model, x0, angle, t_end=300.0, tau=0.05, t_out=np.array([300.0]))
    np.testing.assert_array_equal(m.values, one["angle"][:, -1])


def test_with_the_taylor_reference(angle):
    """Another method computes it with no change: heyoka's Taylor
    integrator agrees with TM to the TM error on the regular R1 at t = 50."""
    model, r1 = varint.paper_orbit("R1")
    t_out = np.array([25.0, 50.0])
    tm = varint.run(model, r1, angle, t_end=50.0, t_out=t_out, tau=0.01)
    ty = varint.run(model, r1, angle, t_end=50.0, t_out=t_out, tau=0.01, method="taylor")
    np.testing.assert_allclose(tm["angle"], ty["angle"], rtol=1e-6)


def test_early_stopping_reads_renormalised_vectors(angle):
    """With early stopping the map reads every orbit at every check time
    (renormalised copies of vectors that the stepper renormalises only
    when needed): the regular orbit's value is the single run's, bit for
    bit, and the chaotic one is stopped below the threshold."""
    model = varint.models.HenonHeiles()
    x0 = np.array([varint.paper_orbit("R1")[1], varint.paper_orbit("C1")[1]])
    m = varint.chaos_map(model, x0, angle, t_end=1500.0, tau=0.05)
    one = varint.run(model, x0[0], angle, t_end=1500.0, tau=0.05, t_out=np.array([1500.0]))
    assert m.values[0] == one["angle"][-1]
    assert m.decided[1] and m.values[1] < 1e-8


def test_a_declared_map_tolerance_sets_the_maps_pilot():
    """An indicator that declares ``map_tolerance`` has its maps' step
    chosen to that energy error; the step is smaller than at the maps'
    default tolerance (error ∝ τ^p), and a meaningless tolerance is refused
    when the indicator is built."""
    from varint.maps import MAP_PILOT_TOL

    fields = dict(summary="smaller angle", renorm="normalize",
                  vectors=lambda model, options, given: 2, read=_read_angle,
                  result=IndicatorResult, require="unit",
                  scalar=lambda record, model, options: record["angle"])
    if "user_angle_tight" not in INDICATORS:
        varint.register_indicator(Indicator(name="user_angle_tight", map_tolerance=1e-10,
                                            **fields))
    model = varint.models.HenonHeiles()
    grid = varint.section_grid(model, 0.125, np.linspace(-0.3, 0.5, 4), np.linspace(-0.3, 0.3, 4))
    tight = varint.chaos_map(model, grid, "user_angle_tight", t_end=50.0, progress=False)
    fli = varint.chaos_map(model, grid, "fli", t_end=50.0, progress=False)
    assert tight.provenance.tau_choice["tolerance"] == 1e-10
    assert fli.provenance.tau_choice["tolerance"] == MAP_PILOT_TOL
    assert tight.provenance.tau < fli.provenance.tau
    for bad in (0.0, -1e-8, float("inf"), "1e-8"):
        with pytest.raises(ValueError, match="map_tolerance must be a positive finite"):
            Indicator(name="bad_tolerance", map_tolerance=bad, **fields)

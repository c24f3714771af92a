"""Every plot kind, rendered headless (Agg) and checked for what a reader
relies on: the axes' scales and labels, the colour map and its special
colours, the legend (issue 32: lattice results drew seven series on one
linear axis, ensembles and batches raised, a map drew SALI = 0 in the
colour of the forbidden region, map axes were x/p_x whatever the model,
MEGNO maps were linear)."""

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

import varint  # noqa: E402
from varint import plotting  # noqa: E402


@pytest.fixture(autouse=True)
def _close():
    yield
    plt.close("all")


def _rendered(fig, tmp_path):
    path = tmp_path / "figure.png"
    fig.savefig(path, dpi=60)
    assert path.stat().st_size > 2000
    return path


def test_a_lattice_result_is_log_log_panels(tmp_path):
    kg = varint.models.DisorderedKG(32, W=4.0, seed=1)
    r = varint.run(kg, kg.initial_block(3, 0.4), "dvd", 20.0, 0.2, scheme="ABA864")
    axes = r.plot()
    assert [a.get_title() for a in axes] == ["finite-time mLCE", "second moment",
                                             "participation number"]
    for ax in axes:
        assert ax.get_xscale() == ax.get_yscale() == "log" and ax.get_xlabel() == "t"
    # m₂ and P of the packet and of the DVD, each in its panel, named.
    assert [t.get_text() for t in axes[1].get_legend().get_texts()] == ["packet", "DVD"]
    assert np.array_equal(axes[1].lines[0].get_ydata(), np.abs(r["m2"]))
    assert np.array_equal(axes[0].lines[0].get_ydata(), np.abs(r["x1"]))
    _rendered(axes[0].figure, tmp_path)
    # "spreading" has no Λ: two panels; into a given Axes's place.
    s = varint.run(kg, kg.initial_block(3, 0.4), "spreading", 20.0, 0.2, scheme="ABA864")
    fig, ax = plt.subplots()
    axes = s.plot(ax=ax)
    assert len(axes) == 2 and len(fig.axes) == 2 and axes[0].get_yscale() == "log"


def test_an_ensemble_is_mean_and_spread(tmp_path):
    e = varint.ensemble(varint.models.DDNLS, range(3),
                        lambda m, s: m.initial_block(3, 1.0, seed=s), "dvd", 10.0, tau=0.1,
                        params={"shape": 24, "W": 4, "beta": 0.04}, scheme="s9ABC6",
                        progress=False)
    axes = e.plot()
    assert len(axes) == 3
    mean, std, _ = e.log_mean("m2")
    line = axes[1].lines[0]
    assert np.allclose(line.get_ydata(), 10 ** mean)
    # The band is ± one standard deviation of log10 over realisations.
    band = axes[1].collections[0].get_paths()[0].vertices[:, 1]
    assert np.isclose(band.max(), np.max(10 ** (mean + std)))
    assert "3 realisations" in axes[1].get_title()
    assert all(a.get_yscale() == "log" for a in axes)
    _rendered(axes[0].figure, tmp_path)


@pytest.mark.parametrize("kind", ["lyapunov", "gali", "megno"])
def test_a_batch_is_overlaid(kind, r1, tmp_path):
    model, x0 = r1
    batch = varint.run(model, np.array([x0, x0 * 0.9, x0 * 0.8]), kind, 20.0, tau=0.05)
    ax = batch.plot()
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert any(lab.startswith("orbit 2:") for lab in labels)
    assert sum(lab.startswith("orbit 0:") for lab in labels) >= 1
    # The laws of regular motion once, not once per orbit.
    dashed = [line for line in ax.lines if line.get_linestyle() == "--"]
    assert len(dashed) <= (3 if kind == "gali" else 1)
    _rendered(ax.figure, tmp_path)


def _sali_map_with_zeros():
    sm = varint.models.StandardMap(1.2)
    grid = varint.phase_grid(sm, np.linspace(0, 2 * np.pi, 12), np.linspace(-np.pi, np.pi, 10))
    m = varint.chaos_map(sm, grid, "sali", t_end=3000, threshold=None)
    assert (m.values == 0).any(), "the test needs orbits whose SALI reached 0"
    return m


def test_a_map_colours_zero_apart_from_the_outside_and_names_the_axes(tmp_path):
    m = _sali_map_with_zeros()
    ax = m.plot()
    mesh = ax.collections[0]
    cmap = mesh.get_cmap()
    under, bad = cmap.get_under(), cmap.get_bad()
    assert matplotlib.colors.to_hex(under) != matplotlib.colors.to_hex(bad)
    assert matplotlib.colors.to_hex(under) == matplotlib.colors.to_hex(plotting.ZERO_COLOR)
    # Zeros are below the colour scale (drawn in the "under" colour), not NaN.
    data = mesh.get_array()
    zeros = m.image()[m.mask] == 0
    assert (data.compressed()[zeros] < mesh.norm.vmin).all()
    assert "SALI = 0" in [t.get_text() for t in ax.get_legend().get_texts()]
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("$x$", "$p$")
    assert "log$_{10}$ SALI" in ax.figure.axes[-1].get_ylabel()
    _rendered(ax.figure, tmp_path)


def test_a_map_carries_its_indicators_log_scale_through_a_file(tmp_path):
    # The map records Indicator.log_scale, so that drawing it needs nothing
    # of the indicator registry; SALI's survives save and load, and a map
    # saved before it was recorded (None) is drawn by the spread of values.
    m = _sali_map_with_zeros()
    assert m.log_scale is varint.indicators.get_indicator("sali").log_scale is True
    m.save(tmp_path / "m.npz")
    back = varint.load_result(tmp_path / "m.npz")
    assert back.log_scale is True
    assert "log$_{10}$ SALI" in back.plot().figure.axes[-1].get_ylabel()
    sm = varint.models.StandardMap(0.5)
    grid = varint.phase_grid(sm, np.linspace(0.5, 1.0, 3), np.linspace(0.1, 0.3, 2))
    narrow = varint.chaos_map(sm, grid, "megno", t_end=50)
    assert narrow.log_scale is False
    narrow.log_scale = None
    assert "log" not in narrow.plot().figure.axes[-1].get_ylabel()


def test_a_section_map_shows_the_forbidden_region_in_its_own_colour(tmp_path):
    model = varint.models.HenonHeiles()
    grid = varint.section_grid(model, 0.125, np.linspace(-0.45, 0.7, 12),
                               np.linspace(-0.45, 0.45, 10))
    m = varint.chaos_map(model, grid, "sali", t_end=50.0, tau=0.05)
    ax = m.plot()
    assert "outside the allowed region" in [t.get_text() for t in ax.get_legend().get_texts()]
    data = ax.collections[0].get_array()
    assert data.mask.sum() == (~m.mask).sum()       # the outside is masked ("bad")
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("$y$", "$p_{y}$")
    _rendered(ax.figure, tmp_path)


def test_a_coupled_map_and_a_sympy_model_name_their_own_axes():
    cm = varint.models.CoupledStandardMaps(1.5, 1.5, 0.1)
    grid = varint.phase_grid(cm, np.linspace(0, 1, 4), np.linspace(0, 1, 3), axes=(0, 2))
    ax = varint.chaos_map(cm, grid, "x1", t_end=20).plot()
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("$x_{1}$", "$x_{3}$")
    import sympy as sp

    u, w = sp.symbols("u w")
    model = varint.models.from_potential((u**2 + w**2) / 2 + u**2 * w, [u, w])
    s = varint.surface_of_section(model, [0.0, 0.1, 0.3, 0.0], 50.0)
    ax = s.plot()
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("$w$", "$p_{w}$")


def test_megno_maps_go_log_when_they_span_decades():
    """A few strongly chaotic orbits (MEGNO in the hundreds) next to
    regular ones (≈ 2): a linear scale would show all regular orbits in
    one colour."""
    values = np.r_[np.full(50, 2.0) + np.linspace(0, 0.1, 50), [400.0, 900.0]]
    assert plotting._spans_decades(values)
    assert not plotting._spans_decades(np.linspace(1.9, 8.0, 50))
    assert not plotting._spans_decades(np.r_[values, -1.0])
    sm = varint.models.StandardMap(2.0)
    grid = varint.phase_grid(sm, np.linspace(0.1, 6, 10), np.linspace(-3, 3, 8))
    m = varint.chaos_map(sm, grid, "megno", t_end=500)
    ax = m.plot()
    label = ax.figure.axes[-1].get_ylabel()
    assert label.startswith("log$_{10}$") == plotting._spans_decades(m.values)
    assert m.plot(log=False).figure.axes[-1].get_ylabel() == "MEGNO"


def test_failed_orbits_of_a_map_have_their_own_colour():
    model = varint.models.HenonHeiles()
    x0 = np.array([[0.0, 0.1, 0.3, 0.0], [0.0, 0.2, 0.25, 0.0], [0.0, 0.0, 0.9, 0.7]])
    with pytest.warns(RuntimeWarning, match="1 of 3 orbits failed"), \
            pytest.warns(varint.AccuracyWarning, match="1 of 3 orbits"):
        m = varint.chaos_map(model, x0, "sali", t_end=200.0, tau=0.05)
    assert (m.status > 0).any()
    ax = m.plot()
    colours = [matplotlib.colors.to_hex(c.get_facecolor()[0]) for c in ax.collections[1:]]
    assert matplotlib.colors.to_hex(plotting.FAILED_COLOR) in colours
    assert "failed" in [t.get_text() for t in ax.get_legend().get_texts()]


def test_an_overlay_draws_the_regular_law_through_the_regular_orbit(r1, c1):
    """The t⁻¹ guide of a batch goes through the orbit with the smallest
    X₁ (R1), not through the first orbit (here the chaotic C1)."""
    model, x_r1 = r1
    _, x_c1 = c1
    batch = varint.lyapunov_spectrum(model, np.array([x_c1, x_r1]), 500.0, tau=0.05)
    ax = batch.plot()
    guide = [line for line in ax.lines if line.get_linestyle() == "--"]
    assert len(guide) == 1
    assert np.isclose(guide[0].get_ydata()[-1], abs(batch.exponents[1, -1, 0]))

"""Results as DataFrames, plots of every result, and the new results saved
and loaded."""

import sys

import matplotlib
import numpy as np
import pytest

import varint
from varint.results import load_result

matplotlib.use("Agg")
pd = pytest.importorskip("pandas")


@pytest.fixture(scope="module")
def results(r1, c1):
    model, x0 = r1
    both = np.array([x0, c1[1]])
    grid = varint.section_grid(model, 0.125, np.linspace(-0.4, 0.6, 5), np.linspace(-0.3, 0.3, 4))
    return {
        "lyapunov": varint.lyapunov_spectrum(model, x0, 5.0, t_out=4),
        "lyapunov_batch": varint.lyapunov_spectrum(model, both, 5.0, t_out=4, n_exponents=2),
        "gali": varint.gali(model, x0, 5.0, t_out=3, k=(2, 4)),
        "sali_batch": varint.sali(model, both, 5.0, t_out=3),
        "megno": varint.megno(model, x0, 5.0, t_out=4),
        "integrate": varint.integrate(model, x0, 5.0, t_out=5),
        "section": varint.surface_of_section(model, both, 30.0),
        "map": varint.chaos_map(model, grid, "sali", t_end=5.0, progress=False),
    }


def test_time_series_tables(results):
    r = results["lyapunov"]
    df = r.to_dataframe()
    assert list(df.columns) == ["t", "energy_error", "X1", "X2", "X3", "X4"]
    assert np.array_equal(df["X3"], r.exponents[:, 2]) and np.array_equal(df["t"], r.t)
    assert df.attrs["provenance"]["kind"] == "lyapunov"
    b = results["lyapunov_batch"]
    df = b.to_dataframe()
    assert len(df) == 2 * len(b.t) and list(df["orbit"]) == [0] * 4 + [1] * 4
    assert np.array_equal(df["X2"], b.exponents[:, :, 1].ravel())
    df = results["gali"].to_dataframe()
    assert {"gali_2", "gali_4"} <= set(df.columns)
    assert np.array_equal(df["gali_4"], results["gali"].gali[4])
    df = results["sali_batch"].to_dataframe()
    assert np.array_equal(df["sali"], results["sali_batch"].sali.ravel())
    df = results["megno"].to_dataframe()
    assert {"megno", "mean_megno", "fli", "ofli"} <= set(df.columns)
    df = results["integrate"].to_dataframe()
    assert {"q0", "q1", "p0", "p1"} <= set(df.columns)
    assert np.array_equal(df["p1"], results["integrate"].states[:, 3])


def test_section_and_map_tables(results):
    s = results["section"]
    df = s.to_dataframe()
    assert len(df) == s.n_points.sum()
    assert np.array_equal(df[df.orbit == 1]["q1"], s.points[1, :s.n_points[1], 1])
    m = results["map"]
    df = m.to_dataframe()
    assert len(df) == len(m.values) and np.array_equal(df["value"], m.values)
    assert np.array_equal(df["q1"], m.x0[:, 1])


def test_pandas_missing_is_said(results, monkeypatch):
    monkeypatch.setitem(sys.modules, "pandas", None)
    with pytest.raises(ImportError, match="needs pandas: pip install pandas"):
        results["sali_batch"].to_dataframe()


@pytest.mark.parametrize("name", ["lyapunov", "gali", "megno", "integrate", "section", "map"])
def test_every_result_plots(results, name):
    import matplotlib.pyplot as plt

    ax = results[name].plot()
    assert ax.has_data()
    plt.close("all")


def test_batch_plots_overlay_their_orbits(results):
    import matplotlib.pyplot as plt

    batch = results["sali_batch"]
    ax = batch.plot()
    assert len(ax.lines) == len(batch.status)
    for m, line in enumerate(ax.lines):
        assert np.array_equal(line.get_ydata(), batch.sali[m])
    assert [t.get_text() for t in ax.get_legend().get_texts()][:2] == ["orbit 0: SALI",
                                                                    "orbit 1: SALI"]
    plt.close("all")
    ax = batch.plot(orbit=1)
    assert np.array_equal(ax.lines[0].get_ydata(), results["sali_batch"].sali[1])
    plt.close("all")


@pytest.mark.parametrize("name", ["section", "map"])
def test_new_results_save_and_load(results, name, tmp_path):
    r = results[name]
    r.save(tmp_path / "r.npz")
    back = load_result(tmp_path / "r.npz")
    assert type(back) is type(r)
    for field in ("points", "values", "t_stop", "mask", "u", "status", "energy_error"):
        if hasattr(r, field):
            assert np.array_equal(getattr(back, field), getattr(r, field), equal_nan=True)
    if name == "map":
        assert back.axes == [1, 3] and back.indicator == "sali" and back.threshold == 1e-8
        assert np.array_equal(back.image(), r.image(), equal_nan=True)


def test_gali_guides_are_in_the_legend_and_keep_the_axis_to_the_data():
    """A short GALI run: the t⁻² and t⁻⁴ laws of regular motion are drawn
    and named in the legend, and they do not stretch the y-axis beyond the
    decades the GALIs span (t⁻⁴ over three decades would reach 1e12)."""
    import matplotlib.pyplot as plt

    model, x0 = varint.paper_orbit("R1")
    g = varint.gali(model, x0, 10.0, tau=0.05, k=(2, 3, 4))
    ax = g.plot()
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert r"$\propto t^{-2}$" in labels and r"$\propto t^{-4}$" in labels
    values = np.concatenate([g.gali[k] for k in (2, 3, 4)])
    low, high = ax.get_ylim()
    assert high <= 10 * values.max() and low >= values.min() / 10
    plt.close("all")


def test_the_lyapunov_guide_is_in_the_legend():
    import matplotlib.pyplot as plt

    model, x0 = varint.paper_orbit("R1")
    ax = varint.lyapunov_spectrum(model, x0, 100.0, tau=0.05).plot()
    assert r"$\propto t^{-1}$" in [t.get_text() for t in ax.get_legend().get_texts()]
    plt.close("all")

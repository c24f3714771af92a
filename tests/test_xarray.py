"""Every result class as an xarray Dataset: named dimensions with their
coordinates, the same numbers as the result's arrays, the provenance in the
attributes; the DataFrame is the same variables flattened; netCDF holds it."""

import json
import sys

import numpy as np
import pytest

import varint
from varint.results import _CLASSES, Provenance

xr = pytest.importorskip("xarray")
pd = pytest.importorskip("pandas")

LABELS = ["q0", "q1", "p0", "p1"]


@pytest.fixture(scope="module")
def results(r1, c1):
    # The same runs as tests/test_tables.py where possible, so that the
    # compiled kernels are shared within a test session.
    model, x0 = r1
    both = np.array([x0, c1[1]])
    grid = varint.section_grid(model, 0.125, np.linspace(-0.4, 0.6, 5), np.linspace(-0.3, 0.3, 4))
    return {
        "LyapunovResult": varint.lyapunov_spectrum(model, x0, 5.0, t_out=4),
        "LyapunovResult/batch": varint.lyapunov_spectrum(model, both, 5.0, t_out=4,
                                                         n_exponents=2),
        "GALIResult": varint.gali(model, x0, 5.0, t_out=3, k=(2, 4)),
        "SALIResult": varint.sali(model, both, 5.0, t_out=3),
        "MEGNOResult": varint.megno(model, x0, 5.0, t_out=4),
        "IntegrationResult": varint.integrate(model, x0, 5.0, t_out=5, deviations=np.eye(4)),
        "IndicatorResult": varint.run(model, x0, "fli", 5.0, t_out=3),
        "LocalExponentsResult": varint.run(model, x0, "local_exponents", 20.0, window=5.0,
                                           n_exponents=2),
        "SectionResult": varint.surface_of_section(model, both, 30.0),
        "SectionResult/single": varint.surface_of_section(model, x0, 30.0),
        "ChaosMapResult": varint.chaos_map(model, grid, "sali", t_end=5.0, progress=False),
        "ChaosMapResult/orbits": varint.chaos_map(model, both, "sali", t_end=5.0,
                                                  progress=False),
        "EnsembleResult": varint.ensemble(
            varint.models.DDNLS, range(2), lambda m, s: m.initial_block(3, 1.0, seed=s),
            "dvd", 2.0, tau=0.1, params={"shape": 16, "W": 4, "beta": 0.04}, progress=False),
    }


def test_every_result_class_is_covered(results):
    """A new result class must be added to the fixture above."""
    covered = {type(r).__name__ for r in results.values()}
    assert set(_CLASSES) <= covered, set(_CLASSES) - covered


@pytest.mark.parametrize("name", ["LyapunovResult", "SectionResult", "ChaosMapResult",
                                  "LocalExponentsResult"])
def test_provenance_in_the_attributes(results, name):
    r = results[name]
    ds = r.to_xarray()
    assert Provenance(**json.loads(ds.attrs["provenance"])) == r.provenance
    assert ds.attrs["result"] == type(r).__name__
    assert ds.attrs["method"] == r.provenance.method and ds.attrs["tau"] == r.provenance.tau
    assert ds.attrs["varint_version"] == varint.__version__
    assert all(isinstance(v, (str, int, float)) for v in ds.attrs.values())


def test_lyapunov_spectrum(results):
    r = results["LyapunovResult"]
    ds = r.to_xarray()
    assert ds.exponents.dims == ("t", "exponent")
    assert np.array_equal(ds.t, r.t) and list(ds.exponent.values) == [1, 2, 3, 4]
    assert np.array_equal(ds.exponents.sel(exponent=3), r.exponents[:, 2])
    assert ds.deviations.dims == ("component", "vector")
    assert list(ds.component.values) == LABELS
    assert np.array_equal(ds.deviations, r.deviations)
    assert np.array_equal(ds.state, r.state) and int(ds.status) == int(r.status)
    b = results["LyapunovResult/batch"]
    ds = b.to_xarray()
    assert ds.exponents.dims == ("orbit", "t", "exponent") and ds.sizes["exponent"] == 2
    assert np.array_equal(ds.exponents.sel(orbit=1, exponent=2), b.exponents[1, :, 1])
    assert np.array_equal(ds.status, b.status) and ds.energy_error.dims == ("orbit", "t")


def test_gali_orders_are_a_dimension(results):
    r = results["GALIResult"]
    ds = r.to_xarray()
    assert ds.gali.dims == ("t", "k") and list(ds.k.values) == [2, 4]
    for k in (2, 4):
        assert np.array_equal(ds.gali.sel(k=k), r.gali[k])


@pytest.mark.parametrize("name, fields", [
    ("SALIResult", ("sali",)),
    ("MEGNOResult", ("megno", "mean_megno", "fli", "ofli")),
])
def test_scalar_series(results, name, fields):
    r = results[name]
    ds = r.to_xarray()
    lead = ("orbit",) if np.ndim(r.status) else ()
    for f in fields:
        assert ds[f].dims == lead + ("t",)
        assert np.array_equal(ds[f], getattr(r, f))


def test_integration_states_and_raw_vectors(results):
    r = results["IntegrationResult"]
    ds = r.to_xarray()
    assert ds.states.dims == ("t", "component")
    assert np.array_equal(ds.states.sel(component="p1"), r.states[:, 3])
    assert ds.deviations.shape == (4, 4) and np.array_equal(ds.deviations, r.deviations)


def test_indicator_result_series_by_name(results):
    r = results["IndicatorResult"]
    ds = r.to_xarray()
    assert ds.fli.dims == ("t",) and np.array_equal(ds.fli, r["fli"])


def test_local_exponents(results):
    r = results["LocalExponentsResult"]
    ds = r.to_xarray()
    for f in ("local", "mean", "std", "minimum", "maximum", "windows"):
        assert ds[f].dims == ("t", "exponent")
        assert np.array_equal(ds[f], getattr(r, f), equal_nan=True)
    assert ds.attrs["window"] == 5.0 and list(ds.exponent.values) == [1, 2]


def test_sections_by_crossing(results):
    r = results["SectionResult"]
    ds = r.to_xarray()
    assert ds.points.dims == ("orbit", "crossing", "component")
    assert np.array_equal(ds.points, r.points, equal_nan=True)
    assert np.array_equal(ds.times, r.times, equal_nan=True)
    assert np.array_equal(ds.n_points, r.n_points)
    assert ds.attrs["plane"] == 0 and ds.attrs["value"] == 0.0
    one = results["SectionResult/single"].to_xarray()
    assert one.points.dims == ("crossing", "component") and float(one.t_end) == 30.0


def test_grid_map_on_its_grid(results):
    r = results["ChaosMapResult"]
    ds = r.to_xarray()
    # Hénon–Heiles section x = 0: u = y (state index 1), v = p_y (index 3).
    assert ds.value.dims == ("p1", "q1")
    assert np.array_equal(ds.q1, r.u) and np.array_equal(ds.p1, r.v)
    assert np.array_equal(ds.value, r.image(), equal_nan=True)
    assert np.array_equal(ds.allowed, r.mask)
    assert np.array_equal(ds.status.values[r.mask], r.status)
    assert np.isnan(ds.status.values[~r.mask]).all()
    index = ds.orbit.values
    assert (index[~r.mask] == -1).all()
    assert np.array_equal(ds.x0.values[r.mask], r.x0[index[r.mask]])
    assert np.array_equal(ds.t_check, r.t) and ds.attrs["indicator"] == "sali"


def test_map_of_orbits(results):
    r = results["ChaosMapResult/orbits"]
    ds = r.to_xarray()
    assert ds.value.dims == ("orbit",) and np.array_equal(ds.value, r.values)
    assert ds.x0.dims == ("orbit", "component") and np.array_equal(ds.x0, r.x0)


@pytest.mark.parametrize("name", ["LyapunovResult/batch", "GALIResult", "SALIResult",
                                  "MEGNOResult",
                                  "IntegrationResult", "LocalExponentsResult",
                                  "IndicatorResult"])
def test_dataframe_is_the_dataset_flattened(results, name):
    r = results[name]
    ds, df = r.to_xarray(), r.to_dataframe()
    rows = ("orbit", "t") if "orbit" in ds.dims else ("t",)
    n = int(np.prod([ds.sizes[d] for d in rows]))
    assert len(df) == n
    for var in ds.data_vars:
        a = ds[var]
        if a.dims[:len(rows)] != rows:
            assert var not in df.columns  # final states and vectors are not per row
            continue
        if a.ndim == len(rows):
            assert np.array_equal(df[var], a.values.ravel(), equal_nan=True)
            continue
        dim = a.dims[-1]
        for c in ds[dim].values:
            column = {("exponents", "exponent"): f"X{c}"}.get((var, dim), f"{var}_{c}")
            column = str(c) if dim == "component" else column
            assert np.array_equal(df[column], a.sel({dim: c}).values.ravel(), equal_nan=True)


def test_netcdf_round_trip(results, tmp_path):
    for name in ("GALIResult", "SectionResult", "ChaosMapResult"):
        ds = results[name].to_xarray()
        path = tmp_path / f"{name}.nc"
        ds.to_netcdf(path)
        back = xr.load_dataset(path)
        for var in ds.data_vars:
            assert np.array_equal(back[var].values, ds[var].values, equal_nan=True), var
        assert back.attrs["provenance"] == ds.attrs["provenance"]


def test_xarray_missing_is_said(results, monkeypatch):
    monkeypatch.setitem(sys.modules, "xarray", None)
    with pytest.raises(ImportError, match=r"needs xarray: pip install xarray .*varint\[xarray\]"):
        results["SALIResult"].to_xarray()

"""Results as labelled data: sweep results as an xarray Dataset (parameters as dimensions, units
as attributes) and a pandas DataFrame, the NetCDF file round trip, time series and measured
records as DataFrames. Synthetic inputs (no simulation), checked against the tables they come
from; the end-to-end sweep of tests/test_sweep.py checks the ``results.nc`` a real sweep writes."""

import numpy as np
import pandas as pd
import pytest
import xarray as xr
from test_cli import _fake_solution

import jaxclear as jc
from jaxclear import io, sweep
from jaxclear._errors import ParameterError

XS, YS = np.array([0.1e-3, 0.25e-3, 0.5e-3]), np.array([0.5, 0.7, 0.9])
MANIFEST = {"config": {"mechanism": {"preset": "flores-slider-crank", "friction": 0.05}, "mode": "grid",
                       "run": {"revolutions": 3.0, "ideal_reference": True}}, "sweep_hash": "abc"}


def _grid_result(missing=(), order=None):
    """3 x 3 grid (clearance slowest), runs listed in ``order``, ``missing`` runs not on disk."""
    X, Y = np.meshgrid(XS, YS, indexing="ij")
    keep = [i for i in (range(9) if order is None else order) if i not in missing]
    table = {"run": np.arange(9)[keep], "clearance": X.ravel()[keep], "restitution": Y.ravel()[keep],
             "t_end_s": np.full(len(keep), 0.036),
             "peak_contact_force_n": (1e4 * (1 + X.ravel() * 1e3) * Y.ravel())[keep],
             "num_steps": (100 + np.arange(9))[keep], "status": np.zeros(len(keep), np.int64),
             "status_message": np.array(["ok"] * len(keep), dtype=object)}
    poincare = np.random.default_rng(0).normal(scale=1e-4, size=(9, 5, 1, 4))[keep]
    return sweep.SweepResult("unused", table, ("clearance", "restitution"), poincare,
                             {"clearance": XS, "restitution": YS}, "grid", manifest=MANIFEST)


def test_grid_dataset_has_parameters_as_dimensions_and_units():
    res = _grid_result(order=[8, 0, 4, 2, 6, 1, 3, 5, 7])  # row order must not matter
    ds = res.to_xarray()
    assert isinstance(ds, xr.Dataset)
    assert ds["peak_contact_force_n"].dims == ("clearance", "restitution")
    np.testing.assert_array_equal(ds["clearance"], XS)
    np.testing.assert_array_equal(ds["restitution"], YS)
    # every cell is the run with those parameter values (the formula the table was made from)
    expected = 1e4 * (1 + XS[:, None] * 1e3) * YS[None, :]
    np.testing.assert_array_equal(ds["peak_contact_force_n"].values, expected)
    assert float(ds["peak_contact_force_n"].sel(clearance=0.25e-3, restitution=0.9)) == expected[1, 2]
    np.testing.assert_array_equal(ds["run"].values, np.arange(9).reshape(3, 3))  # first name slowest
    assert ds["poincare"].dims == ("clearance", "restitution", "section", "joint", "coordinate")
    assert list(ds["coordinate"].values) == list(sweep.POINCARE_COORDS)
    assert ds["peak_contact_force_n"].attrs == {"units": "N", "long_name": "peak contact force"}
    assert ds["clearance"].attrs["units"] == "m" and ds["restitution"].attrs["units"] == "1"
    assert ds["t_end_s"].attrs["units"] == "s"
    assert ds.attrs["sweep_mode"] == "grid" and ds.attrs["revolutions"] == 3.0


def test_grid_dataset_marks_runs_not_on_disk():
    ds = _grid_result(missing=(4,)).to_xarray()
    assert np.isnan(ds["peak_contact_force_n"].values[1, 1]) and np.isnan(ds["poincare"].values[1, 1]).all()
    assert ds["num_steps"].values[1, 1] == -1 and ds["run"].values[1, 1] == -1
    assert ds["status_message"].values[1, 1] == ""
    assert np.isfinite(ds["peak_contact_force_n"].values).sum() == 8


def test_netcdf_round_trip(tmp_path):
    res = _grid_result(missing=(4,))
    ds = res.to_xarray()
    path = sweep.write_netcdf(ds, tmp_path / sweep.NETCDF_NAME)
    back = sweep.open_dataset(tmp_path)  # the folder or the file
    for name in ("peak_contact_force_n", "poincare", "t_end_s"):
        np.testing.assert_array_equal(back[name].values, ds[name].values)  # float64 kept bit for bit
    np.testing.assert_array_equal(back["num_steps"].values, ds["num_steps"].values)
    assert list(back["status_message"].values.ravel()) == list(ds["status_message"].values.ravel())
    assert back["clearance"].attrs == ds["clearance"].attrs and back.attrs["sweep_hash"] == "abc"
    assert str(path).endswith("results.nc")


def test_list_dataset_and_dataframe():
    table = {"run": np.arange(3), "speed_rpm": np.array([3000.0, 4000.0, 5000.0]),
             "mass:slider": np.array([0.14, 0.2, 0.3]), "peak_contact_force_n": np.array([1.0, 2.0, np.nan]),
             "status": np.array([0, 0, 1]), "status_message": np.array(["ok", "ok", "max steps"], dtype=object)}
    res = sweep.SweepResult("unused", table, ("speed_rpm", "mass:slider"), np.zeros((3, 2, 1, 4)),
                            {"speed_rpm": table["speed_rpm"], "mass:slider": table["mass:slider"]}, "list")
    ds = res.to_xarray()
    assert ds["peak_contact_force_n"].dims == ("run",)
    np.testing.assert_array_equal(ds["speed_rpm"].values, table["speed_rpm"])  # a coordinate along run
    assert ds["speed_rpm"].attrs["units"] == "rpm" and ds["mass:slider"].attrs["units"] == "kg"
    df = res.to_dataframe()
    assert isinstance(df, pd.DataFrame) and df.index.name == "run" and len(df) == 3
    np.testing.assert_array_equal(df["speed_rpm"].to_numpy(), table["speed_rpm"])
    assert df.attrs["units"]["peak_contact_force_n"] == "N" and df.loc[2, "status_message"] == "max steps"


def test_heatmap_needs_one_value_of_every_other_parameter(tmp_path):
    X, Y, Z = np.meshgrid(XS, YS, [0.0, 0.1], indexing="ij")
    table = {"run": np.arange(18), "clearance": X.ravel(), "restitution": Y.ravel(), "friction": Z.ravel(),
             "peak_contact_force_n": np.arange(18.0), "status": np.zeros(18, int)}
    res = sweep.SweepResult("unused", table, ("clearance", "restitution", "friction"), np.zeros((18, 1, 1, 4)),
                            {"clearance": XS, "restitution": YS, "friction": np.array([0.0, 0.1])}, "grid")
    with pytest.raises(ParameterError, match="sel="):
        sweep.heatmap(res, "peak_contact_force_n", x="clearance", y="restitution")
    fig = sweep.heatmap(res, "peak_contact_force_n", x="clearance", y="restitution", sel={"friction": 0.1},
                        path=tmp_path / "h.png")
    # the cell (clearance 0.25 mm, c_r 0.5, mu 0.1) is run 1*6 + 0*2 + 1 = 7
    ax = fig.axes[0]
    assert "clearance [mm]" == ax.get_xlabel() and "restitution c_r [-]" == ax.get_ylabel()
    assert "7" in [t.get_text() for t in ax.texts]


def test_timeseries_and_record_frames(tmp_path):
    mech = jc.preset("flores-slider-crank")
    sol = _fake_solution(mech)
    df = jc.timeseries_frame(mech, sol)
    table = io.timeseries_table(mech, sol)
    assert df.index.name == "time_s" and list(df.columns) == io.timeseries_columns(mech)[1:]
    for name in df.columns:
        np.testing.assert_array_equal(df[name].to_numpy(), table[name])
    assert df.attrs["units"]["slider_acc_m_s2"] == "m/s^2" and df.attrs["units"]["contact_force_n"] == "N"
    path = tmp_path / "rec.csv"
    path.write_text("# rig: bench\ntime_s,slider_acc_m_s2,crank_angle_rad\n0,1.5,0\n1e-3,2.5,0.1\n")
    rec = io.read_measurements(path).to_dataframe()
    assert list(rec.columns) == ["slider_acc_m_s2", "crank_angle_rad"] and rec.attrs["metadata"] == {"rig": "bench"}
    np.testing.assert_array_equal(rec["slider_acc_m_s2"].to_numpy(), [1.5, 2.5])

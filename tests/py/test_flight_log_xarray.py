"""A flight log opens in xarray as a team expects: each stream a dataset
with named dimensions, its time field as the time coordinate and CF
`units`; the dimensions added for that leave the log as the diagnosis
reads it (format versions 1 and 2)."""

from __future__ import annotations

import numpy as np
import pytest

from bench.gap import bundled
from bench.sim.flight_log import read_flight_log, write_flight_log

xr = pytest.importorskip("xarray")
pytest.importorskip("h5netcdf")


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    v1 = read_flight_log(bundled.LOG)  # the bundled run is format version 1
    path = write_flight_log(tmp_path_factory.mktemp("xr") / "log.h5", v1)
    return v1, path


def test_imu_opens_as_a_tidy_dataset(logs):
    _, path = logs
    ds = xr.open_dataset(path, group="imu", engine="h5netcdf")
    assert dict(ds.sizes) == {"t_s": 1199, "axis": 3}
    assert not any(d.startswith("phony_dim") for d in ds.dims)
    assert "t_s" in ds.coords and ds["t_s"].attrs["units"] == "s" and ds["t_s"].attrs["standard_name"] == "time"
    assert ds["accel_b_mps2"].dims == ("t_s", "axis") and ds["accel_b_mps2"].attrs["units"] == "m/s^2"
    assert ds["omega_bi_b_rps"].attrs["units"] == "rad/s"
    # and from there to pandas
    df = ds.to_dataframe()
    assert df.index.names == ["t_s", "axis"] and len(df) == 3 * 1199


def test_every_stream_has_its_own_time_coordinate(logs):
    v1, path = logs
    for name in v1.streams:
        ds = xr.open_dataset(path, group=name, engine="h5netcdf")
        assert not any(d.startswith("phony_dim") for d in ds.dims), name
        time = {"pose": "t_capture_s"}.get(name, "t_s")
        assert time in ds.coords and all(v.dims[0] == time for v in ds.data_vars.values()), name
    pose = xr.open_dataset(path, group="pose", engine="h5netcdf")
    assert pose["q_hb"].dims == ("t_capture_s", "quaternion") and pose["q_hb"].attrs["units"] == "1"


def test_the_dimensions_leave_the_log_as_the_diagnosis_reads_it(logs):
    v1, path = logs
    back = read_flight_log(path)
    assert {k: sorted(v) for k, v in back.streams.items()} == {k: sorted(v) for k, v in v1.streams.items()}
    for name, fields in v1.streams.items():
        for key, arr in fields.items():
            assert np.array_equal(np.asarray(arr), back[name][key]), f"{name}/{key}"
    # the bundled file (format 1, no dimensions) reads as before
    assert read_flight_log(bundled.LOG).streams.keys() == v1.streams.keys()

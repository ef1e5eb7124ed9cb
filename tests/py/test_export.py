"""`proxops export`: a small flight log written as CSV, Parquet and MCAP and
read back with the readers a team uses (pandas, pyarrow, mcap.reader): every
stream, its column names, values, times and units; and the mistakes a user
can make, each one line and exit 2 with nothing written."""

from __future__ import annotations

import json

import numpy as np
import pytest

from bench import cli
from bench.sim.flight_log import FlightLog, write_flight_log

pd = pytest.importorskip("pandas")
pa = pytest.importorskip("pyarrow")
pq = pytest.importorskip("pyarrow.parquet")
mcap_reader = pytest.importorskip("mcap.reader")

EPOCH = 1.7e9  # a Unix-epoch clock: the ns log times must keep the stamps' fractions


def _small_log() -> FlightLog:
    rng = np.random.default_rng(7)
    t = EPOCH + 0.1 * np.arange(1, 21)
    q = rng.normal(size=(4, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    on = np.zeros((20, 8))
    on[3, 2], on[4, 5] = 0.05, 0.1  # thrusters 2 and 5 fire once
    tp = EPOCH + np.array([0.5, 1.0, 1.5, 2.0])
    streams = {
        "imu": {"t_s": t, "accel_b_mps2": rng.normal(size=(20, 3)) * 1e-3, "omega_bi_b_rps": rng.normal(size=(20, 3))},
        "pose": {
            "t_capture_s": tp,
            "t_delivered_s": tp + 0.01,
            "r_hill_m": rng.normal(size=(4, 3)),
            "q_hb": q,
            "r_sigma_m": np.full(4, 0.02),
            "att_sigma_rad": np.full(4, 0.01),
        },
        "valves": {"t_s": t, "on_time_s": on},
        "update": {
            "t_s": tp + 0.01,
            "status": np.array([0, 1, 0, 3]),
            "fused": np.array([1, 0, 1, 0]),
            "innovation": rng.normal(size=(4, 6)) * 1e-2,
            "nis": rng.uniform(0, 10, 4),
            "log_likelihood": rng.normal(size=4),
        },
    }
    return FlightLog(streams=streams, config={"source": "test"}, description={})


# Expected columns of each stream, from the log: (name, values, unit).
def _expected(log: FlightLog) -> dict:
    imu, pose, valves, update = (log[s] for s in ("imu", "pose", "valves", "update"))
    xyz = ("x", "y", "z")
    exp = {
        "imu": [("t_s", imu["t_s"], "s")]
        + [(f"accel_b_mps2_{a}", imu["accel_b_mps2"][:, i], "m/s^2") for i, a in enumerate(xyz)]
        + [(f"omega_bi_b_rps_{a}", imu["omega_bi_b_rps"][:, i], "rad/s") for i, a in enumerate(xyz)],
        "pose": [("t_capture_s", pose["t_capture_s"], "s"), ("t_delivered_s", pose["t_delivered_s"], "s")]
        + [(f"r_hill_m_{a}", pose["r_hill_m"][:, i], "m") for i, a in enumerate(xyz)]
        + [(f"q_hb_{a}", pose["q_hb"][:, i], "1") for i, a in enumerate("wxyz")]
        + [("r_sigma_m", pose["r_sigma_m"], "m"), ("att_sigma_rad", pose["att_sigma_rad"], "rad")],
        "valves": [("t_s", valves["t_s"], "s")]
        + [(f"on_time_s_{k}", valves["on_time_s"][:, k], "s") for k in range(8)],
        "update": [("t_s", update["t_s"], "s"), ("status", update["status"], None), ("fused", update["fused"], None)]
        + [
            (f"innovation_{b}_{a}", update["innovation"][:, 3 * j + i], u)
            for j, (b, u) in enumerate((("r", "m"), ("att", "rad")))
            for i, a in enumerate(xyz)
        ]
        + [("nis", update["nis"], "1"), ("log_likelihood", update["log_likelihood"], "1")],
    }
    return exp


@pytest.fixture(scope="module")
def log_path(tmp_path_factory):
    path = tmp_path_factory.mktemp("log") / "flight_log.h5"
    write_flight_log(path, _small_log())
    return path


def _export(log_path, fmt, out, capsys) -> None:
    assert cli.main(["export", str(log_path), "--to", fmt, "--out", str(out)]) == 0
    said = capsys.readouterr().out
    assert "imu 20" in said and "pose 4" in said, said


def test_csv_reads_back_in_pandas_with_units(log_path, tmp_path, capsys):
    out = tmp_path / "csv"
    _export(log_path, "csv", out, capsys)
    assert sorted(p.name for p in out.iterdir()) == ["imu.csv", "pose.csv", "units.csv", "update.csv", "valves.csv"]
    units = pd.read_csv(out / "units.csv")
    for stream, cols in _expected(_small_log()).items():
        # The text holds every float exactly; pandas' default parser may round the last bit.
        df = pd.read_csv(out / f"{stream}.csv", float_precision="round_trip")
        assert list(df.columns) == [c[0] for c in cols], stream
        for name, values, _ in cols:
            np.testing.assert_array_equal(df[name].to_numpy(), values, err_msg=f"{stream}/{name}")
        got = units[units.stream == stream].set_index("column").unit
        for name, _, unit in cols:
            if unit is not None:
                assert got[name] == unit, (stream, name)
    assert pd.read_csv(out / "update.csv")["status"].dtype.kind == "i"


def test_parquet_reads_back_with_units_and_time_column(log_path, tmp_path, capsys):
    out = tmp_path / "pq"
    _export(log_path, "parquet", out, capsys)
    for stream, cols in _expected(_small_log()).items():
        table = pq.read_table(out / f"{stream}.parquet")
        assert table.column_names == [c[0] for c in cols], stream
        assert table.schema.metadata[b"time_column"].decode() == cols[0][0]
        for name, values, unit in cols:
            np.testing.assert_array_equal(table[name].to_numpy(), values, err_msg=f"{stream}/{name}")
            if unit is not None:
                assert table.schema.field(name).metadata[b"unit"].decode() == unit, (stream, name)
    assert pq.read_table(out / "update.parquet").schema.field("fused").type == pa.int64()


def test_mcap_reads_back_one_channel_per_stream_at_the_stamps(log_path, tmp_path, capsys):
    out = tmp_path / "log.mcap"
    _export(log_path, "mcap", out, capsys)
    expected = _expected(_small_log())
    got = {s: [] for s in expected}
    with open(out, "rb") as f:
        reader = mcap_reader.make_reader(f)
        summary = reader.get_summary()
        topics = {c.topic: c for c in summary.channels.values()}
        assert sorted(topics) == sorted(f"/{s}" for s in expected)
        last = 0
        for schema, channel, msg in reader.iter_messages(log_time_order=False):
            assert msg.log_time >= last  # written in time order across streams
            last = msg.log_time
            assert schema.encoding == "jsonschema" and channel.message_encoding == "json"
            got[channel.topic[1:]].append((msg.log_time, json.loads(msg.data)))
        schemas = {s.name: json.loads(s.data) for s in summary.schemas.values()}
    for stream, cols in expected.items():
        times = [t for t, _ in got[stream]]
        stamps = cols[0][1]
        assert len(times) == stamps.size, stream
        # Exact to the ns the stamp holds (float64 resolves 0.24 us at 1.7e9 s).
        assert np.max(np.abs(np.array(times, dtype=np.float64) - stamps * 1e9)) <= 256, stream
        assert times[0] // 10**9 == int(EPOCH)
        units = json.loads(topics[f"/{stream}"].metadata["units"])
        assert topics[f"/{stream}"].metadata["time_column"] == cols[0][0]
        assert list(schemas[stream]["properties"]) == [c[0] for c in cols]
        for name, values, unit in cols:
            np.testing.assert_array_equal([m[name] for _, m in got[stream]], values, err_msg=f"{stream}/{name}")
            if unit is not None:
                assert units[name] == unit and schemas[stream]["properties"][name]["description"] == unit
    assert schemas["update"]["properties"]["status"]["type"] == "integer"


def _one_line_exit_2(argv, capsys) -> str:
    assert cli.main(argv) == 2
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("proxops export: error: "), captured.err
    assert "Traceback" not in captured.err
    return lines[0]


def test_mistakes_give_one_line_exit_2_and_write_nothing(log_path, tmp_path, capsys):
    a_file = tmp_path / "a_file"
    a_file.write_text("x")
    assert "not found" in _one_line_exit_2(["export", str(tmp_path / "no.h5"), "--to", "csv", "--out", "o"], capsys)
    assert "--to" in _one_line_exit_2(["export", str(log_path), "--to", "xlsx", "--out", str(tmp_path / "o")], capsys)
    line = _one_line_exit_2(["export", str(log_path), "--to", "csv", "--out", str(a_file / "sub")], capsys)
    assert "--out" in line
    assert "is a file" in _one_line_exit_2(["export", str(log_path), "--to", "parquet", "--out", str(a_file)], capsys)
    assert "is a folder" in _one_line_exit_2(["export", str(log_path), "--to", "mcap", "--out", str(tmp_path)], capsys)
    assert "not an HDF5 file" in _one_line_exit_2(["export", str(a_file), "--to", "csv", "--out", "o"], capsys)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a_file"]


def test_a_stamp_before_zero_is_refused_for_mcap(tmp_path, capsys):
    log = _small_log()
    for stream, time_field in (("imu", "t_s"), ("pose", "t_capture_s"), ("valves", "t_s"), ("update", "t_s")):
        log[stream][time_field] = log[stream][time_field] - EPOCH - 1.0  # imu from -0.9 s
    log["pose"]["t_delivered_s"] = log["pose"]["t_delivered_s"] - EPOCH - 1.0
    path = tmp_path / "negative.h5"
    write_flight_log(path, log)
    line = _one_line_exit_2(["export", str(path), "--to", "mcap", "--out", str(tmp_path / "x.mcap")], capsys)
    assert "imu/t_s row 0" in line and "before 0" in line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["negative.h5"]

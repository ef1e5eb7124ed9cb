"""The flight-log contract: round trip, and a validator that names stream,
field, row and problem."""

import h5py
import numpy as np
import pytest

from bench.sim.flight_log import FlightLog, FlightLogError, read_flight_log, validate_log, write_flight_log


def minimal_log(n=50, m=5):
    rng = np.random.default_rng(7)
    q = rng.normal(size=(m, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    return FlightLog(
        streams={
            "imu": {
                "t_s": 0.1 * np.arange(1, n + 1),
                "accel_b_mps2": rng.normal(size=(n, 3)),
                "omega_bi_b_rps": rng.normal(size=(n, 3)),
            },
            "pose": {
                "t_capture_s": np.arange(1.0, m + 1),
                "t_delivered_s": np.arange(1.0, m + 1) + 0.2,
                "r_hill_m": rng.normal(size=(m, 3)),
                "q_hb": q,
                "r_sigma_m": np.full(m, 0.05),
                "att_sigma_rad": np.full(m, 0.01),
            },
        },
        config={"orbit_radius_m": 6878137.0},
    )


def test_round_trip_preserves_streams_and_config(tmp_path):
    log = minimal_log()
    path = write_flight_log(tmp_path / "a.h5", log)
    back = read_flight_log(path)
    assert back.config == log.config
    for s in ("imu", "pose"):
        for k, v in log[s].items():
            np.testing.assert_array_equal(back[s][k], v)


def test_missing_stream_is_named():
    log = minimal_log()
    del log.streams["pose"]
    assert [str(p) for p in validate_log(log)] == ["pose: missing stream"]


def test_wrong_shape_names_field_and_expected_shape():
    log = minimal_log()
    log["imu"]["accel_b_mps2"] = np.zeros((50, 2))
    assert "imu/accel_b_mps2: wrong shape (50, 2), expected (N, 3)" in [str(p) for p in validate_log(log)]


def test_non_monotonic_time_names_row():
    log = minimal_log()
    log["imu"]["t_s"][17] = log["imu"]["t_s"][16]
    msgs = [str(p) for p in validate_log(log)]
    assert any(m.startswith("imu/t_s row 17: time not increasing") for m in msgs), msgs


def test_non_unit_quaternion_names_row():
    log = minimal_log()
    log["pose"]["q_hb"][3] *= 1.01
    msgs = [str(p) for p in validate_log(log)]
    assert any(m.startswith("pose/q_hb row 3: quaternion [w, x, y, z] norm") for m in msgs), msgs


def test_nan_names_row():
    log = minimal_log()
    log["imu"]["omega_bi_b_rps"][9, 1] = np.nan
    msgs = [str(p) for p in validate_log(log)]
    assert any(m.startswith("imu/omega_bi_b_rps row 9: not finite") for m in msgs), msgs


def test_unequal_lengths_reported():
    log = minimal_log()
    log["imu"]["t_s"] = log["imu"]["t_s"][:-1]
    assert any("fields differ in length" in str(p) for p in validate_log(log))


def test_writer_refuses_invalid_log(tmp_path):
    log = minimal_log()
    log["pose"]["r_hill_m"][0, 0] = np.inf
    with pytest.raises(FlightLogError, match="pose/r_hill_m row 0: not finite"):
        write_flight_log(tmp_path / "bad.h5", log)


def test_reader_rejects_foreign_file(tmp_path):
    p = tmp_path / "foreign.h5"
    with h5py.File(p, "w") as h:
        h.attrs["format"] = "something-else"
    with pytest.raises(FlightLogError, match="attribute 'format'"):
        read_flight_log(p)


def test_reader_names_problem_in_file_written_by_plain_h5py(tmp_path):
    # A user writing with h5py alone, following docs/FLIGHT_LOG.md, with one mistake.
    p = tmp_path / "user.h5"
    log = minimal_log()
    with h5py.File(p, "w") as h:
        h.attrs["format"] = "proxops-flight-log"
        h.attrs["format_version"] = 1
        for s, data in log.streams.items():
            g = h.create_group(s)
            for k, v in data.items():
                g.create_dataset(k, data=v)
        del h["imu/omega_bi_b_rps"]
    with pytest.raises(FlightLogError, match="imu/omega_bi_b_rps: missing field"):
        read_flight_log(p)


# --- format version 2 ------------------------------------------------------


def v2_log(n_thr=12):
    from bench.sim.vehicles import inspector_12kg

    log = minimal_log()
    log.description = inspector_12kg()
    t = np.arange(0.0, 5.0, 0.1)
    on = np.zeros((t.size, n_thr))
    on[::3, 2] = 0.03
    log.streams["valves"] = {"t_s": t, "on_time_s": on}
    return log


def test_v2_round_trip_keeps_description_and_on_times(tmp_path):
    log = v2_log()
    back = read_flight_log(write_flight_log(tmp_path / "v2.h5", log))
    assert back.description == log.description
    np.testing.assert_array_equal(back["valves"]["on_time_s"], log["valves"]["on_time_s"])


def test_v2_on_times_need_one_column_per_described_thruster():
    log = v2_log(n_thr=8)  # the description has 12 thrusters
    msgs = [str(p) for p in validate_log(log)]
    assert "valves/on_time_s: wrong shape (50, 8), expected (N, 12) (one column per thruster)" in msgs, msgs


def test_v2_valve_forms_and_pulses_checked():
    log = v2_log()
    log["valves"]["mask"] = np.zeros(50, dtype=np.int64)
    assert "valves: give on_time_s or mask with interval_s, not both" in [str(p) for p in validate_log(log)]
    log = v2_log()
    log["valves"]["on_time_s"][4, 1] = 0.25  # the next command is 0.1 s later
    msgs = [str(p) for p in validate_log(log)]
    assert any(m.startswith("valves/on_time_s row 4: pulse of 0.25 s runs past the next command") for m in msgs), msgs
    log = v2_log()
    log["valves"]["on_time_s"][7, 0] = -0.01
    assert any(str(p).startswith("valves/on_time_s row 7: negative") for p in validate_log(log))
    log = minimal_log()  # the bench inspector: 8 thrusters
    log.streams["valves"] = {"t_s": np.arange(3.0), "interval_s": np.full(3, 0.5), "mask": np.array([1, 256, 0])}
    assert "valves/mask row 1: opens a thruster beyond the vehicle's 8 (256)" in [str(p) for p in validate_log(log)]


def test_v2_bad_description_named_by_the_validator(tmp_path):
    log = v2_log()
    log.description["vehicle"]["thrusters"][0]["thrust_n"] = 0.0
    msgs = [str(p) for p in validate_log(log)]
    assert "/description_json: vehicle.thrusters[0].thrust_n: 0.0 must be > 0.0" in msgs, msgs


def test_v1_file_with_a_description_is_refused(tmp_path):
    p = write_flight_log(tmp_path / "a.h5", minimal_log())
    with h5py.File(p, "a") as h:
        h.attrs["format_version"] = 1
        h.attrs["description_json"] = "{}"
    with pytest.raises(FlightLogError, match="description_json: needs format_version 2"):
        read_flight_log(p)


@pytest.mark.parametrize(
    "attr, value, message",
    [
        ("format_version", "abc", "/format_version: 'abc' is not an integer"),
        ("format_version", 7, "/format_version: 7 not supported"),
        ("config_json", "{not json", "/config_json: not valid JSON"),
        ("description_json", "[1, 2]", "/description_json: expected a JSON object"),
    ],
)
def test_header_problems_named(tmp_path, attr, value, message):
    p = write_flight_log(tmp_path / "a.h5", minimal_log())
    with h5py.File(p, "a") as h:
        h.attrs[attr] = value
    with pytest.raises(FlightLogError, match=message.replace("[", r"\[").replace("]", r"\]").replace("{", r"\{")):
        read_flight_log(p)


def test_stream_stored_as_a_dataset_is_named(tmp_path):
    p = write_flight_log(tmp_path / "a.h5", minimal_log())
    with h5py.File(p, "a") as h:
        h["truth"] = np.zeros(3)
    with pytest.raises(FlightLogError, match="truth: expected a group of fields"):
        read_flight_log(p)


def test_one_row_stream_is_refused():
    log = minimal_log(n=1, m=5)
    assert "imu/t_s: 1 samples (at least 2 needed)" in [str(p) for p in validate_log(log)]

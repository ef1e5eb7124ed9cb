"""The plate over the link: range images to the flight executable behind a
pseudo-terminal, tm_modal back; the same numbers as the flight app
in-process, and a link that loses bytes loses only segments."""

import json

import fsw_bindings as fb
import numpy as np
import pytest

pytest.importorskip("serial")

from hil_sim import packets as pk  # noqa: E402
from hil_sim.faults import FaultConfig  # noqa: E402
from hil_sim.modal_link import PlateHilConfig, parse_tm_modal, plate_hil_summary, run_plate_hil  # noqa: E402


def _in_process(uplink: bytes) -> dict:
    app = fb.FlightApp(fb.NavConfig())
    down = pk.Deframer(pk.FROM_FLIGHT)
    out = {}
    for i in range(0, len(uplink), 4096):  # in pieces, as the port delivers them (the app's transmit buffer is 16 kB)
        for item in down.feed(app.on_bytes(uplink[i : i + 4096])):
            if isinstance(item, pk.Packet) and item.apid == pk.APID_BY_NAME["tm_modal"].apid:
                m = parse_tm_modal(item)
                out[m["image_id"]] = m
    return out


def test_flight_executable_answers_every_image_as_the_app_in_process():
    res = run_plate_hil(PlateHilConfig(images=60, seed=2))
    s = plate_hil_summary(res)
    assert s["images_answered"] == s["images_fused"] == 60
    assert s["points_used"] == s["points_sent"] and s["images_with_points_lost"] == 0
    assert res["fsw_node_exit_code"] == 0
    ref = _in_process(res["uplink"])
    assert sorted(ref) == sorted(res["answers"])
    for k, m in res["answers"].items():
        for key in ("omega_radps", "alpha_ps", "amplitude", "amplitude_sigma"):
            np.testing.assert_array_equal(m[key], ref[k][key])
        assert (m["nis"], m["rcond"], m["n_used"]) == (ref[k]["nis"], ref[k]["rcond"], ref[k]["n_used"])
    # One lowest-mode period with every prior 5 % low: the well-excited
    # modes are already within 2 %.
    rel = np.abs(np.array(s["final_frequency_rel_error"]))[s["strong_modes"]]
    assert len(rel) >= 5 and np.all(rel < 0.02), rel


def test_lost_bytes_lose_segments_not_images():
    # 1e-5 of the bytes dropped: about one of every three 30 kB images loses
    # a segment (the frame fails its CRC or COBS and is counted, the link
    # resynchronises at the next delimiter).
    res = run_plate_hil(PlateHilConfig(images=60, seed=5, faults=FaultConfig(drop_rate=1e-5)))
    s = plate_hil_summary(res)
    assert res["faults_up"]["bytes_dropped"] > 0
    assert s["images_with_points_lost"] > 0
    assert s["images_answered"] >= 58  # an image whose first segment is lost may still answer (id from any segment)
    assert s["images_fused"] == s["images_answered"]
    lost = s["points_sent"] - s["points_used"]
    assert 0 < lost < 0.05 * s["points_sent"]
    assert res["fsw_node_exit_code"] == 0


def test_proxops_hil_plate_command(tmp_path, capsys):
    from bench.cli import main

    out = tmp_path / "hil_plate.json"
    assert main(["hil", "--scenario", "plate", "--images", "5", "--seed", "1", "--json", str(out)]) == 0
    s = json.loads(out.read_text())
    assert s["scenario"] == "plate" and s["images_answered"] == s["images_fused"] == 5
    assert "answered 5, fused 5" in capsys.readouterr().out
    assert main(["hil", "--scenario", "plate", "--images", "0"]) == 2

"""The docking scenario with the 1 Hz pose from rendered images through the
flight vision pipeline (ScenarioConfig(pose_source="images")): the filter
fuses the image poses, the errors stay within the navigation bounds, and the
pipeline's statuses are counted. The 50-run campaign is
`proxops nav --pose-source images` (docs/VISION.md)."""

import numpy as np
import pytest

fb = pytest.importorskip("fsw_bindings")
if not hasattr(fb, "NavUkf") or not hasattr(fb, "LedPoseEstimator"):
    pytest.skip("fsw_bindings lacks NavUkf or LedPoseEstimator", allow_module_level=True)

from bench.campaigns.nav_campaign import run_campaign  # noqa: E402
from bench.sim import camera as cm  # noqa: E402
from bench.sim.image_pose import DOCK_FACE_OFFSET_M, Q_H_PATTERN, ImagePoseSensor, docking_camera  # noqa: E402
from bench.sim.scenario_docking import DOCK_HILL_M, ScenarioConfig, run_docking  # noqa: E402
from bench.sim.sensors import NoiseProfile  # noqa: E402


@pytest.fixture(scope="module")
def campaign():
    summary, runs = run_campaign(2, seed=1, cfg=ScenarioConfig(pose_source="images"), keep_runs=2)
    return summary, runs


def test_filter_fuses_image_poses_every_second(campaign):
    summary, runs = campaign
    assert summary["pose_source"] == "images" and summary["docked"] == 2
    for run in runs:
        s, u = run.summary, run.updates
        assert s.t_nav_init_s == 0.0  # these starts see the pattern at once
        frames = sum(s.vision_status_counts.values())
        assert frames == int(np.floor(s.t_end_s + 1e-9)) + 1  # one frame per whole second, t = 0 included
        ok = s.vision_status_counts.get("Ok", 0)
        assert ok >= 0.95 * frames
        # Every Ok frame after the initialising one is fused (none gated).
        assert len(u.nis) == ok - 1 and np.all(u.fused)
        # The covariance is the pipeline's (millimetres), not the synthetic 5 % of range (centimetres).
        rng_m = np.linalg.norm(u.r_meas, axis=1)
        assert np.all(u.r_sigma < 0.01 * rng_m)
        assert np.all(u.r_sigma > 0.0) and np.all(u.att_sigma > 0.0)


def test_errors_within_the_navigation_bounds(campaign):
    summary, _ = campaign
    assert max(summary["max_pos_err_m"]["per_run"]) <= 0.10
    assert max(summary["max_vel_err_mps"]["per_run"]) <= 0.03
    assert summary["max_pos_err_m"]["median"] <= 0.05
    assert summary["max_vel_err_mps"]["median"] <= 0.015
    assert summary["checks"]["pos_p95_le_0.10"] and summary["checks"]["vel_p95_le_0.03"]


def test_campaign_counts_vision_statuses(campaign):
    summary, runs = campaign
    counts = summary["vision_status_counts"]
    assert sum(counts.values()) == summary["vision_frames"]
    assert summary["vision_frames"] == sum(sum(r.summary.vision_status_counts.values()) for r in runs)
    assert summary["fused_pose_count"] == sum(len(r.updates.nis) for r in runs)
    assert set(counts) <= {
        "Ok",
        "TooFewLeds",
        "AmbiguousIdentity",
        "TargetBehindCamera",
        "DegenerateGeometry",
        "SolverFailed",
        "BadInput",
    }


def test_frame_without_a_pose_delivers_nothing_and_is_counted():
    sensor = ImagePoseSensor(NoiseProfile.paper(), np.random.default_rng(3))
    # Docked attitude but turned half a turn about z: the camera looks away from the host.
    m = sensor.measure(5.0, np.array([0.0, -0.6, 0.0]), np.array([0.0, 0.0, 0.0, 1.0]))
    assert m is None and sensor.status_counts == {"TooFewLeds": 1}
    m = sensor.measure(6.0, np.array([0.02, -0.6, -0.01]), np.array([1.0, 0.0, 0.0, 0.0]))
    assert m is not None and m.t_capture_s == 6.0 and m.R.shape == (6, 6)
    assert sensor.status_counts == {"TooFewLeds": 1, "Ok": 1}
    assert np.linalg.norm(m.r_hill_m - [0.02, -0.6, -0.01]) < 0.01


def test_pattern_in_view_with_margin_at_contact():
    cam = docking_camera()
    px, front, X_c = cm.led_pixels(
        DOCK_HILL_M,
        np.array([1.0, 0.0, 0.0, 0.0]),
        Q_H_PATTERN,
        cam,
        cm.pattern_host_m(cm.HALF_SIDE_M, DOCK_FACE_OFFSET_M),
    )
    assert front.all()
    assert px.min() > 50 and np.all(px.max(0) < [cam.width - 51, cam.height - 51])
    assert np.linalg.norm(X_c, axis=1).min() > 0.15


def test_unknown_pose_source_is_refused():
    with pytest.raises(ValueError, match="pose_source"):
        run_docking(1000, ScenarioConfig(pose_source="magic", t_max_s=1.0))


def test_start_out_of_view_holds_valves_until_the_first_image_pose():
    # Seed 2186 starts with the pattern partly outside the image: the t = 0
    # frame gives no pose, the valves stay closed and the filter starts from
    # the t = 1 s frame.
    run = run_docking(2186, ScenarioConfig(pose_source="images", t_max_s=10.0))
    s = run.summary
    assert s.t_nav_init_s == 1.0 and s.first_update_t_s == 2.0
    assert s.vision_status_counts == {"TooFewLeds": 1, "Ok": 10}
    assert not np.any(run.config[:10])  # steps ending at 0.1 .. 1.0 s: no valve open
    assert np.all(np.isnan(run.nees[:10])) and np.all(np.isfinite(run.nees[10:]))
    assert np.all(np.isfinite(run.est[10:]))


def _pose_errors_mm(run):
    u = run.updates
    i = np.searchsorted(run.t, np.asarray(u.t_capture) - 1e-9)
    return 1e3 * np.linalg.norm(u.r_meas - run.r_true[i], axis=1)


def test_lens_distortion_effect_biases_image_poses_and_the_innovations_show_it():
    # The lens_distortion effect renders the frames through a distorted lens
    # the pipeline takes for a pinhole: same seed, same trajectory start, the
    # pose errors grow from sub-millimetre to centimetres and NIS leaves 6.
    base = run_docking(1001, ScenarioConfig(pose_source="images", t_max_s=12.0))
    lens = run_docking(1001, ScenarioConfig(pose_source="images", t_max_s=12.0, effects={"lens_distortion": [-0.1]}))
    e0, e1 = np.median(_pose_errors_mm(base)), np.median(_pose_errors_mm(lens))
    assert e0 < 3.0 and e1 > 10.0 * e0
    assert np.mean(lens.updates.nis) > 5.0 * max(np.mean(base.updates.nis), 6.0)


def test_lens_distortion_effect_needs_image_poses():
    with pytest.raises(ValueError, match="lens_distortion needs pose_source 'images'"):
        run_docking(1, ScenarioConfig(t_max_s=1.0, effects={"lens_distortion": [0.05]}))

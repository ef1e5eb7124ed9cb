"""The flight app's modal estimator fed by the bench over the link: range
images of the paper's plate (bench/sim/structure.py: ray-cast, 3 % range noise),
segmented by hil_sim.packets, into the flight app in-process; tm_modal back.
Checked against the same decomposition and joint filter called directly."""

import numpy as np
import pytest

from bench.campaigns.modal_campaign import make_filter
from bench.sim import structure as st
from hil_sim import packets as P

fb = pytest.importorskip("fsw_bindings")

TM_MODAL = P.APID_BY_NAME["tm_modal"].apid
SEG = P.APID_BY_NAME["range_image_segment"].apid


def _tm_modal(deframer, data):
    out = []
    for p in deframer.feed(data):
        if isinstance(p, P.Packet) and p.apid == TM_MODAL:
            v = p.values()
            out.append(
                dict(
                    t_s=p.t_s,
                    image_id=v[0],
                    status=v[1],
                    decomposition=v[2],
                    fused=v[3],
                    n_modes=v[4],
                    n_used=v[5],
                    n_skipped=v[6],
                    rcond=v[7],
                    nis=v[8],
                    omega=np.array(v[9:19]),
                    alpha=np.array(v[19:29]),
                    amplitude=np.array(v[29:39]),
                    amplitude_sigma=np.array(v[39:49]),
                )
            )
    return out


def test_range_image_segments_split_and_flag_as_the_link_requires():
    pts = np.arange(50 * 3, dtype=float).reshape(50, 3)
    segs = P.range_image_segments(7, pts, np.full(50, 0.5))
    assert [f for f, _ in segs] == [
        P.SequenceFlags.FIRST_SEGMENT,
        P.SequenceFlags.CONTINUATION_SEGMENT,
        P.SequenceFlags.LAST_SEGMENT,
    ]
    v = P.unpack_payload(SEG, segs[2][1])
    assert v[:4] == (7, 50, 48, 2)
    assert v[5:9] == (144.0, 145.0, 146.0, 0.5) and v[13] == 0.0
    assert [f for f, _ in P.range_image_segments(1, pts[:3], [0.1] * 3)] == [P.SequenceFlags.UNSEGMENTED]
    with pytest.raises(ValueError, match="points"):
        P.range_image_segments(1, np.zeros((4097, 3)), np.zeros(4097))
    bad = pts[:5].copy()
    bad[2, 1] = np.nan
    with pytest.raises(ValueError, match="point 2 is not finite"):
        P.range_image_segments(1, bad, np.ones(5))
    with pytest.raises(ValueError, match="point 4 .* negative sigma"):
        P.range_image_segments(1, pts[:5], [1, 1, 1, 1, -1])
    with pytest.raises(ValueError, match=r"\(n, 3\)"):
        P.range_image_segments(1, np.zeros((5, 2)), np.ones(5))


class _PlateOverLink:
    """The paper's plate imaged once a minute, each image segmented into the
    in-process flight app; per image the app's tm_modal and the same image's
    decomposition by the library, and the library's joint filter from the
    model's frequencies (10 % sigma), as the app starts."""

    def __init__(self, seed):
        self.rng = np.random.default_rng(seed)
        self.plate = st.Plate(n_modes=10)
        self.sensor = st.plate_sensor(self.plate)
        self.amp, self.phase = st.plate_truth(self.plate, self.rng)
        self.app = fb.FlightApp(fb.NavConfig())
        self.sender, self.down = P.Sender(), P.Deframer(P.FROM_FLIGHT)
        self.w0 = self.plate.omega_radps
        self.dec = fb.ModalDecomposition10()

    def filter(self, omega, sigma_omega):
        return make_filter(
            "joint", 10, omega, np.zeros(10), sigma_v0=self.w0, sigma_w0=sigma_omega, sigma_a0=1e-6, q_a=0.0, q_v=0.0
        )

    def image(self, k, t):
        """(tm_modal answers, library record, points sent)."""
        r_meas, d = st.plate_range_image(
            self.plate, self.sensor, st.plate_coeffs(self.plate, self.amp, self.phase, t), self.rng
        )
        keep = np.isfinite(r_meas)  # missed rays are not sent
        p = self.sensor.pos_m[None, :] + r_meas[keep, None] * d[keep]
        sigma = np.abs(0.03 * r_meas[keep] * d[keep, 2])
        data = b"".join(self.sender.frame(SEG, t, pl, seq_flags=f) for f, pl in P.range_image_segments(k, p, sigma))
        tm = _tm_modal(self.down, self.app.on_bytes(data))
        rec = self.dec.decompose(*st.plate_points(self.plate, self.sensor, r_meas[keep], d[keep]))
        return tm, rec, int(keep.sum())


def test_flight_app_steps_each_bench_image_like_the_library():
    scene = _PlateOverLink(4)
    app, w0, amp = scene.app, scene.w0, scene.amp
    ref = scene.filter(w0, 0.1 * w0)
    n_img, dt = 40, 60.0
    got = []
    for k in range(n_img):
        t = k * dt
        tm, rec, n_sent = scene.image(k, t)
        assert len(tm) == 1 and tm[0]["image_id"] == k and tm[0]["t_s"] == t
        got.append(tm[0])
        ref.step(dt, rec)
        m = tm[0]
        assert m["fused"] == 1 and m["n_used"] == n_sent and m["n_skipped"] == 0
        assert m["rcond"] == pytest.approx(1.0 / rec.condition_number, rel=1e-9)
        np.testing.assert_allclose(m["amplitude"], ref.state[:, 0], rtol=1e-7, atol=1e-9)
        np.testing.assert_allclose(m["omega"], ref.state[:, 2], rtol=1e-9)
    assert app.modal_counters()["images_fused"] == n_img
    assert app.counters()["unhandled"] == 0
    # The priors here are the true frequencies, told with a 10 % sigma (the
    # comparison above is the point of this test; convergence from wrong
    # priors is test_hil_modal's and test_flight_app_modal's). After 40
    # images, one period of the lowest mode, the well-seen modes are within
    # 2 % of them (1.5 % at most, measured).
    strong = amp >= 0.5
    np.testing.assert_allclose(got[-1]["omega"][strong], w0[strong], rtol=0.02)


def test_flight_app_acquires_frequencies_like_the_library():
    # The app's tracker runs the frequency acquisition once the fused images
    # span 2 periods of its model's lowest mode (2400 s: the 81st image of one
    # a minute); every answer before and after it equals the library's
    # decomposition, joint filter, ModalAcquisition10 (search over +-20 % =
    # 2 a priori sigmas of 10 %) and replay, called directly.
    scene = _PlateOverLink(8)
    app, w0 = scene.app, scene.w0
    ref = scene.filter(w0, 0.1 * w0)
    acq = fb.ModalAcquisition10(w0, 0.1 * w0, grid_sigmas=2.0)
    dt, acquired_at = 60.0, None
    for k in range(84):
        t = k * dt
        (tm,), rec, _ = scene.image(k, t)
        ref.step(dt, rec)
        assert acq.add(t, rec) == "ok"
        if acquired_at is None and app.modal_counters()["acquisitions"] == 1:
            acquired_at = k
            assert acq.search() == "ok"
            omega = acq.omega
            ref = scene.filter(omega, 0.01 * omega)
            assert acq.replay_into(ref) == k + 1
        np.testing.assert_allclose(tm["omega"], ref.state[:, 2], rtol=1e-9)
        np.testing.assert_allclose(tm["amplitude"], ref.state[:, 0], rtol=1e-7, atol=1e-9)
    assert acquired_at in (80, 81)  # 2 periods = 4800 s, to the rounding of the model's period
    c = app.modal_counters()
    assert c["acquisitions"] == 1 and c["acquisitions_failed"] == 0 and c["acquisition_refused"] == 0
    assert np.max(np.abs(omega / w0 - 1)) > 1e-3  # the search moved the frequencies: the comparison has teeth

"""The inspector's camera and an 8-bit renderer of the host's LED pattern.

Camera (same defaults as ``fsw_vision::CameraModel``, docs/VISION.md):

    640 x 480 pixels, fx = fy = 320 / tan(30 deg) = 554.26 px (60 deg
    horizontal, 46.8 deg vertical field of view), principal point at the
    image centre (319.5, 239.5) with pixel centres at integer coordinates,
    optional OpenCV radial-tangential distortion [k1, k2, p1, p2, k3].

Mount on the inspector (body frame b): boresight along body +x, image right
along body -y, image down along body -z (``R_BC_DEFAULT``, columns are the
camera axes in body axes), camera centre at ``P_CAM_B_M`` = [0.10, 0.02,
-0.03] m from the inspector's centre of mass; an optional small mounting
rotation ``R_bc = R_BC_DEFAULT @ Exp(mount_err)`` models a misaligned camera.

LED pattern (host body frame, origin at the host's centre of mass): a
0.16 m square on the host's +x face (x = 0.15 m), corners 0..3 at
(y, z) = (-a,-a), (a,-a), (a,a), (-a,a) with a = 0.08 m, and the identifier
LED on edge 0-1 a quarter of the way from corner 0, at (-a/2, -a).

Image formation (vectorised numpy): each LED is a Gaussian spot (pixel-
integrated with erf) whose flux falls off as 1/range^2 and with the cosine
of the viewing angle, whose width is the optics' PSF combined with the LED's
own angular size, on a dark background with read and shot noise, optional
Gaussian blur (defocus), background clutter (bright spots and lines), and a
bright-sun case (a saturated disc, its halo and a glare gradient); the
sensor saturates at 255 counts after the optics.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.ndimage import gaussian_filter
from scipy.special import erf

from bench.so3 import qexp, qnormalize, quat_from_rotmat, rotmat

WIDTH, HEIGHT = 640, 480
FOCAL_PX = 320.0 / np.tan(np.radians(30.0))
R_BC_DEFAULT = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
P_CAM_B_M = np.array([0.10, 0.02, -0.03])
HALF_SIDE_M = 0.08
FACE_OFFSET_M = 0.15
ID_FRACTION = 0.25
PATTERN_NORMAL_HOST = np.array([1.0, 0.0, 0.0])


def pattern_host_m(half_side_m: float = HALF_SIDE_M, face_offset_m: float = FACE_OFFSET_M) -> np.ndarray:
    """(5, 3) LED positions in the host body frame [m]: corners 0..3, identifier."""
    a, x = half_side_m, face_offset_m
    c = np.array([[x, -a, -a], [x, a, -a], [x, a, a], [x, -a, a]])
    return np.vstack([c, c[0] + ID_FRACTION * (c[1] - c[0])])


@dataclass
class Camera:
    width: int = WIDTH
    height: int = HEIGHT
    fx_px: float = FOCAL_PX
    fy_px: float = FOCAL_PX
    cx_px: float = (WIDTH - 1) / 2.0
    cy_px: float = (HEIGHT - 1) / 2.0
    dist: np.ndarray = field(default_factory=lambda: np.zeros(5))  # k1, k2, p1, p2, k3
    R_bc: np.ndarray = field(default_factory=lambda: R_BC_DEFAULT.copy())
    p_cam_b_m: np.ndarray = field(default_factory=lambda: P_CAM_B_M.copy())

    def with_mount_error(self, dtheta_rad) -> "Camera":
        """The same camera rotated by Exp(dtheta) about its own axes."""
        out = Camera(**{k: (np.array(v, float) if isinstance(v, np.ndarray) else v) for k, v in self.__dict__.items()})
        out.R_bc = self.R_bc @ rotmat(qexp(np.asarray(dtheta_rad, float)))
        return out

    def project(self, X_c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Camera-frame points (N, 3) -> pixels (N, 2), in_front (N,). OpenCV's model."""
        X_c = np.atleast_2d(np.asarray(X_c, float))
        z = X_c[:, 2]
        front = z > 0.0
        zs = np.where(front, z, 1.0)
        x, y = X_c[:, 0] / zs, X_c[:, 1] / zs
        k1, k2, p1, p2, k3 = self.dist
        r2 = x * x + y * y
        radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
        xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
        yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
        return np.column_stack([self.fx_px * xd + self.cx_px, self.fy_px * yd + self.cy_px]), front


def make_estimator(
    cam: Camera | None = None,
    model_distortion: bool = True,
    pixel_sigma_px: float | None = None,
    face_offset_m: float = FACE_OFFSET_M,
):
    """The flight pipeline (fsw_bindings.LedPoseEstimator) configured with this camera: one source of truth."""
    import fsw_bindings as fb

    cam = Camera() if cam is None else cam
    cfg = fb.LedPoseConfig()
    cfg.width, cfg.height = cam.width, cam.height
    cfg.fx_px, cfg.fy_px, cfg.cx_px, cfg.cy_px = cam.fx_px, cam.fy_px, cam.cx_px, cam.cy_px
    cfg.dist = np.asarray(cam.dist, float) if model_distortion else np.zeros(5)
    cfg.R_bc = cam.R_bc
    cfg.p_cam_b_m = cam.p_cam_b_m
    cfg.set_pattern(HALF_SIDE_M, face_offset_m)
    if pixel_sigma_px is not None:
        cfg.pixel_sigma_px = pixel_sigma_px
    return fb.LedPoseEstimator(cfg)


def camera_from_nav(r_hill_m, q_hb, q_h_host, cam: Camera):
    """Inspector pose (r_hill_m, q_hb) and host attitude -> (R_cp, t_cp_m): host body -> camera."""
    R_hb, R_hp = rotmat(q_hb), rotmat(q_h_host)
    p_host_b = -R_hb.T @ np.asarray(r_hill_m, float)
    return cam.R_bc.T @ R_hb.T @ R_hp, cam.R_bc.T @ (p_host_b - cam.p_cam_b_m)


def nav_from_camera(R_cp, t_cp_m, q_h_host, cam: Camera):
    """(R_cp, t_cp_m) and host attitude -> inspector pose (r_hill_m, q_hb)."""
    R_hb = rotmat(q_h_host) @ np.asarray(R_cp).T @ cam.R_bc.T
    return -R_hb @ (cam.R_bc @ np.asarray(t_cp_m, float) + cam.p_cam_b_m), quat_from_rotmat(R_hb)


def led_pixels(r_hill_m, q_hb, q_h_host, cam: Camera, pattern=None):
    """(5, 2) pixel coordinates of the LEDs, in_front (5,), camera-frame points (5, 3)."""
    P = pattern_host_m() if pattern is None else pattern
    R_cp, t = camera_from_nav(r_hill_m, q_hb, q_h_host, cam)
    X_c = P @ R_cp.T + t
    px, front = cam.project(X_c)
    return px, front, X_c


def random_quat(rng: np.random.Generator) -> np.ndarray:
    return qnormalize(rng.standard_normal(4))


def sample_pose(
    rng: np.random.Generator,
    cam: Camera,
    range_m: tuple = (0.3, 5.0),
    max_tilt_deg: float = 55.0,
    margin_px: float = 15.0,
    pattern=None,
    max_tries: int = 1000,
):
    """A random inspector pose with the whole pattern in view.

    Range (camera to pattern centre) uniform in ``range_m``, pattern centre
    anywhere in the image, face normal within ``max_tilt_deg`` of the line
    of sight, random roll about it, random host attitude.
    Returns (r_hill_m, q_hb, q_h_host, range_m)."""
    P = pattern_host_m() if pattern is None else pattern
    centre_p = P[:4].mean(axis=0)
    for _ in range(max_tries):
        d = rng.uniform(*range_m)
        u, v = rng.uniform(0, cam.width - 1), rng.uniform(0, cam.height - 1)
        ray = np.array([(u - cam.cx_px) / cam.fx_px, (v - cam.cy_px) / cam.fy_px, 1.0])
        ray /= np.linalg.norm(ray)
        # Host axes: normal (+x) against the ray, then a random roll about it.
        n_c = -ray
        a = np.cross(n_c, [0.0, 1.0, 0.0])
        a /= np.linalg.norm(a)
        b = np.cross(n_c, a)
        R0 = np.column_stack([n_c, a, b])
        R_roll = rotmat(qexp(np.array([rng.uniform(0, 2 * np.pi), 0.0, 0.0])))
        axis = np.cross(n_c, rng.standard_normal(3))
        axis /= np.linalg.norm(axis)
        tilt = np.radians(max_tilt_deg) * np.sqrt(rng.uniform())  # uniform over the cone's solid angle (small-angle)
        R_cp = rotmat(qexp(tilt * axis)) @ R0 @ R_roll
        t_cp = d * ray - R_cp @ centre_p
        q_h_host = random_quat(rng)
        r, q = nav_from_camera(R_cp, t_cp, q_h_host, cam)
        px, front, _ = led_pixels(r, q, q_h_host, cam, P)
        inside = (
            (px[:, 0] > margin_px)
            & (px[:, 0] < cam.width - 1 - margin_px)
            & (px[:, 1] > margin_px)
            & (px[:, 1] < cam.height - 1 - margin_px)
        )
        if front.all() and inside.all():
            return r, q, q_h_host, d
    raise ValueError("sample_pose: no pose with the pattern in view")


@dataclass
class Scene:
    """Image-formation parameters (counts are 8-bit digital numbers)."""

    background_counts: float = 6.0
    read_noise_counts: float = 1.5
    shot_gain: float = 0.05  # shot-noise variance per count of signal
    led_flux_1m_counts: float = 5400.0  # total LED flux at 1 m, seen face-on
    led_radius_m: float = 0.004
    psf_sigma_px: float = 0.8
    blur_sigma_px: float = 0.0  # extra Gaussian blur (defocus)
    clutter_spots: int = 0
    clutter_lines: int = 0
    sun: bool = False


CONDITIONS = {
    "nominal": Scene(),
    "blur": Scene(blur_sigma_px=2.0),
    "clutter": Scene(clutter_spots=8, clutter_lines=4),
    "sun": Scene(sun=True),
}


def gauss_patch(img: np.ndarray, u: float, v: float, sigma: float, flux: float) -> None:
    """Adds a pixel-integrated Gaussian spot of total ``flux`` at (u, v)."""
    h = int(np.ceil(4.0 * sigma)) + 1
    c0, c1 = max(int(np.floor(u)) - h, 0), min(int(np.floor(u)) + h + 2, img.shape[1])
    r0, r1 = max(int(np.floor(v)) - h, 0), min(int(np.floor(v)) + h + 2, img.shape[0])
    if c0 >= c1 or r0 >= r1:
        return
    s = np.sqrt(2.0) * sigma
    cols = np.arange(c0, c1 + 1) - 0.5
    rows = np.arange(r0, r1 + 1) - 0.5
    gx = np.diff(0.5 * erf((cols - u) / s))
    gy = np.diff(0.5 * erf((rows - v) / s))
    img[r0:r1, c0:c1] += flux * np.outer(gy, gx)


def _line(img: np.ndarray, p0, p1, width_px: float, level: float) -> None:
    lo = np.floor(np.minimum(p0, p1) - 3 * width_px).astype(int)
    hi = np.ceil(np.maximum(p0, p1) + 3 * width_px).astype(int)
    c0, r0 = max(lo[0], 0), max(lo[1], 0)
    c1, r1 = min(hi[0], img.shape[1]), min(hi[1], img.shape[0])
    if c0 >= c1 or r0 >= r1:
        return
    yy, xx = np.mgrid[r0:r1, c0:c1]
    P = np.stack([xx, yy], -1).astype(float)
    d = np.asarray(p1, float) - np.asarray(p0, float)
    t = np.clip(((P - p0) @ d) / max(d @ d, 1e-9), 0.0, 1.0)
    dist2 = np.sum((P - (np.asarray(p0) + t[..., None] * d)) ** 2, -1)
    img[r0:r1, c0:c1] += level * np.exp(-0.5 * dist2 / (0.5 * width_px) ** 2)


def render(
    r_hill_m,
    q_hb,
    q_h_host,
    scene: Scene,
    rng: np.random.Generator,
    cam: Camera | None = None,
    pattern=None,
    leds_on=None,
) -> np.ndarray:
    """8-bit image (height, width) of the LED pattern seen by the inspector's camera.

    ``leds_on``: optional (5,) booleans, False for an occluded LED."""
    cam = Camera() if cam is None else cam
    P = pattern_host_m() if pattern is None else pattern
    img = np.full((cam.height, cam.width), scene.background_counts, float)
    px, front, X_c = led_pixels(r_hill_m, q_hb, q_h_host, cam, P)
    R_cp, _ = camera_from_nav(r_hill_m, q_hb, q_h_host, cam)
    n_c = R_cp @ PATTERN_NORMAL_HOST
    for i in range(len(P)):
        if not front[i] or (leds_on is not None and not leds_on[i]):
            continue
        rng_m = np.linalg.norm(X_c[i])
        cos_view = -n_c @ X_c[i] / rng_m  # LED emits from the face's outer side
        if cos_view <= 0.0:
            continue
        flux = scene.led_flux_1m_counts * cos_view / rng_m**2
        sigma = np.hypot(scene.psf_sigma_px, 0.5 * cam.fx_px * scene.led_radius_m / rng_m)
        gauss_patch(img, px[i, 0], px[i, 1], sigma, flux)
    H, W = img.shape
    for _ in range(scene.clutter_spots):
        gauss_patch(img, rng.uniform(0, W), rng.uniform(0, H), rng.uniform(0.6, 2.5), rng.uniform(150, 3000))
    for _ in range(scene.clutter_lines):
        p0 = rng.uniform([0, 0], [W, H])
        p1 = p0 + rng.uniform(40, 250) * np.array([np.cos(a := rng.uniform(0, np.pi)), np.sin(a)])
        _line(img, p0, p1, rng.uniform(1.0, 2.5), rng.uniform(60, 220))
    if scene.sun:
        yy, xx = np.mgrid[0:H, 0:W]
        c = rng.uniform([0, 0], [W, H])
        rad = rng.uniform(30, 110)
        d = np.hypot(xx - c[0], yy - c[1])
        img += 400.0 * (d < rad) + 150.0 * np.exp(-np.maximum(d - rad, 0) / rng.uniform(40, 120))
        g = rng.standard_normal(2)
        g /= np.linalg.norm(g)
        ramp = ((xx - W / 2) * g[0] + (yy - H / 2) * g[1]) / (0.5 * np.hypot(W, H))
        img += rng.uniform(20, 90) * np.clip(ramp + 0.5, 0, None)
    if scene.blur_sigma_px > 0:
        img = gaussian_filter(img, scene.blur_sigma_px, mode="nearest")
    var = scene.read_noise_counts**2 + scene.shot_gain * np.maximum(img - scene.background_counts, 0.0)
    img = img + np.sqrt(var) * rng.standard_normal(img.shape)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)

"""Range images of vibrating structures for the modal estimator (after Lichter and Dubowsky,
"Shape, Motion, and Parameter Estimation of Large Flexible Space Structures
using Range Images").

Two documented models:

``Plate`` -- the paper's simulation (section VI.A). A simply supported
rectangular plate, 2000 m x 1732 m (about 2 km across), vibrating out of
plane. Modes Phi_pq(x, y) = s_pq sin(p pi x / Lx) sin(q pi y / Ly), orthogonal
on the plate, with plate-bending frequencies
omega_pq = omega_11 ((p/Lx)^2 + (q/Ly)^2) / ((1/Lx)^2 + (1/Ly)^2); omega_11 is
set for a first period of 40 min, which puts the 100th mode's period at about
40 s (37 s here). Energy-normalised: omega_pq^2 s_pq^2 is the same for every
mode, so a modal coefficient of 1 carries the same elastic energy in every
mode; s_11 = 25 m (the paper's "amplitude of vibration about 25 m"). Truth:
A_i(t) = a_i sin(omega_i t + phi_i), a_i ~ U[0, 1], phi_i ~ U[0, 2 pi), no
damping. One range sensor, 30 x 30 pixels, 80 deg field of view, 600 m
above the plate centre looking straight down, so it sees about the central
quarter of the structure; rays that miss the plate return NaN.
Range noise: Gaussian, 1-sigma 3 % of the range. One image per minute.

``Pendulum`` -- the paper's experiment (section VI.B) as a model. Four equal
panels (0.25 m long, 0.30 m wide) hinged in a chain from a fixed top hinge.
Mode shapes: the horizontal displacement u(s) along the chain of the modes of
the linearised quadruple pendulum (four equal point masses at the panel ends,
massless panels), evaluated linearly along each panel. The frequencies and
damping of the first two modes are set to the paper's 4.31 and 8.68 rad/s,
0.049 and 0.143 1/s; a third, heavily damped mode (15.5 rad/s, 2.0 1/s, gone
in under two seconds) is excited too; the fourth is not. Images at 15 Hz:
600 points per image drawn anew each time over the panels (the sample space
changes), 5 % of them missing (NaN), range noise 3 mm along the camera axis
(normal to the panels). The estimator gets mode shapes with an error: each
hinge-angle mode vector is perturbed by a random vector of 5 % of its norm,
and mode 3's estimate also leaks 5 % of mode 1 (as the paper observed),
drawn per trial.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

# ---------------------------------------------------------------------------
# Plate (simulation)


@dataclass
class Plate:
    n_modes: int = 10
    lx_m: float = 2000.0
    ly_m: float = 1732.0
    period1_s: float = 2400.0
    peak1_m: float = 25.0
    pq: np.ndarray = field(init=False)
    omega_radps: np.ndarray = field(init=False)
    scale_m: np.ndarray = field(init=False)

    def __post_init__(self):
        cand = [(p, q) for p in range(1, 40) for q in range(1, 40)]
        k = np.array([(p / self.lx_m) ** 2 + (q / self.ly_m) ** 2 for p, q in cand])
        order = np.argsort(k, kind="stable")
        self._all_pq = np.array(cand)[order]
        self._all_k = k[order]
        self.pq = self._all_pq[: self.n_modes]
        w1 = 2 * np.pi / self.period1_s
        self.omega_radps = w1 * self._all_k[: self.n_modes] / self._all_k[0]
        self.scale_m = self.peak1_m * w1 / self.omega_radps  # energy normalisation

    def mode_period_s(self, index: int) -> float:
        """Period of the index-th mode (0-based) of the full sorted set."""
        w1 = 2 * np.pi / self.period1_s
        return 2 * np.pi / (w1 * self._all_k[index] / self._all_k[0])

    def phi(self, x, y):
        """Mode-shape values (n, M) [m per unit coefficient] at plate points."""
        x = np.asarray(x, float)[:, None]
        y = np.asarray(y, float)[:, None]
        p = self.pq[:, 0][None, :]
        q = self.pq[:, 1][None, :]
        return self.scale_m * np.sin(p * np.pi * x / self.lx_m) * np.sin(q * np.pi * y / self.ly_m)

    def inside(self, x, y):
        return (x >= 0) & (x <= self.lx_m) & (y >= 0) & (y <= self.ly_m)

    def grid(self, n: int = 40):
        """Points of an n x n grid over the whole plate (for the shape RMS)."""
        gx, gy = np.meshgrid((np.arange(n) + 0.5) / n * self.lx_m, (np.arange(n) + 0.5) / n * self.ly_m)
        return gx.ravel(), gy.ravel()


@dataclass
class RangeSensor:
    """Pinhole range imager looking straight down (-z) from pos_m."""

    pos_m: np.ndarray
    pixels: int = 30
    fov_rad: float = np.deg2rad(80.0)

    def rays(self):
        t = np.tan(self.fov_rad / 2) * ((np.arange(self.pixels) + 0.5) / self.pixels * 2 - 1)
        u, v = np.meshgrid(t, t)
        d = np.stack([u.ravel(), v.ravel(), -np.ones(u.size)], axis=1)
        return d / np.linalg.norm(d, axis=1, keepdims=True)


def plate_sensor(plate: Plate) -> RangeSensor:
    """600 m above the plate centre: the 80 deg view covers the central quarter
    of the plate (a corner quadrant of this simply supported plate, where the
    modes are small and nearly dependent, gives cond(M_Y) ~ 1e5 at 10 modes
    and an ill-conditioned M_Y at 50)."""
    return RangeSensor(pos_m=np.array([plate.lx_m / 2, plate.ly_m / 2, 600.0]))


def plate_truth(plate: Plate, rng: np.random.Generator):
    amp = rng.uniform(0.0, 1.0, plate.n_modes)
    phase = rng.uniform(0.0, 2 * np.pi, plate.n_modes)
    return amp, phase


def plate_coeffs(plate: Plate, amp, phase, t):
    return amp * np.sin(plate.omega_radps * t + phase)


def plate_range_image(plate: Plate, sensor: RangeSensor, coeffs, rng, noise_frac=0.03, iters=4):
    """One range image: returns measured ranges (pixels^2,), NaN for misses,
    plus the ray directions."""
    d = sensor.rays()
    s = sensor.pos_m
    r = (0.0 - s[2]) / d[:, 2]  # flat-plate intersection
    for _ in range(iters):  # fixed point on the deformed surface w(x, y)
        x = s[0] + r * d[:, 0]
        y = s[1] + r * d[:, 1]
        w = plate.phi(x, y) @ coeffs
        r = (w - s[2]) / d[:, 2]
    x = s[0] + r * d[:, 0]
    y = s[1] + r * d[:, 1]
    r_meas = r + noise_frac * r * rng.standard_normal(r.size)
    r_meas[~plate.inside(x, y)] = np.nan
    return r_meas, d


POINTS_AT = ("measured", "footprint")


def plate_points(plate: Plate, sensor: RangeSensor, r_meas, d, noise_frac=0.03, at="measured"):
    """Estimator side: measured points -> (phi (n, M), z (n,), var (n,)).
    Deflection = height of the measured point; its variance is the range
    variance projected on the vertical (eq. 4a inputs). Mode shapes at
    at = "measured": the measured point (the paper's "points actually seen").
      Range noise moves it along the ray, so its horizontal position errs
      together with its height (errors in variables): the coarse amplitudes
      of modes symmetric about the view's centre are biased.
    at = "footprint": where the ray meets the undeformed plane (needs the
      ray, known to the sensor), independent of the range noise."""
    if at not in POINTS_AT:
        raise ValueError(f"at: one of {POINTS_AT}, got {at!r}")
    p = sensor.pos_m[None, :] + r_meas[:, None] * d
    if at == "measured":
        phi = plate.phi(p[:, 0], p[:, 1])
    else:
        f = sensor.pos_m[None, :] + (-sensor.pos_m[2] / d[:, 2])[:, None] * d
        phi = plate.phi(f[:, 0], f[:, 1])
    z = p[:, 2]
    var = (noise_frac * r_meas * d[:, 2]) ** 2
    return phi, z, var


# ---------------------------------------------------------------------------
# Quadruple pendulum (experiment analogue)

PENDULUM_OMEGA = np.array([4.31, 8.68, 15.5])
PENDULUM_ALPHA = np.array([0.049, 0.143, 2.0])
# One-significant-digit a priori values, as from a stopwatch (seed VI.B).
PENDULUM_OMEGA_PRIOR = np.array([4.0, 9.0, 20.0])
PENDULUM_ALPHA_PRIOR = np.array([0.1, 0.1, 1.0])


def pendulum_mode_vectors(n_links: int = 4, length_m: float = 0.25, g: float = 9.81):
    """Hinge-angle mode vectors (columns, sorted by frequency) of the
    linearised chain of n equal point masses on massless links."""
    n = n_links
    mass = np.array([[(n - max(i, j)) * length_m**2 for j in range(n)] for i in range(n)], float)
    stiff = np.diag([(n - i) * g * length_m for i in range(n)])
    w2, v = np.linalg.eig(np.linalg.solve(mass, stiff))
    order = np.argsort(w2.real)
    return v[:, order].real


@dataclass
class Pendulum:
    n_links: int = 4
    length_m: float = 0.25
    width_m: float = 0.30
    theta: np.ndarray = field(init=False)  # (4, 4) hinge-angle vectors, unit peak displacement

    def __post_init__(self):
        v = pendulum_mode_vectors(self.n_links, self.length_m)
        for i in range(v.shape[1]):
            u = self.displacement(v[:, i], np.linspace(0, self.n_links * self.length_m, 201))
            v[:, i] /= u[np.argmax(np.abs(u))]
        self.theta = v

    def displacement(self, theta, s):
        """Horizontal displacement [m] at arc length s from the top hinge."""
        s = np.asarray(s, float)
        j = np.clip((s // self.length_m).astype(int), 0, self.n_links - 1)
        cum = np.concatenate([[0.0], np.cumsum(theta * self.length_m)])
        return cum[j] + (s - j * self.length_m) * theta[j]

    def phi(self, theta_modes, s):
        """(n, M) mode-shape values for the given hinge-angle vectors (columns)."""
        return np.stack([self.displacement(theta_modes[:, i], s) for i in range(theta_modes.shape[1])], axis=1)

    def estimator_modes(self, rng, n_modes=3, err=0.05, leak31=0.05):
        th = self.theta[:, :n_modes].copy()
        for i in range(n_modes):
            e = rng.standard_normal(self.n_links)
            th[:, i] += err * np.linalg.norm(th[:, i]) * e / np.linalg.norm(e)
        if n_modes >= 3:
            th[:, 2] += leak31 * self.theta[:, 0]
        return th


def pendulum_coeffs(amp, phase, t, omega=PENDULUM_OMEGA, alpha=PENDULUM_ALPHA):
    return amp * np.exp(-alpha * t) * np.sin(omega * t + phase)


def pendulum_image(pend: Pendulum, coeffs, rng, n_points=600, noise_m=0.003, dropout=0.05):
    """Arc-length positions s (n,) and measured displacements z (n,) (NaN = missing)."""
    s = rng.uniform(0.0, pend.n_links * pend.length_m, n_points)
    z = pend.phi(pend.theta[:, : coeffs.size], s) @ coeffs + noise_m * rng.standard_normal(n_points)
    z[rng.uniform(size=n_points) < dropout] = np.nan
    return s, z

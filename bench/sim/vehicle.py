"""The 3 kg inspector: mass properties and the eight-thruster cold-gas system.

Body frame B: origin at the centre of mass, axes along the edges of a
0.20 m cube-like body (half-size ``HALF_SIZE_M`` = 0.10 m). The docking face
is the body's +y face.

Mass properties: m = 3.0 kg. A uniform 0.20 m cube of 3 kg has
J = m s^2 / 6 = 0.020 kg m^2 about every axis; the tank and avionics make the
body slightly unequal, documented as
    J = diag(0.021, 0.019, 0.020) kg m^2  (principal axes = body axes).

Thrusters: eight 20 mN cold-gas valves, one at each corner of the cube,
r_i = 0.10 m * (+-1, +-1, +-1). Each nozzle lies in the plane of one cube
face and fires along that face's diagonal, so every valve produces both a
force and a torque about the centre of mass. ``DIRECTIONS_B`` is the unit
force on the vehicle (the exhaust leaves the other way). Thrusters come in
antipodal pairs (i, i+4) with opposite position and opposite force: a pair
fired together is a pure couple, and single valves or mixed sets give the
forces. Over the 256 valve configurations the set of wrenches
[F; tau / 0.1 m] positively spans R^6 (checked in tests/py/test_controller.py
by a linear programme), so every direction of translation and rotation can
be commanded.

    i  position r_i / 0.10 m   force direction f_i
    0  (+1, +1, +1)            ( 0, +1, -1)/sqrt2
    1  (+1, +1, -1)            (+1, -1,  0)/sqrt2
    2  (+1, -1, +1)            ( 0, -1, -1)/sqrt2
    3  (+1, -1, -1)            (+1, +1,  0)/sqrt2
    4  (-1, -1, -1)            ( 0, -1, +1)/sqrt2
    5  (-1, -1, +1)            (-1, +1,  0)/sqrt2
    6  (-1, +1, -1)            ( 0, +1, +1)/sqrt2
    7  (-1, +1, +1)            (-1, -1,  0)/sqrt2

Valve configuration k (0..255) has valve i open when bit i of k is set.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

MASS_KG = 3.0
HALF_SIZE_M = 0.10
INERTIA_KGM2 = np.diag([0.021, 0.019, 0.020])
THRUST_N = 0.020
N_THRUSTERS = 8
N_CONFIGS = 2**N_THRUSTERS

_S2 = 1.0 / np.sqrt(2.0)
POSITIONS_B_M = HALF_SIZE_M * np.array(
    [
        [+1, +1, +1],
        [+1, +1, -1],
        [+1, -1, +1],
        [+1, -1, -1],
        [-1, -1, -1],
        [-1, -1, +1],
        [-1, +1, -1],
        [-1, +1, +1],
    ],
    dtype=float,
)
DIRECTIONS_B = _S2 * np.array(
    [
        [0, +1, -1],
        [+1, -1, 0],
        [0, -1, -1],
        [+1, +1, 0],
        [0, -1, +1],
        [-1, +1, 0],
        [0, +1, +1],
        [-1, -1, 0],
    ],
    dtype=float,
)

# Docking face centre in the body frame (the +y face).
DOCK_FACE_B_M = np.array([0.0, HALF_SIZE_M, 0.0])


def config_valves(k: int) -> np.ndarray:
    """Valve states (8,) of configuration k: bit i set means valve i open."""
    return np.array([(int(k) >> i) & 1 for i in range(N_THRUSTERS)], dtype=float)


ALL_VALVES = np.array([config_valves(k) for k in range(N_CONFIGS)])  # (256, 8)


@dataclass
class Vehicle:
    """Mass properties and thruster geometry about the centre of mass.
    ``thrust_n`` is one thrust for every valve or one per valve (K,);
    ``thrust_scale`` (K,) multiplies each valve's thrust (1 = nominal): the
    truth plant can differ from the controller's nominal model through it and
    ``directions_b``. Any number of thrusters K (the bench's inspector has 8;
    a flight log can describe another vehicle, bench/sim/log_description.py)."""

    mass_kg: float = MASS_KG
    inertia_kgm2: np.ndarray = field(default_factory=lambda: INERTIA_KGM2.copy())
    thrust_n: float | np.ndarray = THRUST_N
    positions_b_m: np.ndarray = field(default_factory=lambda: POSITIONS_B_M.copy())
    directions_b: np.ndarray = field(default_factory=lambda: DIRECTIONS_B.copy())
    thrust_scale: np.ndarray = field(default_factory=lambda: np.ones(N_THRUSTERS))

    def thruster_forces_b_n(self) -> np.ndarray:
        """(K, 3) force of each valve on the vehicle, body frame [N]."""
        thrust = np.broadcast_to(np.asarray(self.thrust_n, dtype=float), (self.n_thrusters,))
        return (thrust * np.asarray(self.thrust_scale, dtype=float))[:, None] * self.directions_b

    @property
    def n_thrusters(self) -> int:
        return int(np.asarray(self.directions_b).shape[0])

    def thruster_torques_b_nm(self) -> np.ndarray:
        """(K, 3) torque of each valve about the centre of mass, body frame [N m]."""
        return np.cross(self.positions_b_m, self.thruster_forces_b_n())

    def wrench(self, valves) -> tuple[np.ndarray, np.ndarray]:
        """(force_b_n, torque_b_nm) of a valve vector (8,) of 0/1."""
        v = np.asarray(valves, dtype=float)
        return v @ self.thruster_forces_b_n(), v @ self.thruster_torques_b_nm()

    def config_table(self) -> tuple[np.ndarray, np.ndarray]:
        """Force (256, 3) [N] and torque (256, 3) [N m] of every configuration."""
        return ALL_VALVES @ self.thruster_forces_b_n(), ALL_VALVES @ self.thruster_torques_b_nm()

    def one_thruster_accel_mps2(self) -> float:
        """Acceleration of one nominal valve [m/s^2] (0.020 N / 3 kg; the
        mean valve when their thrusts differ)."""
        return float(np.mean(self.thrust_n)) / self.mass_kg

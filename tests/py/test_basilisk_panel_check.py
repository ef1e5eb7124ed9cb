"""A flexible appendage against a thrust loss (bench/campaigns/basilisk_panel_check.py):
the first 12 s of the 12 kg inspector's characterisation (its two x
thrusters, which turn it about the panel's hinge axis), noise-free. About 20 s."""

from __future__ import annotations

import numpy as np
import pytest

from bench.campaigns import basilisk_crosscheck as xc
from bench.campaigns.basilisk_panel_check import panel_added_on_top, panel_projection
from bench.sim.vehicles import VEHICLES

DESC = VEHICLES["12kg"]()


@pytest.fixture(scope="module")
def projection():
    return panel_projection(DESC, xc.short_plan(DESC, 12.0), 0.5, 0.002)


def test_a_panel_added_on_top_of_the_described_inertia_is_a_thrust_loss(projection):
    # The rigid vehicle is heavier about z by the panel's inertia about the hinge: each
    # pulse turns it by J / (J + I_panel) of the described turn, a loss on both thrusters.
    v = panel_added_on_top(DESC)["vehicle"]
    j_zz, j_on_top = DESC["vehicle"]["inertia_kgm2"][2][2], v["inertia_kgm2"][2][2]
    assert v["mass_kg"] == DESC["vehicle"]["mass_kg"]
    r = projection["panel added on top, rigid"]["gyro"]
    assert r["captured"] > 0.95
    np.testing.assert_allclose(r["loss"][:2], 1.0 - j_zz / j_on_top, rtol=0.1)


def test_the_panel_flown_as_part_of_the_vehicle_is_not_a_thrust_loss(projection):
    for case in ("basilisk panel", "basilisk panel started at rest", "bench mode"):
        r = projection[case]["both"]
        assert r["energy"] > 100.0  # a signature the noise does not hide (sum of squares in noise units)
        assert r["captured"] < 0.05, case

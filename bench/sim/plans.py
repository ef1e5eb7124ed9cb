"""Manoeuvre plans for any described vehicle (bench/sim/vehicle_sim.py), flown
open loop: what a team would fly to characterise its vehicle.

``characterisation_plan``: every thruster alone, pulse-width modulated
(``duty`` of each ``cycle_s`` control cycle, never below the thruster's
minimum on-time) for ``fire_s``, then a coast of ``coast_s`` that holds the
rate change; ``per_run`` thrusters per run, the run's thrusters fired in
``passes`` passes (so that each thruster fires in the first and in the
second half of its run: the diagnosis trains on alternate time blocks and
scores on the others, and a thruster fired once would be seen by one only),
each run from rest at a seeded start about 1.5 m from the host with a
seeded attitude.
"""

from __future__ import annotations

import numpy as np

from bench.sim.log_description import resolve
from bench.sim.vehicle_sim import PlanSegment
from bench.so3 import qexp, qnormalize

# What a bench-inspector campaign run flies: the docking runs alone, or the
# docking runs then the thruster characterisation the diagnoser names to
# separate a nozzle tilt from a thrust loss (each valve alone
# CHARACTERISATION_FIRE_S, then CHARACTERISATION_COAST_S without firing;
# python -m bench.campaigns.gap.characterise compares the two on it).
MANOEUVRES = ("docking", "docking+characterisation")
CHARACTERISATION_FIRE_S, CHARACTERISATION_COAST_S = 3.0, 20.0
DT_S = 0.1  # control interval of the docking scenario (bench/sim/scenario_docking.py)
LEAD_S = 2.0  # valves closed until the first pose has initialised navigation


def characterisation_plan(
    description: dict,
    seed: int = 0,
    fire_s: float = 1.0,
    coast_s: float = 5.0,
    lead_s: float = 1.5,
    duty: float = 0.4,
    cycle_s: float = 0.1,
    per_run: int = 4,
    passes: int = 2,
) -> list:
    desc = resolve(description)
    k = desc.n_thrusters
    rng = np.random.default_rng([int(seed), 0x91A7])
    plan = []
    for first in range(0, k, per_run):
        group = list(range(first, min(first + per_run, k)))
        t_cmd, on = [], []
        t = lead_s
        for i in group * passes:
            n_cyc = int(round(fire_s / cycle_s))
            width = max(duty * cycle_s, desc.thrusters[i].min_on_time_s)
            for c in range(n_cyc):
                row = np.zeros(k)
                row[i] = min(width, cycle_s)
                t_cmd.append(t + c * cycle_s)
                on.append(row)
            t += fire_s + coast_s
        r0 = np.array([0.2, -1.5, 0.1]) + rng.normal(0.0, 0.15, 3)
        q0 = qnormalize(qexp(rng.normal(0.0, 0.3, 3)))
        plan.append(PlanSegment("characterisation", t, r0, q0, np.asarray(t_cmd), np.asarray(on).reshape(-1, k)))
    return plan


def single_valve_scripts(fire_s: float = 2.0, coast_s: float = 10.0, lead_s: float = LEAD_S) -> list:
    """The bench inspector's characterisation, one valve script per valve:
    closed for lead_s, valve i alone for fire_s, closed for coast_s
    (configuration k opens valve i when bit i is set)."""
    n_lead, n_fire, n_coast = (int(round(x / DT_S)) for x in (lead_s, fire_s, coast_s))
    return [[0] * n_lead + [1 << i] * n_fire + [0] * n_coast for i in range(8)]


def scripts_duration_s(scripts: list) -> float:
    return sum(len(s) for s in scripts) * DT_S


def then_scripts(key: dict) -> list | None:
    """The valve scripts flown after the docking runs of a bench-inspector
    campaign run (``key["manoeuvres"]``)."""
    if key.get("manoeuvres", "docking") == "docking":
        return None
    return single_valve_scripts(CHARACTERISATION_FIRE_S, CHARACTERISATION_COAST_S)

"""A valve plan flown over the HIL link (`proxops hil --plan FILE`).

The plan (``proxops plan --separate --json``: run by run, each valve's open
and close times from the run's start) is flown run after run, end to end:
each run's times are offset by the durations of the runs before it, so the
flight side holds one plan from the first run's start to the last run's
end. The bench's docking plant is started as a docking run would be (its
navigation initialised from the first pose); the plan is then uplinked
entry by entry (cmd_plan_entry), loaded (cmd_plan load: the flight side
checks it against its limits and answers with tm_plan_status) and started
at the first IMU tick. From then on the plant fires, in each control
interval, exactly the valves the flight side commanded for it
(tm_plan_valves, answered with the IMU sample that opens the interval);
a command lost on the link leaves the valves closed. Nothing nulls the
rates between runs: the plan's runs start from rest on the vehicle the
plan was designed for, not here.

A load answered "incomplete" (an entry lost on a faulty link) is sent
again, entries and load, up to ``attempts`` times; any other refusal ends
the run before a valve opens.
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from bench.sim.scenario_docking import ScenarioConfig, nav_config, run_docking
from hil_sim import packets as pk
from hil_sim.faults import FaultConfig
from hil_sim.link_nav import LinkNav
from hil_sim.pty_link import BAUD, open_link
from hil_sim.run import Pacer, link_result

_ENTRY = pk.APID_BY_NAME["cmd_plan_entry"].apid
_PLAN = pk.APID_BY_NAME["cmd_plan"].apid
_STATUS = pk.APID_BY_NAME["tm_plan_status"].apid
_VALVES = pk.APID_BY_NAME["tm_plan_valves"].apid
_IMU = pk.APID_BY_NAME["imu_sample"].apid
EDGE_TOL_S = 1e-9  # as the flight side's ValvePlan::kEdgeTolS


def plan_entries(plan: dict) -> tuple[list, float]:
    """([(valve, t_open_s, t_close_s)], duration_s) of a plan file's
    designed schedule (or a bare {"schedule": [...]}), its runs end to end,
    ordered by opening time. Raises ValueError on a file that is no plan."""
    sched = plan.get("designed", plan).get("schedule") if isinstance(plan, dict) else None
    if not isinstance(sched, list) or not sched:
        raise ValueError("no schedule: expected the JSON of `proxops plan --separate --json`")
    entries, t0 = [], 0.0
    for k, run in enumerate(sched):
        try:
            duration = float(run["duration_s"])
            spans = [(int(v), float(a), float(b)) for v, ab in run["valves"].items() for a, b in ab]
        except (KeyError, TypeError, ValueError, AttributeError) as exc:
            raise ValueError(f"schedule run {k}: not a run of a plan ({exc!r})") from None
        if not math.isfinite(duration):
            raise ValueError(f"schedule run {k}: duration_s {duration} is not finite")
        entries += [(v, t0 + a, t0 + b) for v, a, b in spans]
        t0 += duration
    entries.sort(key=lambda e: (e[1], e[0]))
    return entries, t0


def read_plan(path) -> tuple[list, float]:
    """plan_entries of a plan file; FileNotFoundError or ValueError with one line."""
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"--plan {path}: no such file")
    try:
        plan = json.loads(p.read_text())
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"--plan {path}: not a JSON file ({exc})") from None
    try:
        return plan_entries(plan)
    except ValueError as exc:
        raise ValueError(f"--plan {path}: {exc}") from None


def plan_masks(entries: list, duration_s: float, dt_s: float) -> np.ndarray:
    """The valve mask of each control interval [k dt, (k + 1) dt) of the plan."""
    n = int(math.ceil(duration_s / dt_s - 1e-9))
    masks = np.zeros(n, int)
    for v, a, b in entries:
        for k in range(max(0, int(a // dt_s) - 1), min(n, int(b // dt_s) + 2)):
            if min(b, (k + 1) * dt_s) - max(a, k * dt_s) > EDGE_TOL_S:
                masks[k] |= 1 << v
    return masks


class PlanLinkNav(LinkNav):
    """LinkNav that, at the navigation's first initialisation, uplinks the
    plan, loads and starts it, and keeps the flight side's valve command of
    every interval (``commands``: IMU tick -> tm_plan_valves fields)."""

    def __init__(self, link, entries: list, duration_s: float, plan_id: int = 1, dt_s: float = 0.1, **kw):
        super().__init__(link, send_valves=False, **kw)
        self.entries, self.duration_s, self.plan_id, self.dt_s = entries, duration_s, plan_id, dt_s
        self.attempts = 5
        self.answer_timeout_s = max(1.0, 20 * self.step_timeout_s)
        self.commands: dict = {}  # tick index (round(t / dt)) -> decoded tm_plan_valves
        self.statuses: list = []  # every tm_plan_status, in arrival order
        self.verdict: str | None = None  # of the load, then "started" refusals aside
        self.started = False
        self.ended: str | None = None  # "finished" or "aborted" once the flight side says so

    def init(self, t_s, r_hill_m, v_hill_mps, q_hb, P0):
        rec = super().init(t_s, r_hill_m, v_hill_mps, q_hb, P0)
        if self.verdict is None:
            self._uplink(float(t_s))
        return rec

    def _uplink(self, t_s: float):
        payloads = pk.plan_entry_payloads(self.plan_id, self.entries)
        st = None
        for _ in range(self.attempts):
            for pl in payloads:
                self._send(_ENTRY, t_s, pl, hold=True)
            st = self._command("load", t_s, len(payloads), self.duration_s)
            if st is not None and st["verdict"] != "incomplete":
                break
        self.verdict = "no answer" if st is None else st["verdict"]
        if self.verdict != "accepted":
            return
        for attempt in range(self.attempts):
            st = self._command("start", t_s + self.dt_s)
            # A start whose answer was lost is running already: a repeat is refused as "running".
            if st is not None and (st["verdict"] == "accepted" or (attempt and st["verdict"] == "running")):
                self.started = True
                return

    def _command(self, action: str, t_s: float, count: int = 0, duration_s: float = 0.0):
        """Sends cmd_plan and waits for its tm_plan_status (None: lost)."""
        code = pk.PLAN_ACTIONS[action]
        n0 = len(self.statuses)
        self._send(_PLAN, t_s, pk.plan_command_payload(action, self.plan_id, count, duration_s))
        self._wait(lambda: any(s["action"] == code for s in self.statuses[n0:]), self.answer_timeout_s)
        got = [s for s in self.statuses[n0:] if s["action"] == code]
        return got[-1] if got else None

    def _wait(self, done, timeout_s: float):
        deadline = time.perf_counter() + timeout_s
        while not done() and time.perf_counter() < deadline:
            self.link.pump(0.01)
            data = self.link.read_available()
            for item in self.deframer.feed(data) if data else ():
                if isinstance(item, pk.Packet):
                    self._on_packet(item, _Dummy())

    def _step(self, apid, t_s, payload):
        rec = super()._step(apid, t_s, payload)
        if apid == _IMU and self.started and self.ended is None:
            k = self.tick(t_s)
            self._wait(lambda: k in self.commands or self.ended is not None, self.step_timeout_s)
        return rec

    def tick(self, t_s: float) -> int:
        return int(round(float(t_s) / self.dt_s))

    def _on_packet(self, p, rec) -> bool:
        if p.apid == _VALVES:
            v = pk.decode_plan_valves(p.payload)
            if v["state"] == "running":
                self.commands[self.tick(p.t_s - self.time_offset_s)] = v
            else:
                self.ended = v["state"]
            return False
        if p.apid == _STATUS:
            self.statuses.append(pk.decode_plan_status(p.payload))
            return False
        return super()._on_packet(p, rec)

    def mask(self, k: int) -> int:
        """The valves the flight side commanded for control interval k
        (closed when its command never arrived)."""
        c = self.commands.get(k)
        return 0 if c is None else int(c["valve_mask"])


class _Dummy:
    """A step record nobody reads (telemetry read while waiting on a command)."""

    received = False

    def __setattr__(self, name, value):
        pass


class FlightValves:
    """The docking run's valve script: interval k fires what the flight side
    commanded for it (PlanLinkNav.mask); n steps."""

    def __init__(self, nav: PlanLinkNav, n: int):
        self.nav, self.n = nav, n

    def __len__(self) -> int:
        return self.n if self.nav.started else 0  # a refused plan flies nothing

    def __getitem__(self, k: int) -> int:
        return self.nav.mask(k)


@dataclass
class PlanHilConfig:
    entries: list
    duration_s: float
    seed: int = 1
    realtime: bool = False
    faults: FaultConfig = field(default_factory=FaultConfig)
    step_timeout_s: float = 0.05
    device: str | None = None
    baud: int = BAUD
    plan_id: int = 1


def run_plan_hil(cfg: PlanHilConfig) -> dict:
    """Flies the plan over the link (module docstring). Returns run_hil's
    figures and ``plan``: the verdict, the commands and the comparison."""
    base = ScenarioConfig()
    dt = base.dt_s
    n = int(math.ceil(cfg.duration_s / dt - 1e-9)) + 2  # lead interval, the plan, the finishing tick
    link = open_link(faults_up=cfg.faults, faults_down=cfg.faults, seed=cfg.seed, device=cfg.device, baud=cfg.baud)
    nav = PlanLinkNav(link, cfg.entries, cfg.duration_s, cfg.plan_id, dt, step_timeout_s=cfg.step_timeout_s)
    sc = ScenarioConfig(**{**base.__dict__, "t_max_s": n * dt + dt, "valve_script": FlightValves(nav, n)})
    wall0 = time.perf_counter()
    pacer = Pacer(cfg.realtime, 0.0, wall0)
    runs = []
    try:
        nav.configure_nav(nav_config(sc), t_s=0.0)
        run = run_docking(cfg.seed, sc, nav=nav, on_step=pacer)
        if nav.started:
            runs.append(run)
    finally:
        wall = time.perf_counter() - wall0
        ended = link.close()
    res = link_result(nav, link, runs, wall, sum(float(r.summary.t_end_s) + dt for r in runs), [pacer], ended)
    res["plan"] = plan_summary(nav, runs, dt)
    return res


def plan_summary(nav: PlanLinkNav, runs: list, dt: float) -> dict:
    """The plan's verdict and, when flown, the valves the plant fired
    against the plan's masks, interval by interval."""
    want = plan_masks(nav.entries, nav.duration_s, dt)
    out = {
        "entries": len(nav.entries),
        "duration_s": nav.duration_s,
        "on_time_s": float(sum(b - a for _, a, b in nav.entries)),
        "verdict": nav.verdict,
        "started": nav.started,
        "ended": nav.ended,
        "commands_received": len(nav.commands),
        "flight_status": nav.statuses[-1] if nav.statuses else None,
    }
    if not runs:
        return out
    # Interval 0 is the lead (the start is tagged at the first tick); the
    # plan's interval j is the run's interval j + 1.
    flown = np.asarray(runs[0].config, int)[1 : 1 + len(want)]
    flown = np.concatenate([flown, np.zeros(len(want) - len(flown), int)])
    fired = np.asarray(runs[0].config, int)
    out.update(
        {
            "intervals": int(len(want)),
            "intervals_firing": int(np.count_nonzero(want)),
            "intervals_differing": int(np.count_nonzero(flown != want)),
            "firing_outside_the_plan": int(np.count_nonzero(fired[0])) + int(np.count_nonzero(fired[1 + len(want) :])),
            "valve_seconds_planned": float(sum(bin(int(m)).count("1") for m in want) * dt),
            "valve_seconds_flown": float(sum(bin(int(m)).count("1") for m in fired) * dt),
        }
    )
    return out

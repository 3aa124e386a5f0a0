"""Hazard events made on purpose near the ego, with SUMO's own commands (with traffic.py, the
modules that talk to libsumo).

Each hazard kind of the scenario is due about ``per_minute`` times a simulated minute
(exponential waits, from the scenario's seed); when one is due, it starts at the first step
where the traffic around the ego allows it:

Cut-ins, hard braking and jaywalkers start only where the ego's lane runs straight ahead (a
time to collision under constant velocity means little in a bend, and a jaywalker crosses in
the direction the road has at its start).

- ``cut_in``: a vehicle ahead of the ego in a lane beside it, ``distance_m`` and ``time_gap_s``
  ahead, changes into the ego's lane at once (lane-change mode 0: SUMO's safety checks off for
  this change) and slows to 60 % of the ego's speed within a second (braking at most at
  5 m/s^2), holding it 4 s, so the gap closes; SUMO's car-following brakes the ego. The
  vehicle is chosen from 15 m behind to 60 m ahead of the ego's front, and driven 2 m/s faster
  or slower than the ego until it is the drawn gap ahead and the ego's lane has room for it
  (1 m before the ego's leader).
- ``hard_brake``: the ego's leader within ``distance_m`` brakes at ``decel_mps2`` to
  ``to_speed_mps``, holds it 2 s, then drives on; the ego follows with SUMO's car-following.
- ``jaywalker``: a pedestrian steps off the kerb on the ego's side and walks across at
  ``walk_mps`` outside any crossing, where it reaches the ego's path when the ego is its
  braking distance (at 7.5 m/s^2) plus 5 m away (within ``distance_m``); from just before the
  front bumper of the tallest parked car standing near there, in line behind it as the ego
  sees it. Jaywalkers are the scene's shortest pedestrian type. The ego brakes (up to 7.5 m/s^2) for a
  pedestrian within 40 m ahead that is in its path or will be before it could stop.
- ``red_light``: while the ego approaches a green light ``distance_m`` away, a vehicle on a
  crossing approach with red drives through (speed mode 7: red lights and right of way
  ignored), timed to clear the junction at least 1.5 s before the ego can reach it at its
  speed, or, when it cannot, slowed to enter 1.5 s after the ego has crossed.

An event ends after a fixed time (cut_in 6 s, hard_brake when its hold ends, jaywalker when
the pedestrian has crossed, red_light 10 s) or when an actor leaves the simulation; the
actors get their SUMO settings back. :meth:`HazardController.active` lists the events
under way, which the world state carries to the labels.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from cosim.scenario import HazardConfig
from gtgen.frame import ActiveHazard
from networks.sumo_tools import sumo_home

sumo_home()  # exports SUMO_HOME before libsumo loads
import libsumo  # noqa: E402

LANE_CHANGE_DEFAULT = 0b011001010101  # SUMO's default lane-change mode (1621)
SPEED_DEFAULT = 31
IGNORE_RED_AND_RIGHT_OF_WAY = 7  # speed mode: safe speed, acceleration and deceleration limits only
EGO_STOP_DECEL = 7.5
CUT_IN_HOLD_S, CUT_IN_S = 4.0, 6.0
CUT_IN_SPEED_SHARE, CUT_IN_BRAKE_S = 0.6, 1.0  # the cutting vehicle slows to 60 % of the ego's speed in 1 s
CUT_IN_ROOM_M = 1.0  # free space it needs in front of it in the ego's lane (no one is cut into)
CUT_IN_MAX_DECEL = 5.0  # m/s^2: the cutting vehicle brakes no harder than this (the ego can follow)
CUT_IN_SPEED_FACTOR = 1.3  # of the speed limit, while it overtakes the ego
CUT_IN_BEHIND_M = 15.0  # it may start up to this far behind the ego's front, and overtake
CUT_IN_LOOK_M, CUT_IN_APPROACH_MPS, CUT_IN_APPROACH_S = 60.0, 2.0, 12.0  # its approach: from up to 60 m ahead
HOLD_S = 2.0
RED_LIGHT_S = 10.0
RED_RUN_MPS = 9.0  # a red-light runner speeds up to at least this
RED_MARGIN_S = 1.5  # it leaves the junction this long before the ego can reach it (or enters after)
JUNCTION_M = 25.0  # the way through a junction
JAYWALK_PATH_M, JAYWALK_LOOK_M = 1.8, 40.0  # the ego's path: this far either side of its lane centre
JAYWALK_STEP_M = 0.6  # the pedestrian starts this far beyond the kerb
JAYWALK_HIDDEN_M = 0.5  # and this much farther when it starts in front of a parked car


@dataclass(slots=True)
class _Event:
    number: int
    kind: str
    actors: list[str]
    ends_s: float
    restore: list[Callable[[], None]] = field(default_factory=list)
    path: tuple[np.ndarray, np.ndarray, float] | None = None  # jaywalker: start, unit direction, length
    started_s: float = 0.0
    hidden: bool = False  # a cut-in's approach: not an event yet
    gap_m: float = 0.0  # the gap a cut-in is made at
    config: HazardConfig | None = None  # the scenario's entry it was made for


class HazardController:
    def __init__(
        self, hazards: tuple[HazardConfig, ...], seed: int, parked: set[str], walk_edges: list[str],
        pedestrian_type: str = "",
    ) -> None:  # fmt: skip
        self._hazards = hazards
        self._pedestrian_type = pedestrian_type  # the jaywalkers' (the smallest of the scene's pedestrians)
        self._walk_edges = sorted(walk_edges)
        self._rng = np.random.default_rng([seed, 0x4A2D])
        self._parked = parked
        self._due: list[float] | None = None  # drawn at the first step, from its time
        self._active: dict[int, _Event] = {}  # by hazard index
        self._count = 0
        self._people = 0

    def _wait(self, hazard: HazardConfig, now: float = 0.0) -> float:
        return now + float(self._rng.exponential(60.0 / hazard.per_minute))

    def step(self, ego: str, now: float) -> None:
        """Move the events under way, end those that are over, start those that are due."""
        if self._due is None:
            self._due = [self._wait(h, now) for h in self._hazards]
        due = self._due
        for index, event in list(self._active.items()):
            was_hidden = event.hidden
            try:
                done = self._advance(event, ego, now)
            except libsumo.TraCIException:
                done = True  # an actor left the simulation
            if was_hidden and not event.hidden:  # a cut-in's approach became the event: the next wait starts
                due[index] = self._wait(self._hazards[index], now)
            elif was_hidden and done:
                due[index] = now + 1.0  # the approach came to nothing: another candidate soon
            if done:
                for undo in event.restore:
                    with contextlib.suppress(libsumo.TraCIException):  # an actor gone
                        undo()
                del self._active[index]
        for index, hazard in enumerate(self._hazards):
            if index in self._active or now < due[index]:
                continue
            try:
                started = self._start(hazard, ego, now)
            except libsumo.TraCIException:
                started = None
            if started is not None:
                started.started_s = now
                self._active[index] = started
                if not started.hidden:
                    due[index] = self._wait(hazard, now)

    def active(self, track_id: Callable[[str], int], ego: str) -> tuple[ActiveHazard, ...]:
        shown = sorted((e for e in self._active.values() if not e.hidden), key=lambda e: e.number)
        return tuple(ActiveHazard(f"{e.kind}-{e.number}", e.kind, tuple(track_id(a) for a in e.actors),
                                  track_id(ego)) for e in shown)  # fmt: skip

    # --- one step of an event under way ----------------------------------------------------
    def _advance(self, event: _Event, ego: str, now: float) -> bool:
        config = event.config
        if config is None:
            return True
        if event.hidden:
            return not self._cut_now(event, config, ego, now)
        if event.kind == "jaywalker" and event.path is not None:
            start, direction, length = event.path
            walked = (now - event.started_s) * config.walk_mps
            person = event.actors[0]
            if walked >= length:
                return True
            x, y = start + direction * walked
            angle = math.degrees(math.atan2(direction[0], direction[1])) % 360.0  # SUMO: clockwise from north
            libsumo.person.moveToXY(person, "", float(x), float(y), angle, keepRoute=2)
            ex, ey = libsumo.vehicle.getPosition(ego)
            heading = math.radians(90.0 - libsumo.vehicle.getAngle(ego))
            fwd = np.array([math.cos(heading), math.sin(heading)])
            rel = np.array([x - ex, y - ey])
            along, across = float(rel @ fwd), float(rel @ np.array([-fwd[1], fwd[0]]))
            speed = libsumo.vehicle.getSpeed(ego)
            entering_s = max(0.0, (abs(across) - JAYWALK_PATH_M) / config.walk_mps)
            coming = across < JAYWALK_PATH_M and entering_s <= speed / EGO_STOP_DECEL + 1.0
            if -6.0 < along < JAYWALK_LOOK_M and coming:
                libsumo.vehicle.setSpeed(ego, 0.0)  # the ego stops for a pedestrian stepping into its path
            else:
                libsumo.vehicle.setSpeed(ego, -1.0)
        return now >= event.ends_s

    # --- starting an event ------------------------------------------------------------------
    def _start(self, hazard: HazardConfig, ego: str, now: float) -> _Event | None:
        start = {"cut_in": self._cut_in, "hard_brake": self._hard_brake, "jaywalker": self._jaywalker,
                 "red_light": self._red_light}[hazard.kind]  # fmt: skip
        event = start(hazard, ego, now)
        if event is not None:
            event.config = hazard
        if event is not None and not event.hidden:
            self._count += 1
            event.number = self._count
        return event

    def _movable(self, vid: str, ego: str) -> bool:
        """A vehicle that can act in a new event: not the ego, parked, a bicycle, or in an event."""
        busy = {a for e in self._active.values() for a in e.actors}
        return (bool(vid) and vid != ego and vid not in self._parked and vid not in busy
                and libsumo.vehicle.getVehicleClass(vid) not in ("bicycle", "pedestrian"))  # fmt: skip

    def _cut_in(self, hazard: HazardConfig, ego: str, now: float) -> _Event | None:
        """A vehicle ahead in a lane beside the ego is held a little slower than the ego
        (unseen as an event) until the gap is as drawn, then cuts in."""
        ego_speed = libsumo.vehicle.getSpeed(ego)
        if ego_speed < 3.0 or not _straight_ahead(ego, STRAIGHT_REACH_M):
            return None
        gaps = _side_gaps(ego)
        candidates = [vid for vid, gap in gaps.items()
                      if self._movable(vid, ego) and -CUT_IN_BEHIND_M <= gap <= CUT_IN_LOOK_M]  # fmt: skip
        if not candidates:
            return None
        vid = sorted(candidates)[int(self._rng.integers(0, len(candidates)))]
        gap_m = float(self._rng.uniform(*hazard.distance_m))
        factor = libsumo.vehicle.getSpeedFactor(vid)
        libsumo.vehicle.setSpeedFactor(vid, max(factor, CUT_IN_SPEED_FACTOR))  # it may pass the ego at the limit
        libsumo.vehicle.setSpeed(vid, _approach_speed(ego_speed, gaps[vid], gap_m))
        restore = [lambda: libsumo.vehicle.setSpeed(vid, -1.0), lambda: libsumo.vehicle.setSpeedFactor(vid, factor)]
        event = _Event(0, "cut_in", [vid], now + CUT_IN_APPROACH_S, restore)
        event.hidden, event.gap_m = True, gap_m
        return event

    def _cut_now(self, event: _Event, hazard: HazardConfig, ego: str, now: float) -> bool:
        """During a cut-in's approach: cut in once the gap is as drawn (True: the event goes on)."""
        vid = event.actors[0]
        ego_speed = libsumo.vehicle.getSpeed(ego)
        gaps = _side_gaps(ego)
        if vid not in gaps or ego_speed < 3.0:
            return now < event.ends_s
        gap = gaps[vid]
        libsumo.vehicle.setSpeed(vid, _approach_speed(ego_speed, gap, event.gap_m))
        if gap < hazard.distance_m[0]:
            return now < event.ends_s  # not far enough ahead yet
        slow = libsumo.vehicle.getSpeed(vid) < ego_speed - CUT_IN_APPROACH_MPS - 2.0  # it would be rammed
        leader = libsumo.vehicle.getLeader(ego, gap + 40.0)
        room = not leader or not leader[0] or leader[1] >= gap + libsumo.vehicle.getLength(vid) + CUT_IN_ROOM_M
        if slow or not room or gap > event.gap_m or not hazard.time_gap_s[0] <= gap / ego_speed <= hazard.time_gap_s[1]:
            return now < event.ends_s
        lane = libsumo.vehicle.getLaneIndex(ego)
        libsumo.vehicle.setLaneChangeMode(vid, 0)
        libsumo.vehicle.changeLane(vid, lane, CUT_IN_HOLD_S)
        slower = max(CUT_IN_SPEED_SHARE * ego_speed, ego_speed - CUT_IN_MAX_DECEL * CUT_IN_BRAKE_S)
        decel = libsumo.vehicle.getDecel(vid)
        libsumo.vehicle.setDecel(vid, max(decel, (ego_speed - slower) / CUT_IN_BRAKE_S))
        libsumo.vehicle.slowDown(vid, slower, CUT_IN_BRAKE_S)
        libsumo.vehicle.setSpeed(vid, slower)
        event.restore += [lambda: libsumo.vehicle.setDecel(vid, decel),
                          lambda: libsumo.vehicle.setLaneChangeMode(vid, LANE_CHANGE_DEFAULT)]  # fmt: skip
        self._count += 1
        event.number, event.hidden, event.started_s, event.ends_s = self._count, False, now, now + CUT_IN_S
        return True

    def _hard_brake(self, hazard: HazardConfig, ego: str, now: float) -> _Event | None:
        lo, hi = hazard.distance_m
        if not _straight_ahead(ego, min(hi + 10.0, STRAIGHT_REACH_M)):
            return None
        leader = libsumo.vehicle.getLeader(ego, hi)
        if not leader or not leader[0]:
            return None
        vid, gap = leader
        speed = libsumo.vehicle.getSpeed(vid)
        if not self._movable(vid, ego) or not lo <= gap <= hi or speed < hazard.to_speed_mps + 4.0:
            return None
        decel, emergency = libsumo.vehicle.getDecel(vid), libsumo.vehicle.getEmergencyDecel(vid)
        libsumo.vehicle.setEmergencyDecel(vid, max(emergency, hazard.decel_mps2))
        libsumo.vehicle.setDecel(vid, hazard.decel_mps2)
        braking_s = (speed - hazard.to_speed_mps) / hazard.decel_mps2
        libsumo.vehicle.slowDown(vid, hazard.to_speed_mps, braking_s)
        libsumo.vehicle.setSpeed(vid, hazard.to_speed_mps)
        restore = [lambda: libsumo.vehicle.setSpeed(vid, -1.0), lambda: libsumo.vehicle.setDecel(vid, decel),
                   lambda: libsumo.vehicle.setEmergencyDecel(vid, emergency)]  # fmt: skip
        return _Event(0, "hard_brake", [vid], now + braking_s + HOLD_S, restore)

    def _jaywalker(self, hazard: HazardConfig, ego: str, now: float) -> _Event | None:
        """A pedestrian at the kerb on the ego's side steps out where it reaches the ego's path
        when the ego is about its braking distance (plus 5 m) away."""
        lane_id = libsumo.vehicle.getLaneID(ego)
        speed = libsumo.vehicle.getSpeed(ego)
        if speed < 2.0 or not self._walk_edges or not _straight_ahead(ego, STRAIGHT_REACH_M):
            return None  # on a straight road: the crossing direction, fixed at the start, stays across
        edge, lane_index = libsumo.vehicle.getRoadID(ego), libsumo.vehicle.getLaneIndex(ego)
        lanes = libsumo.edge.getLaneNumber(edge)
        driving = [i for i in range(lanes) if "passenger" not in libsumo.lane.getDisallowed(f"{edge}_{i}")]
        if lane_index not in driving:
            return None
        widths = [libsumo.lane.getWidth(f"{edge}_{i}") for i in range(lanes)]
        kerb_m = widths[lane_index] / 2.0 + sum(widths[min(driving) : lane_index])  # ego lane centre to kerb
        across_path = kerb_m + JAYWALK_STEP_M - JAYWALK_PATH_M  # walked until the pedestrian is in the ego's path
        fast = speed + 2.0  # the ego may speed up meanwhile
        reach = fast * across_path / hazard.walk_mps + fast * fast / (2.0 * EGO_STOP_DECEL) + 5.0
        lo, hi = hazard.distance_m
        if not lo <= reach <= hi:
            return None
        position = libsumo.vehicle.getLanePosition(ego)
        if reach + 10.0 > libsumo.lane.getLength(lane_id) - position:
            return None  # stay on the ego's road
        # the road's own direction and the ego's place across it (the ego may be changing lanes)
        ex, ey = libsumo.simulation.convert2D(edge, position, lane_index)
        ax, ay = libsumo.simulation.convert2D(edge, position + reach, lane_index)
        fwd = np.array([ax - ex, ay - ey]) / max(math.hypot(ax - ex, ay - ey), 1e-6)
        left = np.array([-fwd[1], fwd[0]])
        leader = libsumo.vehicle.getLeader(ego, reach + 20.0)
        if leader and leader[0] and leader[1] < reach + 8.0:
            return None  # a vehicle ahead would drive through the pedestrian
        along, across = reach, -(kerb_m + JAYWALK_STEP_M)
        if hazard.behind_parked:  # from just before the front bumper of the tallest parked car near there
            near = []
            for vid in sorted(self._parked):
                px, py = libsumo.vehicle.getPosition(vid)  # its front bumper
                rel = np.array([px - ex, py - ey])
                if abs(float(rel @ fwd) - reach) < 6.0 and -kerb_m - 4.5 < float(rel @ left) < -kerb_m:
                    near.append((libsumo.vehicle.getHeight(vid), float(rel @ fwd)))
            if near:
                along = max(near)[1] + 0.6
                across -= JAYWALK_HIDDEN_M  # in line behind it, seen from the ego
        start = np.array([ex, ey]) + fwd * along + left * across
        length = abs(across) + widths[lane_index] / 2.0 + sum(widths[lane_index + 1 : max(driving) + 1]) + 1.0
        self._people += 1
        person = f"jaywalker_{self._people}"
        libsumo.person.add(person, self._walk_edges[0], 0.0, typeID=self._pedestrian_type or "DEFAULT_PEDTYPE")
        libsumo.person.appendWaitingStage(person, 3600.0)
        libsumo.person.moveToXY(person, "", float(start[0]), float(start[1]), 0.0, keepRoute=2)
        decel = libsumo.vehicle.getDecel(ego)
        libsumo.vehicle.setDecel(ego, max(decel, EGO_STOP_DECEL))
        restore = [lambda: libsumo.person.remove(person), lambda: libsumo.vehicle.setSpeed(ego, -1.0),
                   lambda: libsumo.vehicle.setDecel(ego, decel)]  # fmt: skip
        event = _Event(0, "jaywalker", [person], now + length / hazard.walk_mps + 1.0, restore)
        event.path = (start, left.copy(), length)
        return event

    def _red_light(self, hazard: HazardConfig, ego: str, now: float) -> _Event | None:
        lo, hi = hazard.distance_m
        ahead = [t for t in libsumo.vehicle.getNextTLS(ego) if lo <= t[2] <= hi]
        if not ahead:
            return None
        tls, ego_link, ego_dist, ego_state = ahead[0]
        if ego_state not in "Gg":
            return None
        ego_speed = max(libsumo.vehicle.getSpeed(ego), 1.0)
        ego_time = ego_dist / ego_speed  # until the ego reaches its stop line
        ego_clear = (ego_dist + JUNCTION_M) / ego_speed + RED_MARGIN_S  # until it has crossed, with a margin
        state = libsumo.trafficlight.getRedYellowGreenState(tls)
        links = libsumo.trafficlight.getControlledLinks(tls)
        ego_in = links[ego_link][0][0] if links[ego_link] else ""
        candidates = []
        for index, link in enumerate(links):
            if not link or state[index] not in "rR":
                continue
            lane = link[0][0]
            if lane.rsplit("_", 1)[0] == ego_in.rsplit("_", 1)[0]:
                continue
            for vid in libsumo.lane.getLastStepVehicleIDs(lane):
                if not self._movable(vid, ego):
                    continue
                speed = libsumo.vehicle.getSpeed(vid)
                dist = libsumo.lane.getLength(lane) - libsumo.vehicle.getLanePosition(vid)
                if speed < 2.0 or not 3.0 <= dist <= 60.0:
                    continue
                run_speed = max(speed, RED_RUN_MPS)
                if (dist + JUNCTION_M) / (0.5 * (speed + run_speed)) + RED_MARGIN_S <= ego_time:
                    candidates.append((vid, run_speed, RED_LIGHT_S))  # through before the ego
                elif dist / ego_clear >= 3.0:  # through behind the ego, at a speed that brings it there then
                    candidates.append((vid, dist / ego_clear, ego_clear + JUNCTION_M / (dist / ego_clear) + 1.0))
        if not candidates:
            return None
        vid, speed, lasts_s = sorted(candidates)[int(self._rng.integers(0, len(candidates)))]
        libsumo.vehicle.setSpeedMode(vid, IGNORE_RED_AND_RIGHT_OF_WAY)
        libsumo.vehicle.setSpeed(vid, speed)
        restore = [
            lambda: libsumo.vehicle.setSpeed(vid, -1.0),
            lambda: libsumo.vehicle.setSpeedMode(vid, SPEED_DEFAULT),
        ]
        return _Event(0, "red_light", [vid], now + max(RED_LIGHT_S, lasts_s), restore)


STRAIGHT_DEG = 4.0
STRAIGHT_REACH_M = 30.0


def _approach_speed(ego_speed: float, gap_m: float, wanted_m: float) -> float:
    """A cut-in's approach: pass the ego (2 m/s faster) until the wanted gap, then let the ego
    close in (2 m/s slower)."""
    return ego_speed + CUT_IN_APPROACH_MPS if gap_m < wanted_m else max(ego_speed - CUT_IN_APPROACH_MPS, 1.0)


def _side_gaps(ego: str) -> dict[str, float]:
    """The vehicles in the lanes beside the ego's on its road, each with its gap ahead of the
    ego (from the ego's front bumper to its rear; negative: beside or behind)."""
    road = libsumo.vehicle.getRoadID(ego)
    if road.startswith(":"):
        return {}
    index, position = libsumo.vehicle.getLaneIndex(ego), libsumo.vehicle.getLanePosition(ego)
    gaps = {}
    for side in (index - 1, index + 1):
        if 0 <= side < libsumo.edge.getLaneNumber(road):
            for vid in libsumo.lane.getLastStepVehicleIDs(f"{road}_{side}"):
                gaps[vid] = libsumo.vehicle.getLanePosition(vid) - libsumo.vehicle.getLength(vid) - position
    return gaps


def _straight_ahead(ego: str, reach_m: float) -> bool:
    """Whether the ego's lane runs straight (within ``STRAIGHT_DEG``) over ``reach_m`` ahead:
    there, constant velocities predict where the ego and the vehicles ahead go, and a time to
    collision means what it says."""
    road = libsumo.vehicle.getRoadID(ego)
    if road.startswith(":"):
        return False
    lane_index, position = libsumo.vehicle.getLaneIndex(ego), libsumo.vehicle.getLanePosition(ego)
    length = libsumo.lane.getLength(libsumo.vehicle.getLaneID(ego))
    if position + reach_m > length:
        return False
    x0, y0 = libsumo.simulation.convert2D(road, position, lane_index)
    x1, y1 = libsumo.simulation.convert2D(road, position + reach_m / 2.0, lane_index)
    x2, y2 = libsumo.simulation.convert2D(road, position + reach_m, lane_index)
    turn = math.atan2(y2 - y1, x2 - x1) - math.atan2(y1 - y0, x1 - x0)
    return abs(math.degrees(math.atan2(math.sin(turn), math.cos(turn)))) <= STRAIGHT_DEG


__all__ = ["ActiveHazard", "HazardController"]

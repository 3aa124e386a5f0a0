"""Hazard events made on purpose near the ego, with SUMO's own commands (with traffic.py, the
modules that talk to libsumo).

Each hazard kind of the scenario is due about ``per_minute`` times a simulated minute (spaced
0.5 to 1.5 times 60 / per_minute apart, from the scenario's seed); when one is due, it starts
at the first step where the traffic around the ego allows it, and the next is due from when
this one was (up to two events a kind are owed, so waiting for the traffic does not lower the
rate where it allows events later).

Cut-ins, hard braking and jaywalkers start only where the ego's way (its lane and the lanes its
route goes on) runs straight ahead (a time to collision under constant velocity means little in
a bend, and a jaywalker crosses in the direction the road has at its start); a hard brake also
on a gentle bend when its leader is in line with the ego.

- ``cut_in``: a vehicle in a lane beside the ego (SUMO's nearest neighbours left and right, from
  30 m behind to 40 m ahead, whose route goes on where the ego's does) is driven at the ego's
  speed, up to 6 m/s faster or 4 m/s slower, until it is a gap within ``distance_m`` and
  ``time_gap_s`` ahead, at the ego's pace, with room before the ego's leader; then it changes
  into the ego's lane at once (lane-change mode 0: SUMO's safety checks off for this change)
  and slows to half the ego's speed within 2 s (braking at most at 5 m/s^2), holding it 4 s.
  The ego keeps its lane and its driver reacts a second late (SUMO's action step length), then
  brakes with SUMO's car-following.
- ``hard_brake``: the ego's leader within ``distance_m`` brakes at ``decel_mps2`` to
  ``to_speed_mps``, holds it 2 s, then drives on; the ego follows with SUMO's car-following.
- ``jaywalker``: a pedestrian (by default a child of Euro NCAP's child target size) steps off
  the kerb on the ego's side and walks across at ``walk_mps`` outside any crossing, where it
  reaches the ego's path when the ego is its braking distance (at 7.5 m/s^2) plus 5 m away
  (within ``distance_m``); from just before the front bumper of the tallest parked car
  standing near there, in line behind it as the ego sees it (with ``behind_parked``, a
  jaywalker due waits up to 20 s for such a place, then steps out in the open). The ego brakes (up to 7.5 m/s^2)
  for a pedestrian within 40 m ahead that is in its path or will be before it could stop.
- ``red_light``: while the ego approaches a green light ``distance_m`` away, a vehicle on a
  crossing approach with red (moving, or the first in its queue) drives through (speed mode 7:
  red lights and right of way ignored), timed to clear the junction at least 1.5 s before the
  ego can reach it at its speed, or, when it cannot, slowed to enter 1.5 s after the ego has
  crossed.

An event ends after a fixed time (cut_in 6 s, hard_brake when its hold ends, jaywalker when
the pedestrian has crossed, red_light 10 s) or when an actor leaves the simulation; the
actors (and the ego) get their SUMO settings back. :meth:`HazardController.active` lists the
events under way, which the world state carries to the labels.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from cosim.kinematics import sumo_angle_to_yaw
from cosim.scenario import HazardConfig
from gtgen.frame import ActiveHazard
from networks.sumo_tools import sumo_home

sumo_home()  # exports SUMO_HOME before libsumo loads
import libsumo  # noqa: E402

# Jaywalking children: a pedestrian type of Euro NCAP's child target's size, made with the controller.
CHILD_TYPE = "pedestrian_child"
CHILD_LWH_M = (0.25, 0.4, 1.15)

LANE_CHANGE_DEFAULT = 0b011001010101  # SUMO's default lane-change mode (1621)
SPEED_DEFAULT = 31
IGNORE_RED_AND_RIGHT_OF_WAY = 7  # speed mode: safe speed, acceleration and deceleration limits only
EGO_STOP_DECEL = 7.5
CUT_IN_HOLD_S, CUT_IN_S = 4.0, 6.0
CUT_IN_SPEED_SHARE, CUT_IN_BRAKE_S = 0.5, 2.0  # the cutting vehicle slows to half the ego's speed within 2 s
REACTION_S = 0.6  # the ego's driver decides this often while surprised (SUMO's action step length)
CUT_IN_LATERAL_MPS = 2.5  # the cutting vehicle's sideways speed
CUT_IN_ROOM_M = 1.0  # free space it needs in front of it in the ego's lane (no one is cut into)
CUT_IN_MAX_DECEL = 4.0  # m/s^2: the cutting vehicle brakes no harder than this (the ego can follow)
CUT_IN_SPEED_FACTOR = 1.3  # of the speed limit, while it overtakes the ego
CUT_IN_BEHIND_M = 30.0  # it may start up to this far behind the ego's front, and overtake
CUT_IN_OVERTAKE_MPS = 6.0  # how much faster than the ego it overtakes
CUT_IN_LOOK_M, CUT_IN_APPROACH_MPS, CUT_IN_APPROACH_S = 40.0, 4.0, 12.0  # its approach: from up to 40 m ahead
CUT_IN_ROAD_M = 120.0  # or where the ego's road goes on this far: it drives beside the ego as long
CUT_IN_LOST_S = 1.0  # an approach ends this long after its vehicle is no longer beside the ego
HOLD_S = 2.0
BACKLOG = 2.0  # events of a kind owed at most, when the traffic held them back
RED_LIGHT_S = 10.0
RED_RUN_MPS = 9.0  # a red-light runner speeds up to at least this
RED_MARGIN_S = 1.5  # it leaves the junction this long before the ego can reach it (or enters after)
JUNCTION_M = 25.0  # the way through a junction
JAYWALK_PATH_M, JAYWALK_LOOK_M = 1.8, 40.0  # the ego's path: this far either side of its lane centre
JAYWALK_STEP_M = 0.6  # the pedestrian starts this far beyond the kerb
JAYWALK_HIDDEN_M = 0.5  # and this much farther when it starts in front of a parked car
JAYWALK_PARKED_WAIT_S = 20.0  # a jaywalker due waits this long for a place behind a parked car


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
    beside_s: float = 0.0  # the last time a cut-in's vehicle was seen beside the ego
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
        self._due: list[float] | None = None  # by hazard: when the next is due (drawn at the first step)
        self._retry: list[float] = []  # by hazard: not before (after a cut-in's approach came to nothing)
        self._late_s = 0.0  # how long the event being started has been due
        self._active: dict[int, _Event] = {}  # by hazard index
        self._count = 0
        self._people = 0
        if any(h.kind == "jaywalker" and h.child for h in hazards):
            libsumo.vehicletype.copy("DEFAULT_PEDTYPE", CHILD_TYPE)
            libsumo.vehicletype.setLength(CHILD_TYPE, CHILD_LWH_M[0])
            libsumo.vehicletype.setWidth(CHILD_TYPE, CHILD_LWH_M[1])
            libsumo.vehicletype.setHeight(CHILD_TYPE, CHILD_LWH_M[2])

    def _wait(self, hazard: HazardConfig) -> float:
        """The time from one event of a kind to the next: 0.5 to 1.5 times 60 / per_minute."""
        return float(self._rng.uniform(0.5, 1.5)) * 60.0 / hazard.per_minute

    def _schedule_next(self, index: int, now: float) -> None:
        """An event of this kind started: the next is due a wait after the one that was due, so
        an event that had to wait for the traffic does not push the later ones back (at most
        ``BACKLOG`` events are owed)."""
        assert self._due is not None
        mean = 60.0 / self._hazards[index].per_minute
        self._due[index] = max(self._due[index] + self._wait(self._hazards[index]), now - BACKLOG * mean)

    def step(self, ego: str, now: float) -> None:
        """Move the events under way, end those that are over, start those that are due."""
        if self._due is None:
            self._due = [now + self._wait(h) for h in self._hazards]
            self._retry = [now for _ in self._hazards]
        due, retry = self._due, self._retry
        for index, event in list(self._active.items()):
            was_hidden = event.hidden
            try:
                done = self._advance(event, ego, now)
            except libsumo.TraCIException:
                done = True  # an actor left the simulation
            if was_hidden and not event.hidden:  # a cut-in's approach became the event
                self._schedule_next(index, now)
            elif was_hidden and done:
                retry[index] = now + 1.0  # the approach came to nothing: another candidate soon
            if done:
                for undo in event.restore:
                    with contextlib.suppress(libsumo.TraCIException):  # an actor gone
                        undo()
                del self._active[index]
        for index, hazard in enumerate(self._hazards):
            if index in self._active or now < due[index] or now < retry[index]:
                continue
            self._late_s = now - due[index]
            try:
                started = self._start(hazard, ego, now)
            except libsumo.TraCIException:
                started = None
            if started is not None:
                started.started_s = now
                self._active[index] = started
                if not started.hidden:
                    self._schedule_next(index, now)

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
            libsumo.person.moveToXY(person, "", float(x), float(y), _sumo_angle(direction), keepRoute=2)
            ex, ey = libsumo.vehicle.getPosition(ego)
            fwd = _forward(ego)
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
        """A vehicle in a lane beside the ego is driven (unseen as an event: its approach)
        until it is the drawn gap ahead; :meth:`_cut_now` then makes it cut in."""
        ego_speed = libsumo.vehicle.getSpeed(ego)
        if ego_speed < 3.0 or not _straight_ahead(ego, STRAIGHT_REACH_M):
            return None
        gaps = _side_gaps(ego)
        candidates = [vid for vid, gap in gaps.items()
                      if self._movable(vid, ego) and -CUT_IN_BEHIND_M <= gap <= CUT_IN_LOOK_M
                      and _same_way(ego, vid)]  # fmt: skip
        if not candidates:
            return None
        near, far = _cut_in_gaps(hazard, ego_speed)
        if near >= far:
            return None  # no gap in metres is also one in seconds at this speed
        vid = sorted(candidates)[int(self._rng.integers(0, len(candidates)))]
        gap_m = float(self._rng.uniform(near, far))
        factor = libsumo.vehicle.getSpeedFactor(vid)
        libsumo.vehicle.setSpeedFactor(vid, max(factor, CUT_IN_SPEED_FACTOR))  # it may pass the ego at the limit
        libsumo.vehicle.setSpeed(vid, _approach_speed(ego_speed, gaps[vid], gap_m))
        restore = [lambda: libsumo.vehicle.setSpeed(vid, -1.0), lambda: libsumo.vehicle.setSpeedFactor(vid, factor)]
        event = _Event(0, "cut_in", [vid], now + CUT_IN_APPROACH_S, restore)
        event.hidden, event.gap_m, event.beside_s = True, gap_m, now
        return event

    def _cut_now(self, event: _Event, hazard: HazardConfig, ego: str, now: float) -> bool:
        """During a cut-in's approach: cut in once the gap is as drawn (True: the event goes on)."""
        vid = event.actors[0]
        ego_speed = libsumo.vehicle.getSpeed(ego)
        gap = _beside_gap(ego, vid)
        if gap is None:
            return now - event.beside_s < CUT_IN_LOST_S  # gone from beside the ego: another candidate
        event.beside_s = now
        if ego_speed < 3.0:
            return now < event.ends_s
        libsumo.vehicle.setSpeed(vid, _approach_speed(ego_speed, gap, event.gap_m - 1.0))  # aims a metre short
        near, _ = _cut_in_gaps(hazard, ego_speed)
        if not near <= gap <= event.gap_m:
            return now < event.ends_s  # not yet at the gap drawn, or closer than the scenario allows
        speed = libsumo.vehicle.getSpeed(vid)
        off_pace = not ego_speed - CUT_IN_APPROACH_MPS - 2.0 <= speed <= ego_speed + 0.5  # rammed, or pulling away
        leader = libsumo.vehicle.getLeader(ego, gap + 40.0)
        room = not leader or not leader[0] or leader[1] >= gap + libsumo.vehicle.getLength(vid) + CUT_IN_ROOM_M
        if off_pace or not room:
            return now < event.ends_s
        lane = _into_ego_lane(ego, vid)
        if lane is None or not _straight_ahead(ego, STRAIGHT_REACH_M):
            return now < event.ends_s
        lateral = libsumo.vehicle.getMaxSpeedLat(vid)
        libsumo.vehicle.setMaxSpeedLat(vid, CUT_IN_LATERAL_MPS)  # across in about 1.5 s (a lane change is 3 s)
        libsumo.vehicle.setLaneChangeMode(vid, 0)
        libsumo.vehicle.changeLane(vid, lane, CUT_IN_HOLD_S)
        slower = max(CUT_IN_SPEED_SHARE * ego_speed, ego_speed - CUT_IN_MAX_DECEL * CUT_IN_BRAKE_S)
        decel = libsumo.vehicle.getDecel(vid)
        libsumo.vehicle.setDecel(vid, max(decel, (ego_speed - slower) / CUT_IN_BRAKE_S))
        libsumo.vehicle.slowDown(vid, slower, CUT_IN_BRAKE_S)
        libsumo.vehicle.setSpeed(vid, slower)
        ego_mode = libsumo.vehicle.getLaneChangeMode(ego)
        libsumo.vehicle.setLaneChangeMode(ego, 0)  # the ego keeps its lane and brakes (no swerving around)
        event.restore.append(_react_late(ego))
        event.restore += [lambda: libsumo.vehicle.setDecel(vid, decel),
                          lambda: libsumo.vehicle.setMaxSpeedLat(vid, lateral),
                          lambda: libsumo.vehicle.setLaneChangeMode(vid, LANE_CHANGE_DEFAULT),
                          lambda: libsumo.vehicle.setLaneChangeMode(ego, ego_mode)]  # fmt: skip
        self._count += 1
        event.number, event.hidden, event.started_s, event.ends_s = self._count, False, now, now + CUT_IN_S
        return True

    def _hard_brake(self, hazard: HazardConfig, ego: str, now: float) -> _Event | None:
        lo, hi = hazard.distance_m
        leader = libsumo.vehicle.getLeader(ego, hi)
        if not leader or not leader[0]:
            return None
        vid, gap = leader
        speed = libsumo.vehicle.getSpeed(vid)
        if not self._movable(vid, ego) or not lo <= gap <= hi or speed < hazard.to_speed_mps + 4.0:
            return None
        if not _straight_ahead(ego, gap + 10.0) and not _in_line(ego, vid):
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
            elif self._late_s < JAYWALK_PARKED_WAIT_S:
                return None  # wait a while for a place with a parked car, then step out in the open
        start = np.array([ex, ey]) + fwd * along + left * across
        length = abs(across) + widths[lane_index] / 2.0 + sum(widths[lane_index + 1 : max(driving) + 1]) + 1.0
        self._people += 1
        person = f"jaywalker_{self._people}"
        kind = CHILD_TYPE if hazard.child else self._pedestrian_type or "DEFAULT_PEDTYPE"
        libsumo.person.add(person, self._walk_edges[0], 0.0, typeID=kind)
        libsumo.person.appendWaitingStage(person, 3600.0)
        libsumo.person.moveToXY(person, "", float(start[0]), float(start[1]), _sumo_angle(left), keepRoute=2)
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
            queue = libsumo.lane.getLastStepVehicleIDs(lane)
            front = max(queue, key=libsumo.vehicle.getLanePosition, default="")  # the nearest the stop line
            for vid in queue:
                if not self._movable(vid, ego):
                    continue
                speed = libsumo.vehicle.getSpeed(vid)
                dist = libsumo.lane.getLength(lane) - libsumo.vehicle.getLanePosition(vid)
                if (speed < 2.0 and vid != front) or not 0.5 <= dist <= 60.0:  # the front one may start from a stop
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


STRAIGHT_DEG = 6.0
STRAIGHT_REACH_M = 30.0
IN_LINE_M, IN_LINE_DEG = 1.0, 8.0


def _forward(vid: str) -> np.ndarray:
    """A vehicle's unit heading in the map plane."""
    yaw = float(sumo_angle_to_yaw(libsumo.vehicle.getAngle(vid)))
    return np.array([math.cos(yaw), math.sin(yaw)])


def _sumo_angle(direction: np.ndarray) -> float:
    """SUMO's angle of a direction in the map plane: degrees clockwise from north."""
    return math.degrees(math.atan2(direction[0], direction[1])) % 360.0


def _react_late(ego: str) -> Callable[[], None]:
    """The ego's driver reacts ``REACTION_S`` late (SUMO's action step length: the driver
    decides that often and keeps its acceleration in between); returns the undo."""
    step = libsumo.vehicle.getActionStepLength(ego)
    libsumo.vehicle.setActionStepLength(ego, REACTION_S, resetActionOffset=True)
    return lambda: libsumo.vehicle.setActionStepLength(ego, step, resetActionOffset=True)


def _cut_in_gaps(hazard: HazardConfig, ego_speed: float) -> tuple[float, float]:
    """The gaps a cut-in may leave at this speed: within ``distance_m`` and ``time_gap_s``."""
    return (max(hazard.distance_m[0], hazard.time_gap_s[0] * ego_speed),
            min(hazard.distance_m[1], hazard.time_gap_s[1] * ego_speed))  # fmt: skip


def _approach_speed(ego_speed: float, gap_m: float, wanted_m: float) -> float:
    """A cut-in's approach: the ego's speed, up to 6 m/s faster while the gap is short of the
    wanted one and up to 4 m/s slower while it is longer (closing the difference in a second)."""
    change = float(np.clip(wanted_m - gap_m, -CUT_IN_APPROACH_MPS, CUT_IN_OVERTAKE_MPS))
    return max(ego_speed + change, 1.0)


def _same_way(ego: str, vid: str) -> bool:
    """Whether a vehicle's route goes on where the ego's does: the ego's next road is among its
    next two, or the ego's road goes on for ``CUT_IN_ROAD_M`` (they drive side by side as long)."""
    route, at = libsumo.vehicle.getRoute(ego), libsumo.vehicle.getRouteIndex(ego)
    left_m = libsumo.lane.getLength(libsumo.vehicle.getLaneID(ego)) - libsumo.vehicle.getLanePosition(ego)
    if at + 1 >= len(route) or left_m >= CUT_IN_ROAD_M:
        return True
    theirs, their_at = libsumo.vehicle.getRoute(vid), libsumo.vehicle.getRouteIndex(vid)
    return route[at + 1] in theirs[their_at + 1 : their_at + 3]


def _beside_gap(ego: str, vid: str) -> float | None:
    """A vehicle's gap ahead of the ego (its rear from the ego's front bumper, along the ego's
    heading) while it drives in a lane beside the ego's (its centre 1.5 to 6 m to the side, its
    heading within 20 degrees); None otherwise."""
    forward, their_forward = _forward(ego), _forward(vid)
    length = libsumo.vehicle.getLength(vid)
    rear = np.array(libsumo.vehicle.getPosition(vid)) - length * their_forward
    offset = rear + 0.5 * length * their_forward - np.array(libsumo.vehicle.getPosition(ego))
    across = abs(float(offset @ np.array([-forward[1], forward[0]])))
    if not 1.5 <= across <= 6.0 or float(forward @ their_forward) < math.cos(math.radians(20.0)):
        return None
    return float((rear - np.array(libsumo.vehicle.getPosition(ego))) @ forward)


def _side_gaps(ego: str) -> dict[str, float]:
    """The nearest vehicles ahead and behind in the lanes left and right of the ego's (SUMO's
    neighbours, across the road's edges), each with its gap ahead of the ego (from the ego's
    front bumper to its rear; negative: beside or behind)."""
    gaps = {}
    ego_length, ego_min_gap = libsumo.vehicle.getLength(ego), libsumo.vehicle.getMinGap(ego)
    for mode in (0, 1):  # followers left, right: their front bumper (and min gap) behind the ego's rear
        for vid, behind in libsumo.vehicle.getNeighbors(ego, mode):
            length, min_gap = libsumo.vehicle.getLength(vid), libsumo.vehicle.getMinGap(vid)
            gaps[vid] = -(behind + min_gap + ego_length + length)
    for mode in (2, 3):  # leaders left, right: their rear ahead of the ego's front bumper and min gap
        for vid, ahead in libsumo.vehicle.getNeighbors(ego, mode):
            gaps[vid] = ahead + ego_min_gap
    return gaps


def _into_ego_lane(ego: str, vid: str) -> int | None:
    """The lane index a vehicle beside the ego changes to, to be in the ego's lane or the one
    the ego's route continues on (None: no lane beside it is)."""
    lane = libsumo.vehicle.getLaneID(ego)
    ahead = next((best[5] for best in libsumo.vehicle.getBestLanes(ego) if best[0] == lane), (lane,))
    edge, index = libsumo.vehicle.getRoadID(vid), int(libsumo.vehicle.getLaneIndex(vid))
    for side in (index - 1, index + 1):
        if f"{edge}_{side}" in (lane, *ahead):
            return side
    return None


def _straight_ahead(ego: str, reach_m: float) -> bool:
    """Whether the ego's way runs straight (within ``STRAIGHT_DEG``) over ``reach_m`` ahead, along
    its lane and the lanes its route continues on: there, constant velocities predict where
    the ego and the vehicles ahead go, and a time to collision means what it says."""
    road = libsumo.vehicle.getRoadID(ego)
    if road.startswith(":"):
        return False
    lane = libsumo.vehicle.getLaneID(ego)
    ahead = next((best[5] for best in libsumo.vehicle.getBestLanes(ego) if best[0] == lane), (lane,))
    path = [np.array(libsumo.vehicle.getPosition(ego))]
    travelled = libsumo.vehicle.getLanePosition(ego)  # along the first lane's shape
    for next_lane in ahead or (lane,):
        shape = np.array(libsumo.lane.getShape(next_lane), dtype=float)
        along = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(shape, axis=0), axis=1))])
        path += list(shape[along > travelled])
        travelled = 0.0
        if _length(np.array(path)) >= reach_m:
            break
    points = np.array(path)
    if _length(points) < reach_m:
        return False  # the route ends (or is not known) within reach
    x0, x1, x2 = (_at(points, s) for s in (0.0, reach_m / 2.0, reach_m))
    turn = math.atan2(*(x2 - x1)[::-1]) - math.atan2(*(x1 - x0)[::-1])
    return abs(math.degrees(math.atan2(math.sin(turn), math.cos(turn)))) <= STRAIGHT_DEG


def _in_line(ego: str, vid: str) -> bool:
    """Whether a vehicle ahead is in line with the ego (a leader on a gentle bend): its centre
    within ``IN_LINE_M`` of the ego's heading line, its heading within ``IN_LINE_DEG``; a time to
    collision under constant velocity then still says how close a stop ahead comes."""
    forward, their_forward = _forward(ego), _forward(vid)
    half = libsumo.vehicle.getLength(vid) / 2.0
    centre = np.array(libsumo.vehicle.getPosition(vid)) - half * their_forward
    offset = centre - np.array(libsumo.vehicle.getPosition(ego))
    left = np.array([-forward[1], forward[0]])
    across = abs(float(offset @ left))
    turn = math.degrees(math.atan2(float(their_forward @ left), float(their_forward @ forward)))
    return across <= IN_LINE_M and abs(turn) <= IN_LINE_DEG


def _length(points: np.ndarray) -> float:
    return float(np.linalg.norm(np.diff(points, axis=0), axis=1).sum()) if len(points) > 1 else 0.0


def _at(points: np.ndarray, distance_m: float) -> np.ndarray:
    """The point ``distance_m`` along a polyline."""
    along = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])
    return np.array([np.interp(distance_m, along, points[:, 0]), np.interp(distance_m, along, points[:, 1])])


__all__ = ["ActiveHazard", "HazardController"]

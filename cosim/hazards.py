"""Hazard events made on purpose near the ego, with SUMO's own commands (with traffic.py and
hazard_roads.py, the modules that talk to libsumo).

Each hazard kind of the scenario is due ``per_minute`` times a simulated minute: one event in
each period of 60 / per_minute seconds, at a time drawn in its middle half (from the scenario's
seed; :mod:`cosim.hazard_plan`). Before an event is due, its actor is prepared: found in the
traffic around the ego and brought into place, or, where the traffic has none, made where no
sensor of the rig sees it and no label reaches (a car on the road the ego came along, far enough
behind; a pedestrian at the kerb far enough ahead, or hidden in front of a parked car), so that
it drives or walks into view as any other road user. The event starts when it is due and its
actor is in place (an event that had to wait does not push the next ones back: up to two a
kind are owed).

Cut-ins and hard braking start only where the ego's way (its lane and the lanes its route goes
on) runs straight ahead (a time to collision under constant velocity means little in a bend),
a hard brake also on a gentle bend when its leader is in line with the ego; jaywalkers cross
straight roads (their direction is fixed when they step out).

- ``cut_in``: a vehicle in a lane beside the ego going its way (from up to 30 m behind to 40 m
  ahead, brought from farther behind, or made out of sight behind the ego) is paced so that
  it is a gap within ``distance_m`` and ``time_gap_s`` ahead, at the ego's pace, when the event
  is due; then it changes into the ego's lane at once (lane-change mode 0: SUMO's safety checks
  off for this change) and slows to half the ego's speed within 2 s (braking at most at
  4 m/s^2), holding it 4 s. The ego keeps its lane and its driver reacts 0.6 s late (SUMO's
  action step length), then brakes with SUMO's car-following.
- ``hard_brake``: the ego's leader (within 120 m ahead, paced to a gap within ``distance_m``;
  where the ego has none, a vehicle from beside it, or made behind it, overtakes and changes
  into the ego's lane ahead of it) brakes at ``decel_mps2`` to ``to_speed_mps``, holds it 2 s,
  then drives on; the ego follows with SUMO's car-following.
- ``jaywalker``: a pedestrian (by default a child of Euro NCAP's child target size) steps off
  the kerb on the ego's side and walks across at ``walk_mps`` outside any crossing, where it
  reaches the ego's path when the ego is its braking distance (at 7.5 m/s^2) plus 5 m away
  (within ``distance_m``): with ``behind_parked``, from just before the front bumper of a
  parked car on the ego's way, in line behind it as the ego sees it (placed there as it steps
  out, hidden by the car); elsewhere from where it stood waiting at the kerb, placed before
  the rig could see it. The ego brakes (up to 7.5 m/s^2) for a pedestrian within 40 m ahead
  that is in its path or will be before it could stop.
- ``red_light``: while the ego approaches a green light ``distance_m`` away, a vehicle on a
  crossing approach with red (moving, or the first in its queue) drives through (speed mode 7:
  red lights and right of way ignored), timed to clear the junction at least 1.5 s before the
  ego can reach it at its speed, or, when it cannot, slowed to enter 1.5 s after the ego has
  crossed.

An event ends after a fixed time (cut_in 6 s, hard_brake when its hold ends, jaywalker when
the pedestrian has crossed, red_light 10 s) or when an actor leaves the simulation; the
actors (and the ego) get their SUMO settings back. A pedestrian who crossed (or waited in
vain) is taken out of the simulation once no sensor sees it. :meth:`HazardController.active`
lists the events under way, which the world state carries to the labels.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from cosim import hazard_roads as roads
from cosim.hazard_plan import Schedule, Sight
from cosim.scenario import HazardConfig
from gtgen.frame import ActiveHazard
from networks.sumo_tools import sumo_home

sumo_home()  # exports SUMO_HOME before libsumo loads
import libsumo  # noqa: E402

# Jaywalking children: a pedestrian type of Euro NCAP's child target's size, made with the controller.
CHILD_TYPE = "pedestrian_child"
CHILD_LWH_M = (0.25, 0.4, 1.15)
MADE = "hazard"  # vehicles made for events are named hazard_1, hazard_2, ...

LANE_CHANGE_DEFAULT = 0b011001010101  # SUMO's default lane-change mode (1621)
KEEP_LANE = 0b011000000001  # while prepared: changes for its route and asked ones only, into safe gaps
SPEED_DEFAULT = 31
OVER_THE_LIMIT = 64  # speed mode: a speed asked may exceed the lane's speed limit
IGNORE_RED_AND_RIGHT_OF_WAY = 7  # speed mode: safe speed, acceleration and deceleration limits only
EGO_STOP_DECEL = 7.5
CUT_IN_HOLD_S, CUT_IN_S = 4.0, 6.0
CUT_IN_SPEED_SHARE, CUT_IN_BRAKE_S = 0.5, 2.0  # the cutting vehicle slows to half the ego's speed within 2 s
REACTION_S = 0.6  # the ego's driver decides this often while surprised (SUMO's action step length)
CUT_IN_LATERAL_MPS = 2.5  # the cutting vehicle's sideways speed
CUT_IN_ROOM_M = 1.0  # free space it needs in front of it in the ego's lane (no one is cut into)
CUT_IN_MAX_DECEL = 4.0  # m/s^2: the cutting vehicle brakes no harder than this (the ego can follow)
CUT_IN_SPEED_FACTOR = 1.3  # of the speed limit: the fastest a prepared vehicle drives (or as fast as it must)
CUT_IN_BEHIND_M = 30.0  # it may start up to this far behind the ego's front, and overtake
CUT_IN_OVERTAKE_MPS = 6.0  # how much faster than the ego it overtakes
CUT_IN_LOOK_M, CUT_IN_APPROACH_MPS = 40.0, 4.0  # it may start up to 40 m ahead, and drop back
CUT_IN_ROAD_M = 120.0  # or where the ego's road goes on this far: it drives beside the ego as long
LOST_S = 3.0  # a preparation ends this long after its vehicle is no longer where it needs it
CATCH_UP_MPS = 10.0  # how much faster than the ego a vehicle drives while it catches up from far behind
CAR_RADIUS_M, HIDDEN_MARGIN_M = 3.0, 5.0  # a vehicle is made this far beyond the rig's sight and labels
SIDE_LEAD_S = 12.0  # a vehicle beside the ego is brought to its gap from this long before the event is due
MAKE_LEAD_S = 20.0  # and, where none is, a vehicle is made behind the ego this long before
LATE_S = 10.0  # a preparation is given up this long after its event was due (another is tried)
AHEAD_OF_TIME_S = 3.0  # a prepared vehicle is brought to its place this long before its event is due
LEADER_SLOWER_MPS, LEADER_FASTER_MPS = 10.0, 5.0  # a hard brake's leader is paced this much slower or faster
LEADER_LEAD_S = 30.0  # one is made ahead of the ego up to this long before it is due
LEADER_PACE_S = 20.0  # and the ego's leader is paced from at least this long before
LEADER_SETTLE_S = 3.0  # and brakes no sooner than this after it became the ego's leader
HOLD_S = 2.0
RED_LIGHT_S = 10.0
RED_RUN_MPS = 9.0  # a red-light runner speeds up to at least this
RED_MARGIN_S = 1.5  # it leaves the junction this long before the ego can reach it (or enters after)
JUNCTION_M = 25.0  # the way through a junction
RED_NEAR_M = 60.0  # a runner is within this of its stop line
RED_LEAD_S, RED_LATE_S = 15.0, 30.0  # a red-light runner is prepared this long before it is due, given up after
RED_EARLY_S = 2.0  # and may run this long before it is due
RED_ACTUATE_S = 10.0  # the ego's light turns green for it if it would reach it within this, from this before due
RED_PLAN_M = 200.0  # the ego's next light is looked at within this
JAYWALK_PATH_M, JAYWALK_LOOK_M = 1.8, 40.0  # the ego's path: this far either side of its lane centre
JAYWALK_STEP_M = 0.6  # the pedestrian starts this far beyond the kerb
JAYWALK_HIDDEN_M = 0.5  # and this much farther when it starts in front of a parked car
JAYWALK_LEAD_S = 20.0  # its place is chosen this long before it is due
JAYWALK_LATE_S = 40.0  # and given up this long after (the ego may wait at a red light before it)
JAYWALK_PACE_SHARE = 0.7  # of the speed limit: the ego's pace, to tell where it will be when it is due
JAYWALK_ROAD_M = 25.0  # it steps out at least this far along its road, and 10 m before the road's end
JAYWALK_PARKED_WAIT_S = 10.0  # a jaywalker due waits this long for the ego to come to a parked car
JAYWALK_CATCH_M = 4.0  # it steps out when the ego is its reach or up to this much less away
LEADS_S = {"cut_in": MAKE_LEAD_S, "hard_brake": LEADER_LEAD_S, "jaywalker": JAYWALK_LEAD_S, "red_light": RED_LEAD_S}
PREPARED_AT_ONCE = {"cut_in": 2, "hard_brake": 1, "jaywalker": 2, "red_light": 1}  # a kind's next events


@dataclass(slots=True)
class _Event:
    index: int  # the scenario's hazard entry it is made for
    config: HazardConfig
    actors: list[str]
    due_s: float
    ends_s: float  # while prepared: when it is given up; under way: when it ends
    restore: list[Callable[[], None]] = field(default_factory=list)
    number: int = 0  # 0 while it is being prepared (not an event yet)
    started_s: float = 0.0
    gap_m: float = 0.0  # cut_in: the gap it cuts in at; hard_brake: the gap its leader is paced to
    seen_s: float = 0.0  # when its actor was last where the preparation needs it
    leading: bool = False  # hard_brake: its vehicle has been the ego's leader
    led_s: float = 0.0  # since then
    spot: tuple[str, float] = ("", 0.0)  # jaywalker: the road and the position where it steps out
    parked: str = ""  # jaywalker: the parked car it steps out in front of
    path: tuple[np.ndarray, np.ndarray, float] | None = None  # jaywalker: start, unit direction, length

    @property
    def kind(self) -> str:
        return self.config.kind


class HazardController:
    def __init__(
        self, hazards: tuple[HazardConfig, ...], seed: int, parked: set[str], walk_edges: list[str], sight: Sight,
        pedestrian_type: str = "", car_types: tuple[str, ...] = (),
    ) -> None:  # fmt: skip
        self._hazards = hazards
        self._pedestrian_type = pedestrian_type  # the jaywalkers' (the smallest of the scene's pedestrians)
        self._walk_edges = sorted(walk_edges)
        self._sight = sight
        self._behind_m = sight.clear_behind_m(3.5, CAR_RADIUS_M + HIDDEN_MARGIN_M) + 10.0
        self._ahead_m = sight.clear_ahead_m(CAR_RADIUS_M + HIDDEN_MARGIN_M) + 10.0  # where leaders are made
        self._car_types = car_types  # vehicles made for events are cars of these types
        self._rng = np.random.default_rng([seed, 0x4A2D])
        self._seed = seed
        self._parked = parked
        self._parked_at: dict[str, tuple[str, float]] = {}  # parked car: its road and front bumper's position
        self._schedules: list[Schedule] = []  # by hazard (made at the first step)
        self._retry = [0.0 for _ in hazards]  # by hazard: no preparation before (after one came to nothing)
        self._events: list[_Event] = []
        self._way_back = roads.WayBack()
        self._count = 0
        self._people = 0
        self._made = 0
        self._pending: set[str] = set()  # vehicles made, not on the road yet
        self._ego_mode: int | None = None  # the ego's own lane-change mode while cut-ins hold its lane
        self._held: dict[str, tuple[float, float, float]] = {}  # pedestrians standing: x, y, SUMO angle
        self._leftover: set[str] = set()  # those of past events, removed once out of sight
        if any(h.kind == "jaywalker" and h.child for h in hazards):
            libsumo.vehicletype.copy("DEFAULT_PEDTYPE", CHILD_TYPE)
            libsumo.vehicletype.setLength(CHILD_TYPE, CHILD_LWH_M[0])
            libsumo.vehicletype.setWidth(CHILD_TYPE, CHILD_LWH_M[1])
            libsumo.vehicletype.setHeight(CHILD_TYPE, CHILD_LWH_M[2])

    @property
    def lead_s(self) -> float:
        """How long before an event is due its preparation may start."""
        return max(LEADS_S[h.kind] for h in self._hazards)

    def begin(self, start_s: float) -> None:
        """Events are due from ``start_s`` on (the first step's time, if not called)."""
        self._schedules = [Schedule(60.0 / h.per_minute, start_s, np.random.default_rng([self._seed, 0x5C4E, i]))
                           for i, h in enumerate(self._hazards)]  # fmt: skip

    def step(self, ego: str, now: float) -> None:
        """Move the events under way and those being prepared, end those that are over,
        prepare those due soon."""
        if not self._schedules:
            self.begin(now)
        self._way_back.note(ego)
        self._take_back_unmade()
        self._hold_people(ego)
        for event in list(self._events):
            self._move(event, ego, now)
        for index, hazard in enumerate(self._hazards):
            self._prepare(index, hazard, ego, now)
        self._hold_ego_lane(ego)

    def active(self, track_id: Callable[[str], int], ego: str) -> tuple[ActiveHazard, ...]:
        shown = sorted((e for e in self._events if e.number), key=lambda e: e.number)
        return tuple(ActiveHazard(f"{e.kind}-{e.number}", e.kind, tuple(track_id(a) for a in e.actors),
                                  track_id(ego)) for e in shown)  # fmt: skip

    # --- the events' life ----------------------------------------------------------------
    def _prepare(self, index: int, hazard: HazardConfig, ego: str, now: float) -> None:
        """Start preparing the next event of a kind when it is due within its lead time."""
        preparing = {e.due_s for e in self._events if e.index == index and not e.number}
        if now < self._retry[index] or len(preparing) >= PREPARED_AT_ONCE[hazard.kind]:
            return
        due = next(d for d in map(self._schedules[index].due_s, range(len(preparing) + 1)) if d not in preparing)
        if now < due - LEADS_S[hazard.kind]:
            return
        make = {"cut_in": self._make_cut_in, "hard_brake": self._make_hard_brake, "jaywalker": self._make_jaywalker,
                "red_light": self._make_red_light}[hazard.kind]  # fmt: skip
        try:
            event = make(_Event(index, hazard, [], due, due + LATE_S), ego, now)
        except libsumo.TraCIException:
            event = None
        if event is not None:
            self._events.append(event)

    def _move(self, event: _Event, ego: str, now: float) -> None:
        prepared = not event.number
        try:
            done = self._ready(event, ego, now) if prepared else self._advance(event, ego, now)
        except libsumo.TraCIException:
            done = True  # an actor left the simulation
        if done:
            for undo in reversed(event.restore):  # the last change first
                with contextlib.suppress(libsumo.TraCIException):  # an actor gone
                    undo()
            self._events.remove(event)
            if not event.number:
                self._retry[event.index] = now + 1.0  # it came to nothing: another actor soon

    def _ready(self, event: _Event, ego: str, now: float) -> bool:
        """One step of a preparation (it may start the event); True: it is given up."""
        ready = {"cut_in": self._cut_in_ready, "hard_brake": self._hard_brake_ready,
                 "jaywalker": self._jaywalker_ready, "red_light": self._red_light_ready}[event.kind]  # fmt: skip
        return ready(event, ego, now)

    def _turn_on(self, event: _Event, now: float, ends_s: float) -> None:
        """A prepared event starts: it gets its number, and the next of its kind is due."""
        self._count += 1
        event.number, event.started_s, event.ends_s = self._count, now, ends_s
        self._schedules[event.index].take(now)

    def _under_way(self, index: int) -> bool:
        return any(e.index == index and e.number for e in self._events)

    def _take_back_unmade(self) -> None:
        """Vehicles made last step that could not enter the road are taken back (rather than
        entering later, when they could be in sight); their preparations end."""
        waiting = set(libsumo.simulation.getPendingVehicles())
        for vid in sorted(self._pending & waiting):
            libsumo.vehicle.remove(vid)
        self._pending.clear()

    def _hold_ego_lane(self, ego: str) -> None:
        """The ego keeps its lane while a cut-in or a hard brake is prepared or under way (lane
        changes its route needs only; its leader stays its leader) and changes none while a
        cut-in is under way; then it gets its own lane changes back."""
        cut_ins = [e for e in self._events if e.kind == "cut_in"]
        held = cut_ins or [e for e in self._events if e.kind == "hard_brake"]
        mode = 0 if any(e.number for e in cut_ins) else KEEP_LANE if held else None
        if mode is None and self._ego_mode is not None:
            libsumo.vehicle.setLaneChangeMode(ego, self._ego_mode)
            self._ego_mode = None
        elif mode is not None:
            if self._ego_mode is None:
                self._ego_mode = libsumo.vehicle.getLaneChangeMode(ego)
            libsumo.vehicle.setLaneChangeMode(ego, mode)

    def _hold_people(self, ego: str) -> None:
        """Keep standing pedestrians where they stand (SUMO would take a waiting person back to
        its road); those of past events leave the simulation once no sensor sees them."""
        for person, (x, y, angle) in sorted(self._held.items()):
            try:
                if person in self._leftover and not self._sight.sees(roads.in_ego_frame(ego, np.array([x, y])), 1.0):
                    libsumo.person.remove(person)
                    raise libsumo.TraCIException("removed")
                libsumo.person.moveToXY(person, "", x, y, angle, keepRoute=2)
            except libsumo.TraCIException:
                del self._held[person]
                self._leftover.discard(person)

    def _release(self, person: str) -> None:
        """A jaywalker's event is over: it stands where it is until out of sight."""
        x, y = libsumo.person.getPosition(person)
        self._held[person] = (x, y, libsumo.person.getAngle(person))
        self._leftover.add(person)

    # --- one step of an event under way ----------------------------------------------------
    def _advance(self, event: _Event, ego: str, now: float) -> bool:
        config = event.config
        if event.kind == "jaywalker" and event.path is not None:
            start, direction, length = event.path
            walked = (now - event.started_s) * config.walk_mps
            person = event.actors[0]
            if walked >= length:
                return True
            x, y = start + direction * walked
            libsumo.person.moveToXY(person, "", float(x), float(y), roads.sumo_angle(direction), keepRoute=2)
            ex, ey = libsumo.vehicle.getPosition(ego)
            fwd = roads.forward(ego)
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

    # --- actors ----------------------------------------------------------------------------
    def _movable(self, vid: str, ego: str) -> bool:
        """A vehicle that can act in a new event: not the ego, parked, a bicycle, or in an event."""
        busy = {a for e in self._events for a in e.actors}
        return (bool(vid) and vid != ego and vid not in self._parked and vid not in busy
                and libsumo.vehicle.getVehicleClass(vid) not in ("bicycle", "pedestrian"))  # fmt: skip

    def _beside(
        self, ego: str, now: float, due: float, wanted_m: float, road_m: float, ahead_m: float = CUT_IN_LOOK_M
    ) -> tuple[str, float] | None:
        """A vehicle to bring beside the ego, ``wanted_m`` ahead of it, for an event due at
        ``due``, with its gap ahead of the ego now. Once it needs the time left to get there:
        the first in a lane beside the ego's on either side of that place (from as far behind
        the ego as a car is made to 40 m ahead); where a lane beside it
        is empty up to there, from ``MAKE_LEAD_S`` before, a car made there out of the rig's
        sight; else one from a lane farther out (it moves over). Of those, the one that gets
        there soonest. ``road_m``: how far along the ego's way it must go (see ``same_way``);
        ``ahead_m``: how far ahead of the ego it may be found."""
        if now < due - MAKE_LEAD_S:
            return None
        around = self._around(ego, ahead_m)
        index = libsumo.vehicle.getLaneIndex(ego)
        firsts, empty = [], []
        for side in (1, -1):
            line = [(gap, vid) for vid, (lane, gap) in around.items() if lane == index + side]
            if not line and not roads.has_lane(ego, index + side):
                continue
            behind = [f for f in line if f[0] < wanted_m]
            ahead = [f for f in line if f[0] >= wanted_m]
            firsts += [max(behind)] if behind else []
            firsts += [min(ahead)] if ahead else []
            if not [vid for gap, vid in line if gap < wanted_m + 10.0 and roads.same_way(ego, vid, float("inf"))]:
                empty.append(side)  # but for vehicles about to leave the ego's way
        found = [(vid, gap) for gap, vid in firsts if self._usable(vid, ego, gap, wanted_m, road_m)]
        if not found and empty:
            vid = self._make_behind(ego, empty)
            return None if vid is None else (vid, -self._behind_m)
        if not found:  # from a lane farther out, or from behind the ego in its lane
            found = [(vid, gap) for vid, (lane, gap) in around.items() if self._usable(vid, ego, gap, wanted_m, road_m)
                     and abs(lane - index) != 1 and -CUT_IN_BEHIND_M <= gap <= ahead_m]  # fmt: skip
        if not found:
            return None
        vid, gap = min(found, key=lambda f: (_approach_s(f[1], wanted_m), f[0]))  # the one there soonest
        return (vid, gap) if now >= due - _approach_s(gap, wanted_m) else None

    def _around(self, ego: str, ahead_m: float) -> dict[str, tuple[int, float]]:
        """The vehicles in the lanes open to cars of the ego's road and the roads just behind
        and ahead (not ahead of it in its lane), from as far behind it as a car is made to
        ``ahead_m`` ahead: their lane indices and gaps ahead of it."""
        starts = roads.way_starts(ego, self._way_back, self._behind_m)
        own = libsumo.vehicle.getLaneID(ego)
        found: dict[str, tuple[int, float]] = {}
        for road, start in starts.items():
            for lane in roads.car_lanes(road):
                for vid in libsumo.lane.getLastStepVehicleIDs(lane):
                    gap = start + libsumo.vehicle.getLanePosition(vid) - libsumo.vehicle.getLength(vid)
                    if -self._behind_m <= gap <= ahead_m and not (lane == own and gap > 0.0) and vid != ego:
                        found[vid] = (int(lane.rsplit("_", 1)[1]), gap)
        return dict(sorted(found.items()))

    def _usable(self, vid: str, ego: str, gap_m: float, wanted_m: float, road_m: float) -> bool:
        """A vehicle beside the ego can act: free, going its way, and, when it is short of the
        place wanted, able to drive 3 m/s faster than the ego and driving at half its speed or more."""
        ego_speed = libsumo.vehicle.getSpeed(ego)
        fast = libsumo.vehicle.getMaxSpeed(vid) >= ego_speed + 3.0 and libsumo.vehicle.getSpeed(vid) >= 0.5 * ego_speed
        return self._movable(vid, ego) and (gap_m >= wanted_m or fast) and roads.same_way(ego, vid, road_m)

    def _make_behind(self, ego: str, sides: list[int]) -> str | None:
        """A car made in a lane beside the ego's (on one of ``sides``, +1 left, -1 right) on the
        road it came along, at the nearest point behind it that no sensor sees, routed along the
        ego's way."""
        if not self._car_types or libsumo.vehicle.getRoadID(ego).startswith(":"):
            return None
        index, here = libsumo.vehicle.getLaneIndex(ego), libsumo.vehicle.getRoadID(ego)
        for back_m in np.arange(20.0, self._behind_m + 1.0, 10.0):
            place = self._way_back.place(ego, float(back_m))
            if place is None:
                return None
            way, pos = place
            if libsumo.edge.getLaneNumber(way[0]) != libsumo.edge.getLaneNumber(here):
                continue  # lanes added or dropped in between: a lane there need not lead beside the ego
            lanes = [int(lane.rsplit("_", 1)[1]) for lane in roads.car_lanes(way[0])]
            for lane_index in (index + side for side in sides if index + side in lanes):
                if not _free(f"{way[0]}_{lane_index}", pos, 25.0):
                    continue
                xy = np.array(libsumo.simulation.convert2D(way[0], pos, lane_index))
                if not self._sight.sees(roads.in_ego_frame(ego, xy), CAR_RADIUS_M + HIDDEN_MARGIN_M):
                    route, at = libsumo.vehicle.getRoute(ego), libsumo.vehicle.getRouteIndex(ego)
                    return self._add_car([*way, *route[at + 1 :]], pos, lane_index)
        return None

    def _add_car(self, roads_on: list[str], pos: float, lane_index: int) -> str:
        """A car made on the first of ``roads_on`` (its route), ``pos`` along it."""
        self._made += 1
        vid = f"{MADE}_{self._made}"
        libsumo.route.add(f"{vid}_route", roads_on)
        type_id = self._car_types[int(self._rng.integers(0, len(self._car_types)))]
        libsumo.vehicle.add(vid, f"{vid}_route", typeID=type_id, depart="now", departLane=str(lane_index),
                            departPos=f"{pos:.2f}", departSpeed="max")  # fmt: skip
        self._pending.add(vid)
        return vid

    def _drive(self, event: _Event, vid: str, now: float, gap_m: float) -> None:
        """Take a vehicle's speed and lane changes over for a preparation (given back at its
        end); one that has far to come has longer than ``LATE_S`` after it is due."""
        event.ends_s = max(event.due_s, now + abs(gap_m - event.gap_m) / CATCH_UP_MPS) + LATE_S
        event.seen_s = now
        speed_mode, mode = libsumo.vehicle.getSpeedMode(vid), libsumo.vehicle.getLaneChangeMode(vid)
        factor = libsumo.vehicle.getSpeedFactor(vid)
        libsumo.vehicle.setSpeedMode(vid, SPEED_DEFAULT | OVER_THE_LIMIT)  # it may pass the ego above the limit
        libsumo.vehicle.setSpeedFactor(vid, max(factor, CUT_IN_SPEED_FACTOR))  # and wants to (passing slower ones)
        libsumo.vehicle.setLaneChangeMode(vid, KEEP_LANE)
        event.actors.append(vid)
        event.restore += [lambda: libsumo.vehicle.setSpeed(vid, -1.0),
                          lambda: libsumo.vehicle.setSpeedMode(vid, speed_mode),
                          lambda: libsumo.vehicle.setSpeedFactor(vid, factor),
                          lambda: libsumo.vehicle.setLaneChangeMode(vid, mode)]  # fmt: skip

    def _bring_beside(self, event: _Event, ego: str, now: float, wanted_m: float, left_s: float) -> float | None:
        """Pace a prepared vehicle beside the ego to a gap ``wanted_m`` ahead in ``left_s``;
        its gap now (along the ego's heading while it is beside it, else along its way), None
        while it is not on the ego's way or, near the ego, a slower vehicle ahead of it holds it
        back (far behind, it changes lanes to pass)."""
        vid = event.actors[0]
        gap = roads.beside_gap(ego, vid)
        gap = roads.route_gap(ego, vid) if gap is None else gap
        far = gap is not None and gap < -CUT_IN_BEHIND_M
        if gap is None or (_blocked(vid, gap, wanted_m) and not far):
            return None
        event.seen_s = now
        ego_speed = libsumo.vehicle.getSpeed(ego)
        faster = CATCH_UP_MPS if far else CUT_IN_OVERTAKE_MPS
        fastest = max(
            CUT_IN_SPEED_FACTOR * libsumo.lane.getMaxSpeed(libsumo.vehicle.getLaneID(vid)), ego_speed + faster
        )
        libsumo.vehicle.setSpeed(vid, min(_pace(ego_speed, gap, wanted_m, left_s), fastest))
        road, lane = libsumo.vehicle.getRoadID(vid), libsumo.vehicle.getLaneIndex(vid)
        ego_lane = libsumo.vehicle.getLaneIndex(ego)
        if far and _blocked(vid, gap, wanted_m):  # far behind: it passes the slower one in another lane
            libsumo.vehicle.changeLane(vid, lane + (1 if lane + 1 < libsumo.edge.getLaneNumber(road) else -1), 1.0)
        elif not far and road == libsumo.vehicle.getRoadID(ego) and abs(lane - ego_lane) != 1:
            side = 1 if lane > ego_lane or (lane == ego_lane and lane + 1 < libsumo.edge.getLaneNumber(road)) else -1
            libsumo.vehicle.changeLane(vid, ego_lane + side, 1.0)  # to a lane beside the ego's
        return gap

    # --- cut-ins -----------------------------------------------------------------------------
    def _make_cut_in(self, event: _Event, ego: str, now: float) -> _Event | None:
        ego_speed = libsumo.vehicle.getSpeed(ego)
        near, far = _cut_in_gaps(event.config, ego_speed)
        if ego_speed < 3.0 or near >= far:
            return None  # no gap in metres is also one in seconds at this speed
        gap_m = float(self._rng.uniform(near, far))
        found = self._beside(ego, now, event.due_s, gap_m, CUT_IN_ROAD_M)
        if found is None:
            return None
        event.gap_m = gap_m
        self._drive(event, found[0], now, found[1])
        return event

    def _cut_in_ready(self, event: _Event, ego: str, now: float) -> bool:
        """A cut-in's vehicle paced to its gap; it cuts in once due and at the gap drawn."""
        vid, ego_speed = event.actors[0], libsumo.vehicle.getSpeed(ego)
        near, far = _cut_in_gaps(event.config, ego_speed)
        wanted = float(np.clip(event.gap_m, near + 1.0, max(far, near + 1.0)))  # the gap drawn, at today's speed
        if self._bring_beside(event, ego, now, wanted - 0.5, event.due_s - now - AHEAD_OF_TIME_S) is None:
            return now - event.seen_s >= LOST_S  # gone from the ego's way: another candidate
        gap = roads.beside_gap(ego, vid)
        if gap is None or now < event.due_s or ego_speed < 3.0 or self._under_way(event.index):
            return now >= event.ends_s
        if not near <= gap <= wanted:
            return now >= event.ends_s  # not yet at the gap drawn, or closer than the scenario allows
        speed = libsumo.vehicle.getSpeed(vid)
        off_pace = not ego_speed - CUT_IN_APPROACH_MPS - 2.0 <= speed <= ego_speed + 3.0  # rammed, or pulling away
        leader = libsumo.vehicle.getLeader(ego, gap + 40.0)
        room = not leader or not leader[0] or leader[1] >= gap + libsumo.vehicle.getLength(vid) + CUT_IN_ROOM_M
        lane = roads.into_ego_lane(ego, vid)
        if off_pace or not room or lane is None or not roads.straight_ahead(ego, STRAIGHT_REACH_M):
            return now >= event.ends_s
        self._cut(event, ego, vid, lane, ego_speed)
        self._turn_on(event, now, now + CUT_IN_S)
        return False

    @staticmethod
    def _cut(event: _Event, ego: str, vid: str, lane: int, ego_speed: float) -> None:
        lateral = libsumo.vehicle.getMaxSpeedLat(vid)
        libsumo.vehicle.setMaxSpeedLat(vid, CUT_IN_LATERAL_MPS)  # across in about 1.5 s (a lane change is 3 s)
        libsumo.vehicle.setLaneChangeMode(vid, 0)
        libsumo.vehicle.changeLane(vid, lane, CUT_IN_HOLD_S)
        slower = max(CUT_IN_SPEED_SHARE * ego_speed, ego_speed - CUT_IN_MAX_DECEL * CUT_IN_BRAKE_S)
        decel = libsumo.vehicle.getDecel(vid)
        libsumo.vehicle.setDecel(vid, max(decel, (ego_speed - slower) / CUT_IN_BRAKE_S))
        libsumo.vehicle.slowDown(vid, slower, CUT_IN_BRAKE_S)
        libsumo.vehicle.setSpeed(vid, slower)
        libsumo.vehicle.setLaneChangeMode(ego, 0)  # the ego keeps its lane and brakes (no swerving around)
        event.restore.append(_react_late(ego))
        event.restore += [lambda: libsumo.vehicle.setDecel(vid, decel),
                          lambda: libsumo.vehicle.setMaxSpeedLat(vid, lateral)]  # fmt: skip

    # --- hard braking --------------------------------------------------------------------------
    def _make_hard_brake(self, event: _Event, ego: str, now: float) -> _Event | None:
        """The ego's leader (within what the rig sees ahead; its route becomes the ego's, so that it
        keeps leading), else a car made ahead of the ego on its lane's way, beyond the rig's
        sight, slower than it: paced so that it leads the ego by a gap within ``distance_m`` by
        the time the event is due."""
        lo, hi = event.config.distance_m
        event.gap_m = float(np.clip(libsumo.vehicle.getSpeed(ego), lo + 0.25 * (hi - lo), hi - 0.25 * (hi - lo)))
        leader = libsumo.vehicle.getLeader(ego, self._ahead_m)
        if leader and leader[0] and leader[1] <= self._ahead_m:
            vid, gap = leader
            if not self._movable(vid, ego):
                return None  # one that cannot act (a bicycle): wait
            if now < event.due_s - _closing_s(gap, event.gap_m) or not roads.follow(vid, ego):
                return None
            self._drive(event, vid, now, gap)
            return event
        made = self._make_ahead(ego) if now >= event.due_s - _closing_s(self._ahead_m, event.gap_m) else None
        if made is None:
            return None
        self._drive(event, made, now, self._ahead_m)
        return event

    def _make_ahead(self, ego: str) -> str | None:
        """A car made on the ego's way ahead (its lane and the lanes its route goes on), at the
        nearest point beyond the rig's sight and labels, routed along the ego's way."""
        if not self._car_types or libsumo.vehicle.getRoadID(ego).startswith(":"):
            return None
        lanes = [libsumo.vehicle.getLaneID(ego), *roads.lane_ahead(ego)]
        route, at = libsumo.vehicle.getRoute(ego), libsumo.vehicle.getRouteIndex(ego)
        start = -libsumo.vehicle.getLanePosition(ego)
        for lane in dict.fromkeys(lanes):
            road, length = lane.rsplit("_", 1)[0], libsumo.lane.getLength(lane)
            for pos in np.arange(max(10.0, self._ahead_m - start), length - 10.0, 10.0):
                xy = np.array(libsumo.simulation.convert2D(road, float(pos), int(lane.rsplit("_", 1)[1])))
                hidden = not self._sight.sees(roads.in_ego_frame(ego, xy), CAR_RADIUS_M + HIDDEN_MARGIN_M)
                if hidden and _free(lane, float(pos), 30.0) and road in route[at:]:
                    way = list(route[list(route).index(road, at) :])
                    return self._add_car(way, float(pos), int(lane.rsplit("_", 1)[1]))
            start += length
            if start > 2.0 * self._ahead_m:
                break
        return None

    def _hard_brake_ready(self, event: _Event, ego: str, now: float) -> bool:
        """The leader is paced to its gap (from the ego's own free speed, so that the ego's
        following does not feed back); once it is due and the leader has led for 3 s, at a gap
        within ``distance_m`` on a straight way (or in line on a gentle bend), it brakes."""
        vid, hazard = event.actors[0], event.config
        gap = roads.route_gap(ego, vid)
        leader = libsumo.vehicle.getLeader(ego, max(self._ahead_m, gap or 0.0) + 10.0)
        between = leader and leader[0] and leader[0] != vid and gap is not None and leader[1] < gap
        if gap is None or gap < 0.0 or between or (event.leading and (not leader or leader[0] != vid)):
            return now - event.seen_s >= LOST_S  # it left the ego's way or lane, or another came between them
        event.seen_s = now
        left_s = max(event.due_s - now - AHEAD_OF_TIME_S, 1.0)
        cruise = libsumo.vehicle.getAllowedSpeed(ego)  # the ego's own free speed (no loop through its following)
        libsumo.vehicle.setSpeed(vid, max(cruise + _leader_change(event.gap_m, gap, left_s), 1.0))
        if not leader or leader[0] != vid:
            return now >= event.ends_s
        if not event.leading:
            event.leading, event.led_s = True, now
        gap = leader[1]
        if now < max(event.due_s, event.led_s + LEADER_SETTLE_S) or self._under_way(event.index):
            return now >= event.ends_s
        lo, hi = hazard.distance_m
        speed = libsumo.vehicle.getSpeed(vid)
        if not lo <= gap <= hi or speed < hazard.to_speed_mps + 4.0:
            return now >= event.ends_s
        if not roads.straight_ahead(ego, gap + 10.0) and not roads.in_line(ego, vid):
            return now >= event.ends_s
        braking_s = self._brake(event, vid, speed)
        self._turn_on(event, now, now + braking_s + HOLD_S)
        return False

    @staticmethod
    def _brake(event: _Event, vid: str, speed: float) -> float:
        hazard = event.config
        decel, emergency = libsumo.vehicle.getDecel(vid), libsumo.vehicle.getEmergencyDecel(vid)
        libsumo.vehicle.setEmergencyDecel(vid, max(emergency, hazard.decel_mps2))
        libsumo.vehicle.setDecel(vid, hazard.decel_mps2)
        braking_s = (speed - hazard.to_speed_mps) / hazard.decel_mps2
        libsumo.vehicle.slowDown(vid, hazard.to_speed_mps, braking_s)
        libsumo.vehicle.setSpeed(vid, hazard.to_speed_mps)
        event.restore += [lambda: libsumo.vehicle.setDecel(vid, decel),
                          lambda: libsumo.vehicle.setEmergencyDecel(vid, emergency)]  # fmt: skip
        return braking_s

    # --- jaywalkers ----------------------------------------------------------------------------
    def _make_jaywalker(self, event: _Event, ego: str, now: float) -> _Event | None:
        """A jaywalker to come: with ``behind_parked`` and parked cars on the ego's way, it steps
        out in front of the parked car the ego comes to when it is due; else from a kerb on the
        ego's way about where the ego will be then, beyond the rig's sight, where a pedestrian
        is placed to wait."""
        hazard = event.config
        if not self._walk_edges or libsumo.vehicle.getRoadID(ego).startswith(":"):
            return None
        event.ends_s = event.due_s + JAYWALK_LATE_S
        if hazard.behind_parked and self._parked_on_way(ego):
            return event  # the parked car is picked as the ego comes to one
        return event if self._place_open(event, ego, now) else None

    def _place_open(self, event: _Event, ego: str, now: float) -> bool:
        """A pedestrian placed to wait at a kerb of the ego's way beyond the rig's sight, about
        where the ego will be when the event is due."""
        limit = libsumo.lane.getMaxSpeed(libsumo.vehicle.getLaneID(ego))
        pace = max(libsumo.vehicle.getSpeed(ego), JAYWALK_PACE_SHARE * limit)
        spot = self._open_spot(ego, _jaywalk_reach(event.config, pace, 2.0) + pace * max(event.due_s - now, 0.0))
        if spot is None:
            return False
        event.spot = spot
        self._place_waiting(event, ego)
        return True

    def _parked_for(self, event: _Event, ego: str, now: float) -> str | None:
        """The parked car on the ego's side of its way the ego comes to its reach from nearest
        the time the event is due (at its speed, or 0.7 of the limit if slower)."""
        limit = libsumo.lane.getMaxSpeed(libsumo.vehicle.getLaneID(ego))
        pace = max(libsumo.vehicle.getSpeed(ego), JAYWALK_PACE_SHARE * limit)
        reach = self._reach(event, ego, None) or _jaywalk_reach(event.config, pace, 2.0)
        best: tuple[float, str] | None = None
        for vid, ahead in self._parked_on_way(ego):
            if ahead >= reach - JAYWALK_CATCH_M:
                off_s = abs((ahead - reach) / pace - (event.due_s - now))
                best = (off_s, vid) if best is None or off_s < best[0] else best
        return None if best is None else best[1]

    def _parked_on_way(self, ego: str) -> list[tuple[str, float]]:
        """The parked cars at the kerb on the ego's side of its way, on straight stretches, not
        taken by another jaywalker: with how far ahead of the ego each one's front is."""
        route = set(libsumo.vehicle.getRoute(ego)[libsumo.vehicle.getRouteIndex(ego) :])
        found = []
        for vid, (road, pos) in self._parked_places().items():
            if road not in route or self._spot_taken(road, pos):
                continue
            ahead = libsumo.vehicle.getDrivingDistance(ego, road, pos)
            if ahead == roads.INVALID or ahead < 0.0 or not self._crossable(road, pos):
                continue
            place = roads.kerb(road, pos)
            side = float((np.array(libsumo.vehicle.getPosition(vid)) - place.xy_m) @ place.left) if place else 0.0
            if -4.5 < side < 0.0:
                found.append((vid, ahead))
        return found

    def _parked_places(self) -> dict[str, tuple[str, float]]:
        """Each parked car's road and the position of its front bumper along it."""
        if not self._parked_at and self._parked:
            for vid in sorted(self._parked):  # parked off the lane: its place along the road, from where it stands
                road, pos, _ = libsumo.simulation.convertRoad(*libsumo.vehicle.getPosition(vid), vClass="passenger")
                if road == libsumo.vehicle.getRoadID(vid):
                    self._parked_at[vid] = (road, pos)
        return self._parked_at

    def _open_spot(self, ego: str, want_m: float) -> tuple[str, float] | None:
        """A place on the ego's way at least ``want_m`` ahead, on a straight stretch away from
        parked cars, at a kerb that no sensor sees now."""
        route, at = libsumo.vehicle.getRoute(ego), libsumo.vehicle.getRouteIndex(ego)
        for road in route[at : at + 6]:
            start = libsumo.vehicle.getDrivingDistance(ego, road, 0.0)
            if start == roads.INVALID:
                continue
            length = libsumo.lane.getLength(f"{road}_0")
            for pos in np.arange(max(want_m - start, JAYWALK_ROAD_M), length - 10.0, 10.0):
                if not self._crossable(road, float(pos)) or self._parked_near(road, float(pos)):
                    continue
                if self._spot_taken(road, float(pos)):
                    continue
                place = roads.kerb(road, float(pos))
                if place and not self._sight.sees(roads.in_ego_frame(ego, place.xy_m), 1.0 + HIDDEN_MARGIN_M):
                    return road, float(pos)
        return None

    def _crossable(self, road: str, pos: float) -> bool:
        """Whether a road is straight 40 m before ``pos`` and 10 m after, which lies on it."""
        lane = f"{road}_0"
        return JAYWALK_ROAD_M <= pos <= libsumo.lane.getLength(lane) - 10.0 and roads.straight_lane(
            lane, max(pos - 40.0, 0.0), pos + 10.0
        )

    def _spot_taken(self, road: str, pos: float) -> bool:
        """Whether another jaywalker steps out within 40 m of a place."""
        return any(e.spot[0] == road and abs(e.spot[1] - pos) < 40.0 for e in self._events if e.kind == "jaywalker")

    def _parked_near(self, road: str, pos: float) -> bool:
        return any(r == road and abs(p - pos) < 8.0 for r, p in self._parked_places().values())

    def _place_waiting(self, event: _Event, ego: str) -> None:
        """A pedestrian placed at the kerb of the event's spot, facing across, waiting."""
        start, direction, _ = self._crossing(event, ego)
        self._people += 1
        person = f"jaywalker_{self._people}"
        kind = CHILD_TYPE if event.config.child else self._pedestrian_type or "DEFAULT_PEDTYPE"
        libsumo.person.add(person, self._walk_edges[0], 0.0, typeID=kind)
        libsumo.person.appendWaitingStage(person, 3600.0)
        self._held[person] = (float(start[0]), float(start[1]), roads.sumo_angle(direction))
        libsumo.person.moveToXY(person, "", *self._held[person], keepRoute=2)
        event.actors.append(person)
        event.restore.append(lambda: self._release(person))

    def _crossing(self, event: _Event, ego: str) -> tuple[np.ndarray, np.ndarray, float]:
        """Where the jaywalker starts (beyond the kerb; in front of the parked car, in line behind
        it), its direction across the road and the length of its walk past the last lane."""
        road, pos = event.spot
        place = roads.kerb(road, pos)
        if place is None:
            raise libsumo.TraCIException(f"road {road} has no lane open to cars")
        start = place.xy_m - place.left * JAYWALK_STEP_M
        if event.parked:
            front = np.array(libsumo.vehicle.getPosition(event.parked))
            start = start + place.forward * (float((front - place.xy_m) @ place.forward) + 0.6)
            start = start - place.left * JAYWALK_HIDDEN_M  # in line behind the car, seen from the ego
        length = float((place.xy_m - start) @ place.left) + place.across_m() + 1.0
        return start, place.left.copy(), length

    def _jaywalker_ready(self, event: _Event, ego: str, now: float) -> bool:
        """The jaywalker steps out once the ego is its reach away from its place: the parked car
        the ego comes to nearest the time it is due (``JAYWALK_PARKED_WAIT_S`` after it, a waiting
        pedestrian is placed in the open instead), or the kerb where it waits."""
        if event.spot[0]:
            ahead = libsumo.vehicle.getDrivingDistance(ego, *event.spot)
            if ahead == roads.INVALID or ahead < 0.0:
                return True  # the ego went another way, or passed
            return False if self._step_out(event, ego, now, event.spot, "") else now >= event.ends_s
        if now >= event.due_s + JAYWALK_PARKED_WAIT_S:
            self._place_open(event, ego, now)
            return now >= event.ends_s
        parked = self._parked_for(event, ego, now)
        if parked is not None and self._step_out(event, ego, now, self._parked_at[parked], parked):
            return False
        return now >= event.ends_s

    def _reach(self, event: _Event, ego: str, spot: tuple[str, float] | None) -> float | None:
        """Where, ahead of the ego, its jaywalker steps out at the ego's speed (within
        ``distance_m``); None while the ego is slower than 2 m/s or off a road of its way."""
        road, pos = spot or (libsumo.vehicle.getRoadID(ego), libsumo.vehicle.getLanePosition(ego))
        place, lane = roads.kerb(road, pos), _lane_on(ego, road)
        speed = libsumo.vehicle.getSpeed(ego)
        if place is None or lane is None or speed < 2.0:
            return None
        lo, hi = event.config.distance_m
        return float(np.clip(_jaywalk_reach(event.config, speed, place.to_lane_m(lane)), lo, hi))

    def _step_out(self, event: _Event, ego: str, now: float, spot: tuple[str, float], parked: str) -> bool:
        """The jaywalker steps out at ``spot`` (in front of the ``parked`` car) if the ego is its
        reach away from it, on a straight way, with no vehicle between them."""
        ahead = libsumo.vehicle.getDrivingDistance(ego, *spot)
        reach = self._reach(event, ego, spot)
        if reach is None or self._under_way(event.index) or not reach - JAYWALK_CATCH_M <= ahead <= reach:
            return False
        leader = libsumo.vehicle.getLeader(ego, ahead + 20.0)
        if leader and leader[0] and leader[1] < ahead + 8.0:
            return False  # a vehicle ahead would drive through the pedestrian
        if not roads.straight_ahead(ego, min(ahead, STRAIGHT_REACH_M)):
            return False
        event.spot, event.parked = spot, parked
        start, direction, length = self._crossing(event, ego)
        if parked:
            self._place_waiting(event, ego)  # hidden by the parked car
        event.actors = event.actors[-1:]
        self._held.pop(event.actors[0], None)  # it walks
        libsumo.person.moveToXY(event.actors[0], "", float(start[0]), float(start[1]), roads.sumo_angle(direction),
                                keepRoute=2)  # fmt: skip
        event.path = (start, direction, length)
        decel = libsumo.vehicle.getDecel(ego)
        libsumo.vehicle.setDecel(ego, max(decel, EGO_STOP_DECEL))
        event.restore += [lambda: libsumo.vehicle.setSpeed(ego, -1.0), lambda: libsumo.vehicle.setDecel(ego, decel)]
        self._turn_on(event, now, now + length / event.config.walk_mps + 1.0)
        return True

    # --- red-light runners ------------------------------------------------------------------------
    def _make_red_light(self, event: _Event, ego: str, now: float) -> _Event | None:
        """A red-light runner to come (the ego's light is made green as it comes, and a crossing
        vehicle made where none could run the red)."""
        event.ends_s = event.due_s + RED_LATE_S
        return event

    def _red_light_ready(self, event: _Event, ego: str, now: float) -> bool:
        if now >= event.due_s - RED_EARLY_S and not self._under_way(event.index) and self._run_red(event, ego, now):
            return False
        soon = now >= event.due_s - RED_ACTUATE_S
        ahead = self._green_ahead(ego, soon)
        if soon and ahead is not None and event.spot[0] != ahead[0] and self._make_crosser(ego, *ahead):
            event.spot = (ahead[0], 0.0)  # one for each light
        return now >= event.ends_s

    def _green_ahead(self, ego: str, actuate: bool) -> tuple[str, int, float] | None:
        """The ego's next light (its id, the ego's link and distance) if it shows the ego green,
        within ``RED_PLAN_M``; with ``actuate``, a red one the ego would stop at is switched to
        green for it first (as a light that detects it coming would: the crossing direction's
        green ends at once, through its yellow)."""
        ahead = libsumo.vehicle.getNextTLS(ego)
        if not ahead or ahead[0][2] > RED_PLAN_M:
            return None
        tls, link, dist, state = ahead[0]
        if state in "Gg":
            return tls, link, dist
        lane = libsumo.vehicle.getLaneID(ego)
        speed = max(libsumo.vehicle.getSpeed(ego), 0.5 * libsumo.lane.getMaxSpeed(lane) if lane else 1.0)
        waiting = libsumo.vehicle.getSpeed(ego) < 1.0  # in the queue at the light: it may turn green at once
        if actuate and state in "rR" and dist / speed <= RED_ACTUATE_S:
            _green_for(tls, link, float("inf") if waiting else dist / speed)
        return None

    def _make_crosser(self, ego: str, tls: str, ego_link: int, ego_dist: float) -> bool:
        """A car made on a crossing approach of a light the ego comes to (one whose link has red
        when the ego's has green), where no sensor sees it, routed across; none is made where a
        vehicle could run the red already. True: made (or not needed)."""
        links = libsumo.trafficlight.getControlledLinks(tls)
        state = libsumo.trafficlight.getRedYellowGreenState(tls)
        ego_in = links[ego_link][0][0].rsplit("_", 1)[0] if links[ego_link] else ""
        crossing = [i for i, link in enumerate(links) if link and state[i] in "rRyY"
                    and link[0][0].rsplit("_", 1)[0] != ego_in
                    and "passenger" not in libsumo.lane.getDisallowed(link[0][0])]  # fmt: skip
        if not crossing or any(self._runners(tls, i, ego) for i in crossing):
            return bool(crossing)
        index = crossing[int(self._rng.integers(0, len(crossing)))]
        in_lane, out_lane, _ = links[index][0]
        road, lane_index = in_lane.rsplit("_", 1)
        length = libsumo.lane.getLength(in_lane)
        for pos in np.arange(length - RED_NEAR_M, 5.0, -10.0):
            xy = np.array(libsumo.simulation.convert2D(road, float(pos), int(lane_index)))
            if _free(in_lane, float(pos), 20.0) and not self._sight.sees(
                roads.in_ego_frame(ego, xy), CAR_RADIUS_M + HIDDEN_MARGIN_M
            ):
                self._add_car([road, out_lane.rsplit("_", 1)[0]], float(pos), int(lane_index))
                return True
        return False

    def _runners(self, tls: str, index: int, ego: str) -> list[str]:
        """Vehicles on the approach lane of a link that could run its red: within ``RED_NEAR_M``
        of the stop line, moving, or the first in the queue."""
        lane = libsumo.trafficlight.getControlledLinks(tls)[index][0][0]
        queue = libsumo.lane.getLastStepVehicleIDs(lane)
        front = max(queue, key=libsumo.vehicle.getLanePosition, default="")  # the nearest the stop line
        length = libsumo.lane.getLength(lane)
        return [vid for vid in queue if self._movable(vid, ego)
                and (libsumo.vehicle.getSpeed(vid) >= 2.0 or vid == front)
                and 0.5 <= length - libsumo.vehicle.getLanePosition(vid) <= RED_NEAR_M]  # fmt: skip

    def _run_red(self, event: _Event, ego: str, now: float) -> bool:
        """While the ego approaches its green within ``distance_m``, a vehicle on a crossing
        approach with red runs it, timed to clear the junction before the ego or to enter it
        after. True: it started."""
        lo, hi = event.config.distance_m
        ahead = [t for t in libsumo.vehicle.getNextTLS(ego) if lo <= t[2] <= hi]
        if not ahead or ahead[0][3] not in "Gg":
            return False
        tls, ego_link, ego_dist, _ = ahead[0]
        ego_speed = max(libsumo.vehicle.getSpeed(ego), 1.0)
        ego_time = ego_dist / ego_speed  # until the ego reaches its stop line
        ego_clear = (ego_dist + JUNCTION_M) / ego_speed + RED_MARGIN_S  # until it has crossed, with a margin
        state = libsumo.trafficlight.getRedYellowGreenState(tls)
        links = libsumo.trafficlight.getControlledLinks(tls)
        ego_in = links[ego_link][0][0] if links[ego_link] else ""
        candidates = []
        for index, link in enumerate(links):
            if not link or state[index] not in "rR" or link[0][0].rsplit("_", 1)[0] == ego_in.rsplit("_", 1)[0]:
                continue
            lane = link[0][0]
            for vid in self._runners(tls, index, ego):
                speed = libsumo.vehicle.getSpeed(vid)
                dist = libsumo.lane.getLength(lane) - libsumo.vehicle.getLanePosition(vid)
                run_speed = max(speed, RED_RUN_MPS)
                if (dist + JUNCTION_M) / (0.5 * (speed + run_speed)) + RED_MARGIN_S <= ego_time:
                    candidates.append((vid, run_speed, RED_LIGHT_S))  # through before the ego
                elif dist / ego_clear >= 3.0:  # through behind the ego, at a speed that brings it there then
                    candidates.append((vid, dist / ego_clear, ego_clear + JUNCTION_M / (dist / ego_clear) + 1.0))
        if not candidates:
            return False
        vid, speed, lasts_s = sorted(candidates)[int(self._rng.integers(0, len(candidates)))]
        libsumo.vehicle.setSpeedMode(vid, IGNORE_RED_AND_RIGHT_OF_WAY)
        libsumo.vehicle.setSpeed(vid, speed)
        event.actors.append(vid)
        event.restore += [lambda: libsumo.vehicle.setSpeed(vid, -1.0),
                          lambda: libsumo.vehicle.setSpeedMode(vid, SPEED_DEFAULT)]  # fmt: skip
        self._turn_on(event, now, now + max(RED_LIGHT_S, lasts_s))
        return True


def _green_for(tls: str, link: int, eta_s: float) -> bool:
    """Switch a light to the yellow that ends the current green, and leads to the phase giving
    ``link`` green, if the ego gets there no sooner than that yellow ends (and the program's
    own order allows it: a link green now is yellow or green then, or goes red next anyway)."""
    program = libsumo.trafficlight.getProgram(tls)
    phases = next(logic.phases for logic in libsumo.trafficlight.getAllProgramLogics(tls) if logic.programID == program)
    now_at, count = libsumo.trafficlight.getPhase(tls), len(phases)
    green = next(
        ((now_at + k) % count for k in range(1, count) if phases[(now_at + k) % count].state[link] in "Gg"), None
    )
    if green is None or (green - 1) % count == now_at:
        return False
    yellow, here, after = phases[(green - 1) % count], phases[now_at].state, phases[(now_at + 1) % count].state
    safe = all(c not in "Gg" or y in "GgyY" or a in "rR" for c, y, a in zip(here, yellow.state, after, strict=True))
    if not safe or eta_s < yellow.duration + 1.0:
        return False
    libsumo.trafficlight.setPhase(tls, (green - 1) % count)
    return True


STRAIGHT_REACH_M = 30.0


def _blocked(vid: str, gap_m: float, wanted_m: float) -> bool:
    """Whether a vehicle short of its gap has a leader in its lane, no faster than it, before
    the place it should reach."""
    leader = libsumo.vehicle.getLeader(vid, max(wanted_m - gap_m, 0.0) + 10.0)
    if gap_m >= wanted_m - 2.0 or not leader or not leader[0]:
        return False
    return bool(libsumo.vehicle.getSpeed(leader[0]) <= libsumo.vehicle.getSpeed(vid) + 1.0)


def _free(lane: str, pos: float, margin_m: float) -> bool:
    """Whether no vehicle on a lane is within ``margin_m`` of ``pos``."""
    on_lane = libsumo.lane.getLastStepVehicleIDs(lane)
    return all(abs(libsumo.vehicle.getLanePosition(v) - pos) > margin_m for v in on_lane)


def _lane_on(ego: str, road: str) -> int | None:
    """The ego's lane index on a road of its way: its own on its road, else the lane its
    route continues on there."""
    if libsumo.vehicle.getRoadID(ego) == road:
        return int(libsumo.vehicle.getLaneIndex(ego))
    lane = next((lane for lane in roads.lane_ahead(ego) if lane.rsplit("_", 1)[0] == road), None)
    return None if lane is None else int(lane.rsplit("_", 1)[1])


def _jaywalk_reach(hazard: HazardConfig, speed: float, kerb_m: float) -> float:
    """How far ahead of the ego a jaywalker steps out: the ego's way (at 2 m/s faster, it may
    speed up) while the pedestrian walks into its path, plus its braking distance and 5 m."""
    fast = speed + 2.0
    across_path = kerb_m + JAYWALK_STEP_M - JAYWALK_PATH_M
    return fast * across_path / hazard.walk_mps + fast * fast / (2.0 * EGO_STOP_DECEL) + 5.0


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


def _leader_change(wanted_m: float, gap_m: float, left_s: float) -> float:
    """How much slower or faster than the ego's free speed a leader drives to bring its gap to
    the one wanted in ``left_s``."""
    return float(np.clip((wanted_m - gap_m) / left_s, -LEADER_SLOWER_MPS, LEADER_FASTER_MPS))


def _closing_s(gap_m: float, wanted_m: float) -> float:
    """About how long a leader takes from a gap to the one wanted, with 3 s to spare (and at
    least ``LEADER_PACE_S``)."""
    rate = 0.75 * (LEADER_SLOWER_MPS if gap_m > wanted_m else LEADER_FASTER_MPS)
    return max(LEADER_PACE_S, abs(gap_m - wanted_m) / rate + AHEAD_OF_TIME_S)


def _approach_s(gap_m: float, wanted_m: float) -> float:
    """About how long a vehicle beside the ego takes from a gap to the one wanted (from far
    behind at 3/4 of ``CATCH_UP_MPS``), with 3 s to spare."""
    far = max(-CUT_IN_BEHIND_M - gap_m, 0.0)
    near = abs(wanted_m - max(gap_m, -CUT_IN_BEHIND_M))
    return far / (0.75 * CATCH_UP_MPS) + near / (0.75 * CUT_IN_OVERTAKE_MPS) + 3.0


def _pace(ego_speed: float, gap_m: float, wanted_m: float, left_s: float) -> float:
    """A speed that brings a vehicle's gap ahead of the ego to ``wanted_m`` in ``left_s`` (at
    least 1 s): up to 6 m/s faster than the ego (10 m/s while more than 30 m behind it), up to
    4 m/s slower."""
    fastest = CUT_IN_OVERTAKE_MPS if gap_m >= -CUT_IN_BEHIND_M else CATCH_UP_MPS
    change = float(np.clip((wanted_m - gap_m) / max(left_s, 1.0), -CUT_IN_APPROACH_MPS, fastest))
    return max(ego_speed + change, 1.0)


__all__ = ["ActiveHazard", "HazardController"]

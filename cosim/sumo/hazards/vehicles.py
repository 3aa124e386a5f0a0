"""Cut-ins and hard braking: vehicles beside the ego brought to a gap ahead of it (or made
out of sight behind it), leaders paced (or made out of sight ahead of it)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from cosim.hazards.decisions import (
    AHEAD_OF_TIME_S,
    CATCH_UP_MPS,
    CUT_IN_BEHIND_M,
    CUT_IN_OVERTAKE_MPS,
    approach_s,
    braking_s,
    closing_s,
    cut_in_gaps,
    cut_in_room,
    leader_brakes,
    leader_change,
    pace,
)
from cosim.sumo.hazards import roads
from cosim.sumo.hazards.base import (
    CAR_RADIUS_M,
    HIDDEN_MARGIN_M,
    LOST_S,
    SPEED_FACTOR,
    STRAIGHT_REACH_M,
    Base,
    Event,
    free,
)
from networks.sumo_tools import sumo_home

sumo_home()  # exports SUMO_HOME before libsumo loads
import libsumo  # noqa: E402

CUT_IN_HOLD_S, CUT_IN_S = 4.0, 6.0
CUT_IN_SPEED_SHARE, CUT_IN_BRAKE_S = 0.5, 2.0  # the cutting vehicle slows to half the ego's speed within 2 s
REACTION_S = 0.6  # the ego's driver decides this often while surprised (SUMO's action step length)
CUT_IN_LATERAL_MPS = 2.5  # the cutting vehicle's sideways speed
CUT_IN_MAX_DECEL = 4.0  # m/s^2: the cutting vehicle brakes no harder than this (the ego can follow)
CUT_IN_LOOK_M = 40.0  # it may start up to 40 m ahead, and drop back
CUT_IN_ROAD_M = 120.0  # or where the ego's road goes on this far: it drives beside the ego as long
MAKE_LEAD_S = 20.0  # where no vehicle is beside the ego, one is made behind it this long before it is due
LEADER_LEAD_S = 30.0  # one is made ahead of the ego up to this long before it is due
LEADER_SETTLE_S = 3.0  # and brakes no sooner than this after it became the ego's leader
HOLD_S = 2.0


class Vehicles(Base):
    # --- vehicles brought beside the ego -------------------------------------------------
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
        vid, gap = min(found, key=lambda f: (approach_s(f[1], wanted_m), f[0]))  # the one there soonest
        return (vid, gap) if now >= due - approach_s(gap, wanted_m) else None

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
                if not free(f"{way[0]}_{lane_index}", pos, 25.0):
                    continue
                xy = np.array(libsumo.simulation.convert2D(way[0], pos, lane_index))
                if not self._sight.sees(roads.in_ego_frame(ego, xy), CAR_RADIUS_M + HIDDEN_MARGIN_M):
                    route, at = libsumo.vehicle.getRoute(ego), libsumo.vehicle.getRouteIndex(ego)
                    return self._add_car([*way, *route[at + 1 :]], pos, lane_index)
        return None

    def _bring_beside(self, event: Event, ego: str, now: float, wanted_m: float, left_s: float) -> float | None:
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
        fastest = max(SPEED_FACTOR * libsumo.lane.getMaxSpeed(libsumo.vehicle.getLaneID(vid)), ego_speed + faster)
        libsumo.vehicle.setSpeed(vid, min(pace(ego_speed, gap, wanted_m, left_s), fastest))
        road, lane = libsumo.vehicle.getRoadID(vid), libsumo.vehicle.getLaneIndex(vid)
        ego_lane = libsumo.vehicle.getLaneIndex(ego)
        if far and _blocked(vid, gap, wanted_m):  # far behind: it passes the slower one in another lane
            count = libsumo.edge.getLaneNumber(road)
            passing = [i for i in (lane - 1, lane + 1) if 0 <= i < count and i != ego_lane]  # not behind the ego
            if passing:
                libsumo.vehicle.changeLane(vid, min(passing, key=lambda i: abs(i - ego_lane)), 1.0)
        elif not far and road == libsumo.vehicle.getRoadID(ego) and abs(lane - ego_lane) != 1:
            side = 1 if lane > ego_lane or (lane == ego_lane and lane + 1 < libsumo.edge.getLaneNumber(road)) else -1
            libsumo.vehicle.changeLane(vid, ego_lane + side, 1.0)  # to a lane beside the ego's
        return gap

    # --- cut-ins -----------------------------------------------------------------------------
    def _make_cut_in(self, event: Event, ego: str, now: float) -> Event | None:
        ego_speed = libsumo.vehicle.getSpeed(ego)
        near, far = cut_in_gaps(event.config, ego_speed)
        if ego_speed < 3.0 or near >= far:
            return None  # no gap in metres is also one in seconds at this speed
        gap_m = float(self._rng.uniform(near, far))
        found = self._beside(ego, now, event.due_s, gap_m, CUT_IN_ROAD_M)
        if found is None or not roads.join(found[0], ego):
            return None
        event.gap_m = gap_m
        self._drive(event, found[0], now, found[1])
        return event

    def _cut_in_ready(self, event: Event, ego: str, now: float) -> bool:
        """A cut-in's vehicle paced to its gap; it cuts in once due and at the gap drawn."""
        vid, ego_speed = event.actors[0], libsumo.vehicle.getSpeed(ego)
        near, far = cut_in_gaps(event.config, ego_speed)
        wanted = float(np.clip(event.gap_m, near + 1.0, max(far, near + 1.0)))  # the gap drawn, at today's speed
        if self._bring_beside(event, ego, now, wanted - 0.5, event.due_s - now - AHEAD_OF_TIME_S) is None:
            return now - event.seen_s >= LOST_S  # gone from the ego's way: another candidate
        gap = roads.beside_gap(ego, vid)
        if gap is None or now < event.due_s or ego_speed < 3.0 or self._under_way(event.index):
            return now >= event.ends_s
        if not near <= gap <= wanted:
            return now >= event.ends_s  # not yet at the gap drawn, or closer than the scenario allows
        leader = libsumo.vehicle.getLeader(ego, gap + 40.0)
        leader_gap = leader[1] if leader and leader[0] else None
        d = libsumo.vehicle
        room = cut_in_room(gap, d.getSpeed(vid), ego_speed, d.getLength(vid), leader_gap)
        lane = roads.into_ego_lane(ego, vid)
        if not room or lane is None or not roads.straight_ahead(ego, STRAIGHT_REACH_M):
            return now >= event.ends_s
        self._cut(event, ego, vid, lane, ego_speed)
        self._turn_on(event, now, now + CUT_IN_S)
        return False

    @staticmethod
    def _cut(event: Event, ego: str, vid: str, lane: int, ego_speed: float) -> None:
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
        event.restore += [
            lambda: libsumo.vehicle.setDecel(vid, decel),
            lambda: libsumo.vehicle.setMaxSpeedLat(vid, lateral),
        ]

    # --- hard braking --------------------------------------------------------------------------
    def _make_hard_brake(self, event: Event, ego: str, now: float) -> Event | None:
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
            if now < event.due_s - closing_s(gap, event.gap_m) or not roads.follow(vid, ego):
                return None
            self._drive(event, vid, now, gap)
            return event
        made = self._make_ahead(ego) if now >= event.due_s - closing_s(self._ahead_m, event.gap_m) else None
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
                if hidden and free(lane, float(pos), 30.0) and road in route[at:]:
                    way = list(route[list(route).index(road, at) :])
                    return self._add_car(way, float(pos), int(lane.rsplit("_", 1)[1]))
            start += length
            if start > 2.0 * self._ahead_m:
                break
        return None

    def _hard_brake_ready(self, event: Event, ego: str, now: float) -> bool:
        """The leader is paced to its gap (from the ego's own free speed, so that the ego's
        following does not feed back); once it is due and the leader has led for 3 s, at a gap
        within ``distance_m`` on a straight way (or in line on a gentle bend), it brakes."""
        vid, hazard = event.actors[0], event.config
        leader = libsumo.vehicle.getLeader(ego, 2.0 * self._ahead_m)
        gap = leader[1] if leader and leader[0] == vid else roads.route_gap(ego, vid)  # (through junctions too)
        between = leader and leader[0] and leader[0] != vid and gap is not None and leader[1] < gap
        if gap is None or gap < 0.0 or between or (event.leading and (not leader or leader[0] != vid)):
            return now - event.seen_s >= LOST_S  # it left the ego's way or lane, or another came between them
        event.seen_s = now
        left_s = max(event.due_s - now - AHEAD_OF_TIME_S, 1.0)
        cruise = libsumo.vehicle.getAllowedSpeed(ego)  # the ego's own free speed (no loop through its following)
        libsumo.vehicle.setSpeed(vid, max(cruise + leader_change(event.gap_m, gap, left_s), 1.0))
        if not leader or leader[0] != vid:
            return now >= event.ends_s
        if not event.leading:
            event.leading, event.led_s = True, now
        gap = leader[1]
        if now < max(event.due_s, event.led_s + LEADER_SETTLE_S) or self._under_way(event.index):
            return now >= event.ends_s
        speed = libsumo.vehicle.getSpeed(vid)
        if not leader_brakes(gap, speed, hazard):
            return now >= event.ends_s
        if not roads.straight_ahead(ego, gap + 10.0) and not roads.in_line(ego, vid):
            return now >= event.ends_s
        brake_s = self._brake(event, vid, speed)
        self._turn_on(event, now, now + brake_s + HOLD_S)
        return False

    @staticmethod
    def _brake(event: Event, vid: str, speed: float) -> float:
        hazard = event.config
        decel, emergency = libsumo.vehicle.getDecel(vid), libsumo.vehicle.getEmergencyDecel(vid)
        libsumo.vehicle.setEmergencyDecel(vid, max(emergency, hazard.decel_mps2))
        libsumo.vehicle.setDecel(vid, hazard.decel_mps2)
        brake_s = braking_s(speed, hazard)
        libsumo.vehicle.slowDown(vid, hazard.to_speed_mps, brake_s)
        libsumo.vehicle.setSpeed(vid, hazard.to_speed_mps)
        event.restore += [
            lambda: libsumo.vehicle.setDecel(vid, decel),
            lambda: libsumo.vehicle.setEmergencyDecel(vid, emergency),
        ]
        return brake_s


def _blocked(vid: str, gap_m: float, wanted_m: float) -> bool:
    """Whether a vehicle short of its gap has a leader in its lane, no faster than it, before
    the place it should reach."""
    leader = libsumo.vehicle.getLeader(vid, max(wanted_m - gap_m, 0.0) + 10.0)
    if gap_m >= wanted_m - 2.0 or not leader or not leader[0]:
        return False
    return bool(libsumo.vehicle.getSpeed(leader[0]) <= libsumo.vehicle.getSpeed(vid) + 1.0)


def _react_late(ego: str) -> Callable[[], None]:
    """The ego's driver reacts ``REACTION_S`` late (SUMO's action step length: the driver
    decides that often and keeps its acceleration in between); returns the undo."""
    step = libsumo.vehicle.getActionStepLength(ego)
    libsumo.vehicle.setActionStepLength(ego, REACTION_S, resetActionOffset=True)
    return lambda: libsumo.vehicle.setActionStepLength(ego, step, resetActionOffset=True)

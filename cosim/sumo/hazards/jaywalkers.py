"""Jaywalkers: a child (or the scene's shortest adult) steps onto the road where the ego comes,
from in front of a parked car or from a kerb where it waited out of the rig's sight."""

from __future__ import annotations

import numpy as np

from cosim.hazards.decisions import (
    EGO_STOP_DECEL,
    JAYWALK_CATCH_M,
    JAYWALK_STEP_M,
    ego_stops_for_walker,
    jaywalk_reach,
    parked_in_time,
    sumo_angle,
)
from cosim.sumo.hazards import roads
from cosim.sumo.hazards.base import CHILD_TYPE, HIDDEN_MARGIN_M, STRAIGHT_REACH_M, Base, Event
from networks.sumo_tools import sumo_home
from networks.vocabulary import HazardKind

sumo_home()  # exports SUMO_HOME before libsumo loads
import libsumo  # noqa: E402

JAYWALK_HIDDEN_M = 0.5  # and this much farther when it starts in front of a parked car
JAYWALK_LEAD_S = 20.0  # its place is chosen this long before it is due
JAYWALK_LATE_S = 40.0  # and given up this long after (the ego may wait at a red light before it)
JAYWALK_PACE_SHARE = 0.7  # of the speed limit: the ego's pace, to tell where it will be when it is due
JAYWALK_ROAD_M = 25.0  # it steps out at least this far along its road, and 10 m before the road's end
JAYWALK_PARKED_WAIT_S = 10.0  # a jaywalker due waits this long for the ego to come to a parked car


class Jaywalkers(Base):
    def _make_jaywalker(self, event: Event, ego: str, now: float) -> Event | None:
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

    def _place_open(self, event: Event, ego: str, now: float) -> bool:
        """A pedestrian placed to wait at a kerb of the ego's way beyond the rig's sight, about
        where the ego will be when the event is due."""
        limit = libsumo.lane.getMaxSpeed(libsumo.vehicle.getLaneID(ego))
        pace = max(libsumo.vehicle.getSpeed(ego), JAYWALK_PACE_SHARE * limit)
        spot = self._open_spot(ego, jaywalk_reach(event.config, pace, 2.0) + pace * max(event.due_s - now, 0.0))
        if spot is None:
            return False
        event.spot = spot
        self._place_waiting(event, ego)
        return True

    def _parked_for(self, event: Event, ego: str, now: float) -> str | None:
        """The parked car on the ego's side of its way the ego comes to its reach from nearest
        the time the event is due (at its speed, or 0.7 of the limit if slower)."""
        limit = libsumo.lane.getMaxSpeed(libsumo.vehicle.getLaneID(ego))
        pace = max(libsumo.vehicle.getSpeed(ego), JAYWALK_PACE_SHARE * limit)
        reach = self._reach(event, ego, None) or jaywalk_reach(event.config, pace, 2.0)
        return parked_in_time(self._parked_on_way(ego), reach, pace, event.due_s - now)

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
        return any(
            e.spot[0] == road and abs(e.spot[1] - pos) < 40.0 for e in self._events if e.kind == HazardKind.JAYWALKER
        )

    def _parked_near(self, road: str, pos: float) -> bool:
        return any(r == road and abs(p - pos) < 8.0 for r, p in self._parked_places().values())

    def _place_waiting(self, event: Event, ego: str) -> None:
        """A pedestrian placed at the kerb of the event's spot, facing across, waiting."""
        start, direction, _ = self._crossing(event, ego)
        self._people += 1
        person = f"jaywalker_{self._people}"
        kind = CHILD_TYPE if event.config.child else self._pedestrian_type or "DEFAULT_PEDTYPE"
        libsumo.person.add(person, self._walk_edges[0], 0.0, typeID=kind)
        libsumo.person.appendWaitingStage(person, 3600.0)
        self._held[person] = (float(start[0]), float(start[1]), sumo_angle(direction))
        libsumo.person.moveToXY(person, "", *self._held[person], keepRoute=2)
        event.actors.append(person)
        event.restore.append(lambda: self._release(person))

    def _crossing(self, event: Event, ego: str) -> tuple[np.ndarray, np.ndarray, float]:
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

    def _jaywalker_ready(self, event: Event, ego: str, now: float) -> bool:
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

    def _reach(self, event: Event, ego: str, spot: tuple[str, float] | None) -> float | None:
        """Where, ahead of the ego, its jaywalker steps out at the ego's speed (within
        ``distance_m``); None while the ego is slower than 2 m/s or off a road of its way."""
        road, pos = spot or (libsumo.vehicle.getRoadID(ego), libsumo.vehicle.getLanePosition(ego))
        place, lane = roads.kerb(road, pos), _lane_on(ego, road)
        speed = libsumo.vehicle.getSpeed(ego)
        if place is None or lane is None or speed < 2.0:
            return None
        lo, hi = event.config.distance_m
        return float(np.clip(jaywalk_reach(event.config, speed, place.to_lane_m(lane)), lo, hi))

    def _step_out(self, event: Event, ego: str, now: float, spot: tuple[str, float], parked: str) -> bool:
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
        libsumo.person.moveToXY(
            event.actors[0], "", float(start[0]), float(start[1]), sumo_angle(direction), keepRoute=2
        )
        event.path = (start, direction, length)
        decel = libsumo.vehicle.getDecel(ego)
        libsumo.vehicle.setDecel(ego, max(decel, EGO_STOP_DECEL))
        event.restore += [lambda: libsumo.vehicle.setSpeed(ego, -1.0), lambda: libsumo.vehicle.setDecel(ego, decel)]
        self._turn_on(event, now, now + length / event.config.walk_mps + 1.0)
        return True

    def _walk(self, event: Event, ego: str, now: float) -> bool:
        """A step of a jaywalker crossing (True: it has crossed); the ego stops for it if it is
        in the ego's path or will be before the ego could stop."""
        config = event.config
        if event.kind == HazardKind.JAYWALKER and event.path is not None:
            start, direction, length = event.path
            walked = (now - event.started_s) * config.walk_mps
            person = event.actors[0]
            if walked >= length:
                return True
            x, y = start + direction * walked
            libsumo.person.moveToXY(person, "", float(x), float(y), sumo_angle(direction), keepRoute=2)
            if ego_stops_for_walker(roads.pose(ego), x, y, libsumo.vehicle.getSpeed(ego), config.walk_mps):
                libsumo.vehicle.setSpeed(ego, 0.0)  # the ego stops for a pedestrian stepping into its path
            else:
                libsumo.vehicle.setSpeed(ego, -1.0)
        return now >= event.ends_s

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


def _lane_on(ego: str, road: str) -> int | None:
    """The ego's lane index on a road of its way: its own on its road, else the lane its
    route continues on there."""
    if libsumo.vehicle.getRoadID(ego) == road:
        return int(libsumo.vehicle.getLaneIndex(ego))
    lane = next((lane for lane in roads.lane_ahead(ego) if lane.rsplit("_", 1)[0] == road), None)
    return None if lane is None else int(lane.rsplit("_", 1)[1])

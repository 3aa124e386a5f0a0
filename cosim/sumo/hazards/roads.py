"""The roads around the ego as hazard events need them, read from libsumo (for
:mod:`cosim.sumo.hazards`): where its way runs straight, who drives beside it and how far ahead,
the roads it came along (where vehicles are made out of its sight) and the kerb of a road."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cosim.hazards import decisions
from cosim.hazards.decisions import Kerb, Pose, straight
from networks.geometry import arc_lengths, polyline_length
from networks.sumo_tools import sumo_home
from networks.vocabulary import SignalState

sumo_home()  # exports SUMO_HOME before libsumo loads
import libsumo  # noqa: E402

INVALID = libsumo.constants.INVALID_DOUBLE_VALUE
HISTORY = 40  # roads of the ego's way back kept


def pose(vid: str) -> Pose:
    """A vehicle's front bumper, heading and length, decoded."""
    d = libsumo.vehicle
    return Pose.of_sumo(d.getPosition(vid), d.getAngle(vid), d.getLength(vid))


def in_ego_frame(ego: str, xy_map_m: np.ndarray) -> np.ndarray:
    """A map point in the ego frame (x forward, y left, from the ego's footprint centre)."""
    return decisions.in_ego_frame(pose(ego), xy_map_m)


def next_lights(ego: str) -> list[tuple[str, int, float, SignalState]]:
    """The lights on the ego's way: each one's id, the ego's link, its distance and state."""
    return [(tls, link, dist, SignalState.of(letter)) for tls, link, dist, letter in libsumo.vehicle.getNextTLS(ego)]


@dataclass(slots=True)
class WayBack:
    """The roads the ego came along, oldest first (vehicles made behind it start on them)."""

    ego: str = ""
    roads: list[str] | None = None

    def note(self, ego: str) -> None:
        """Call each step: keeps the ego's road when it enters a new one (a new ego starts anew)."""
        road = libsumo.vehicle.getRoadID(ego)
        if ego != self.ego or self.roads is None:  # a new ego: the roads of its route it drove
            route = libsumo.vehicle.getRoute(ego)
            self.ego, self.roads = ego, list(route[: libsumo.vehicle.getRouteIndex(ego)])
        if road and not road.startswith(":") and (not self.roads or self.roads[-1] != road):
            self.roads = [*self.roads[-HISTORY + 1 :], road]

    def place(self, ego: str, back_m: float) -> tuple[list[str], float] | None:
        """The roads from a point ``back_m`` behind the ego's front bumper along its way to the
        road it is on, and that point's position on the first of them (None: the ego came from
        nearer than that)."""
        roads = self.roads or []
        if not roads or libsumo.vehicle.getRoadID(ego) != roads[-1]:
            return None
        left = back_m - libsumo.vehicle.getLanePosition(ego)
        k = len(roads) - 1
        while left > 0.0:
            k -= 1
            if k < 0:
                return None
            left -= libsumo.lane.getLength(f"{roads[k]}_0")
        return roads[k:], -left


def route_gap(ego: str, vid: str) -> float | None:
    """A vehicle's gap ahead of the ego along the ego's way: from the ego's front bumper to its
    rear (negative: beside or behind); None when neither is on the other's way (or in a junction)."""
    length = libsumo.vehicle.getLength(vid)
    road, pos = libsumo.vehicle.getRoadID(vid), libsumo.vehicle.getLanePosition(vid)
    if not road.startswith(":"):
        ahead = libsumo.vehicle.getDrivingDistance(ego, road, pos)
        if ahead != INVALID and ahead >= 0.0:
            return float(ahead - length)
    road, pos = libsumo.vehicle.getRoadID(ego), libsumo.vehicle.getLanePosition(ego)
    if not road.startswith(":"):
        behind = libsumo.vehicle.getDrivingDistance(vid, road, pos)
        if behind != INVALID and behind >= 0.0:
            return float(-behind - length)
    return None


def way_starts(ego: str, way_back: WayBack, behind_m: float) -> dict[str, float]:
    """The roads of the ego's way from ``behind_m`` behind it to the next road of its route,
    each with where it starts relative to the ego's front bumper (metres along the way;
    junctions between them are not counted)."""
    here, pos = libsumo.vehicle.getRoadID(ego), libsumo.vehicle.getLanePosition(ego)
    place = way_back.place(ego, behind_m)
    back = list(place[0]) if place else [here]
    starts, start = {}, -pos
    for road in reversed(back):
        if road != here:
            start -= libsumo.lane.getLength(f"{road}_0")
        starts[road] = start
    route, at = libsumo.vehicle.getRoute(ego), libsumo.vehicle.getRouteIndex(ego)
    for road in route[at + 1 : at + 2]:
        starts.setdefault(road, libsumo.lane.getLength(f"{here}_0") - pos)
    return starts


def has_lane(ego: str, index: int) -> bool:
    """Whether the ego's road has a lane open to cars of this index."""
    return f"{libsumo.vehicle.getRoadID(ego)}_{index}" in car_lanes(libsumo.vehicle.getRoadID(ego))


def car_lanes(road: str) -> list[str]:
    """A road's lanes open to cars."""
    lanes = [f"{road}_{i}" for i in range(libsumo.edge.getLaneNumber(road))]
    return [lane for lane in lanes if "passenger" not in libsumo.lane.getDisallowed(lane)]


def beside_gap(ego: str, vid: str) -> float | None:
    """A vehicle's gap ahead of the ego while it drives in a lane beside the ego's
    (:func:`cosim.hazards.decisions.beside_gap`); None otherwise."""
    return decisions.beside_gap(pose(ego), pose(vid))


def same_way(ego: str, vid: str, road_m: float) -> bool:
    """Whether a vehicle's route goes on where the ego's does: the ego's next road is among its
    next two, or the ego's road goes on for ``road_m`` (they drive side by side as long; inf:
    the ego's next two roads must be its next ones, it is to lead the ego)."""
    route, at = libsumo.vehicle.getRoute(ego), libsumo.vehicle.getRouteIndex(ego)
    left_m = libsumo.lane.getLength(libsumo.vehicle.getLaneID(ego)) - libsumo.vehicle.getLanePosition(ego)
    if at + 1 >= len(route) or left_m >= road_m:
        return True
    theirs, their_at = libsumo.vehicle.getRoute(vid), libsumo.vehicle.getRouteIndex(vid)
    if road_m == float("inf"):
        ahead = list(theirs[their_at:])
        ego_next = [r for r in route[at + 1 : at + 3] if r != theirs[their_at]]
        start = ahead.index(ego_next[0]) if ego_next and ego_next[0] in ahead else -1
        return start >= 0 and ahead[start : start + len(ego_next)] == ego_next
    return route[at + 1] in theirs[their_at + 1 : their_at + 3]


def follow(vid: str, ego: str) -> bool:
    """Route a vehicle along the ego's way from the road it is on (it leads the ego there; in a
    junction, it keeps its route); False: it is not on the ego's way ahead."""
    road = libsumo.vehicle.getRoadID(vid)
    route, at = list(libsumo.vehicle.getRoute(ego)), libsumo.vehicle.getRouteIndex(ego)
    if road.startswith(":"):
        return True
    if road not in route[at:]:
        return False
    libsumo.vehicle.setRoute(vid, route[route.index(road, at) :])
    return True


def join(vid: str, ego: str) -> bool:
    """Route a vehicle beside or behind the ego along the ego's way, from the road it is on
    (it drives beside the ego as long as the ego goes on, rather than turning off or arriving
    where its own trip ends; in a junction, it keeps its route); False: no way leads from its
    road to the ego's."""
    road = libsumo.vehicle.getRoadID(vid)
    route, at = list(libsumo.vehicle.getRoute(ego)), libsumo.vehicle.getRouteIndex(ego)
    if road.startswith(":"):
        return True
    if road in route[at:]:
        way = route[route.index(road, at) :]
    else:
        found = libsumo.simulation.findRoute(road, route[at])
        if not found.edges:
            return False
        way = [*found.edges, *route[at + 1 :]]
    try:
        libsumo.vehicle.setRoute(vid, way)
    except libsumo.TraCIException:
        return False
    return True


def lane_ahead(ego: str) -> tuple[str, ...]:
    """The lanes the ego's route continues on from its lane (SUMO's best lanes)."""
    lane = libsumo.vehicle.getLaneID(ego)
    return next((tuple(best[5]) for best in libsumo.vehicle.getBestLanes(ego) if best[0] == lane), (lane,))


def into_ego_lane(ego: str, vid: str) -> int | None:
    """The lane index a vehicle beside the ego changes to, to be in the ego's lane or the one
    the ego's route continues on (None: no lane beside it is)."""
    lane = libsumo.vehicle.getLaneID(ego)
    ahead = lane_ahead(ego)
    road, index = libsumo.vehicle.getRoadID(vid), int(libsumo.vehicle.getLaneIndex(vid))
    for side in (index - 1, index + 1):
        if f"{road}_{side}" in (lane, *ahead):
            return side
    return None


def straight_ahead(ego: str, reach_m: float) -> bool:
    """Whether the ego's way runs straight (within ``STRAIGHT_DEG``) over ``reach_m`` ahead, along
    its lane and the lanes its route continues on: there, constant velocities predict where
    the ego and the vehicles ahead go, and a time to collision means what it says."""
    if libsumo.vehicle.getRoadID(ego).startswith(":"):
        return False
    path = [np.array(libsumo.vehicle.getPosition(ego))]
    travelled = libsumo.vehicle.getLanePosition(ego)  # along the first lane's shape
    for next_lane in lane_ahead(ego) or (libsumo.vehicle.getLaneID(ego),):
        shape = np.array(libsumo.lane.getShape(next_lane), dtype=float)
        along = arc_lengths(shape)
        path += list(shape[along > travelled])
        travelled = 0.0
        if polyline_length(np.array(path)) >= reach_m:
            break
    return straight(np.array(path), reach_m)


def straight_lane(lane: str, start_m: float, end_m: float) -> bool:
    """Whether a lane runs straight (within ``STRAIGHT_DEG``) from ``start_m`` to ``end_m``."""
    shape = np.array(libsumo.lane.getShape(lane), dtype=float)
    along = arc_lengths(shape)
    inner = shape[(along > start_m) & (along < end_m)]
    points = np.array([decisions.point_along(shape, start_m), *inner, decisions.point_along(shape, end_m)])
    return straight(points, end_m - start_m)


def in_line(ego: str, vid: str) -> bool:
    """Whether a vehicle ahead is in line with the ego (:func:`cosim.hazards.decisions.in_line`)."""
    return decisions.in_line(pose(ego), pose(vid))


def kerb(road: str, position_m: float) -> Kerb | None:
    """The kerb of a road at ``position_m`` along it (None: no lane open to cars)."""
    count = libsumo.edge.getLaneNumber(road)
    driving = tuple(i for i in range(count) if "passenger" not in libsumo.lane.getDisallowed(f"{road}_{i}"))
    if not driving:
        return None
    widths = tuple(libsumo.lane.getWidth(f"{road}_{i}") for i in range(count))
    first = driving[0]
    length = libsumo.lane.getLength(f"{road}_{first}")
    a = np.array(libsumo.simulation.convert2D(road, max(position_m - 5.0, 0.0), first))
    b = np.array(libsumo.simulation.convert2D(road, min(position_m + 5.0, length), first))
    fwd = (b - a) / max(float(np.linalg.norm(b - a)), 1e-6)
    left = np.array([-fwd[1], fwd[0]])
    centre = np.array(libsumo.simulation.convert2D(road, position_m, first))
    return Kerb(centre - left * widths[first] / 2.0, fwd, left, driving, widths)

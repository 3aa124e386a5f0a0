"""The hazards' decisions as pure functions of what SUMO reported, decoded (no SUMO here):
where a vehicle is relative to the ego, whether a way runs straight, how fast an actor is
paced, when a jaywalker makes the ego stop, who runs a red light and which phase a light is
switched to. :mod:`cosim.sumo.hazards` reads the simulation into these types and issues the
commands they decide.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from cosim.kinematics import front_bumper_to_center, sumo_angle_to_yaw
from cosim.scenario import HazardConfig
from networks.geometry import arc_lengths, polyline_length
from networks.records import check_arrays
from networks.vocabulary import SignalState

F64 = npt.NDArray[np.float64]

STRAIGHT_DEG = 6.0
IN_LINE_M, IN_LINE_DEG = 1.0, 8.0
BESIDE_ACROSS_M, BESIDE_DEG = (1.5, 6.0), 20.0  # a vehicle beside the ego: its centre this far across

AHEAD_OF_TIME_S = 3.0  # a prepared vehicle is brought to its place this long before its event is due
CATCH_UP_MPS = 10.0  # how much faster than the ego a vehicle drives while it catches up from far behind
CUT_IN_BEHIND_M = 30.0  # a cut-in's vehicle may start up to this far behind the ego's front, and overtake
CUT_IN_OVERTAKE_MPS = 6.0  # how much faster than the ego it overtakes
CUT_IN_APPROACH_MPS = 4.0  # how much slower than the ego it drops back
CUT_IN_ROOM_M = 1.0  # free space it needs in front of it in the ego's lane (no one is cut into)
LEADER_SLOWER_MPS, LEADER_FASTER_MPS = 10.0, 5.0  # a hard brake's leader is paced this much slower or faster
LEADER_PACE_S = 20.0  # and the ego's leader is paced from at least this long before

EGO_STOP_DECEL = 7.5  # the ego brakes at up to this for a jaywalker
JAYWALK_PATH_M, JAYWALK_LOOK_M = 1.8, 40.0  # the ego's path: this far either side of its lane centre
JAYWALK_STEP_M = 0.6  # the pedestrian starts this far beyond the kerb
JAYWALK_CATCH_M = 4.0  # it steps out when the ego is its reach or up to this much less away

RED_RUN_MPS = 9.0  # a red-light runner speeds up to at least this
RED_MARGIN_S = 1.5  # it leaves the junction this long before the ego can reach it (or enters after)
RED_LIGHT_S = 10.0
JUNCTION_M = 25.0  # the way through a junction


@dataclass(frozen=True, slots=True)
class Pose:
    """A vehicle or a person in the map plane as SUMO reports it, decoded: ``front_xy_m``
    ``(2,) float64`` is SUMO's position (a vehicle's front bumper), ``yaw_rad`` its heading
    (counter-clockwise from east), ``length_m`` its length."""

    front_xy_m: F64
    yaw_rad: float
    length_m: float

    def __post_init__(self) -> None:
        check_arrays(self, front_xy_m=(np.float64, (2,)))

    @classmethod
    def of_sumo(cls, position: Sequence[float], angle_deg: float, length_m: float) -> Pose:
        """From SUMO's position, angle (degrees clockwise from north) and length."""
        return cls(np.array(position, dtype=np.float64), float(sumo_angle_to_yaw(angle_deg)), float(length_m))

    @property
    def forward(self) -> F64:
        """Unit heading in the map plane."""
        return np.array([math.cos(self.yaw_rad), math.sin(self.yaw_rad)])

    @property
    def centre_xy_m(self) -> F64:
        """The footprint's centre: half a length behind the front bumper (the traffic's box
        centres, :func:`cosim.kinematics.front_bumper_to_center`, on level ground)."""
        front = np.array([self.front_xy_m[0], self.front_xy_m[1], 0.0])
        return front_bumper_to_center(front, self.yaw_rad, 0.0, self.length_m, 0.0)[0, :2]


def left_of(forward: F64) -> F64:
    """The unit vector to the left of a unit heading."""
    return np.array([-forward[1], forward[0]])


def sumo_angle(direction: F64) -> float:
    """SUMO's angle of a direction in the map plane: degrees clockwise from north."""
    return math.degrees(math.atan2(direction[0], direction[1])) % 360.0


def in_ego_frame(ego: Pose, xy_map_m: npt.ArrayLike) -> F64:
    """A map point in the ego frame (x forward, y left, from the ego's footprint centre)."""
    fwd = ego.forward
    rel = np.asarray(xy_map_m, dtype=float) - ego.centre_xy_m
    return np.array([float(rel @ fwd), float(rel @ left_of(fwd))])


def beside_gap(ego: Pose, other: Pose) -> float | None:
    """A vehicle's gap ahead of the ego (its rear from the ego's front bumper, along the ego's
    heading) while it drives in a lane beside the ego's (its centre 1.5 to 6 m to the side of
    the ego's front bumper, its heading within 20 degrees); None otherwise."""
    fwd, their_forward = ego.forward, other.forward
    length = other.length_m
    rear = other.front_xy_m - length * their_forward
    offset = rear + 0.5 * length * their_forward - ego.front_xy_m
    across = abs(float(offset @ left_of(fwd)))
    if not BESIDE_ACROSS_M[0] <= across <= BESIDE_ACROSS_M[1]:
        return None
    if float(fwd @ their_forward) < math.cos(math.radians(BESIDE_DEG)):
        return None
    return float((rear - ego.front_xy_m) @ fwd)


def in_line(ego: Pose, other: Pose) -> bool:
    """Whether a vehicle ahead is in line with the ego (a leader on a gentle bend): its centre
    within ``IN_LINE_M`` of the ego's heading line, its heading within ``IN_LINE_DEG``; a time to
    collision under constant velocity then still says how close a stop ahead comes."""
    fwd, their_forward = ego.forward, other.forward
    half = other.length_m / 2.0
    centre = other.front_xy_m - half * their_forward
    offset = centre - ego.front_xy_m
    left = left_of(fwd)
    across = abs(float(offset @ left))
    turn = math.degrees(math.atan2(float(their_forward @ left), float(their_forward @ fwd)))
    return across <= IN_LINE_M and abs(turn) <= IN_LINE_DEG


def straight(points: F64, reach_m: float) -> bool:
    """Whether a polyline ``(K, 2)`` runs straight (within ``STRAIGHT_DEG``) over its first
    ``reach_m`` (False where it is shorter): the turn between its first and second halves."""
    if polyline_length(points) < reach_m - 1e-6:
        return False  # the route ends (or is not known) within reach
    x0, x1, x2 = (point_along(points, s) for s in (0.0, reach_m / 2.0, reach_m))
    turn = math.atan2(*(x2 - x1)[::-1]) - math.atan2(*(x1 - x0)[::-1])
    return abs(math.degrees(math.atan2(math.sin(turn), math.cos(turn)))) <= STRAIGHT_DEG


def point_along(points: F64, distance_m: float) -> F64:
    """The point ``distance_m`` along a polyline ``(K, 2)``."""
    along = arc_lengths(points)
    return np.array([np.interp(distance_m, along, points[:, 0]), np.interp(distance_m, along, points[:, 1])])


@dataclass(frozen=True, slots=True)
class Kerb:
    """A road's driving lanes at a point: the point on the right kerb (the outer edge of the
    rightmost lane open to cars), the road's unit direction there and unit left, and the
    driving lanes' indices and widths (all of the road's lanes)."""

    xy_m: F64
    forward: F64
    left: F64
    driving: tuple[int, ...]
    widths_m: tuple[float, ...]

    def to_lane_m(self, index: int) -> float:
        """From lane ``index``'s centre to the kerb."""
        return self.widths_m[index] / 2.0 + sum(self.widths_m[min(self.driving) : index])

    def across_m(self) -> float:
        """The width of the driving lanes."""
        return sum(self.widths_m[i] for i in self.driving)


# --- pacing -------------------------------------------------------------------------------------
def cut_in_gaps(hazard: HazardConfig, ego_speed: float) -> tuple[float, float]:
    """The gaps a cut-in may leave at this speed: within ``distance_m`` and ``time_gap_s``."""
    return (
        max(hazard.distance_m[0], hazard.time_gap_s[0] * ego_speed),
        min(hazard.distance_m[1], hazard.time_gap_s[1] * ego_speed),
    )


def leader_change(wanted_m: float, gap_m: float, left_s: float) -> float:
    """How much slower or faster than the ego's free speed a leader drives to bring its gap to
    the one wanted in ``left_s``."""
    return float(np.clip((wanted_m - gap_m) / left_s, -LEADER_SLOWER_MPS, LEADER_FASTER_MPS))


def closing_s(gap_m: float, wanted_m: float) -> float:
    """About how long a leader takes from a gap to the one wanted, with 3 s to spare (and at
    least ``LEADER_PACE_S``)."""
    rate = 0.75 * (LEADER_SLOWER_MPS if gap_m > wanted_m else LEADER_FASTER_MPS)
    return max(LEADER_PACE_S, abs(gap_m - wanted_m) / rate + AHEAD_OF_TIME_S)


def approach_s(gap_m: float, wanted_m: float) -> float:
    """About how long a vehicle beside the ego takes from a gap to the one wanted (from far
    behind at 3/4 of ``CATCH_UP_MPS``), with 3 s to spare."""
    far = max(-CUT_IN_BEHIND_M - gap_m, 0.0)
    near = abs(wanted_m - max(gap_m, -CUT_IN_BEHIND_M))
    return far / (0.75 * CATCH_UP_MPS) + near / (0.75 * CUT_IN_OVERTAKE_MPS) + 3.0


def pace(ego_speed: float, gap_m: float, wanted_m: float, left_s: float) -> float:
    """A speed that brings a vehicle's gap ahead of the ego to ``wanted_m`` in ``left_s`` (at
    least 1 s): up to 6 m/s faster than the ego (10 m/s while more than 30 m behind it), up to
    4 m/s slower."""
    fastest = CUT_IN_OVERTAKE_MPS if gap_m >= -CUT_IN_BEHIND_M else CATCH_UP_MPS
    change = float(np.clip((wanted_m - gap_m) / max(left_s, 1.0), -CUT_IN_APPROACH_MPS, fastest))
    return max(ego_speed + change, 1.0)


def cut_in_room(
    gap_m: float, speed_mps: float, ego_speed_mps: float, length_m: float, leader_gap_m: float | None
) -> bool:
    """Whether a vehicle beside the ego, its rear ``gap_m`` ahead of the ego's front bumper, may
    cut in now: at the ego's pace (from ``CUT_IN_APPROACH_MPS`` + 2 m/s slower, rammed, to 3 m/s
    faster, pulling away), with room before the ego's leader (``leader_gap_m`` ahead of the
    ego's front bumper; None: no leader) for its length and ``CUT_IN_ROOM_M``."""
    on_pace = ego_speed_mps - CUT_IN_APPROACH_MPS - 2.0 <= speed_mps <= ego_speed_mps + 3.0
    return on_pace and (leader_gap_m is None or leader_gap_m >= gap_m + length_m + CUT_IN_ROOM_M)


def leader_brakes(gap_m: float, speed_mps: float, hazard: HazardConfig) -> bool:
    """Whether a hard brake's leader, ``gap_m`` ahead of the ego, brakes now: within
    ``distance_m`` and at least 4 m/s faster than the speed it brakes to."""
    lo, hi = hazard.distance_m
    return lo <= gap_m <= hi and speed_mps >= hazard.to_speed_mps + 4.0


def braking_s(speed_mps: float, hazard: HazardConfig) -> float:
    """How long a hard brake takes from ``speed_mps`` to its speed at its deceleration."""
    return (speed_mps - hazard.to_speed_mps) / hazard.decel_mps2


# --- jaywalkers ---------------------------------------------------------------------------------
def jaywalk_reach(hazard: HazardConfig, speed: float, kerb_m: float) -> float:
    """How far ahead of the ego a jaywalker steps out: the ego's way (at 2 m/s faster, it may
    speed up) while the pedestrian walks into its path, plus its braking distance and 5 m."""
    fast = speed + 2.0
    across_path = kerb_m + JAYWALK_STEP_M - JAYWALK_PATH_M
    return fast * across_path / hazard.walk_mps + fast * fast / (2.0 * EGO_STOP_DECEL) + 5.0


def parked_in_time(parked: Sequence[tuple[str, float]], reach_m: float, pace_mps: float, left_s: float) -> str | None:
    """Of the parked cars on the ego's way (each with how far ahead of the ego its front is),
    the one the ego, at ``pace_mps``, comes to ``reach_m`` from nearest ``left_s`` from now (the
    first of equals; None: none is that far ahead, less ``JAYWALK_CATCH_M``)."""
    best: tuple[float, str] | None = None
    for vid, ahead in parked:
        if ahead >= reach_m - JAYWALK_CATCH_M:
            off_s = abs((ahead - reach_m) / pace_mps - left_s)
            best = (off_s, vid) if best is None or off_s < best[0] else best
    return None if best is None else best[1]


def ego_stops_for_walker(ego: Pose, x: float, y: float, ego_speed: float, walk_mps: float) -> bool:
    """Whether the ego stops for a pedestrian crossing at ``(x, y)``: within 6 m behind its front
    bumper to ``JAYWALK_LOOK_M`` ahead, and in its path (``JAYWALK_PATH_M`` either side of its
    heading line, or to its right) or walking into it before the ego could stop (at
    ``EGO_STOP_DECEL``, with 1 s to spare)."""
    fwd = ego.forward
    rel = np.array([x - ego.front_xy_m[0], y - ego.front_xy_m[1]])
    along, across = float(rel @ fwd), float(rel @ np.array([-fwd[1], fwd[0]]))
    entering_s = max(0.0, (abs(across) - JAYWALK_PATH_M) / walk_mps)
    coming = across < JAYWALK_PATH_M and entering_s <= ego_speed / EGO_STOP_DECEL + 1.0
    return -6.0 < along < JAYWALK_LOOK_M and coming


# --- red lights ---------------------------------------------------------------------------------
def red_run(dist_m: float, speed_mps: float, ego_time_s: float, ego_clear_s: float) -> tuple[float, float] | None:
    """How a vehicle ``dist_m`` before its red stop line, at ``speed_mps``, runs it: through
    before the ego reaches its stop line in ``ego_time_s`` (speeding up to ``RED_RUN_MPS``), or
    behind the ego (which has crossed in ``ego_clear_s``), at a speed that brings it there then
    (at least 3 m/s). Its speed and how long the event lasts; None: it can do neither."""
    run_speed = max(speed_mps, RED_RUN_MPS)
    if (dist_m + JUNCTION_M) / (0.5 * (speed_mps + run_speed)) + RED_MARGIN_S <= ego_time_s:
        return run_speed, RED_LIGHT_S
    if dist_m / ego_clear_s >= 3.0:
        return dist_m / ego_clear_s, ego_clear_s + JUNCTION_M / (dist_m / ego_clear_s) + 1.0
    return None


def phase_to_green(
    phases: Sequence[tuple[SignalState, ...]], durations_s: Sequence[float], now_at: int, link: int, eta_s: float
) -> int | None:
    """The phase to switch a light to so that ``link`` gets green next: the yellow before the
    next phase giving it green, if the current phase is not that yellow already, the program's
    own order allows it (a link green now is yellow or green in that yellow, or red in the
    phase after the current one anyway) and the ego, ``eta_s`` away, gets there no sooner than
    that yellow ends (with 1 s to spare). None: leave the light alone."""
    count = len(phases)
    green = next(((now_at + k) % count for k in range(1, count) if phases[(now_at + k) % count][link].is_green), None)
    if green is None or (green - 1) % count == now_at:
        return None
    yellow_at = (green - 1) % count
    yellow, here, after = phases[yellow_at], phases[now_at], phases[(now_at + 1) % count]
    safe = all(
        not c.is_green or y.is_green or y.is_yellow or a.is_red for c, y, a in zip(here, yellow, after, strict=True)
    )
    if not safe or eta_s < durations_s[yellow_at] + 1.0:
        return None
    return yellow_at

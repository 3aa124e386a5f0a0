"""The state every hazard kind shares, and what they do alike: the events, the vehicles made
for them (out of the rig's sight) and the ones taken over."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from cosim.hazards.decisions import CATCH_UP_MPS
from cosim.hazards.plan import Schedule, Sight
from cosim.scenario import HazardConfig
from cosim.sumo.hazards import roads
from networks.sumo_tools import sumo_home
from networks.vocabulary import HazardKind

sumo_home()  # exports SUMO_HOME before libsumo loads
import libsumo  # noqa: E402

# Jaywalking children: a pedestrian type of Euro NCAP's child target's size, made with the controller.
CHILD_TYPE = "pedestrian_child"
CHILD_LWH_M = (0.25, 0.4, 1.15)
MADE = "hazard"  # vehicles made for events are named hazard_1, hazard_2, ...
KEEP_LANE = 0b011000000001  # lane-change mode: changes for its route and asked ones only, into safe gaps
SPEED_DEFAULT = 31
OVER_THE_LIMIT = 64  # speed mode: a speed asked may exceed the lane's speed limit
SPEED_FACTOR = 1.3  # of the speed limit: how fast a vehicle taken over wants to drive
CAR_RADIUS_M, HIDDEN_MARGIN_M = 3.0, 5.0  # a vehicle is made this far beyond the rig's sight and labels
LOST_S = 3.0  # a preparation ends this long after its actor is no longer where it needs it
LATE_S = 10.0  # a preparation is given up this long after its event was due (another is tried)
STRAIGHT_REACH_M = 30.0


@dataclass(slots=True)
class Event:
    """A hazard event, from its preparation (``number`` 0) to its end."""

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
    spot: tuple[str, float] = ("", 0.0)  # jaywalker: road and position where it steps out; red_light: the light
    parked: str = ""  # jaywalker: the parked car it steps out in front of
    path: tuple[np.ndarray, np.ndarray, float] | None = None  # jaywalker: start, unit direction, length

    @property
    def kind(self) -> HazardKind:
        return self.config.kind


class Base:
    """What the hazard kinds share (their mixins make up :class:`~cosim.sumo.hazards.HazardController`)."""

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
        self._events: list[Event] = []
        self._way_back = roads.WayBack()
        self._count = 0
        self._people = 0
        self._made = 0
        self._pending: set[str] = set()  # vehicles made, not on the road yet
        self._ego_mode: int | None = None  # the ego's own lane-change mode while cut-ins hold its lane
        self._held: dict[str, tuple[float, float, float]] = {}  # pedestrians standing: x, y, SUMO angle
        self._leftover: set[str] = set()  # those of past events, removed once out of sight
        if any(h.kind == HazardKind.JAYWALKER and h.child for h in hazards):
            libsumo.vehicletype.copy("DEFAULT_PEDTYPE", CHILD_TYPE)
            libsumo.vehicletype.setLength(CHILD_TYPE, CHILD_LWH_M[0])
            libsumo.vehicletype.setWidth(CHILD_TYPE, CHILD_LWH_M[1])
            libsumo.vehicletype.setHeight(CHILD_TYPE, CHILD_LWH_M[2])

    def _turn_on(self, event: Event, now: float, ends_s: float) -> None:
        """A prepared event starts: it gets its number, and the next of its kind is due."""
        self._count += 1
        event.number, event.started_s, event.ends_s = self._count, now, ends_s
        self._schedules[event.index].take(now)

    def _under_way(self, index: int) -> bool:
        return any(e.index == index and e.number for e in self._events)

    def _movable(self, vid: str, ego: str) -> bool:
        """A vehicle that can act in a new event: not the ego, parked, a bicycle, or in an event."""
        busy = {a for e in self._events for a in e.actors}
        return (bool(vid) and vid != ego and vid not in self._parked and vid not in busy
                and libsumo.vehicle.getVehicleClass(vid) not in ("bicycle", "pedestrian"))  # fmt: skip

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

    def _drive(self, event: Event, vid: str, now: float, gap_m: float) -> None:
        """Take a vehicle's speed and lane changes over for a preparation (given back at its
        end); one that has far to come has longer than ``LATE_S`` after it is due."""
        event.ends_s = max(event.due_s, now + abs(gap_m - event.gap_m) / CATCH_UP_MPS) + LATE_S
        event.seen_s = now
        speed_mode, mode = libsumo.vehicle.getSpeedMode(vid), libsumo.vehicle.getLaneChangeMode(vid)
        factor = libsumo.vehicle.getSpeedFactor(vid)
        libsumo.vehicle.setSpeedMode(vid, SPEED_DEFAULT | OVER_THE_LIMIT)  # it may pass the ego above the limit
        libsumo.vehicle.setSpeedFactor(vid, max(factor, SPEED_FACTOR))  # and wants to (passing slower ones)
        libsumo.vehicle.setLaneChangeMode(vid, KEEP_LANE)
        event.actors.append(vid)
        event.restore += [
            lambda: libsumo.vehicle.setSpeed(vid, -1.0),
            lambda: libsumo.vehicle.setSpeedMode(vid, speed_mode),
            lambda: libsumo.vehicle.setSpeedFactor(vid, factor),
            lambda: libsumo.vehicle.setLaneChangeMode(vid, mode),
        ]


def free(lane: str, pos: float, margin_m: float) -> bool:
    """Whether no vehicle on a lane is within ``margin_m`` of ``pos``."""
    on_lane = libsumo.lane.getLastStepVehicleIDs(lane)
    return all(abs(libsumo.vehicle.getLanePosition(v) - pos) > margin_m for v in on_lane)

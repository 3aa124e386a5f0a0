"""Semantic classes shared by the world mesh, the sensors and the labels.

The numeric values are written into point clouds and masks: never renumber them.
"""

from __future__ import annotations

from enum import IntEnum


class SemanticClass(IntEnum):
    NONE = 0
    ROAD = 1
    SIDEWALK = 2
    CURB = 3
    BUILDING = 4
    VEGETATION = 5
    POLE = 6
    TERRAIN = 7
    CROSSING = 8
    CAR = 10
    TRUCK = 11
    BUS = 12
    MOTORCYCLE = 13
    BICYCLE = 14
    PEDESTRIAN = 15
    TRAILER = 16  # the trailer of an articulated truck, its own object behind the tractor
    CONSTRUCTION_VEHICLE = 17
    TRAFFIC_CONE = 18  # construction zones' static objects
    BARRIER = 19
    LANE_MARKING = 20  # white paint: lane, edge, stop and give-way lines, zebra stripes
    LANE_MARKING_YELLOW = 21  # yellow paint
    TRAFFIC_LIGHT = 22
    TRAFFIC_SIGN = 23
    FENCE = 24  # guardrails and median barriers (SemanticKITTI's fence: fences, crash barriers)
    OTHER_OBJECT = 25  # street furniture: benches, bins, bus shelters (SemanticKITTI's other-object)
    TRUNK = 26  # tree trunks under their crowns (SemanticKITTI's trunk)
    PARKING = 27  # street-parking lanes (OpenDRIVE lane type parking; SemanticKITTI's parking)

    @property
    def is_agent(self) -> bool:
        """An object labelled in every output (3D box, track): the road users the traffic moves, the
        trailers they pull, and the construction zones' vehicles, cones and barriers."""
        return SemanticClass.CAR.value <= self.value <= SemanticClass.BARRIER.value

    @property
    def is_paint(self) -> bool:
        return self in (SemanticClass.LANE_MARKING, SemanticClass.LANE_MARKING_YELLOW)

    @property
    def label(self) -> str:
        """Lower-case name as written in labels (``car``, ``pedestrian``)."""
        return self.name.lower()


AGENT_CLASSES: tuple[SemanticClass, ...] = tuple(c for c in SemanticClass if c.is_agent)

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

    @property
    def is_agent(self) -> bool:
        return self.value >= SemanticClass.CAR.value

    @property
    def label(self) -> str:
        """Lower-case name as written in labels (``car``, ``pedestrian``)."""
        return self.name.lower()


AGENT_CLASSES: tuple[SemanticClass, ...] = tuple(c for c in SemanticClass if c.is_agent)

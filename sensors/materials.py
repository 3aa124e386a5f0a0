"""Per-class surface reflectivity (0..1) used for LiDAR intensity and radar strength."""

from __future__ import annotations

import numpy as np

from networks.classes import SemanticClass

_REFLECTIVITY = {
    SemanticClass.NONE: 0.0,
    SemanticClass.ROAD: 0.12,
    SemanticClass.SIDEWALK: 0.25,
    SemanticClass.CURB: 0.3,
    SemanticClass.BUILDING: 0.45,
    SemanticClass.VEGETATION: 0.35,
    SemanticClass.POLE: 0.5,
    SemanticClass.TERRAIN: 0.2,
    SemanticClass.CROSSING: 0.7,
    SemanticClass.CAR: 0.6,
    SemanticClass.TRUCK: 0.6,
    SemanticClass.BUS: 0.6,
    SemanticClass.MOTORCYCLE: 0.55,
    SemanticClass.BICYCLE: 0.5,
    SemanticClass.PEDESTRIAN: 0.35,
}

REFLECTIVITY_BY_CLASS = np.zeros(256, dtype=np.float32)
for _cls, _value in _REFLECTIVITY.items():
    REFLECTIVITY_BY_CLASS[int(_cls)] = _value

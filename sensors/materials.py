"""Per-class surface properties: LiDAR reflectivity (0..1, also LiDAR intensity), radar
reflectivity (0..1, a relative radar cross-section per unit area) and camera albedo (BGR,
0..1). Each is a ``(256,)`` or ``(256, 3) float32`` table indexed by the class value."""

from __future__ import annotations

import numpy as np

from networks.classes import SemanticClass

# LiDAR reflectivity: asphalt returns weakly (about 0.1), retro-reflective road paint (glass
# beads) several times more: the contrast that LiDAR lane-marking extraction and reflectivity
# maps rely on (Levinson and Thrun, "Robust vehicle localization in urban environments using
# probabilistic maps", ICRA 2010; Guan et al., "Using mobile laser scanning data for automated
# extraction of road markings", ISPRS J. 2014).
_REFLECTIVITY = {
    SemanticClass.NONE: 0.0,
    SemanticClass.ROAD: 0.12,
    SemanticClass.SIDEWALK: 0.25,
    SemanticClass.CURB: 0.3,
    SemanticClass.BUILDING: 0.45,
    SemanticClass.VEGETATION: 0.35,
    SemanticClass.POLE: 0.5,
    SemanticClass.TERRAIN: 0.2,
    SemanticClass.CROSSING: 0.12,  # asphalt: its zebra stripes are paint
    SemanticClass.LANE_MARKING: 0.6,
    SemanticClass.LANE_MARKING_YELLOW: 0.55,
    SemanticClass.TRAFFIC_LIGHT: 0.3,
    SemanticClass.TRAFFIC_SIGN: 0.9,  # retro-reflective sheeting
    SemanticClass.FENCE: 0.55,  # galvanised steel rails, concrete
    SemanticClass.OTHER_OBJECT: 0.4,
    SemanticClass.TRUNK: 0.3,  # bark
    SemanticClass.PARKING: 0.12,  # asphalt, as the road
    SemanticClass.CAR: 0.6,
    SemanticClass.TRUCK: 0.6,
    SemanticClass.BUS: 0.6,
    SemanticClass.MOTORCYCLE: 0.55,
    SemanticClass.BICYCLE: 0.5,
    SemanticClass.PEDESTRIAN: 0.35,
    SemanticClass.TRAILER: 0.6,
    SemanticClass.CONSTRUCTION_VEHICLE: 0.6,
    SemanticClass.TRAFFIC_CONE: 0.5,  # orange plastic; the white bands are retro-reflective parts
    SemanticClass.BARRIER: 0.5,
}

# Metal reflects radar far better than asphalt, plants or people.
_RADAR_REFLECTIVITY = {
    SemanticClass.ROAD: 0.02,
    SemanticClass.SIDEWALK: 0.03,
    SemanticClass.CURB: 0.1,
    SemanticClass.BUILDING: 0.35,
    SemanticClass.VEGETATION: 0.08,
    SemanticClass.POLE: 0.9,
    SemanticClass.TERRAIN: 0.03,
    SemanticClass.CROSSING: 0.02,
    SemanticClass.LANE_MARKING: 0.02,
    SemanticClass.LANE_MARKING_YELLOW: 0.02,
    SemanticClass.TRAFFIC_LIGHT: 0.6,
    SemanticClass.TRAFFIC_SIGN: 0.9,
    SemanticClass.FENCE: 0.8,  # steel guardrails
    SemanticClass.OTHER_OBJECT: 0.5,
    SemanticClass.TRUNK: 0.15,  # wood holds water: a little more than leaves
    SemanticClass.PARKING: 0.02,
    SemanticClass.CAR: 1.0,
    SemanticClass.TRUCK: 1.0,
    SemanticClass.BUS: 1.0,
    SemanticClass.MOTORCYCLE: 0.6,
    SemanticClass.BICYCLE: 0.35,
    SemanticClass.PEDESTRIAN: 0.15,
    SemanticClass.TRAILER: 1.0,
    SemanticClass.CONSTRUCTION_VEHICLE: 1.0,
    SemanticClass.TRAFFIC_CONE: 0.1,  # plastic
    SemanticClass.BARRIER: 0.3,
}

# Blue, green, red in 0..1.
_ALBEDO_BGR = {
    SemanticClass.NONE: (0.5, 0.5, 0.5),
    SemanticClass.ROAD: (0.27, 0.26, 0.25),
    SemanticClass.SIDEWALK: (0.55, 0.57, 0.6),
    SemanticClass.CURB: (0.65, 0.66, 0.68),
    SemanticClass.BUILDING: (0.45, 0.55, 0.7),
    SemanticClass.VEGETATION: (0.1, 0.22, 0.16),  # foliage: darker than grass
    SemanticClass.POLE: (0.35, 0.35, 0.38),
    SemanticClass.TERRAIN: (0.15, 0.32, 0.26),  # grass: yellow-green (sensors.textures.grass)
    SemanticClass.CROSSING: (0.27, 0.26, 0.25),  # asphalt under the stripes
    SemanticClass.LANE_MARKING: (0.85, 0.85, 0.85),
    SemanticClass.LANE_MARKING_YELLOW: (0.1, 0.7, 0.9),
    SemanticClass.TRAFFIC_LIGHT: (0.08, 0.08, 0.08),
    SemanticClass.TRAFFIC_SIGN: (0.8, 0.8, 0.8),
    SemanticClass.FENCE: (0.62, 0.63, 0.64),  # galvanised steel, grey concrete
    SemanticClass.OTHER_OBJECT: (0.25, 0.32, 0.4),  # dark wood and painted steel
    SemanticClass.TRUNK: (0.13, 0.17, 0.21),  # grey-brown bark
    SemanticClass.PARKING: (0.27, 0.26, 0.25),  # asphalt
    SemanticClass.CAR: (0.6, 0.3, 0.2),
    SemanticClass.TRUCK: (0.3, 0.55, 0.8),
    SemanticClass.BUS: (0.15, 0.7, 0.85),
    SemanticClass.MOTORCYCLE: (0.2, 0.2, 0.7),
    SemanticClass.BICYCLE: (0.6, 0.6, 0.2),
    SemanticClass.PEDESTRIAN: (0.35, 0.45, 0.75),
    SemanticClass.TRAILER: (0.8, 0.8, 0.8),
    SemanticClass.CONSTRUCTION_VEHICLE: (0.05, 0.6, 0.9),  # construction yellow
    SemanticClass.TRAFFIC_CONE: (0.05, 0.35, 0.95),  # signal orange
    SemanticClass.BARRIER: (0.1, 0.1, 0.8),
}

# Paint colours (BGR, 0..1) cycled over instance ids of vehicles, so that cars differ.
VEHICLE_PAINT_BGR = np.array(
    [[0.75, 0.75, 0.75], [0.1, 0.1, 0.1], [0.2, 0.2, 0.75], [0.7, 0.35, 0.15], [0.9, 0.9, 0.9],
     [0.35, 0.35, 0.35], [0.2, 0.5, 0.2], [0.15, 0.6, 0.85], [0.5, 0.2, 0.1], [0.55, 0.5, 0.45]],
    dtype=np.float32,
)  # fmt: skip


def _table(values: dict[SemanticClass, float]) -> np.ndarray:
    out = np.zeros(256, dtype=np.float32)
    for cls, value in values.items():
        out[int(cls)] = value
    return out


REFLECTIVITY_BY_CLASS = _table(_REFLECTIVITY)
# Retro-reflective surfaces send the light back towards its source over a wide range of
# incidence angles (glass beads in road paint, prismatic sheeting on signs: EN 1436, EN 12899-1):
# their LiDAR return hardly weakens as the beam grazes them.
RETRO_BY_CLASS = np.zeros(256, dtype=np.bool_)
RETRO_BY_CLASS[
    [int(SemanticClass.LANE_MARKING), int(SemanticClass.LANE_MARKING_YELLOW), int(SemanticClass.TRAFFIC_SIGN)]
] = True
RADAR_REFLECTIVITY_BY_CLASS = _table(_RADAR_REFLECTIVITY)
ALBEDO_BGR_BY_CLASS = np.full((256, 3), 0.5, dtype=np.float32)
for _cls, _bgr in _ALBEDO_BGR.items():
    ALBEDO_BGR_BY_CLASS[int(_cls)] = _bgr
PAINTED_CLASSES = np.zeros(256, dtype=np.bool_)
PAINTED_CLASSES[[int(SemanticClass.CAR), int(SemanticClass.TRUCK), int(SemanticClass.MOTORCYCLE)]] = True

"""One colour per semantic class, for every picture and viewer the project makes (bird's-eye
views, Foxglove boxes and annotations): RGB in 0..1, chosen to stand out on black."""

from __future__ import annotations

from networks.classes import SemanticClass

CLASS_RGB: dict[int, tuple[float, float, float]] = {
    SemanticClass.ROAD: (0.35, 0.35, 0.35),
    SemanticClass.SIDEWALK: (0.67, 0.59, 0.59),
    SemanticClass.CURB: (0.78, 0.75, 0.75),
    SemanticClass.BUILDING: (0.78, 0.51, 0.27),
    SemanticClass.VEGETATION: (0.24, 0.67, 0.24),
    SemanticClass.POLE: (0.86, 0.86, 0.0),
    SemanticClass.TERRAIN: (0.24, 0.35, 0.24),
    SemanticClass.CROSSING: (0.5, 0.5, 0.55),
    SemanticClass.CAR: (0.2, 0.6, 1.0),
    SemanticClass.TRUCK: (1.0, 0.6, 0.12),
    SemanticClass.BUS: (1.0, 0.86, 0.12),
    SemanticClass.MOTORCYCLE: (0.9, 0.2, 0.9),
    SemanticClass.BICYCLE: (0.2, 0.9, 0.9),
    SemanticClass.PEDESTRIAN: (1.0, 0.24, 0.24),
    SemanticClass.TRAILER: (1.0, 0.45, 0.0),
    SemanticClass.CONSTRUCTION_VEHICLE: (0.85, 0.65, 0.1),
    SemanticClass.TRAFFIC_CONE: (1.0, 0.5, 0.3),
    SemanticClass.BARRIER: (0.75, 0.4, 1.0),
    SemanticClass.LANE_MARKING: (1.0, 1.0, 1.0),
    SemanticClass.LANE_MARKING_YELLOW: (1.0, 0.85, 0.1),
    SemanticClass.TRAFFIC_LIGHT: (0.1, 1.0, 0.4),
    SemanticClass.TRAFFIC_SIGN: (1.0, 0.3, 0.6),
    SemanticClass.FENCE: (0.55, 0.45, 0.3),
    SemanticClass.OTHER_OBJECT: (0.6, 0.3, 0.9),
    SemanticClass.TRUNK: (0.55, 0.35, 0.15),
    SemanticClass.PARKING: (0.45, 0.4, 0.5),
}


def class_bgr255(cls: int, default: tuple[int, int, int] = (128, 128, 128)) -> tuple[int, int, int]:
    """The class's colour as OpenCV's 0..255 BGR."""
    rgb = CLASS_RGB.get(int(cls))
    if rgb is None:
        return default
    r, g, b = (round(255 * c) for c in rgb)
    return (b, g, r)

"""nuScenes-lidarseg and Panoptic nuScenes labels of the keyframe LiDAR sweeps.

Each point of a ``LIDAR_TOP`` keyframe sweep gets the index of its class in nuScenes-lidarseg's
32 categories (``lidarseg/<version>/<sample_data token>_lidarseg.bin``, one uint8 per point)
and, for Panoptic nuScenes, ``index * 1000 + instance`` (``panoptic/<version>/<token>_panoptic.npz``,
uint16 ``data``): the instance numbered from 1 within its scene in the order the devkit's own
``generate_panoptic_labels`` numbers annotations (first keyframe seen, then track id), 0 for the
static world. Classes come from the simulation per point, never from boxes: a point is a car's
because its ray hit that car.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from networks.classes import SemanticClass

# nuScenes-lidarseg's categories in index order (the devkit's colour map lists them so).
LIDARSEG_CATEGORIES = (
    "noise", "animal", "human.pedestrian.adult", "human.pedestrian.child", "human.pedestrian.construction_worker",
    "human.pedestrian.personal_mobility", "human.pedestrian.police_officer", "human.pedestrian.stroller",
    "human.pedestrian.wheelchair", "movable_object.barrier", "movable_object.debris",
    "movable_object.pushable_pullable", "movable_object.trafficcone", "static_object.bicycle_rack", "vehicle.bicycle",
    "vehicle.bus.bendy", "vehicle.bus.rigid", "vehicle.car", "vehicle.construction", "vehicle.emergency.ambulance",
    "vehicle.emergency.police", "vehicle.motorcycle", "vehicle.trailer", "vehicle.truck", "flat.driveable_surface",
    "flat.other", "flat.sidewalk", "flat.terrain", "static.manmade", "static.other", "static.vegetation",
    "vehicle.ego",
)  # fmt: skip
STUFF_FROM = LIDARSEG_CATEGORIES.index("flat.driveable_surface")  # indices from here on have no instances
MAX_INSTANCES = 999  # Panoptic nuScenes's ids hold the instance in the last three digits

# Our classes as nuScenes-lidarseg's (its annotator instructions): paint and crossings are drivable
# surface, curbs go with the sidewalk, poles, buildings, traffic lights and signs are man-made;
# 0 "noise" for the spurious returns of rain and fog.
_CATEGORY_OF = {
    SemanticClass.NONE: "noise",
    SemanticClass.ROAD: "flat.driveable_surface",
    SemanticClass.CROSSING: "flat.driveable_surface",
    SemanticClass.PARKING: "flat.driveable_surface",  # nuScenes-lidarseg counts parking lanes and lots as driveable
    SemanticClass.LANE_MARKING: "flat.driveable_surface",
    SemanticClass.LANE_MARKING_YELLOW: "flat.driveable_surface",
    SemanticClass.SIDEWALK: "flat.sidewalk",
    SemanticClass.CURB: "flat.sidewalk",
    SemanticClass.TERRAIN: "flat.terrain",
    SemanticClass.VEGETATION: "static.vegetation",
    SemanticClass.TRUNK: "static.vegetation",  # nuScenes-lidarseg counts trunks as vegetation
    SemanticClass.BUILDING: "static.manmade",
    SemanticClass.POLE: "static.manmade",
    SemanticClass.TRAFFIC_LIGHT: "static.manmade",
    SemanticClass.TRAFFIC_SIGN: "static.manmade",
    SemanticClass.FENCE: "static.manmade",  # guard rails and fences are man-made structures in nuScenes-lidarseg
    SemanticClass.OTHER_OBJECT: "static.manmade",  # so are benches, bins and bus stops
    SemanticClass.CAR: "vehicle.car",
    SemanticClass.TRUCK: "vehicle.truck",
    SemanticClass.BUS: "vehicle.bus.rigid",
    SemanticClass.MOTORCYCLE: "vehicle.motorcycle",
    SemanticClass.BICYCLE: "vehicle.bicycle",
    SemanticClass.PEDESTRIAN: "human.pedestrian.adult",
    SemanticClass.TRAILER: "vehicle.trailer",
    SemanticClass.CONSTRUCTION_VEHICLE: "vehicle.construction",
    SemanticClass.TRAFFIC_CONE: "movable_object.trafficcone",
    SemanticClass.BARRIER: "movable_object.barrier",
}
LIDARSEG_LUT = np.zeros(256, np.uint8)  # a class not listed is noise
for _cls, _name in _CATEGORY_OF.items():
    LIDARSEG_LUT[int(_cls)] = LIDARSEG_CATEGORIES.index(_name)


def lidarseg_labels(semantic_class: npt.NDArray[np.uint8]) -> npt.NDArray[np.uint8]:
    """``(N,) uint8``: each point's nuScenes-lidarseg category index."""
    return np.asarray(LIDARSEG_LUT[semantic_class], np.uint8)


def lidarseg_of_objects(
    semantic_class: npt.NDArray[np.uint8], instance_id: npt.NDArray[np.uint32], category_of_track: dict[int, str]
) -> npt.NDArray[np.uint8]:
    """``(N,) uint8`` category indices as :func:`lidarseg_labels`, but the points of the tracks
    in ``category_of_track`` with their boxes' category (a police car's points are
    ``vehicle.emergency.police``, as its box, not ``vehicle.car``, as its class)."""
    out = lidarseg_labels(semantic_class)
    for track, category in category_of_track.items():
        out[instance_id == track] = LIDARSEG_CATEGORIES.index(category)
    return out


def panoptic_labels(
    semantic_class: npt.NDArray[np.uint8],
    instance_id: npt.NDArray[np.uint32],
    number_of: dict[int, int],
    category_of_track: dict[int, str] | None = None,
) -> npt.NDArray[np.uint16]:
    """``(N,) uint16``: ``category * 1000 + instance``, the instance by ``number_of`` (track id ->
    1..999 in its scene) on the points of objects (0 where a track has no number); categories as
    :func:`lidarseg_of_objects`."""
    category = lidarseg_of_objects(semantic_class, instance_id, category_of_track or {}).astype(np.int64)
    tracks = np.asarray(instance_id, np.int64)
    numbers = np.array([number_of.get(int(t), 0) for t in np.unique(tracks)], np.int64)
    instance = numbers[np.searchsorted(np.unique(tracks), tracks)] if len(tracks) else tracks
    instance = np.where((category > 0) & (category < STUFF_FROM), instance, 0)
    return (category * 1000 + instance).astype(np.uint16)


def number_instances(tracks_per_keyframe: list[list[int]]) -> dict[int, int]:
    """Track id -> instance number in a scene, from the annotated tracks of its keyframes in
    time order: numbered from 1 as each first appears (then by track id), at most ``MAX_INSTANCES``."""
    number_of: dict[int, int] = {}
    for tracks in tracks_per_keyframe:
        for track in sorted(tracks):
            if track not in number_of and len(number_of) < MAX_INSTANCES:
                number_of[track] = len(number_of) + 1
    return number_of

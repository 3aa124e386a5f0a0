"""Per-frame labels computed from the objects and the sensors' rays (numpy, all objects at once)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from gtgen.counting import count_hits
from gtgen.objects import ObjectBoxes
from gtgen.projection import CameraBoxes, camera_boxes
from gtgen.visibility import CameraVisibility, camera_visibility
from networks.geometry import SE3
from sensors.agents import AgentBoxes
from sensors.camera import CameraFrame, CameraSpec
from sensors.lidar import LidarScan
from sensors.radar import RadarScan


@dataclass(frozen=True, slots=True)
class CameraLabels:
    """One camera's view of the labelled objects, row-aligned with them."""

    name: str
    boxes: CameraBoxes
    visibility: CameraVisibility


@dataclass(frozen=True, slots=True)
class FrameLabels:
    """Labels of one frame: ``objects`` plus, per object, ``distance_m: (N,) float64``
    (horizontal, from the ego origin), ``lidar_points`` and ``radar_points: (N,) int32``
    summed over the sensors of that kind, ``seen: (N,) bool`` (a ray of some sensor hit the
    object: a LiDAR or radar return, or a visible camera pixel) and one :class:`CameraLabels`
    per camera."""

    frame_index: int
    timestamp_ns: int
    objects: ObjectBoxes
    distance_m: npt.NDArray[np.float64]
    lidar_points: npt.NDArray[np.int32]
    radar_points: npt.NDArray[np.int32]
    seen: npt.NDArray[np.bool_]
    cameras: tuple[CameraLabels, ...] = ()

    def __len__(self) -> int:
        return len(self.objects)


@dataclass(frozen=True, slots=True)
class SensorHits:
    """What the frame's sensors returned, as the labeller needs it."""

    lidar_scans: tuple[LidarScan, ...] = ()
    radar_scans: tuple[RadarScan, ...] = ()
    cameras: tuple[tuple[CameraSpec, CameraFrame], ...] = ()


def label_frame(
    frame_index: int,
    timestamp_ns: int,
    objects: ObjectBoxes,
    agents_map: AgentBoxes,
    map_SE3_ego: SE3,
    hits: SensorHits,
    range_m: float,
) -> FrameLabels:
    """Label every object whose box centre lies within ``range_m`` of the ego, and every
    object a sensor ray hit (a long bus can be hit while its centre is out of range).
    ``agents_map`` is row-aligned with ``objects`` (the same agents in the map frame)."""
    distance = np.linalg.norm(objects.center_ego_m[:, :2], axis=1)
    lidar = sum(
        (count_hits(s.instance_id, objects.track_id) for s in hits.lidar_scans), np.zeros(len(objects), np.int32)
    )
    radar = sum(
        (count_hits(s.instance_id, objects.track_id) for s in hits.radar_scans), np.zeros(len(objects), np.int32)
    )
    pixels_per_camera = [count_hits(f.instance_id.ravel(), objects.track_id) for _, f in hits.cameras]
    pixels = sum(pixels_per_camera, np.zeros(len(objects), np.int32))
    seen = (lidar > 0) | (radar > 0) | (pixels > 0)
    keep = (distance <= range_m) | seen
    kept, kept_map = objects.select(keep), agents_map.select(keep)
    cameras = tuple(_camera_labels(spec, frame, kept, kept_map, map_SE3_ego, px[keep])
                    for (spec, frame), px in zip(hits.cameras, pixels_per_camera, strict=True))  # fmt: skip
    return FrameLabels(frame_index, timestamp_ns, kept, distance[keep], lidar[keep], radar[keep], seen[keep], cameras)


def _camera_labels(
    spec: CameraSpec,
    frame: CameraFrame,
    objects: ObjectBoxes,
    agents_map: AgentBoxes,
    map_SE3_ego: SE3,
    visible_px: npt.NDArray[np.int32],
) -> CameraLabels:
    boxes = camera_boxes(spec, objects)
    visibility = camera_visibility(spec, map_SE3_ego, agents_map, boxes.clipped_px, frame.instance_id, visible_px)
    return CameraLabels(spec.name, boxes, visibility)

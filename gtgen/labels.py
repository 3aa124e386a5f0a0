"""Per-frame labels computed from the objects and the sensors' rays (numpy, all objects at once)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from gtgen.objects import ObjectBoxes
from sensors.lidar import LidarScan


@dataclass(frozen=True, slots=True)
class FrameLabels:
    """Labels of one frame: ``objects`` (every object within LiDAR range) plus, per object,
    ``distance_m: (N,) float64`` from the ego origin, ``lidar_points: (N,) int32`` summed
    over all LiDARs, ``seen: (N,) bool`` (at least one sensor ray hit the object)."""

    frame_index: int
    timestamp_ns: int
    objects: ObjectBoxes
    distance_m: npt.NDArray[np.float64]
    lidar_points: npt.NDArray[np.int32]
    seen: npt.NDArray[np.bool_]

    def __len__(self) -> int:
        return len(self.objects)


def count_hits(instance_ids: npt.NDArray[np.uint32], track_ids: npt.NDArray[np.uint32]) -> npt.NDArray[np.int32]:
    """How many of ``instance_ids`` equal each of ``track_ids``."""
    if track_ids.shape[0] == 0 or instance_ids.shape[0] == 0:
        return np.zeros(track_ids.shape[0], np.int32)
    uniq, counts = np.unique(instance_ids, return_counts=True)
    pos = np.clip(np.searchsorted(uniq, track_ids), 0, uniq.shape[0] - 1)
    return np.where(uniq[pos] == track_ids, counts[pos], 0).astype(np.int32)


def label_frame(
    frame_index: int,
    timestamp_ns: int,
    objects: ObjectBoxes,
    lidar_scans: list[LidarScan],
    range_m: float,
) -> FrameLabels:
    """Label every object whose box centre lies within ``range_m`` of the ego, and every
    object a sensor ray hit (a long bus can be hit while its centre is out of range)."""
    distance = np.linalg.norm(objects.center_ego_m[:, :2], axis=1)
    points = np.zeros(len(objects), np.int32)
    for scan in lidar_scans:
        points += count_hits(scan.instance_id, objects.track_id)
    keep = (distance <= range_m) | (points > 0)
    return FrameLabels(frame_index, timestamp_ns, objects.select(keep), distance[keep], points[keep], points[keep] > 0)

"""Everything one frame hands to the sinks."""

from __future__ import annotations

from dataclasses import dataclass

from gtgen.labels import FrameLabels
from networks.geometry import SE3
from sensors.lidar import LidarScan, LidarSpec


@dataclass(frozen=True, slots=True)
class LidarOutput:
    spec: LidarSpec
    scan: LidarScan


@dataclass(frozen=True, slots=True)
class FrameRecord:
    frame_index: int
    timestamp_ns: int
    map_SE3_ego: SE3
    lidars: tuple[LidarOutput, ...]
    labels: FrameLabels

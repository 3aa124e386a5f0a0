"""Everything one frame hands to the sinks."""

from __future__ import annotations

from dataclasses import dataclass

from gtgen.labels import FrameLabels
from networks.geometry import SE3
from sensors.camera import CameraFrame, CameraSpec
from sensors.lidar import LidarScan, LidarSpec
from sensors.radar import RadarScan, RadarSpec


@dataclass(frozen=True, slots=True)
class LidarOutput:
    spec: LidarSpec
    scan: LidarScan


@dataclass(frozen=True, slots=True)
class CameraOutput:
    spec: CameraSpec
    frame: CameraFrame


@dataclass(frozen=True, slots=True)
class RadarOutput:
    spec: RadarSpec
    scan: RadarScan


@dataclass(frozen=True, slots=True)
class FrameRecord:
    frame_index: int
    timestamp_ns: int
    map_SE3_ego: SE3
    lidars: tuple[LidarOutput, ...]
    cameras: tuple[CameraOutput, ...]
    radars: tuple[RadarOutput, ...]
    labels: FrameLabels

"""Everything one frame hands to the sinks."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from gtgen.labels import FrameLabels
from gtgen.mapgt import MapFrame
from gtgen.occupancy import OccupancyFrame
from gtgen.signals import SignalLabels
from networks.geometry import SE3
from networks.vocabulary import HazardKind
from sensors.camera import CameraOutput
from sensors.lidar import LidarOutput
from sensors.radar import RadarOutput
from sensors.sensor import SensorOutput


@dataclass(frozen=True, slots=True)
class ActiveHazard:
    """A hazard event under way (made by ``cosim.sumo.hazards``): ``name`` (``cut_in-3``: its
    kind and the run's event number), the track ids of its actors and of the ego."""

    name: str
    kind: HazardKind
    actor_ids: tuple[int, ...]
    ego_id: int


@dataclass(frozen=True, slots=True)
class FrameRecord:
    """One frame: the ego's pose, the output of every sensor that fired in it (rig order; each
    sensor fires at its own rate), and the labels (one :class:`~gtgen.labels.CameraLabels` per
    camera that fired, in the order of :attr:`cameras`).
    ``scene_cut``: the ego was put back at the start of a route before this frame (it ran
    out of road): this frame starts a new scene. ``checkpoint``: what the frame loop needs to
    continue after this frame (plain JSON data, kept by the run's resume file). ``signals``:
    the traffic lights' states, for the heads among the labelled objects. ``map``: the map
    ground truth of the frame."""

    frame_index: int
    timestamp_ns: int
    map_SE3_ego: SE3
    sensors: tuple[SensorOutput, ...]
    labels: FrameLabels
    scene_cut: bool = False
    checkpoint: Mapping[str, object] = field(default_factory=dict)
    signals: SignalLabels = field(default_factory=SignalLabels.empty)
    map: MapFrame | None = None  # the map ground truth around the ego (None: not asked for)
    ego_velocity_map_mps: npt.NDArray[np.float64] = field(default_factory=lambda: np.zeros(3))
    hazards: tuple[ActiveHazard, ...] | None = None  # the hazard events under way (None: the run makes none)
    ego_collided: bool = False  # the simulation saw the ego collide in this step
    occupancy: OccupancyFrame | None = None  # occupancy, masks and flow around the ego (None: not asked for)

    @property
    def lidars(self) -> tuple[LidarOutput, ...]:
        return tuple(o for o in self.sensors if isinstance(o, LidarOutput))

    @property
    def cameras(self) -> tuple[CameraOutput, ...]:
        return tuple(o for o in self.sensors if isinstance(o, CameraOutput))

    @property
    def radars(self) -> tuple[RadarOutput, ...]:
        return tuple(o for o in self.sensors if isinstance(o, RadarOutput))

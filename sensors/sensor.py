"""What every sensor model is: one protocol, so a rig is a list of sensors of any kind.

A sensor has a ``spec`` (its name, range, rate and mount ``ego_SE3_sensor``), says which
agents its rays may reach (to cull the frame's scene), makes its rays in the map frame, and
``sense``s one frame of the scene: ``sense(scene, ego, weather, rng) -> output``. Outputs
pair the spec with the data (:class:`~sensors.lidar.LidarOutput`,
:class:`~sensors.camera.CameraOutput`, :class:`~sensors.radar.RadarOutput`).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Protocol

import numpy as np
import numpy.typing as npt

from networks.geometry import SE3
from networks.vocabulary import SensorKind
from sensors.agents import EgoState
from sensors.camera import CameraOutput
from sensors.lidar import LidarOutput
from sensors.radar import RadarOutput
from sensors.weather import Weather

if TYPE_CHECKING:  # Open3D loads only where rays are cast, not in the writer process
    from sensors.engine import Scene

F64 = npt.NDArray[np.float64]
SensorOutput = LidarOutput | CameraOutput | RadarOutput


def fires(rate_hz: float, step_s: float, frame_index: int) -> bool:
    """Whether a sensor of ``rate_hz`` fires in frame ``frame_index`` of frames ``step_s``
    apart: in frame 0, then in the first frame at or after each of its periods (on average
    exactly ``rate_hz``; every frame at the frame rate)."""
    if frame_index == 0 or step_s <= 0:
        return True
    periods = rate_hz * step_s
    return math.floor(frame_index * periods + 1e-6) > math.floor((frame_index - 1) * periods + 1e-6)


class SensorSpec(Protocol):
    @property
    def name(self) -> str: ...

    @property
    def range_m(self) -> float: ...

    @property
    def rate_hz(self) -> float: ...

    @property
    def ego_SE3_sensor(self) -> SE3:
        """The sensor's frame (a camera's: optical) in the ego frame."""
        ...


class Sensor(Protocol):
    @property
    def kind(self) -> SensorKind:
        """What it measures (the stage its frames are timed under)."""
        ...

    @property
    def spec(self) -> SensorSpec: ...

    def reaches(self, center_map_m: F64, radius_m: F64, map_SE3_ego: SE3) -> npt.NDArray[np.bool_]:
        """Which spheres (map frame) this sensor's rays may meet within its range."""
        ...

    def rays(self, map_SE3_ego: SE3) -> npt.NDArray[np.float32]:
        """``(N, 6) float32`` rays (origin, unit direction) in the map frame."""
        ...

    def sense(self, scene: Scene, ego: EgoState, weather: Weather, rng: np.random.Generator) -> SensorOutput:
        """One frame of this sensor in ``scene``, mounted on the ``ego``."""
        ...

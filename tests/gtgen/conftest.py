"""Small real frame records (a road, a few cars, a small rig), handed to the sink tests as
the ``records`` fixture (the suite runs in importlib mode: test modules import no helpers)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest
from shapely.geometry import box as rect

from gtgen.frame import FrameRecord
from gtgen.labels import label_frame
from networks.classes import SemanticClass
from networks.mesh import flat_polygon
from sensors.agents import Agents, EgoState
from sensors.camera import Camera, CameraSpec
from sensors.lidar import Lidar, LidarSpec
from sensors.radar import Radar, RadarSpec
from sensors.scene import FrameScene
from sensors.sensor import Sensor
from sensors.weather import DAY

GROUND = flat_polygon(rect(-300, -300, 300, 300), 0.0, SemanticClass.ROAD)
CENTERS = np.array([[15.0, 0, 0.75], [25, 4, 0.75], [40, -3, 0.75], [12, -6, 0.9]])
SIZES = np.array([[4.5, 1.8, 1.5]] * 3 + [[0.5, 0.5, 1.8]])
CARS = Agents(
    np.array([3, 5, 8, 9]),
    np.array([10, 10, 11, 15]),
    CENTERS,
    SIZES,
    np.array([0.0, 0.3, -2.0, 1.0]),
    np.zeros(4),
    np.array([[5.0, 0, 0], [-3, 1, 0], [0, 0, 0], [1, 1, 0]]),
    np.array([0, 0, 1, 0], bool),
)


RIGHT_CAMERA = CameraSpec(name="right", width_px=160, height_px=90, mount_xyz_m=(0.41, -0.53, 1.64))


def make_record(
    frame_index: int, lidar_azimuth_steps: int = 256, cameras: bool = True, agents: Agents = CARS,
    second_camera: bool = False,
) -> FrameRecord:  # fmt: skip
    """One frame with the ego ``frame_index`` metres along +x from the map origin; with
    ``second_camera``, a second camera 0.53 m right of the first (KITTI's stereo baseline)."""
    ego = EgoState(
        np.array([float(frame_index), 0.0, 0.75]), np.array([4.5, 1.8, 1.5]), 0.0, 0.0, np.array([20.0, 0.0, 0.0])
    )
    scene = FrameScene(GROUND, agents)
    rng = np.random.default_rng(frame_index)
    sensors: list[Sensor] = [Lidar(LidarSpec(beams=16, azimuth_steps=lidar_azimuth_steps))]
    sensors += [Camera(CameraSpec(width_px=160, height_px=90))] if cameras else []
    sensors += [Camera(RIGHT_CAMERA)] if second_camera else []
    sensors += [Radar(RadarSpec(azimuth_steps=90, elevation_steps=6, points_per_frame=50))]
    outputs = tuple(sensor.sense(scene, ego, DAY, rng) for sensor in sensors)
    ns = frame_index * 50_000_000
    labels = label_frame(frame_index, ns, agents, ego, outputs, scene, 100.0)
    return FrameRecord(frame_index, ns, ego.map_SE3_ego(), outputs, labels)


@pytest.fixture(scope="session")
def records() -> list[FrameRecord]:
    return [make_record(i) for i in range(3)]


@pytest.fixture(scope="session")
def record_maker() -> Callable[..., FrameRecord]:
    return make_record

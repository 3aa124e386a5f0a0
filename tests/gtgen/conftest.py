"""Small real frame records (a road, a few cars, a small rig), handed to the sink tests as
the ``records`` fixture (the suite runs in importlib mode: test modules import no helpers)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest
from shapely.geometry import box as rect

from gtgen.frame import CameraOutput, FrameRecord, LidarOutput, RadarOutput
from gtgen.labels import SensorHits, label_frame
from gtgen.objects import ObjectBoxes
from networks.classes import SemanticClass
from networks.geometry import SE3
from networks.mesh import flat_polygon
from sensors.agents import AgentBoxes, agent_meshes
from sensors.camera import Camera, CameraSpec
from sensors.lidar import Lidar, LidarSpec
from sensors.radar import InstanceVelocities, Radar, RadarSpec
from sensors.scene import FrameScene

GROUND = flat_polygon(rect(-300, -300, 300, 300), 0.0, SemanticClass.ROAD)
CENTERS = np.array([[15.0, 0, 0.75], [25, 4, 0.75], [40, -3, 0.75], [12, -6, 0.9]])
SIZES = np.array([[4.5, 1.8, 1.5]] * 3 + [[0.5, 0.5, 1.8]])
CARS = AgentBoxes(np.array([3, 5, 8, 9]), np.full(4, int(SemanticClass.CAR)), CENTERS, SIZES, np.zeros(4), np.zeros(4))


def make_record(frame_index: int, lidar_azimuth_steps: int = 256, cameras: bool = True) -> FrameRecord:
    """One frame with the ego ``frame_index`` metres along +x from the map origin."""
    map_SE3_ego = SE3(np.eye(3), np.array([float(frame_index), 0.0, 0.0]))
    scene = FrameScene(GROUND, agent_meshes(CARS))
    rng = np.random.default_rng(frame_index)
    lidar = Lidar(LidarSpec(beams=16, azimuth_steps=lidar_azimuth_steps))
    camera = Camera(CameraSpec(width_px=160, height_px=90))
    radar = Radar(RadarSpec(azimuth_steps=90, elevation_steps=6, points_per_frame=50))
    lidars = (LidarOutput(lidar.spec, lidar.scan(scene, map_SE3_ego, rng)),)
    cams = (CameraOutput(camera.spec, camera.render(scene, map_SE3_ego, rng=rng)),) if cameras else ()
    velocities = InstanceVelocities.from_unsorted(CARS.instance_id, np.zeros((len(CARS), 3)))
    radars = (RadarOutput(radar.spec, radar.scan(scene, map_SE3_ego, velocities, np.zeros(3), rng)),)
    hits = SensorHits((lidars[0].scan,), (radars[0].scan,), tuple((c.spec, c.frame) for c in cams))
    ego_SE3_map = map_SE3_ego.inverse()
    n = len(CARS)
    objects = ObjectBoxes(CARS.instance_id, CARS.semantic_class, ego_SE3_map.transform_from(CARS.center_map_m),
                          CARS.lwh_m, CARS.yaw_map_rad, np.zeros((n, 3)), np.zeros(n, bool))  # fmt: skip
    ns = frame_index * 50_000_000
    labels = label_frame(frame_index, ns, objects, CARS, map_SE3_ego, hits, 100.0)
    return FrameRecord(frame_index, ns, map_SE3_ego, lidars, cams, radars, labels)


@pytest.fixture(scope="session")
def records() -> list[FrameRecord]:
    return [make_record(i) for i in range(3)]


@pytest.fixture(scope="session")
def record_maker() -> Callable[..., FrameRecord]:
    return make_record

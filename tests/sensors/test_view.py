"""Leaving out the agents no sensor can reach changes no return of any sensor."""

import math

import numpy as np

from networks.classes import SemanticClass
from networks.geometry import SE3
from networks.mesh import ClassedMesh
from sensors.agents import Agents, EgoState
from sensors.camera import Camera, CameraSpec
from sensors.lidar import Lidar, LidarSpec
from sensors.radar import Radar, RadarSpec
from sensors.scene import FrameScene
from sensors.shading import shade_frame
from sensors.view import bounding_radius_m, spheres_in_view
from sensors.weather import DAY

H = 400.0
CORNERS = np.array([[-H, -H, 0.0], [H, -H, 0.0], [H, H, 0.0], [-H, H, 0.0]])
GROUND = ClassedMesh(CORNERS, np.array([[0, 1, 2], [0, 2, 3]]), np.full(2, int(SemanticClass.ROAD)))


def crowd(n: int, seed: int) -> Agents:
    """Cars scattered all around the origin, out to 260 m, some on bridges and in pits."""
    rng = np.random.default_rng(seed)
    r, a = rng.uniform(3.0, 260.0, n), rng.uniform(-math.pi, math.pi, n)
    center = np.column_stack([r * np.cos(a), r * np.sin(a), rng.uniform(-20.0, 40.0, n)])
    return Agents(np.arange(1, n + 1), np.full(n, int(SemanticClass.CAR)), center, np.tile([4.5, 1.8, 1.5], (n, 1)),
                  rng.uniform(-math.pi, math.pi, n), np.zeros(n), rng.uniform(-15.0, 15.0, (n, 3)),
                  np.zeros(n, bool))  # fmt: skip


def test_sphere_tests_keep_what_touches_the_view_and_drop_what_does_not():
    look = SE3.identity()
    centers = np.array([[10.0, 0, 0], [10.0, 9.0, 0], [10.0, 12.0, 0], [-5.0, 0, 0], [130.0, 0, 0], [10.0, 0, 3.5]])
    radius = np.full(len(centers), 0.5)
    # 90 degrees across (|y| <= x), 20 degrees high; the margin widens each sphere by 0.5 m
    keep = spheres_in_view(look, centers, radius, range_m=120.0, hfov_deg=90.0, vfov_deg=20.0)
    assert keep.tolist() == [True, True, False, False, False, False]
    assert spheres_in_view(look, centers, radius, range_m=120.0).tolist() == [True] * 4 + [False, True]


def test_agents_out_of_every_view_change_no_return():
    everyone = crowd(400, seed=1)
    ego = EgoState(np.array([3.0, -2.0, 0.75]), np.array([4.5, 1.8, 1.5]), 0.4, 0.0, np.array([5.0, 2.0, 0.0]))
    map_SE3_ego = ego.map_SE3_ego()
    lidar, radar = Lidar(LidarSpec(beams=32, azimuth_steps=512)), Radar(RadarSpec())
    camera = Camera(CameraSpec(width_px=320, height_px=180, mount_rpy_deg=(0.0, 5.0, 20.0)))
    radius = bounding_radius_m(everyone.lwh_m)
    keep = np.zeros(len(everyone), bool)
    for sensor in (lidar, radar, camera):
        keep |= sensor.reaches(everyone.center_map_m, radius, map_SE3_ego)
    assert 50 < keep.sum() < 300  # the test means something: some agents go, some stay
    outputs = []
    for agents in (everyone, everyone.select(keep)):
        scene = FrameScene(GROUND, agents)
        rng = np.random.default_rng(0)
        outputs.append([sensor.sense(scene, ego, DAY, rng) for sensor in (lidar, camera, radar)])
    for full, culled in zip(*outputs, strict=True):
        data = (full.scan, culled.scan) if hasattr(full, "scan") else (full.frame, culled.frame)
        names = [n for n in data[0].__dataclass_fields__ if n != "shading"]
        for name in names:
            np.testing.assert_array_equal(getattr(data[0], name), getattr(data[1], name), err_msg=name)
    camera_images = [shade_frame(o[1].frame) for o in outputs]
    np.testing.assert_array_equal(*camera_images)

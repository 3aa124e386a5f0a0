"""Leaving out the agents no sensor can reach changes no return of any sensor."""

import math

import numpy as np

from networks.classes import SemanticClass
from networks.geometry import SE3
from networks.mesh import ClassedMesh
from sensors.agents import AgentBoxes, agent_meshes
from sensors.camera import Camera, CameraSpec
from sensors.lidar import Lidar, LidarSpec
from sensors.radar import InstanceVelocities, Radar, RadarSpec
from sensors.scene import FrameScene
from sensors.view import bounding_radius_m, spheres_in_view

H = 400.0
CORNERS = np.array([[-H, -H, 0.0], [H, -H, 0.0], [H, H, 0.0], [-H, H, 0.0]])
GROUND = ClassedMesh(CORNERS, np.array([[0, 1, 2], [0, 2, 3]]), np.full(2, int(SemanticClass.ROAD)))


def crowd(n: int, seed: int) -> AgentBoxes:
    """Cars scattered all around the origin, out to 260 m, some on bridges and in pits."""
    rng = np.random.default_rng(seed)
    r, a = rng.uniform(3.0, 260.0, n), rng.uniform(-math.pi, math.pi, n)
    center = np.column_stack([r * np.cos(a), r * np.sin(a), rng.uniform(-20.0, 40.0, n)])
    return AgentBoxes(np.arange(1, n + 1), np.full(n, int(SemanticClass.CAR)), center, np.tile([4.5, 1.8, 1.5], (n, 1)),
                      rng.uniform(-math.pi, math.pi, n), np.zeros(n))  # fmt: skip


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
    map_SE3_ego = SE3.from_xyz_rpy([3.0, -2.0, 0.0], yaw=0.4)
    lidar, radar = Lidar(LidarSpec(beams=32, azimuth_steps=512)), Radar(RadarSpec())
    camera = Camera(CameraSpec(width_px=320, height_px=180, mount_rpy_deg=(0.0, 5.0, 20.0)))
    radius = bounding_radius_m(everyone.lwh_m)
    keep = np.zeros(len(everyone), bool)
    for sensor in (lidar, radar, camera):
        keep |= sensor.reaches(everyone.center_map_m, radius, map_SE3_ego)
    assert 50 < keep.sum() < 300  # the test means something: some agents go, some stay
    velocities = InstanceVelocities.from_unsorted(everyone.instance_id, np.zeros((len(everyone), 3)))
    outputs = []
    for agents in (everyone, everyone.select(keep)):
        scene = FrameScene(GROUND, agent_meshes(agents))
        rng = np.random.default_rng(0)
        outputs.append((lidar.scan(scene, map_SE3_ego, rng), camera.render(scene, map_SE3_ego, rng=rng),
                        radar.scan(scene, map_SE3_ego, velocities, np.zeros(3), rng)))  # fmt: skip
    for full, culled in zip(*outputs, strict=True):
        names = [n for n in full.__dataclass_fields__ if n not in ("shading", "given_image_bgr")]
        for name in names + (["image_bgr"] if hasattr(full, "image_bgr") else []):
            np.testing.assert_array_equal(getattr(full, name), getattr(culled, name), err_msg=name)

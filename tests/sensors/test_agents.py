from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from networks.classes import AGENT_CLASSES, SemanticClass
from networks.geometry import SE3
from sensors.agents import AGENT_LIFT_M, TEMPLATES, Agents, agent_meshes
from sensors.lidar import Lidar, LidarSpec
from sensors.pinhole import box_corners
from sensors.weather import DAY


def random_agents(n: int, seed: int = 3) -> Agents:
    r = np.random.default_rng(seed)
    cls = r.choice([int(c) for c in AGENT_CLASSES], n)
    lwh = r.uniform([0.3, 0.4, 1.0], [12.0, 2.6, 3.5], (n, 3))
    return Agents(np.arange(1, n + 1), cls, r.uniform(-30, 30, (n, 3)), lwh, r.uniform(-np.pi, np.pi, n),
                  r.uniform(-0.2, 0.2, n), np.zeros((n, 3)), np.zeros(n, bool))  # fmt: skip


def corners(agents_: Agents) -> np.ndarray:
    return box_corners(agents_.center_map_m, agents_.lwh_m, agents_.rotations())


def in_box_frame(agents_: Agents, index: int, xyz_map: np.ndarray) -> np.ndarray:
    map_SE3_box = SE3(agents_.rotations()[index], agents_.center_map_m[index])
    return map_SE3_box.inverse().transform_from(xyz_map)


def test_every_agent_class_has_a_template_inside_the_unit_box() -> None:
    for cls in AGENT_CLASSES:
        template = TEMPLATES[int(cls)]
        assert np.abs(template.unit_vertices).max() <= 0.5
        assert template.triangles.shape[0] > 12


def test_templates_touch_the_ground_and_the_roof_of_their_box() -> None:
    for template in TEMPLATES.values():
        assert template.unit_vertices[:, 2].min() == pytest.approx(-0.5)
        assert template.unit_vertices[:, 2].max() == pytest.approx(0.5)


def test_shaped_meshes_lie_inside_their_posed_boxes() -> None:
    boxes = random_agents(60)
    meshes = agent_meshes(boxes)
    for i, inst in enumerate(boxes.instance_id):
        vert_ids = np.unique(meshes.triangles[meshes.triangle_instance == inst])
        local = in_box_frame(boxes, i, meshes.vertices_m[vert_ids].astype(np.float64))
        assert np.all(np.abs(local) <= boxes.lwh_m[i] / 2 + 1e-4)


def test_each_triangle_carries_its_agents_instance_and_class() -> None:
    boxes = random_agents(40)
    meshes = agent_meshes(boxes)
    class_of = dict(zip(boxes.instance_id.tolist(), boxes.semantic_class.tolist(), strict=True))
    assert set(meshes.triangle_instance.tolist()) == set(class_of)
    expected = np.array([class_of[i] for i in meshes.triangle_instance.tolist()])
    np.testing.assert_array_equal(meshes.triangle_class, expected)
    for inst, cls in class_of.items():
        assert np.sum(meshes.triangle_instance == inst) == TEMPLATES[cls].triangles.shape[0]


def test_a_class_without_template_is_drawn_as_its_box_standing_just_off_the_road(synth: SimpleNamespace) -> None:
    boxes = synth.agents([(5, SemanticClass.POLE, 1.0, 2.0, 1.0, 2.0, 1.0, 2.0, 0.3)])
    meshes = agent_meshes(boxes)
    assert meshes.triangles.shape == (12, 3)
    expected = corners(boxes)[0]
    expected[:, 2] = np.maximum(expected[:, 2], AGENT_LIFT_M)  # the bottom 3 cm above the box's (the road)
    np.testing.assert_allclose(np.sort(meshes.vertices_m, axis=0), np.sort(expected, axis=0), atol=1e-5)


def test_no_agents_give_an_empty_mesh() -> None:
    meshes = agent_meshes(Agents.empty())
    assert meshes.vertices_m.shape == (0, 3) and meshes.triangles.shape == (0, 3)


def test_box_corners_follow_yaw(synth: SimpleNamespace) -> None:
    boxes = synth.agents([(1, SemanticClass.CAR, 10.0, 0.0, 0.75, 4.0, 2.0, 1.5, np.pi / 2)])
    box = corners(boxes)[0]
    np.testing.assert_allclose(box.min(axis=0), [9.0, -2.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(box.max(axis=0), [11.0, 2.0, 1.5], atol=1e-9)


def test_lidar_points_on_shaped_agents_lie_inside_their_boxes(synth: SimpleNamespace, rng: np.random.Generator) -> None:
    sizes = [(SemanticClass.CAR, 4.5, 1.8, 1.5), (SemanticClass.TRUCK, 7.5, 2.5, 3.2),
             (SemanticClass.BUS, 12.0, 2.5, 3.4), (SemanticClass.MOTORCYCLE, 2.2, 0.8, 1.7),
             (SemanticClass.BICYCLE, 1.8, 0.6, 1.75), (SemanticClass.PEDESTRIAN, 0.3, 0.5, 1.75)]  # fmt: skip
    bearing = np.arange(len(sizes)) * 1.0
    rows = [(i + 1, cls, 6.0 * np.cos(b), 6.0 * np.sin(b), hgt / 2, lng, wid, hgt, b + 0.4)
            for i, ((cls, lng, wid, hgt), b) in enumerate(zip(sizes, bearing, strict=True))]  # fmt: skip
    boxes = synth.agents(rows)
    lidar = Lidar(LidarSpec(beams=32, azimuth_steps=1024))
    scan = lidar.sense(synth.scene([synth.ground()], boxes), synth.EGO, DAY, rng).scan
    xyz_map = lidar.spec.ego_SE3_sensor.transform_from(scan.xyz_lidar_m)
    for i, inst in enumerate(boxes.instance_id):
        on = scan.instance_id == inst
        assert on.sum() > 20
        local = in_box_frame(boxes, i, xyz_map[on])
        assert np.all(np.abs(local) <= boxes.lwh_m[i] / 2 + 0.02)
        assert np.all(scan.semantic_class[on] == boxes.semantic_class[i])

"""Object boxes in the ego frame carry the whole orientation of a pitched agent seen from a
pitched ego: its mesh lies inside its box, and the yaw-only box of KITTI holds the box."""

from dataclasses import replace

import numpy as np

from gtgen.objects import ObjectBoxes, points_in_boxes
from networks.geometry import SE3, rotations_from_rpy
from sensors.agents import Agents, EgoState, agent_meshes
from sensors.pinhole import box_corners

# A truck climbing a 10 % ramp and a bus coming down across the ego's path, seen from an ego
# that itself climbs another slope.
AGENTS = Agents(
    np.array([7, 8], np.uint32),
    np.array([11, 12], np.uint8),
    np.array([[30.0, 5.0, 3.0], [20.0, -10.0, 1.0]]),
    np.array([[10.5, 2.5, 3.6], [12.0, 2.5, 3.4]]),
    np.array([0.4, 2.2]),
    np.array([0.0997, -0.06]),
    np.zeros((2, 3)),
    np.zeros(2, bool),
)
EGO = EgoState(np.array([0.0, 0.0, 0.75]), np.array([4.5, 1.8, 1.5]), -0.3, 0.05, np.zeros(3))


def test_boxes_carry_the_agents_orientation_relative_to_the_ego():
    boxes = ObjectBoxes.seen_from(EGO, AGENTS)
    ego_R_map = EGO.map_SE3_ego().inverse().rotation
    assert np.allclose(boxes.rotations(), ego_R_map @ AGENTS.rotations(), atol=1e-12)
    assert np.all(np.abs(boxes.pitch_ego_rad) > 0.015)
    assert np.all(np.abs(boxes.roll_ego_rad) > 0.01)  # headings across a pitched ego: rolled


def test_an_agents_mesh_lies_inside_its_box_and_its_box_inside_the_upright_box():
    boxes = ObjectBoxes.seen_from(EGO, AGENTS)
    meshes = agent_meshes(AGENTS)
    vertices_ego = EGO.map_SE3_ego().inverse().transform_from(meshes.vertices_m.astype(np.float64))
    owner = np.searchsorted(boxes.track_id, np.repeat(meshes.triangle_instance, 3))
    tri_vertices = vertices_ego[meshes.triangles.ravel()]
    assert np.all(points_in_boxes(tri_vertices, boxes, owner, tolerance_m=1e-4))
    level = replace(boxes, pitch_ego_rad=np.zeros(2), roll_ego_rad=np.zeros(2))
    assert not np.all(points_in_boxes(tri_vertices, level, owner, tolerance_m=0.02))  # yaw only: ends stick out
    upright = replace(level, lwh_m=boxes.upright_lwh_m())
    corners = box_corners(boxes.center_ego_m, boxes.lwh_m, boxes.rotations())
    assert np.all(points_in_boxes(corners.reshape(-1, 3), upright, np.repeat(np.arange(2), 8), tolerance_m=1e-9))
    on_faces = np.abs(
        np.einsum("nji,nkj->nki", rotations_from_rpy(0, 0, boxes.yaw_ego_rad), corners - boxes.center_ego_m[:, None])
    ).max(axis=1)
    assert np.allclose(on_faces, boxes.upright_lwh_m() / 2.0)  # the tightest such box


def test_a_level_box_keeps_its_size_and_yaw():
    ego = EgoState.at(SE3.identity())
    agents = Agents.standing([3], [10], [[10.0, 2.0, 0.75]], [[4.5, 1.8, 1.5]], [1.0])
    boxes = ObjectBoxes.seen_from(ego, agents)
    assert np.allclose(boxes.yaw_ego_rad, [1.0])
    assert np.allclose(boxes.pitch_ego_rad, 0) and np.allclose(boxes.roll_ego_rad, 0)
    assert np.allclose(boxes.upright_lwh_m(), [[4.5, 1.8, 1.5]])

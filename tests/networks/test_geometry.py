import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from networks.geometry import (
    SE3,
    quaternion_xyzw_from_rotation,
    rotation_from_quaternion_xyzw,
    rotation_from_rpy,
    rotations_from_rpy,
    rpy_from_rotations,
    wrap_angle,
)

angles = st.floats(-math.pi, math.pi, allow_nan=False)
coords = st.floats(-1e3, 1e3, allow_nan=False)
poses = st.builds(
    lambda x, y, z, r, p, w: SE3.from_xyz_rpy((x, y, z), r, p, w), coords, coords, coords, angles, angles, angles
)
points = st.lists(st.tuples(coords, coords, coords), min_size=2, max_size=8).map(np.array)


@settings(max_examples=200)
@given(poses, points)
def test_compose_with_inverse_is_identity(a_SE3_b, pts_b):
    b_SE3_a = a_SE3_b.inverse()
    assert np.allclose(a_SE3_b.compose(b_SE3_a).as_matrix(), np.eye(4), atol=1e-9)
    assert np.allclose(b_SE3_a.transform_from(a_SE3_b.transform_from(pts_b)), pts_b, atol=1e-6)


@settings(max_examples=200)
@given(poses, points)
def test_transform_preserves_distances(a_SE3_b, pts_b):
    pts_a = a_SE3_b.transform_from(pts_b)
    assert np.allclose(np.linalg.norm(pts_a[0] - pts_a[1]), np.linalg.norm(pts_b[0] - pts_b[1]), atol=1e-6)


@settings(max_examples=100)
@given(poses, poses, points)
def test_compose_matches_applying_in_turn(a_SE3_b, b_SE3_c, pts_c):
    a_SE3_c = a_SE3_b.compose(b_SE3_c)
    assert np.allclose(a_SE3_c.transform_from(pts_c), a_SE3_b.transform_from(b_SE3_c.transform_from(pts_c)), atol=1e-6)
    assert np.allclose(a_SE3_c.as_matrix(), a_SE3_b.as_matrix() @ b_SE3_c.as_matrix(), atol=1e-6)


@settings(max_examples=200)
@given(poses)
def test_quaternion_encodes_the_same_rotation(pose):
    x, y, z, w = quaternion_xyzw_from_rotation(pose.rotation)
    assert math.isclose(x * x + y * y + z * z + w * w, 1.0, rel_tol=1e-9)
    assert np.allclose(rotation_from_quaternion_xyzw(x, y, z, w), pose.rotation, atol=1e-9)


def test_from_matrix_round_trips():
    pose = SE3.from_xyz_rpy((1.0, -2.0, 3.0), 0.1, -0.2, 2.5)
    assert np.allclose(SE3.from_matrix(pose.as_matrix()).as_matrix(), pose.as_matrix())


def test_yaw_is_counter_clockwise_from_x():
    pose = SE3.from_xyz_rpy((0, 0, 0), yaw=math.pi / 2)
    assert np.allclose(pose.transform_from([[1.0, 0.0, 0.0]]), [[0.0, 1.0, 0.0]], atol=1e-12)
    assert math.isclose(pose.yaw_rad(), math.pi / 2)


@given(st.floats(-100, 100, allow_nan=False))
def test_wrap_angle_stays_in_range_and_keeps_direction(a):
    w = float(wrap_angle(a))
    assert -math.pi <= w < math.pi
    assert math.isclose(math.cos(w), math.cos(a), abs_tol=1e-9) and math.isclose(math.sin(w), math.sin(a), abs_tol=1e-9)


@settings(max_examples=200)
@given(angles, st.floats(-1.5, 1.5), angles)
def test_many_rotations_from_roll_pitch_yaw_are_the_single_one_and_read_back(roll, pitch, yaw):
    many = rotations_from_rpy([roll], [pitch], [yaw])
    assert np.allclose(many[0], rotation_from_rpy(roll, pitch, yaw), atol=1e-12)
    r, p, y = rpy_from_rotations(many)
    assert np.allclose(rotations_from_rpy(r, p, y), many, atol=1e-9)
    assert math.isclose(float(p[0]), pitch, abs_tol=1e-9)

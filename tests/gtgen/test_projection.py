import math
from dataclasses import dataclass

import cv2
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from gtgen.objects import ObjectBoxes
from gtgen.projection import camera_boxes
from networks.geometry import SE3, rotation_from_rpy
from sensors.pinhole import Pinhole, box_corners

# ego (x fwd, y left, z up) -> optical (x right, y down, z fwd)
EGO_R_OPTICAL = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


@dataclass(frozen=True)
class Cam:
    """The camera written out by hand (not through the project's camera spec)."""

    width_px: int = 1280
    height_px: int = 720
    hfov_deg: float = 85.0

    @property
    def pinhole(self):
        return Pinhole(self.width_px, self.height_px, self.hfov_deg)

    @property
    def K(self):
        f = self.width_px / 2 / math.tan(math.radians(self.hfov_deg) / 2)
        return np.array([[f, 0, (self.width_px - 1) / 2], [0, f, (self.height_px - 1) / 2], [0, 0, 1.0]])

    @property
    def ego_SE3_cam(self):
        return SE3(EGO_R_OPTICAL, np.array([0.41, 0.0, 1.64]))


def boxes_in(cam, b):
    return camera_boxes(cam.pinhole, cam.ego_SE3_cam, b)


def boxes(centers, yaws, lwh=(4.5, 1.9, 1.6), pitch=0.0, roll=0.0):
    n = len(centers)
    return ObjectBoxes(
        np.arange(1, n + 1), np.full(n, 10), np.asarray(centers, float), np.tile(lwh, (n, 1)), np.asarray(yaws, float),
        np.full(n, pitch), np.full(n, roll), np.zeros((n, 3)), np.zeros(n, bool),
    )  # fmt: skip


def cv2_corners(cam, b):
    """The boxes' corners (turned by each box's roll, pitch, yaw written out as one rotation
    matrix) projected with OpenCV."""
    cam_SE3_ego = cam.ego_SE3_cam.inverse()
    rotations = np.stack(
        [rotation_from_rpy(r, p, y) for r, p, y in zip(b.roll_ego_rad, b.pitch_ego_rad, b.yaw_ego_rad, strict=True)]
    )
    corners = box_corners(b.center_ego_m, b.lwh_m, rotations).reshape(-1, 3)
    rvec, _ = cv2.Rodrigues(cam_SE3_ego.rotation)
    uv, _ = cv2.projectPoints(corners, rvec, cam_SE3_ego.translation, cam.K, None)
    return uv.reshape(len(b), 8, 2)


@settings(max_examples=60, deadline=None)
@given(
    st.floats(6.0, 60.0), st.floats(-15.0, 15.0), st.floats(-1.0, 1.5), st.floats(-math.pi, math.pi),
    st.floats(-0.3, 0.3), st.floats(-0.2, 0.2),
)  # fmt: skip
def test_projected_box_matches_opencv_project_points(x, y, z, yaw, pitch, roll):
    """The 2D box is the projection of the box with its pitch and roll (a truck on a ramp)."""
    cam = Cam()
    b = boxes([[x, y, z]], [yaw], pitch=pitch, roll=roll)
    uv = cv2_corners(cam, b)[0]
    got = boxes_in(cam, b).amodal_px[0]
    expected = [uv[:, 0].min(), uv[:, 1].min(), uv[:, 0].max(), uv[:, 1].max()]
    assert np.allclose(got, expected, atol=0.5)


def test_box_inside_the_image_is_not_truncated():
    cb = boxes_in(Cam(), boxes([[20.0, 0.0, 0.8]], [0.0]))
    assert cb.truncated[0] == 0.0
    assert np.allclose(cb.amodal_px, cb.clipped_px)


def test_box_leaving_the_right_edge_gets_the_analytic_truncation():
    cam = Cam()
    # choose y so that the projected box straddles the right image border
    b = boxes([[15.0, -14.0, 0.8]], [0.0])
    uv = cv2_corners(cam, b)[0]
    u0, u1 = uv[:, 0].min(), uv[:, 0].max()
    assert u0 < cam.width_px < u1
    expected = (u1 - cam.width_px) / (u1 - u0)
    assert math.isclose(boxes_in(cam, b).truncated[0], expected, abs_tol=1e-6)


def test_box_behind_the_camera_is_fully_truncated_and_has_no_box():
    cb = boxes_in(Cam(), boxes([[-20.0, 0.0, 0.8]], [0.0]))
    assert cb.truncated[0] == 1.0 and np.all(np.isnan(cb.clipped_px[0]))


def test_box_crossing_the_camera_plane_is_clipped_at_the_near_plane():
    cb = boxes_in(Cam(), boxes([[0.5, -3.0, 0.8]], [0.0], lwh=(8.0, 1.9, 1.6)))
    assert np.all(np.isfinite(cb.amodal_px[0]))
    assert 0.0 < cb.truncated[0] < 1.0


def test_alpha_follows_kitti_for_objects_ahead_left_and_right():
    # All drive away from the camera (same heading as the ego): rotation_y = -pi/2.
    cb = boxes_in(Cam(), boxes([[20.4, 0.0, 1.64], [20.41, 20.0, 1.64], [20.41, -20.0, 1.64]], [0.0, 0.0, 0.0]))
    assert np.allclose(cb.rotation_y_rad, -math.pi / 2)
    # alpha = rotation_y - atan2(x, z): ahead -pi/2, left (x < 0) -pi/4, right (x > 0) -3pi/4
    assert np.allclose(cb.alpha_rad, [-math.pi / 2, -math.pi / 4, -3 * math.pi / 4], atol=1e-3)


def test_rotation_y_is_zero_for_an_object_heading_to_the_camera_right():
    cb = boxes_in(Cam(), boxes([[20.0, 0.0, 1.0]], [-math.pi / 2]))  # heading ego -y = camera +x
    assert math.isclose(cb.rotation_y_rad[0], 0.0, abs_tol=1e-9)

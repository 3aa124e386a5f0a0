"""Camera geometry of the labels: projected (amodal) 2D boxes, truncation, KITTI alpha.

All functions take every object at once. Boxes are the labels' ego-frame boxes (their whole
orientation: the 2D box is the projection of the pitched or rolled box); KITTI's rotation_y
and alpha are those of the yaw; the camera model is :mod:`sensors.pinhole`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from gtgen.objects import ObjectBoxes
from networks.geometry import SE3, wrap_angle
from sensors.pinhole import BOX_EDGES, Pinhole, box_corners, project

F64 = npt.NDArray[np.float64]
NEAR_PLANE_M = 0.1


@dataclass(frozen=True, slots=True)
class CameraBoxes:
    """Per object: ``amodal_px: (N, 4)`` left, top, right, bottom of the projected 3D box
    (NaN when entirely behind the near plane); ``clipped_px: (N, 4)`` the same clipped to the
    image (NaN when outside); ``truncated: (N,)`` in 0..1; ``alpha_rad``, ``rotation_y_rad``
    (KITTI); ``depth_m: (N,)`` z of the box centre in the camera frame."""

    amodal_px: F64
    clipped_px: F64
    truncated: F64
    alpha_rad: F64
    rotation_y_rad: F64
    depth_m: F64


def clipped_corner_pixels(K: F64, corners_cam: F64) -> tuple[F64, npt.NDArray[np.bool_]]:
    """Pixels of the box clipped at the near plane: corners in front, plus where edges cross it.
    Returns ``(N, 20, 2)`` pixels and ``(N, 20)`` validity."""
    z = corners_cam[..., 2]
    a, b = corners_cam[:, BOX_EDGES[:, 0]], corners_cam[:, BOX_EDGES[:, 1]]
    za, zb = a[..., 2], b[..., 2]
    crosses = (za - NEAR_PLANE_M) * (zb - NEAR_PLANE_M) < 0
    t = np.where(crosses, (NEAR_PLANE_M - za) / np.where(crosses, zb - za, 1.0), 0.0)
    crossing = a + (b - a) * t[..., None]
    points = np.concatenate([corners_cam, crossing], axis=1)
    valid = np.concatenate([z >= NEAR_PLANE_M, crosses], axis=1)
    safe = np.where(valid[..., None], points, np.array([0.0, 0.0, 1.0]))
    return project(K, safe), valid


EDGE_SAMPLES = 33
"""Points per box edge projected through a distorting lens (its edges bow: the extremes of a
box's image need not be at its corners); 33 keep the box within 0.05 px of the curve's."""


def clipped_edge_pixels(pinhole: Pinhole, corners_cam: F64) -> tuple[F64, npt.NDArray[np.bool_]]:
    """Pixels of points along the box's 12 edges clipped at the near plane, through the lens.
    Returns ``(N, 12 * EDGE_SAMPLES, 2)`` pixels and their validity."""
    a, b = corners_cam[:, BOX_EDGES[:, 0]], corners_cam[:, BOX_EDGES[:, 1]]
    za, zb = a[..., 2], b[..., 2]
    span = np.where(np.abs(zb - za) > 0, zb - za, 1.0)
    t_near = (NEAR_PLANE_M - za) / span  # where the edge crosses the near plane
    lo = np.where(za >= NEAR_PLANE_M, 0.0, np.where(zb > za, t_near, 2.0))
    hi = np.where(zb >= NEAR_PLANE_M, 1.0, np.where(za > zb, t_near, -1.0))
    valid = np.repeat(lo <= hi, EDGE_SAMPLES, axis=1)
    s = np.linspace(0.0, 1.0, EDGE_SAMPLES)
    t = lo[..., None] + (hi - lo)[..., None] * s  # (N, 12, S)
    points = a[:, :, None, :] + (b - a)[:, :, None, :] * t[..., None]
    points = points.reshape(len(corners_cam), -1, 3)
    points[..., 2] = np.maximum(points[..., 2], NEAR_PLANE_M)  # float noise at the near plane
    safe = np.where(valid[..., None], points, np.array([0.0, 0.0, 1.0]))
    return pinhole.project(safe), valid


def camera_boxes(pinhole: Pinhole, ego_SE3_cam: SE3, boxes: ObjectBoxes) -> CameraBoxes:
    """The 2D boxes, truncation and angles of ``boxes`` (ego frame) in a camera with the
    optical frame ``ego_SE3_cam`` (through its lens, if it distorts)."""
    cam_SE3_ego = ego_SE3_cam.inverse()
    n = len(boxes)
    corners_ego = box_corners(boxes.center_ego_m, boxes.lwh_m, boxes.rotations())
    corners_cam = cam_SE3_ego.transform_from(corners_ego.reshape(-1, 3)).reshape(n, 8, 3)
    if pinhole.distorted:
        uv, valid = clipped_edge_pixels(pinhole, corners_cam)
    else:
        uv, valid = clipped_corner_pixels(pinhole.K, corners_cam)
    any_valid: npt.NDArray[np.bool_] = np.asarray(valid.any(axis=1))
    lo = np.where(valid[..., None], uv, np.inf).min(axis=1)
    hi = np.where(valid[..., None], uv, -np.inf).max(axis=1)
    amodal = np.where(any_valid[:, None], np.concatenate([lo, hi], axis=1), np.nan)
    w, h = float(pinhole.width_px), float(pinhole.height_px)
    clipped = np.stack(
        [
            np.clip(amodal[:, 0], 0, w),
            np.clip(amodal[:, 1], 0, h),
            np.clip(amodal[:, 2], 0, w),
            np.clip(amodal[:, 3], 0, h),
        ],
        axis=1,
    )
    area = (amodal[:, 2] - amodal[:, 0]) * (amodal[:, 3] - amodal[:, 1])
    inside = np.maximum(clipped[:, 2] - clipped[:, 0], 0) * np.maximum(clipped[:, 3] - clipped[:, 1], 0)
    with np.errstate(invalid="ignore", divide="ignore"):
        truncated = np.where(any_valid & (area > 0), 1.0 - inside / area, 1.0)
    clipped = np.where((inside > 0)[:, None], clipped, np.nan)
    centre_cam = cam_SE3_ego.transform_from(boxes.center_ego_m)
    heading_ego = np.stack([np.cos(boxes.yaw_ego_rad), np.sin(boxes.yaw_ego_rad), np.zeros(n)], axis=1)
    heading_cam = cam_SE3_ego.rotate(heading_ego)
    rotation_y = np.arctan2(-heading_cam[:, 2], heading_cam[:, 0])
    alpha = wrap_angle(rotation_y - np.arctan2(centre_cam[:, 0], centre_cam[:, 2]))
    return CameraBoxes(amodal, clipped, np.clip(truncated, 0.0, 1.0), alpha, wrap_angle(rotation_y), centre_cam[:, 2])

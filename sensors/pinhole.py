"""The pinhole camera model, in one place: intrinsics, projection, pixel rays, box corners.

Pixel ``(u, v)`` is column ``u``, row ``v`` with OpenCV's convention (the centre of the
top-left pixel is ``(0, 0)``), so the principal point at the image centre is
``((W - 1) / 2, (H - 1) / 2)`` and the outer edges of the image lie exactly at +-hfov/2.
Points and rays are in the optical frame (x right, y down, z forward). The camera, the
labels' 2D boxes and visibility, the KITTI and MCAP calibrations all use this module.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from networks.geometry import SE3, place_in_boxes

F64 = npt.NDArray[np.float64]

EGO_AXES_R_OPTICAL = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
"""Rotation from the optical frame (x right, y down, z forward) to a camera's body axes
(x forward, y left, z up): its columns are the optical axes in body axes."""

UNIT_CORNERS = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=np.float64) / 2
"""``(8, 3)`` corners of the unit box (x, y, z in {-1/2, 1/2}); corner ``i`` has bit 2 for x."""
BOX_EDGES = np.array([[0, 1], [2, 3], [4, 5], [6, 7], [0, 2], [1, 3], [4, 6], [5, 7], [0, 4], [1, 5], [2, 6], [3, 7]])
"""The 12 edges of the box as pairs of :data:`UNIT_CORNERS` indices."""


@dataclass(frozen=True, slots=True)
class Pinhole:
    """Square pixels, no distortion, principal point at the image centre."""

    width_px: int
    height_px: int
    hfov_deg: float

    @property
    def focal_px(self) -> float:
        return self.width_px / 2.0 / math.tan(math.radians(self.hfov_deg) / 2.0)

    @property
    def vfov_deg(self) -> float:
        return math.degrees(2.0 * math.atan(self.height_px / 2.0 / self.focal_px))

    @property
    def K(self) -> F64:
        """``(3, 3)`` intrinsics."""
        f = self.focal_px
        return np.array([[f, 0.0, (self.width_px - 1) / 2.0], [0.0, f, (self.height_px - 1) / 2.0], [0.0, 0.0, 1.0]])

    @property
    def P(self) -> F64:
        """``(3, 4)`` projection matrix of the optical frame: ``[K | 0]``."""
        return np.hstack([self.K, np.zeros((3, 1))])

    def pixel_directions(self, u: npt.ArrayLike, v: npt.ArrayLike) -> F64:
        """``(N, 3)`` unit ray directions through the centres of pixels ``(u[i], v[i])``."""
        K = self.K
        u_px, v_px = np.asarray(u).ravel(), np.asarray(v).ravel()
        d = np.stack([(u_px - K[0, 2]) / K[0, 0], (v_px - K[1, 2]) / K[1, 1], np.ones(u_px.shape[0])], axis=1)
        return np.asarray(d / np.linalg.norm(d, axis=1, keepdims=True))

    def image_directions(self) -> npt.NDArray[np.float32]:
        """``(H * W, 3) float32`` unit rays of every pixel, row-major (computed once per model)."""
        return _image_directions(self)


@functools.lru_cache(maxsize=16)
def _image_directions(pinhole: Pinhole) -> npt.NDArray[np.float32]:
    v, u = np.mgrid[0 : pinhole.height_px, 0 : pinhole.width_px].astype(np.float64)
    directions = pinhole.pixel_directions(u, v).astype(np.float32)
    directions.flags.writeable = False
    return directions


def project(K: F64, xyz_cam: F64) -> F64:
    """Pixels ``(..., 2)`` of optical-frame points ``(..., 3)`` with z > 0."""
    uvw = xyz_cam @ K.T
    return np.asarray(uvw[..., :2] / uvw[..., 2:3])


def project_points(K: F64, cam_SE3_x: SE3, xyz_x: npt.ArrayLike) -> F64:
    """``(N, 2)`` pixels of ``(N, 3)`` points given in frame ``x``; NaN for points on or
    behind the camera plane (z <= 1 mm)."""
    xyz_cam = cam_SE3_x.transform_from(np.asarray(xyz_x, dtype=np.float64).reshape(-1, 3))
    z = xyz_cam[:, 2:3]
    in_front = z > 1e-3
    uvw = xyz_cam @ np.asarray(K, dtype=np.float64).T
    return np.where(in_front, uvw[:, :2] / np.where(in_front, z, 1.0), np.nan)


def box_corners(center_m: F64, lwh_m: F64, rotations: F64) -> F64:
    """``(N, 8, 3)`` corners of boxes with centres ``(N, 3)``, sizes ``(N, 3)`` and
    orientations ``(N, 3, 3)`` (box axes: x forward, y left, z up), in the centres' frame."""
    return place_in_boxes(UNIT_CORNERS, center_m, lwh_m, rotations)

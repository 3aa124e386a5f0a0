"""Bird's-eye view pictures: the point cloud coloured by class with the label boxes on top."""

from __future__ import annotations

import cv2
import numpy as np
import numpy.typing as npt

from gtgen.colours import CLASS_RGB, class_bgr255
from gtgen.objects import ObjectBoxes


def _lut() -> npt.NDArray[np.uint8]:
    lut = np.full((256, 3), 128, np.uint8)
    for cls in CLASS_RGB:
        lut[int(cls)] = class_bgr255(cls)
    return lut


_CLASS_LUT = _lut()


def bev_image(
    xyz_ego_m: npt.NDArray[np.floating],
    point_class: npt.NDArray[np.uint8],
    objects: ObjectBoxes,
    seen: npt.NDArray[np.bool_],
    half_extent_m: float = 60.0,
    px_per_m: float = 8.0,
) -> npt.NDArray[np.uint8]:
    """Top view centred on the ego, x (forward) up the image, y (left) to the left; points
    coloured by class, boxes in their class colour (grey: no sensor saw the object)."""
    size = int(2 * half_extent_m * px_per_m)
    img = np.zeros((size, size, 3), np.uint8)

    def to_px(x: npt.NDArray[np.floating], y: npt.NDArray[np.floating]) -> tuple[npt.NDArray[np.int64], ...]:
        row = np.round((half_extent_m - x) * px_per_m).astype(np.int64)
        col = np.round((half_extent_m - y) * px_per_m).astype(np.int64)
        return row, col

    row, col = to_px(xyz_ego_m[:, 0], xyz_ego_m[:, 1])
    inside = (row >= 0) & (row < size) & (col >= 0) & (col < size)
    img[row[inside], col[inside]] = _CLASS_LUT[point_class[inside]]
    o = objects
    for i in range(len(o)):
        c, s = np.cos(o.yaw_ego_rad[i]), np.sin(o.yaw_ego_rad[i])
        hl, hw = o.lwh_m[i, 0] / 2, o.lwh_m[i, 1] / 2
        local = np.array([[hl, hw], [hl, -hw], [-hl, -hw], [-hl, hw]])
        xy = local @ np.array([[c, s], [-s, c]]) + o.center_ego_m[i, :2]
        r, k = to_px(xy[:, 0], xy[:, 1])
        colour = class_bgr255(int(o.semantic_class[i]), (255, 255, 255)) if seen[i] else (80, 80, 80)
        poly = np.stack([k, r], axis=1).astype(np.int32)
        cv2.polylines(img, [poly], True, colour, 1, cv2.LINE_AA)
        cv2.line(
            img, tuple(((poly[0] + poly[1]) // 2).tolist()), tuple(np.mean(poly, 0).astype(int).tolist()), colour, 1
        )
    ego = np.array(to_px(np.array([2.4, 2.4, -2.4, -2.4]), np.array([0.95, -0.95, -0.95, 0.95]))).T[:, ::-1]
    cv2.polylines(img, [ego.astype(np.int32)], True, (255, 255, 255), 2)
    return img

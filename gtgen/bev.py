"""Bird's-eye view pictures: the point cloud coloured by class with the label boxes on top."""

from __future__ import annotations

from typing import Any

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
    for i, xy in enumerate(o.footprints_xy()):
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


# Raster layers under the picture (BGR), drawn in this order.
_LAYER_BGR = {"drivable": (60, 60, 60), "walkway": (70, 90, 110), "crossing": (110, 110, 110)}
_ELEMENT_BGR = {"edge_line": (80, 80, 255), "road_boundary": (40, 40, 230), "stop_line": (255, 255, 255),
                "crossing": (200, 200, 200), "lane_centre": (200, 120, 60)}  # fmt: skip


def map_bev_image(
    vectors: dict[str, Any], layers: dict[str, npt.NDArray[np.uint8]], xyz_ego_m: npt.NDArray[np.floating],
    point_class: npt.NDArray[np.uint8], objects: ObjectBoxes, seen: npt.NDArray[np.bool_], px_per_m: float = 16.0,
) -> npt.NDArray[np.uint8]:  # fmt: skip
    """The map ground truth of a frame over its point cloud: the raster layers (drivable area,
    walkways, crossings) as background, the vector elements (dividers white or yellow, edge lines
    and road boundaries red, stop lines white, crossings grey, lane centres blue), the LiDAR
    points by class and the label boxes; the range of the map only."""
    half_x, half_y = vectors["range_m"]
    res = float(vectors["resolution_m"])
    h, w = round(2 * half_x * px_per_m), round(2 * half_y * px_per_m)
    img = np.zeros((h, w, 3), np.uint8)
    for name, bgr in _LAYER_BGR.items():
        mask = cv2.resize(layers[name], (w, h), interpolation=cv2.INTER_NEAREST).astype(bool)
        img[mask] = bgr

    def to_px(xy: npt.NDArray[np.floating]) -> npt.NDArray[np.int32]:
        return np.column_stack([(half_y - xy[:, 1]) * px_per_m, (half_x - xy[:, 0]) * px_per_m]).astype(np.int32)

    row_col = to_px(np.asarray(xyz_ego_m[:, :2]))
    inside = (row_col[:, 0] >= 0) & (row_col[:, 0] < w) & (row_col[:, 1] >= 0) & (row_col[:, 1] < h)
    img[row_col[inside, 1], row_col[inside, 0]] = _CLASS_LUT[point_class[inside]] // 2 + 40
    for e in vectors["elements"]:
        if e["type"] == "lane_divider":
            bgr = (40, 210, 255) if e.get("colour") == "yellow" else (255, 255, 255)
        else:
            bgr = _ELEMENT_BGR[e["type"]]
        cv2.polylines(img, [to_px(np.asarray(e["points"], np.float64))], False, bgr, 1, cv2.LINE_AA)
    for i, xy in enumerate(objects.footprints_xy()):
        colour = class_bgr255(int(objects.semantic_class[i]), (255, 255, 255)) if seen[i] else (90, 90, 90)
        cv2.polylines(img, [to_px(xy)], True, colour, 1, cv2.LINE_AA)
    ego = to_px(np.array([[2.4, 0.95], [2.4, -0.95], [-2.4, -0.95], [-2.4, 0.95]]))
    cv2.polylines(img, [ego], True, (0, 255, 0), 2)
    text = f"lane {vectors['ego_lane']}  {res} m/px"
    cv2.putText(img, text, (4, 14), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (255, 255, 255), 1, cv2.LINE_AA)
    return img

"""Rays of a sensor in the map frame, as Open3D casts them."""

from __future__ import annotations

import cv2
import numpy as np
import numpy.typing as npt

from networks.geometry import SE3


def sensor_rays(map_SE3_sensor: SE3, dirs_sensor: npt.NDArray[np.float32]) -> npt.NDArray[np.float32]:
    """``(N, 6) float32`` rays (origin, unit direction) in the map frame for unit directions
    ``(N, 3) float32`` given in the sensor's frame (cv2 rotates them: several times faster
    than numpy's float64 path for a LiDAR sweep or a camera image; :func:`map_directions`, so a
    cast of the same directions from the same pose does not turn them again)."""
    rays = np.empty((dirs_sensor.shape[0], 6), np.float32)
    rays[:, :3] = map_SE3_sensor.translation
    rays[:, 3:] = map_directions(map_SE3_sensor.rotation, dirs_sensor)  # kept for the engine's cast_from
    return rays


def turned_directions(
    map_R_sensor: npt.NDArray[np.floating], dirs_sensor: npt.NDArray[np.float32]
) -> npt.NDArray[np.float32]:
    """``(N, 3) float32`` directions ``dirs_sensor`` turned into the map frame by cv2 with the
    rotation in float32 (as :func:`sensor_rays`)."""
    rotation = np.asarray(map_R_sensor, np.float32)
    return np.asarray(cv2.transform(dirs_sensor.reshape(-1, 1, 3), rotation), np.float32).reshape(-1, 3)


_LAST_TURNED: list[tuple[npt.NDArray[np.float32], bytes, npt.NDArray[np.float32]]] = []


def map_directions(
    map_R_sensor: npt.NDArray[np.float64], dirs_sensor: npt.NDArray[np.float32]
) -> npt.NDArray[np.float32]:
    """``(N, 3) float32`` directions ``dirs_sensor`` turned into the map frame by cv2 with the
    rotation in float32 (:func:`turned_directions`). The last answer is kept (read-only) for the
    same directions array and the same rotation: the ray engine's cast and the camera's sun
    visibility of the same rays both ask."""
    rotation = np.asarray(map_R_sensor, np.float32)
    key = rotation.tobytes()
    last = _LAST_TURNED[0] if _LAST_TURNED else None  # one read: another thread may replace it
    if last is not None and last[0] is dirs_sensor and last[1] == key:
        return last[2]
    turned = turned_directions(rotation, dirs_sensor)
    turned.flags.writeable = False
    _LAST_TURNED[:] = [(dirs_sensor, key, turned)]
    return turned

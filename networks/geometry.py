"""Rigid transforms and small planar helpers.

A transform is named ``dst_SE3_src``: ``ego_SE3_lidar.transform_from(xyz_lidar)``
returns the same points in the ego frame, and names cancel when composing:
``map_SE3_lidar = map_SE3_ego.compose(ego_SE3_lidar)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class SE3:
    """Rotation ``(3, 3) float64`` and translation ``(3,) float64``."""

    rotation: FloatArray
    translation: FloatArray

    def __post_init__(self) -> None:
        rotation = np.asarray(self.rotation, dtype=np.float64)
        translation = np.asarray(self.translation, dtype=np.float64).reshape(-1)
        if rotation.shape != (3, 3) or translation.shape != (3,):
            msg = f"SE3 needs a (3, 3) rotation and a (3,) translation, got {rotation.shape} and {translation.shape}"
            raise ValueError(msg)
        object.__setattr__(self, "rotation", rotation)
        object.__setattr__(self, "translation", translation)

    @classmethod
    def identity(cls) -> SE3:
        return cls(np.eye(3), np.zeros(3))

    @classmethod
    def from_matrix(cls, matrix: npt.ArrayLike) -> SE3:
        m = np.asarray(matrix, dtype=np.float64)
        if m.shape != (4, 4):
            raise ValueError(f"SE3.from_matrix needs a (4, 4) matrix, got {m.shape}")
        return cls(m[:3, :3], m[:3, 3])

    @classmethod
    def from_xyz_rpy(cls, xyz: npt.ArrayLike, roll: float = 0.0, pitch: float = 0.0, yaw: float = 0.0) -> SE3:
        """Rotation ``Rz(yaw) @ Ry(pitch) @ Rx(roll)``, then translation ``xyz``."""
        return cls(rotation_from_rpy(roll, pitch, yaw), np.asarray(xyz, dtype=np.float64))

    def as_matrix(self) -> FloatArray:
        m = np.eye(4)
        m[:3, :3] = self.rotation
        m[:3, 3] = self.translation
        return m

    def transform_from(self, points: npt.ArrayLike) -> FloatArray:
        """Map ``(N, 3)`` points from the source frame into the destination frame."""
        p = np.asarray(points, dtype=np.float64)
        return p @ self.rotation.T + self.translation

    def rotate(self, vectors: npt.ArrayLike) -> FloatArray:
        """Rotate ``(N, 3)`` free vectors (directions, velocities); no translation."""
        return np.asarray(vectors, dtype=np.float64) @ self.rotation.T

    def inverse(self) -> SE3:
        r_t = self.rotation.T
        return SE3(r_t, -r_t @ self.translation)

    def compose(self, other: SE3) -> SE3:
        """``a_SE3_b.compose(b_SE3_c)`` is ``a_SE3_c``."""
        return SE3(self.rotation @ other.rotation, self.rotation @ other.translation + self.translation)

    def yaw_rad(self) -> float:
        return math.atan2(self.rotation[1, 0], self.rotation[0, 0])

    def quaternion_xyzw(self) -> tuple[float, float, float, float]:
        return quaternion_xyzw_from_rotation(self.rotation)


def rotation_from_rpy(roll: float, pitch: float, yaw: float) -> FloatArray:
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    rz = np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]])
    ry = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    return np.asarray(rz @ ry @ rx)


def rpy_from_rotation(rotation: npt.ArrayLike) -> tuple[float, float, float]:
    """Roll, pitch, yaw (radians) with ``rotation == Rz(yaw) @ Ry(pitch) @ Rx(roll)``."""
    r = np.asarray(rotation, dtype=np.float64)
    pitch = math.asin(max(-1.0, min(1.0, -float(r[2, 0]))))
    return math.atan2(float(r[2, 1]), float(r[2, 2])), pitch, math.atan2(float(r[1, 0]), float(r[0, 0]))


def quaternion_xyzw_from_rotation(rotation: FloatArray) -> tuple[float, float, float, float]:
    """Unit quaternion (x, y, z, w) of a rotation matrix, with w >= 0."""
    m = rotation
    trace = m[0, 0] + m[1, 1] + m[2, 2]
    if trace > 0.0:
        s = 2.0 * math.sqrt(trace + 1.0)
        q = (((m[2, 1] - m[1, 2]) / s), ((m[0, 2] - m[2, 0]) / s), ((m[1, 0] - m[0, 1]) / s), 0.25 * s)
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = 2.0 * math.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        q = (0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s, (m[2, 1] - m[1, 2]) / s)
    elif m[1, 1] > m[2, 2]:
        s = 2.0 * math.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        q = ((m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s, (m[0, 2] - m[2, 0]) / s)
    else:
        s = 2.0 * math.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        q = ((m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s, (m[1, 0] - m[0, 1]) / s)
    x, y, z, w = q
    sign = -1.0 if w < 0.0 else 1.0
    return (sign * x, sign * y, sign * z, sign * w)


def wrap_angle(angle_rad: npt.ArrayLike) -> FloatArray:
    """Wrap angles into [-pi, pi)."""
    a = np.asarray(angle_rad, dtype=np.float64)
    return (a + np.pi) % (2.0 * np.pi) - np.pi


def yaw_to_rotation(yaw_rad: npt.ArrayLike) -> FloatArray:
    """``(N,)`` yaw angles to ``(N, 3, 3)`` rotations about +z."""
    yaw = np.atleast_1d(np.asarray(yaw_rad, dtype=np.float64))
    c, s = np.cos(yaw), np.sin(yaw)
    out = np.zeros((yaw.shape[0], 3, 3))
    out[:, 0, 0], out[:, 0, 1] = c, -s
    out[:, 1, 0], out[:, 1, 1] = s, c
    out[:, 2, 2] = 1.0
    return out


def box_rotations(yaw_rad: npt.ArrayLike, pitch_rad: npt.ArrayLike) -> FloatArray:
    """``(N, 3, 3)`` orientations of boxes: yaw about +z after pitch (nose-up positive) about
    the box's own y axis."""
    rz = yaw_to_rotation(yaw_rad)
    pitch = np.atleast_1d(np.asarray(pitch_rad, dtype=np.float64))
    cp, sp = np.cos(pitch), np.sin(pitch)
    ry = np.zeros_like(rz)
    ry[:, 0, 0], ry[:, 0, 2], ry[:, 1, 1], ry[:, 2, 0], ry[:, 2, 2] = cp, -sp, 1.0, sp, cp
    return np.asarray(rz @ ry)


def rotations_from_rpy(roll_rad: npt.ArrayLike, pitch_rad: npt.ArrayLike, yaw_rad: npt.ArrayLike) -> FloatArray:
    """``(N, 3, 3)`` rotations ``Rz(yaw) @ Ry(pitch) @ Rx(roll)`` of ``(N,)`` angles (as
    :func:`rotation_from_rpy`, for many at once)."""
    roll, pitch, yaw = (np.atleast_1d(np.asarray(a, dtype=np.float64)) for a in (roll_rad, pitch_rad, yaw_rad))
    cr, sr, cp, sp, cy, sy = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch), np.cos(yaw), np.sin(yaw)
    out = np.empty((yaw.shape[0], 3, 3))
    out[:, 0, 0], out[:, 0, 1], out[:, 0, 2] = cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr
    out[:, 1, 0], out[:, 1, 1], out[:, 1, 2] = sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr
    out[:, 2, 0], out[:, 2, 1], out[:, 2, 2] = -sp, cp * sr, cp * cr
    return out


def rpy_from_rotations(rotations: npt.ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
    """``(N,)`` roll, pitch, yaw of ``(N, 3, 3)`` rotations, with each rotation
    ``Rz(yaw) @ Ry(pitch) @ Rx(roll)`` (yaw in [-pi, pi), pitch in [-pi/2, pi/2])."""
    r = np.asarray(rotations, dtype=np.float64).reshape(-1, 3, 3)
    pitch = np.arcsin(np.clip(-r[:, 2, 0], -1.0, 1.0))
    return np.arctan2(r[:, 2, 1], r[:, 2, 2]), pitch, wrap_angle(np.arctan2(r[:, 1, 0], r[:, 0, 0]))


def place_in_boxes(
    unit_points: FloatArray, center_m: FloatArray, lwh_m: FloatArray, rotations: FloatArray
) -> FloatArray:
    """``(N, V, 3)``: points ``(V, 3)`` of the unit box ``[-1/2, 1/2]^3`` scaled to each box's
    size ``lwh_m: (N, 3)``, turned by ``rotations: (N, 3, 3)`` and moved to ``center_m: (N, 3)``."""
    local = unit_points[None, :, :] * lwh_m[:, None, :]
    return np.asarray(np.einsum("nij,nkj->nki", rotations, local) + center_m[:, None, :])


def rotation_from_quaternion_xyzw(x: float, y: float, z: float, w: float) -> FloatArray:
    """Rotation matrix of a (not necessarily normalised) quaternion."""
    n = math.sqrt(x * x + y * y + z * z + w * w)
    x, y, z, w = x / n, y / n, z / n, w / n
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def arc_lengths(polyline: npt.ArrayLike) -> FloatArray:
    """``(K,)`` distance along a ``(K, 2+)`` polyline (in the plane) to each of its points."""
    p = np.asarray(polyline, np.float64)
    return np.asarray(np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(p[:, :2], axis=0), axis=1))], np.float64)


def polyline_length(polyline: npt.ArrayLike) -> float:
    """The length of a ``(K, 2+)`` polyline in the plane (0 for fewer than two points)."""
    p = np.asarray(polyline, np.float64)
    return float(np.sum(np.linalg.norm(np.diff(p[:, :2], axis=0), axis=1)))


def point_and_heading(polyline: npt.ArrayLike, s_m: float) -> tuple[FloatArray, FloatArray]:
    """The ``(3,)`` point ``s_m`` along a ``(K, 3)`` polyline (in the plane; z interpolated) and
    the ``(2,)`` unit direction of the segment it lies on."""
    p = np.asarray(polyline, np.float64)
    along = arc_lengths(p)
    point = np.array([float(np.interp(s_m, along, p[:, k])) for k in range(3)])
    i = int(np.clip(np.searchsorted(along, s_m) - 1, 0, len(p) - 2))
    heading = p[i + 1, :2] - p[i, :2]
    return point, heading / max(float(np.linalg.norm(heading)), 1e-9)

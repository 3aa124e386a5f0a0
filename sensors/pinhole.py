"""The camera model, in one place: intrinsics, lens distortion, projection, pixel rays, box
corners.

Pixel ``(u, v)`` is column ``u``, row ``v`` with OpenCV's convention (the centre of the
top-left pixel is ``(0, 0)``), so the principal point at the image centre is
``((W - 1) / 2, (H - 1) / 2)`` and the outer edges of the image lie exactly at +-hfov/2.
Points and rays are in the optical frame (x right, y down, z forward). The camera, the
labels' 2D boxes and visibility, the KITTI and MCAP calibrations all use this module.

A lens may distort the image with OpenCV's plumb_bob model (``k1, k2, p1, p2, k3``, as
``distortion``): the camera then casts each pixel's ray through the distorted lens (every
pixel's colour, depth, class and instance come from the lens's own ray), and projection goes
the other way. The focal length and principal point stay those of the pinhole (``K``); the
distortion is on top, as in OpenCV and ROS calibrations.
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


NO_DISTORTION = (0.0, 0.0, 0.0, 0.0, 0.0)


@dataclass(frozen=True, slots=True)
class Pinhole:
    """Square pixels, principal point at the image centre; ``hfov_deg`` sets the focal length;
    ``distortion`` OpenCV's ``k1, k2, p1, p2, k3`` (all 0: none)."""

    width_px: int
    height_px: int
    hfov_deg: float
    distortion: tuple[float, float, float, float, float] = NO_DISTORTION

    @property
    def distorted(self) -> bool:
        return any(c != 0.0 for c in self.distortion)

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
        """``(N, 3)`` unit ray directions through the centres of pixels ``(u[i], v[i])`` (through
        the lens: undistorted)."""
        K = self.K
        u_px, v_px = np.asarray(u, np.float64).ravel(), np.asarray(v, np.float64).ravel()
        if self.distorted:
            xy = undistort_pixels(self, np.stack([u_px, v_px], axis=1))
            d = np.concatenate([xy, np.ones((len(xy), 1))], axis=1)
        else:
            d = np.stack([(u_px - K[0, 2]) / K[0, 0], (v_px - K[1, 2]) / K[1, 1], np.ones(u_px.shape[0])], axis=1)
        return np.asarray(d / np.linalg.norm(d, axis=1, keepdims=True))

    def project(self, xyz_cam: F64) -> F64:
        """Pixels ``(..., 2)`` of optical-frame points ``(..., 3)`` with z > 0, through the lens."""
        if not self.distorted:
            return project(self.K, xyz_cam)
        xy = xyz_cam[..., :2] / xyz_cam[..., 2:3]
        xy_d = distort_normalised(self, xy.reshape(-1, 2)).reshape(xy.shape)
        K = self.K
        return np.stack([K[0, 0] * xy_d[..., 0] + K[0, 2], K[1, 1] * xy_d[..., 1] + K[1, 2]], axis=-1)

    @property
    def view_fov_deg(self) -> tuple[float, float]:
        """Horizontal and vertical field of view (degrees) the image covers: ``hfov_deg`` and
        :attr:`vfov_deg`, or with a lens distortion, twice the widest angle of a border pixel's
        ray from the optical axis (barrel distortion sees more than the pinhole)."""
        if not self.distorted:
            return self.hfov_deg, self.vfov_deg
        return _lens_fov_deg(self)

    def check_lens(self) -> str | None:
        """Why the lens distortion cannot be used over this image (None if it can): each pixel
        must have one ray, so the distortion must grow monotonically out to the image's corners
        and map the border's rays back to their pixels."""
        if not self.distorted:
            return None
        if not all(np.isfinite(self.distortion)):
            return "its coefficients must be finite numbers"
        border = _border(self)
        xy = undistort_pixels(self, border)
        K = self.K
        back = distort_normalised(self, xy) * [K[0, 0], K[1, 1]] + [K[0, 2], K[1, 2]]
        worst = float(np.abs(back - border).max()) if np.all(np.isfinite(back)) else math.inf
        reach = float(np.hypot(xy[:, 0], xy[:, 1]).max()) if np.all(np.isfinite(xy)) else math.inf
        r = np.linspace(0.0, min(reach, 50.0), 512)
        k1, k2, _, _, k3 = self.distortion
        grows = np.all(np.diff(r * (1 + k1 * r**2 + k2 * r**4 + k3 * r**6)) > 0)
        if worst > 0.01 or not grows:
            return "it folds the image over before its corners (the radial factor must grow out to them)"
        return None

    def image_directions(self) -> npt.NDArray[np.float32]:
        """``(H * W, 3) float32`` unit rays of every pixel, row-major (computed once per model)."""
        return _image_directions(self)


def _border(pinhole: Pinhole) -> F64:
    """``(M, 2)`` pixels along the image's outer edges (every 8th, and the corners)."""
    w, h = pinhole.width_px - 1.0, pinhole.height_px - 1.0
    us, vs = np.append(np.arange(0.0, w, 8.0), w), np.append(np.arange(0.0, h, 8.0), h)
    return np.concatenate([np.stack([us, np.zeros_like(us)], 1), np.stack([us, np.full_like(us, h)], 1),
                           np.stack([np.zeros_like(vs), vs], 1), np.stack([np.full_like(vs, w), vs], 1)])  # fmt: skip


def undistort_pixels(pinhole: Pinhole, uv: F64) -> F64:
    """``(N, 2)`` normalised image coordinates (x / z, y / z of the ray) of distorted pixels
    ``(N, 2)`` (OpenCV's iterative inversion, run to 1e-12)."""
    import cv2

    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-12)
    pts = np.ascontiguousarray(uv, np.float64).reshape(-1, 1, 2)
    out = cv2.undistortPoints(pts, pinhole.K, np.asarray(pinhole.distortion, np.float64), None, None, None, criteria)
    return np.asarray(out, np.float64).reshape(-1, 2)


@functools.lru_cache(maxsize=16)
def _lens_fov_deg(pinhole: Pinhole) -> tuple[float, float]:
    """:attr:`Pinhole.view_fov_deg` of a distorting lens (computed once per camera model: the
    camera culls by it every frame)."""
    d = pinhole.pixel_directions(*_border(pinhole).T)
    half_h = np.degrees(np.arctan(np.abs(d[:, 0] / d[:, 2]))).max()
    half_v = np.degrees(np.arctan(np.abs(d[:, 1] / d[:, 2]))).max()
    return float(2.0 * half_h), float(2.0 * half_v)


@functools.lru_cache(maxsize=16)
def _reach(pinhole: Pinhole) -> float:
    """The largest radius (normalised coordinates) of a ray through the image's border."""
    xy = undistort_pixels(pinhole, _border(pinhole))
    return float(np.hypot(xy[:, 0], xy[:, 1]).max())


def distort_normalised(pinhole: Pinhole, xy: F64) -> F64:
    """``(N, 2)`` distorted normalised coordinates of undistorted ones ``(N, 2)`` (plumb_bob).
    Beyond the image's reach (rays that miss the image) the radial factor stays at its value
    there, so projection keeps growing outwards instead of folding back in."""
    k1, k2, p1, p2, k3 = pinhole.distortion
    x, y = xy[:, 0], xy[:, 1]
    r2 = x * x + y * y
    lim = _reach(pinhole) ** 2
    rc = np.minimum(r2, lim)
    radial = 1.0 + k1 * rc + k2 * rc**2 + k3 * rc**3
    xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
    yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
    return np.stack([xd, yd], axis=1)


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

"""Pinhole camera by raycasting: z-depth, instance and class masks and a shaded image.

One ray per pixel, through the pixel's centre. Pixel ``(u, v)`` is column ``u``, row ``v``
with OpenCV's convention (the centre of the top-left pixel is ``(0, 0)``), so the
principal point at the image centre is ``((W - 1) / 2, (H - 1) / 2)`` and the outer edges
of the image lie exactly at +-hfov/2. Where no surface is hit within ``range_m`` the depth
is 0 (also 0 in the 16-bit depth PNG), the class NONE (0) and the instance 0.

Shading: albedo per class (vehicles painted by instance id) times Lambert lighting from a
fixed sun plus ambient (plus headlights at night), blended into haze with distance; misses
show a sky gradient. No shadows, no textures.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import cv2
import numpy as np
import numpy.typing as npt

from networks.geometry import SE3
from sensors.errors import SensorConfigError, SensorError
from sensors.hits import RayHits
from sensors.materials import ALBEDO_BGR_BY_CLASS, PAINTED_CLASSES, VEHICLE_PAINT_BGR
from sensors.rays import sensor_rays
from sensors.view import spheres_in_view
from sensors.weather import DAY, Weather, haze_fraction, image_noise, sky_bgr

if TYPE_CHECKING:  # Open3D loads only where rays are cast, not in the writer process
    from sensors.scene import FrameScene

F64 = npt.NDArray[np.float64]
EGO_AXES_R_OPTICAL = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
"""Rotation from the optical frame (x right, y down, z forward) to the camera's body
axes (x forward, y left, z up): its columns are the optical axes in body axes."""


@dataclass(frozen=True, slots=True)
class CameraSpec:
    """A pinhole camera. ``mount_rpy_deg`` turns the camera body (x forward, y left, z up)
    in the ego frame with ``SE3.from_xyz_rpy``: (0, 0, 0) looks along ego +x; positive
    pitch looks down (ROS convention), positive yaw looks left."""

    name: str = "camera"
    width_px: int = 1280
    height_px: int = 720
    hfov_deg: float = 85.0
    mount_xyz_m: tuple[float, float, float] = (0.41, 0.0, 1.64)
    mount_rpy_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)
    range_m: float = 200.0
    rate_hz: float = 20.0

    def __post_init__(self) -> None:
        if not (8 <= self.width_px <= 8192 and 8 <= self.height_px <= 8192):
            raise SensorConfigError(f"camera {self.name}: width_px and height_px must be 8..8192")
        if not 1.0 <= self.hfov_deg <= 170.0:
            raise SensorConfigError(f"camera {self.name}: hfov_deg must be 1..170, got {self.hfov_deg}")
        if self.range_m <= 0 or self.rate_hz <= 0:
            raise SensorConfigError(f"camera {self.name}: range_m and rate_hz must be > 0")

    @property
    def focal_px(self) -> float:
        return self.width_px / 2.0 / math.tan(math.radians(self.hfov_deg) / 2.0)

    @property
    def vfov_deg(self) -> float:
        return math.degrees(2.0 * math.atan(self.height_px / 2.0 / self.focal_px))

    @property
    def K(self) -> npt.NDArray[np.float64]:
        """``(3, 3)`` intrinsics: square pixels, principal point at the image centre."""
        f = self.focal_px
        return np.array([[f, 0.0, (self.width_px - 1) / 2.0], [0.0, f, (self.height_px - 1) / 2.0], [0.0, 0.0, 1.0]])

    @property
    def ego_SE3_body(self) -> SE3:
        """The camera body (x forward, y left, z up) in the ego frame."""
        r, p, y = np.radians(self.mount_rpy_deg)
        return SE3.from_xyz_rpy(self.mount_xyz_m, r, p, y)

    @property
    def ego_SE3_cam(self) -> SE3:
        """The optical frame (x right, y down, z forward) in the ego frame."""
        return self.ego_SE3_body.compose(SE3(EGO_AXES_R_OPTICAL, np.zeros(3)))


@dataclass(frozen=True, slots=True)
class Shading:
    """What a frame's shaded image is made from: the surface normal per pixel (map frame,
    row-major), the camera's orientation in the map, the weather and the seed of its image
    noise. The image is made on first use, so where the frame is encoded (a writer process)
    rather than where its rays are cast."""

    spec: CameraSpec
    map_R_cam: npt.NDArray[np.float32]
    normal: npt.NDArray[np.float32]
    weather: Weather
    noise_seed: int | None


@dataclass(frozen=True, slots=True)
class CameraFrame:
    """One rendered frame: ``depth_m: (H, W) float32`` z-depth along the optical axis (0: no
    hit within range), ``instance_id: (H, W) uint32`` (0: static world or nothing),
    ``semantic_class: (H, W) uint8`` (0: nothing), and ``image_bgr: (H, W, 3) uint8``: given,
    or shaded from ``shading`` on first use."""

    depth_m: npt.NDArray[np.float32]
    instance_id: npt.NDArray[np.uint32]
    semantic_class: npt.NDArray[np.uint8]
    shading: Shading | None = None
    given_image_bgr: npt.NDArray[np.uint8] | None = field(default=None, repr=False, compare=False)

    def __post_init__(self) -> None:
        hw = self.depth_m.shape
        fields = ((self.depth_m, np.float32, hw), (self.instance_id, np.uint32, hw),
                  (self.semantic_class, np.uint8, hw))  # fmt: skip
        if len(hw) != 2 or any(a.dtype != dt or a.shape != shape for a, dt, shape in fields):
            raise ValueError("CameraFrame: need (H, W) float32 depth, uint32 instance, uint8 class")
        image = self.given_image_bgr
        if image is None and self.shading is None:
            raise ValueError("CameraFrame: need an image or what to shade it from")
        if image is not None and (image.dtype != np.uint8 or image.shape != (*hw, 3)):
            raise ValueError("CameraFrame: the image must be (H, W, 3) uint8")

    @property
    def image_bgr(self) -> npt.NDArray[np.uint8]:
        if self.given_image_bgr is None:
            object.__setattr__(self, "given_image_bgr", shade_frame(self))
        assert self.given_image_bgr is not None
        return self.given_image_bgr

    @property
    def hit(self) -> npt.NDArray[np.bool_]:
        return self.depth_m > 0


def pixel_directions_cam(spec: CameraSpec) -> npt.NDArray[np.float32]:
    """``(H * W, 3)`` unit ray directions in the optical frame, row-major over pixels."""
    v, u = np.mgrid[0 : spec.height_px, 0 : spec.width_px].astype(np.float64)
    K = spec.K
    x = (u.ravel() - K[0, 2]) / K[0, 0]
    y = (v.ravel() - K[1, 2]) / K[1, 1]
    d = np.stack([x, y, np.ones_like(x)], axis=1)
    return (d / np.linalg.norm(d, axis=1, keepdims=True)).astype(np.float32)


def project_points(K: npt.ArrayLike, cam_SE3_x: SE3, xyz_x: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """``(N, 2)`` pixel coordinates ``uv`` of ``(N, 3)`` points given in frame ``x``;
    NaN for points on or behind the camera plane (z <= 1 mm)."""
    xyz_cam = cam_SE3_x.transform_from(np.asarray(xyz_x, dtype=np.float64).reshape(-1, 3))
    z = xyz_cam[:, 2:3]
    in_front = z > 1e-3
    uvw = xyz_cam @ np.asarray(K, dtype=np.float64).T
    return np.where(in_front, uvw[:, :2] / np.where(in_front, z, 1.0), np.nan)


class Camera:
    def __init__(self, spec: CameraSpec) -> None:
        self.spec = spec
        self._dirs_cam = pixel_directions_cam(spec)

    @property
    def shape(self) -> tuple[int, int]:
        return (self.spec.height_px, self.spec.width_px)

    def reaches(self, center_map_m: F64, radius_m: F64, map_SE3_ego: SE3) -> npt.NDArray[np.bool_]:
        """Which spheres this camera's rays may meet within its range (see :mod:`sensors.view`)."""
        body_SE3_map = map_SE3_ego.compose(self.spec.ego_SE3_body).inverse()
        spec = self.spec
        return spheres_in_view(body_SE3_map, center_map_m, radius_m, spec.range_m, spec.hfov_deg, spec.vfov_deg)

    def rays(self, map_SE3_ego: SE3) -> npt.NDArray[np.float32]:
        """``(H * W, 6) float32`` rays in the map frame, row-major over pixels."""
        return sensor_rays(map_SE3_ego.compose(self.spec.ego_SE3_cam), self._dirs_cam)

    def render(
        self,
        scene: FrameScene,
        map_SE3_ego: SE3,
        weather: Weather | None = None,
        rng: np.random.Generator | None = None,
    ) -> CameraFrame:
        """Render one frame. ``weather`` defaults to day; image noise (night, rain, fog) is
        drawn from ``rng`` (pass the frame loop's; a fixed seed 0 is used without one)."""
        w = DAY if weather is None else weather
        rays = self.rays(map_SE3_ego)
        hits = scene.cast(rays)
        far = hits.range_m > np.float32(self.spec.range_m)  # nothing hit within range
        depth = hits.range_m * self._dirs_cam[:, 2]
        depth[far] = 0.0
        hits.instance_id[far] = 0  # the frame's own arrays; shading paints sky over these pixels
        hits.semantic_class[far] = 0
        seed = None
        if w.noise_sigma > 0:
            seed = 0 if rng is None else int(rng.integers(0, 2**63))
        map_R_cam = map_SE3_ego.compose(self.spec.ego_SE3_cam).rotation.astype(np.float32)
        h, wd = self.shape
        return CameraFrame(depth.reshape(h, wd), hits.instance_id.reshape(h, wd), hits.semantic_class.reshape(h, wd),
                           Shading(self.spec, map_R_cam, hits.normal, w, seed))  # fmt: skip


def shade_frame(frame: CameraFrame) -> npt.NDArray[np.uint8]:
    """The shaded ``(H, W, 3) uint8`` image of a rendered frame (see :class:`Shading`)."""
    sh = frame.shading
    assert sh is not None
    dirs_cam = _pixel_directions(sh.spec)
    depth = frame.depth_m.ravel()
    hit = depth > 0
    range_m = depth / dirs_cam[:, 2]
    dirs_map = np.asarray(cv2.transform(dirs_cam.reshape(-1, 1, 3), sh.map_R_cam), np.float32).reshape(-1, 3)
    classes, instances = frame.semantic_class.ravel(), frame.instance_id.ravel()
    noise = None if sh.noise_seed is None else image_noise(sh.weather, np.random.default_rng(sh.noise_seed), len(depth))
    image = np.empty((len(depth), 3), np.uint8)
    for start in range(0, len(depth), STRIPE_PX):
        part = slice(start, start + STRIPE_PX)
        stripe = RayHits(range_m[part], classes[part], instances[part], sh.normal[part])
        shaded = shade(stripe, dirs_map[part], hit[part], dirs_cam[part, 2], sh.weather, sh.spec.range_m)
        if noise is not None:
            shaded += noise[part, None]
        image[part] = to_uint8(shaded)
    return image.reshape(*frame.depth_m.shape, 3)


@functools.lru_cache(maxsize=8)
def _pixel_directions(spec: CameraSpec) -> npt.NDArray[np.float32]:
    return pixel_directions_cam(spec)


STRIPE_PX = 1 << 15
"""Pixels shaded at a time: a stripe's arrays stay in the CPU cache through every step."""


def to_uint8(image: npt.NDArray[np.float32]) -> npt.NDArray[np.uint8]:
    return np.clip(image + np.float32(0.5), 0.0, 255.0).astype(np.uint8)


_ALBEDO_AND_PAINT = np.concatenate([ALBEDO_BGR_BY_CLASS, VEHICLE_PAINT_BGR])


def surface_albedo(
    semantic_class: npt.NDArray[np.uint8], instance_id: npt.NDArray[np.uint32]
) -> npt.NDArray[np.float32]:
    """``(N, 3)`` BGR albedo in 0..1: by class, vehicles painted by instance id."""
    key = semantic_class.astype(np.intp)
    painted = PAINTED_CLASSES[semantic_class]
    key[painted] = 256 + instance_id[painted] % VEHICLE_PAINT_BGR.shape[0]
    return np.take(_ALBEDO_AND_PAINT, key, axis=0)


def lighting(
    normal: npt.NDArray[np.float32],
    dirs: npt.NDArray[np.float32],
    range_m: npt.NDArray[np.float32],
    forward: npt.NDArray[np.float32],
    weather: Weather,
) -> npt.NDArray[np.float32]:
    """``(N,)`` light on surfaces with ``normal`` (either winding) seen along unit ``dirs`` at
    ``range_m``; ``forward`` is each ray's cosine to the optical axis (the headlight cone)."""
    facing = np.einsum("ij,ij->i", normal, dirs)
    sun = np.asarray(weather.sun_dir_map, np.float32)
    sun_cos = (normal @ (sun / np.linalg.norm(sun))) * np.where(facing > 0, np.float32(-1.0), np.float32(1.0))
    light = np.float32(weather.ambient) + np.float32(weather.sun_gain) * np.maximum(sun_cos, np.float32(0.0))
    if weather.headlight_gain > 0:
        falloff = 1.0 / (1.0 + (range_m / np.float32(weather.headlight_range_m)) ** 2)
        diffuse = np.float32(0.4) + np.float32(0.6) * np.abs(facing)
        light += np.float32(weather.headlight_gain) * diffuse * falloff * forward**8
    return light.astype(np.float32)


def shade(
    hits: RayHits,
    dirs_map: npt.NDArray[np.float32],
    hit: npt.NDArray[np.bool_],
    forward: npt.NDArray[np.float32],
    weather: Weather,
    range_m: float,
) -> npt.NDArray[np.float32]:
    """``(N, 3) float32`` BGR in 0..255: lit albedo hazed with distance where ``hit``, sky elsewhere."""
    light = lighting(hits.normal, dirs_map, hits.range_m, forward, weather)
    image = surface_albedo(hits.semantic_class, hits.instance_id)
    image *= (np.float32(255.0 * weather.exposure) * light)[:, None]
    f = haze_fraction(weather, hits.range_m, range_m)[:, None]
    image += (np.asarray(weather.haze_bgr, np.float32) * np.float32(weather.exposure) - image) * f
    miss = np.flatnonzero(~hit)
    image[miss] = sky_bgr(weather, dirs_map[miss, 2]) * np.float32(weather.exposure)
    return image


DEPTH_PNG_MAX_UNITS = 65535


def depth_to_uint16(depth_m: npt.NDArray[np.floating], units_per_m: float = 1000.0) -> npt.NDArray[np.uint16]:
    """``(H, W) uint16`` depth in ``1 / units_per_m`` metres (millimetres by default); 0 where
    there is no depth or it does not fit (beyond 65.535 m in millimetres)."""
    depth = np.asarray(depth_m)
    exact_in_float32 = depth.dtype == np.float32 and math.frexp(units_per_m)[0] == 0.5  # a power of two
    units = (
        np.rint(depth * np.float32(units_per_m))
        if exact_in_float32
        else np.rint(depth.astype(np.float64) * units_per_m)
    )
    valid = np.isfinite(units) & (units > 0) & (units <= DEPTH_PNG_MAX_UNITS)
    return np.where(valid, units, 0).astype(np.uint16)


def encode_depth_png(depth_m: npt.NDArray[np.floating], units_per_m: float = 1000.0, filter_up: bool = False) -> bytes:
    """16-bit PNG bytes of :func:`depth_to_uint16`, zlib level 1 (optionally the UP filter)."""
    params = [cv2.IMWRITE_PNG_COMPRESSION, 1]
    if filter_up:
        params += [cv2.IMWRITE_PNG_FILTER, cv2.IMWRITE_PNG_FILTER_UP]
    ok, buf = cv2.imencode(".png", depth_to_uint16(depth_m, units_per_m), params)
    if not ok:
        raise SensorError("depth PNG encoding failed")
    return bytes(buf)

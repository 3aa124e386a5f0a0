"""Pinhole camera by raycasting: z-depth, instance and class masks, and what its image is
shaded from.

One ray per pixel, through the pixel's centre (the model and its pixel convention:
:mod:`sensors.pinhole`). Where no surface is hit within ``range_m`` the depth is 0 (also 0
in the 16-bit depth PNG), the class NONE (0) and the instance 0. The colour image is made
from the frame by :func:`sensors.shading.shade_frame`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar

import cv2
import numpy as np
import numpy.typing as npt
from numba import njit

from networks.geometry import SE3
from networks.vocabulary import SensorKind
from sensors.agents import Agents, EgoState
from sensors.errors import SensorConfigError, SensorError
from sensors.hits import RayHits
from sensors.photo import SUBPIXEL_OFFSETS, AgentBoxes, Supersamples
from sensors.pinhole import EGO_AXES_R_OPTICAL, NO_DISTORTION, Pinhole
from sensors.rays import map_directions, sensor_rays
from sensors.shade_kernels import depth_units, edges, ids_seen, subpixel_directions
from sensors.shading import CameraFrame, Shading
from sensors.view import spheres_in_view
from sensors.weather import Weather

if TYPE_CHECKING:
    from sensors.engine import Scene

F64 = npt.NDArray[np.float64]
SHADING_STYLES = ("realistic", "flat")
MAX_SHUTTER_S = 0.1
SHADOW_RANGE_M = 120.0
"""Beyond this distance no shadow ray is cast: the sun is taken as visible."""
SHADOW_REACH = 4.0
"""An agent's shadow falls within this many times its bounding radius of its centre (for a
sun at least 27 degrees high: an agent is at most twice its radius tall)."""
SHADOW_LIFT_M = 0.02
"""Shadow rays start this far off the surface, towards the camera's side of it."""


@dataclass(frozen=True, slots=True)
class CameraSpec:
    """A camera. ``mount_rpy_deg`` turns the camera body (x forward, y left, z up)
    in the ego frame with ``SE3.from_xyz_rpy``: (0, 0, 0) looks along ego +x; positive
    pitch looks down (ROS convention), positive yaw looks left. ``distortion``: the lens's
    OpenCV plumb_bob coefficients ``k1, k2, p1, p2, k3`` (all 0: a pinhole; see
    :mod:`sensors.pinhole`). ``shutter_s``: the exposure time over which the image blurs with
    the motion of the ego and the traffic (0: a sharp image)."""

    name: str = SensorKind.CAMERA.value  # named after its kind unless the rig names it
    width_px: int = 1280
    height_px: int = 720
    hfov_deg: float = 85.0
    mount_xyz_m: tuple[float, float, float] = (0.41, 0.0, 1.64)
    mount_rpy_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)
    range_m: float = 200.0
    rate_hz: float = 20.0
    shading: str = "realistic"  # or "flat": one colour per class and face, no shadows, faster
    distortion: tuple[float, float, float, float, float] = NO_DISTORTION  # OpenCV k1, k2, p1, p2, k3
    shutter_s: float = 0.0  # exposure time: motion blur over it (realistic shading; 0: none)

    def __post_init__(self) -> None:
        if self.shading not in SHADING_STYLES:
            raise SensorConfigError(
                f"camera {self.name}: shading must be one of {', '.join(SHADING_STYLES)}, got {self.shading!r}"
            )
        if not (8 <= self.width_px <= 8192 and 8 <= self.height_px <= 8192):
            raise SensorConfigError(f"camera {self.name}: width_px and height_px must be 8..8192")
        if not 1.0 <= self.hfov_deg <= 170.0:
            raise SensorConfigError(f"camera {self.name}: hfov_deg must be 1..170, got {self.hfov_deg}")
        if self.range_m <= 0 or self.rate_hz <= 0:
            raise SensorConfigError(f"camera {self.name}: range_m and rate_hz must be > 0")
        longest = min(MAX_SHUTTER_S, 1.0 / self.rate_hz)
        if not (0.0 <= self.shutter_s <= longest):
            raise SensorConfigError(
                f"camera {self.name}: shutter_s must be 0..{longest:g} s (at most one frame at "
                f"rate_hz {self.rate_hz:g}), got {self.shutter_s}"
            )
        if self.shutter_s > 0 and self.shading == "flat":
            raise SensorConfigError(f"camera {self.name}: shutter_s (motion blur) needs shading: realistic")
        if len(self.distortion) != 5:
            raise SensorConfigError(
                f"camera {self.name}: distortion must be 5 numbers (OpenCV's k1, k2, p1, p2, k3), "
                f"got {len(self.distortion)}"
            )
        why = self.pinhole.check_lens()
        if why is not None:
            raise SensorConfigError(
                f"camera {self.name}: distortion {list(self.distortion)} cannot be used over a "
                f"{self.width_px}x{self.height_px} image with hfov_deg {self.hfov_deg:g}: {why}"
            )

    @property
    def pinhole(self) -> Pinhole:
        return Pinhole(self.width_px, self.height_px, self.hfov_deg, tuple(float(c) for c in self.distortion))  # type: ignore[arg-type]

    @property
    def ego_SE3_body(self) -> SE3:
        """The camera body (x forward, y left, z up) in the ego frame."""
        r, p, y = np.radians(self.mount_rpy_deg)
        return SE3.from_xyz_rpy(self.mount_xyz_m, r, p, y)

    @property
    def ego_SE3_sensor(self) -> SE3:
        """The optical frame (x right, y down, z forward) in the ego frame."""
        return self.ego_SE3_body.compose(SE3(EGO_AXES_R_OPTICAL, np.zeros(3)))


@dataclass(frozen=True, slots=True)
class CameraOutput:
    """A camera's output in one frame: what it rendered and, once shaded, its image (None: not
    shaded yet; the writers shade it, :class:`gtgen.sinks.images.FrameImages`)."""

    spec: CameraSpec
    frame: CameraFrame
    image: npt.NDArray[np.uint8] | None = None


class Camera:
    kind: ClassVar[SensorKind] = SensorKind.CAMERA

    def __init__(self, spec: CameraSpec) -> None:
        self.spec = spec
        self._dirs_cam = spec.pinhole.image_directions()
        self._forward = np.ascontiguousarray(self._dirs_cam[:, 2])  # each ray's cosine to the optical axis
        self._shadows = ShadowScratch()

    @property
    def shape(self) -> tuple[int, int]:
        return (self.spec.height_px, self.spec.width_px)

    def reaches(self, center_map_m: F64, radius_m: F64, map_SE3_ego: SE3) -> npt.NDArray[np.bool_]:
        """Which spheres this camera's rays may meet within its range (see :mod:`sensors.view`);
        with realistic shading also those whose shadows may fall in view (spheres widened by
        :data:`SHADOW_REACH`)."""
        body_SE3_map = map_SE3_ego.compose(self.spec.ego_SE3_body).inverse()
        spec = self.spec
        if spec.shading != "flat":
            radius_m = radius_m * SHADOW_REACH
        hfov_deg, vfov_deg = spec.pinhole.view_fov_deg
        return spheres_in_view(body_SE3_map, center_map_m, radius_m, spec.range_m, hfov_deg, vfov_deg)

    def rays(self, map_SE3_ego: SE3) -> npt.NDArray[np.float32]:
        """``(H * W, 6) float32`` rays in the map frame, row-major over pixels."""
        return sensor_rays(map_SE3_ego.compose(self.spec.ego_SE3_sensor), self._dirs_cam)

    def sense(self, scene: Scene, ego: EgoState, weather: Weather, rng: np.random.Generator) -> CameraOutput:
        """Render one frame; the seed of the image noise is drawn from ``rng``. The realistic
        style also casts a shadow ray towards the sun per pixel and four sub-pixel rays at
        pixels holding an edge (anti-aliasing); labels use the centre rays only."""
        map_SE3_ego = ego.map_SE3_ego()
        map_SE3_cam = map_SE3_ego.compose(self.spec.ego_SE3_sensor)
        hits = scene.cast_from(map_SE3_cam.translation, map_SE3_cam.rotation, self._dirs_cam)
        realistic = self.spec.shading != "flat"
        # the frame's own arrays: nothing hit within range is depth 0, class and instance 0 (and,
        # shaded realistically, part 0 and range inf); shading paints sky over these pixels
        depth = _within_range(hits.range_m, hits.instance_id, hits.semantic_class, hits.part, self._forward,
                              np.float32(self.spec.range_m), realistic)  # fmt: skip
        map_R_cam = map_SE3_cam.rotation.astype(np.float32)
        h, w = self.shape
        if not realistic:
            seed = int(rng.integers(0, 2**63)) if weather.noise_sigma > 0 else None
            shading = Shading(self.spec.pinhole, self.spec.range_m, map_R_cam, hits.normal, weather, seed)
        else:
            seed = int(rng.integers(0, 2**63))
            origin = map_SE3_cam.translation
            dirs_map = map_directions(map_SE3_cam.rotation, self._dirs_cam)  # those of the cast
            sun_lit = sun_visibility(scene, origin, dirs_map, hits.range_m, hits.normal, weather, self._shadows)
            extra = self._supersamples(scene, map_SE3_cam, hits, weather)
            shading = Shading(self.spec.pinhole, self.spec.range_m, map_R_cam, hits.normal, weather, seed,
                              part=hits.part, origin_map_m=np.asarray(origin, np.float64), sun_lit=sun_lit,
                              boxes=boxes_in_view(scene.agents, hits.instance_id), extra=extra,
                              shutter_s=self.spec.shutter_s, ego_velocity_map_mps=ego.velocity_map_mps)  # fmt: skip
        frame = CameraFrame(
            depth.reshape(h, w), hits.instance_id.reshape(h, w), hits.semantic_class.reshape(h, w), shading
        )
        return CameraOutput(self.spec, frame)

    def _supersamples(self, scene: Scene, map_SE3_cam: SE3, hits: RayHits, weather: Weather) -> Supersamples:
        """Four sub-pixel rays at every pixel whose class, instance, part or depth differs from
        a neighbour's; one with nothing within the camera's range is a miss, as a centre ray is
        (range inf; class, instance and part 0)."""
        h, w = self.shape
        pixel = np.flatnonzero(edge_pixels(hits, h, w)).astype(np.int64)
        if len(pixel) == 0:
            z = np.zeros(0, np.float32)
            return Supersamples(pixel, np.zeros((0, 3), np.float32), z, np.zeros(0, np.uint8), np.zeros(0, np.uint32),
                                np.zeros(0, np.uint8), np.zeros((0, 3), np.float32), np.zeros(0, np.bool_))  # fmt: skip
        pinhole = self.spec.pinhole
        if pinhole.distorted:
            v, u = np.divmod(pixel, w)
            su = (u[:, None] + SUBPIXEL_OFFSETS[None, :, 0]).ravel()
            sv = (v[:, None] + SUBPIXEL_OFFSETS[None, :, 1]).ravel()
            dirs_cam = pinhole.pixel_directions(su, sv).astype(np.float32)
        else:
            K = pinhole.K
            dirs_cam = subpixel_directions(pixel, w, SUBPIXEL_OFFSETS, K[0, 0], K[0, 2], K[1, 1], K[1, 2])
        sub = scene.cast_from(map_SE3_cam.translation, map_SE3_cam.rotation, dirs_cam)
        # nothing within range: a miss, as at the centre rays (range inf; class, instance, part 0)
        _within_range(sub.range_m, sub.instance_id, sub.semantic_class, sub.part,
                      np.ascontiguousarray(dirs_cam[:, 2]), np.float32(self.spec.range_m), True)  # fmt: skip
        dirs_map = map_directions(map_SE3_cam.rotation, dirs_cam)
        lit = sun_visibility(scene, map_SE3_cam.translation, dirs_map, sub.range_m, sub.normal, weather, self._shadows)
        return Supersamples(
            pixel, dirs_cam, sub.range_m, sub.semantic_class, sub.instance_id, sub.part, sub.normal, lit
        )


def edge_pixels(hits: RayHits, h: int, w: int) -> npt.NDArray[np.bool_]:
    """``(H * W,)`` pixels that differ from their right or lower neighbour in class, instance
    or part, or whose range jumps by more than 3 %."""
    return edges(
        np.ascontiguousarray(hits.semantic_class, np.uint8), np.ascontiguousarray(hits.part, np.uint8),
        np.ascontiguousarray(hits.instance_id, np.uint32), np.ascontiguousarray(hits.range_m, np.float32), h, w,
    )  # fmt: skip


class ShadowScratch:
    """The shadow rays' arrays, kept from call to call (grown when a call has more rays): a
    camera's 600,000 shadow rays a frame are written into the same memory every frame."""

    def __init__(self) -> None:
        self.at = np.zeros(0, np.int64)
        self.columns = np.zeros((6, 0), np.float32)

    def take(self, n: int) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.float32]]:
        """Room for ``n`` rays: their rows and their ``(6, n)`` columns."""
        if self.at.shape[0] < n:
            self.at = np.empty(n, np.int64)
            self.columns = np.empty((6, n), np.float32)
        return self.at, self.columns


def sun_visibility(scene: Scene, origin_map_m: F64, dirs_map: npt.NDArray[np.float32], range_m: npt.NDArray[np.float32],
                   normal: npt.NDArray[np.float32], weather: Weather,
                   scratch: ShadowScratch | None = None) -> npt.NDArray[np.bool_]:  # fmt: skip
    """``(N,)`` whether the sun reaches each hit point (a shadow ray towards it hits nothing).
    Misses, points beyond :data:`SHADOW_RANGE_M` and surfaces facing away count as lit; with no
    sun and no street lamps overhead every point is lit and no ray is cast. The shadow rays are
    written into ``scratch`` (a fresh one when not given)."""
    lit = np.ones(range_m.shape[0], np.bool_)
    if weather.sun_gain <= 0 and weather.lamp_key_gain <= 0:
        return lit
    sun = np.asarray(weather.sun_dir_map, np.float32)
    sun /= np.linalg.norm(sun)
    at, columns = (scratch or ShadowScratch()).take(range_m.shape[0])
    k = _shadow_rays(
        np.asarray(origin_map_m, np.float64).astype(np.float32), np.ascontiguousarray(dirs_map, np.float32),
        np.ascontiguousarray(range_m, np.float32), np.ascontiguousarray(normal, np.float32), sun,
        np.float32(SHADOW_RANGE_M), np.float32(SHADOW_LIFT_M), at, columns,
    )  # fmt: skip
    if k:
        _set_lit(lit, at[:k], scene.occluded(columns[:, :k].T))  # (K, 6), each column contiguous
    return lit


@njit(cache=True, nogil=True)
def _shadow_rays(
    origin: npt.NDArray[np.float32], dirs: npt.NDArray[np.float32], range_m: npt.NDArray[np.float32],
    normal: npt.NDArray[np.float32], sun: npt.NDArray[np.float32], max_range_m: np.float32, lift_m: np.float32,
    at: npt.NDArray[np.int64], rays: npt.NDArray[np.float32],
) -> int:  # fmt: skip  # pragma: no cover - compiled
    """The rows that need a shadow ray (a hit nearer than ``max_range_m`` whose side facing the
    camera faces the ``sun``) written into ``at`` and their rays into the columns of ``rays``
    ``(6, >= K)``: from the hit, lifted ``lift_m`` off the surface towards the camera's side,
    along ``sun``, in one pass over the rows; returns their number ``K``."""
    k = 0
    s0, s1, s2 = sun[0], sun[1], sun[2]
    o0, o1, o2 = origin[0], origin[1], origin[2]
    for i in range(range_m.shape[0]):
        r = range_m[i]
        if not (r < max_range_m):  # also inf and nan
            continue
        n0, n1, n2 = normal[i, 0], normal[i, 1], normal[i, 2]
        d0, d1, d2 = dirs[i, 0], dirs[i, 1], dirs[i, 2]
        if n0 * d0 + n1 * d1 + n2 * d2 > 0:
            n0, n1, n2 = -n0, -n1, -n2
        if n0 * s0 + n1 * s1 + n2 * s2 > 0:
            at[k] = i
            rays[0, k] = (o0 + d0 * r) + n0 * lift_m
            rays[1, k] = (o1 + d1 * r) + n1 * lift_m
            rays[2, k] = (o2 + d2 * r) + n2 * lift_m
            k += 1
    for j in range(k):
        rays[3, j] = s0
        rays[4, j] = s1
        rays[5, j] = s2
    return k


@njit(cache=True, nogil=True)
def _within_range(
    range_m: npt.NDArray[np.float32], instance: npt.NDArray[np.uint32], cls: npt.NDArray[np.uint8],
    part: npt.NDArray[np.uint8], forward: npt.NDArray[np.float32], max_range_m: np.float32, realistic: bool,
) -> npt.NDArray[np.float32]:  # fmt: skip  # pragma: no cover - compiled
    """``(N,)`` z-depth of each ray's hit (its range times its cosine to the optical axis, float32);
    a ray with nothing within ``max_range_m`` gets depth 0, instance and class 0 and, with
    ``realistic``, part 0 and range inf (written into the arrays given)."""
    depth = np.empty(range_m.shape[0], np.float32)
    for i in range(range_m.shape[0]):
        r = range_m[i]
        if r > max_range_m:
            depth[i] = 0.0
            instance[i] = 0
            cls[i] = 0
            if realistic:
                part[i] = 0
                range_m[i] = np.inf
        else:
            depth[i] = r * forward[i]
    return depth


@njit(cache=True, nogil=True)
def _set_lit(
    lit: npt.NDArray[np.bool_], at: npt.NDArray[np.int64], occluded: npt.NDArray[np.bool_]
) -> None:  # pragma: no cover - compiled
    """``lit[at] = ~occluded``."""
    for j in range(at.shape[0]):
        lit[at[j]] = not occluded[j]


def boxes_in_view(agents: Agents, instance_id: npt.NDArray[np.uint32]) -> AgentBoxes:
    """The boxes of the agents seen in the frame (their contact shadows and lower parts)."""
    seen = ids_seen(np.ascontiguousarray(instance_id, np.uint32).ravel(), np.asarray(agents.instance_id, np.uint32))
    a = agents.select(seen)
    return AgentBoxes(a.instance_id, a.center_map_m, a.lwh_m, a.yaw_map_rad, a.lamps, a.velocity_map_mps)


DEPTH_PNG_MAX_UNITS = 65535


def depth_to_uint16(depth_m: npt.NDArray[np.floating], units_per_m: float = 1000.0) -> npt.NDArray[np.uint16]:
    """``(H, W) uint16`` depth in ``1 / units_per_m`` metres (millimetres by default); 0 where
    there is no depth or it does not fit (beyond 65.535 m in millimetres)."""
    depth = np.asarray(depth_m)
    exact_in_float32 = depth.dtype == np.float32 and math.frexp(units_per_m)[0] == 0.5  # a power of two
    if depth.dtype not in (np.float32, np.float64):
        depth = depth.astype(np.float64)
    flat = np.ascontiguousarray(depth).ravel()
    return depth_units(flat, float(units_per_m), exact_in_float32, float(DEPTH_PNG_MAX_UNITS)).reshape(depth.shape)


def encode_depth_png(depth_m: npt.NDArray[np.floating], units_per_m: float = 1000.0, filter_up: bool = False) -> bytes:
    """16-bit PNG bytes of :func:`depth_to_uint16`, zlib level 1 (optionally the UP filter)."""
    params = [cv2.IMWRITE_PNG_COMPRESSION, 1]
    if filter_up:
        params += [cv2.IMWRITE_PNG_FILTER, cv2.IMWRITE_PNG_FILTER_UP]
    ok, buf = cv2.imencode(".png", depth_to_uint16(depth_m, units_per_m), params)
    if not ok:
        raise SensorError("depth PNG encoding failed")
    return bytes(buf)

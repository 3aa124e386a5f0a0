"""Shading: the camera's colour image, made from what its rays hit.

Albedo per class (vehicles painted by instance id) times Lambert lighting from a fixed sun
plus ambient (plus headlights at night), blended into haze with distance; misses show a sky
gradient. No shadows, no textures.

Shading is a step of its own: a :class:`CameraFrame` carries the
:class:`Shading` it is made from (normals per pixel, the camera's orientation, the weather,
the seed of its noise), and :func:`shade_frame` makes the image where it is needed, in the
writer process, while the next frame's rays are cast.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np
import numpy.typing as npt

from networks.classes import SemanticClass
from networks.geometry import SE3
from networks.records import check_arrays
from networks.vocabulary import Lamp, SignKind
from sensors import shade_kernels
from sensors.hits import RayHits
from sensors.materials import ALBEDO_BGR_BY_CLASS, PAINTED_CLASSES, VEHICLE_PAINT_BGR
from sensors.photo import (
    LENS_BLUR_PX,
    READ_NOISE,
    STRIPE_PX,
    AgentBoxes,
    ShadedRays,
    Supersamples,
    bloom,
    finished_bytes,
    image_motion_px,
    lamp_rays,
    leafy_normals,
    motion_blur,
    radiance,
    rounded_normals,
    sky_light,
    tone_curve,
    vignette,
)
from sensors.pinhole import Pinhole
from sensors.rays import turned_directions
from sensors.weather import Weather, haze_fraction, image_noise, sky_bgr

LAMP_BGR = np.array([[40, 40, 255], [0, 200, 255], [90, 255, 60]], np.float32)  # red, yellow, green: lit
UNLIT_LAMP_BGR = np.array([35, 35, 35], np.float32)
LAMP_UP_M = np.array([0.3, 0.0, -0.3], np.float32)  # each lamp's centre above the housing's centre
LAMP_RADIUS_M = 0.11
LIT_LAMPS = {Lamp.RED: (0,), Lamp.YELLOW: (1,), Lamp.GREEN: (2,), Lamp.RED_YELLOW: (0, 1), Lamp.OFF: ()}
# Sign faces (Vienna Convention colours, BGR 0..1): the field, the rim and the rim's width in metres.
SIGN_FACES = {
    SignKind.STOP: ((0.12, 0.1, 0.75), (0.9, 0.9, 0.9), 0.03),
    SignKind.YIELD: ((0.9, 0.9, 0.9), (0.12, 0.1, 0.75), 0.1),
    SignKind.SPEED_LIMIT: ((0.9, 0.9, 0.9), (0.12, 0.1, 0.75), 0.07),
}
SIGN_KINDS = tuple(SIGN_FACES)


@dataclass(frozen=True, slots=True)
class StreetFaces:
    """Signal heads and sign plates the camera may see, whose fronts it draws: a head's lamps
    (lit ones emissive, in their colour, by day and night), a sign's coloured field and rim.
    Per object: ``instance_id: (K,) uint32``; the ``centre_cam``, the ``front_cam`` (towards
    the traffic) and ``up_cam`` axes, ``(K, 3) float32`` in the camera's optical frame;
    ``size_m: (K, 3) float32`` depth, width, height; ``lit: (K, 3) bool`` the lit lamps (red,
    yellow, green) of a head; ``sign: (K,) int8`` the index of a sign's kind in
    :data:`SIGN_KINDS` (-1: a signal head)."""

    instance_id: npt.NDArray[np.uint32]
    centre_cam: npt.NDArray[np.float32]
    front_cam: npt.NDArray[np.float32]
    up_cam: npt.NDArray[np.float32]
    size_m: npt.NDArray[np.float32]
    lit: npt.NDArray[np.bool_]
    sign: npt.NDArray[np.int8]

    def __post_init__(self) -> None:
        check_arrays(self, instance_id=(np.uint32, ("K",)), centre_cam=(np.float32, ("K", 3)),
                     front_cam=(np.float32, ("K", 3)), up_cam=(np.float32, ("K", 3)),
                     size_m=(np.float32, ("K", 3)), lit=(np.bool_, ("K", 3)), sign=(np.int8, ("K",)))  # fmt: skip

    def paint(self, image: npt.NDArray[np.uint8], points_cam: npt.NDArray[np.float32],
              instance_id: npt.NDArray[np.uint32], pixels: npt.NDArray[np.intp], exposure: float) -> None:  # fmt: skip
        """Draw the fronts into ``image`` (``(H * W, 3)``, shaded) at ``pixels``, the objects'
        pixels, whose surface points are ``points_cam`` and ids ``instance_id``."""
        if len(self.instance_id) == 0 or len(pixels) == 0:
            return
        order = np.argsort(self.instance_id)
        pos = np.minimum(np.searchsorted(self.instance_id[order], instance_id), len(order) - 1)
        found = self.instance_id[order][pos] == instance_id
        k, at = order[pos[found]], pixels[found]
        d = points_cam[found] - self.centre_cam[k]
        forward = np.einsum("ij,ij->i", d, self.front_cam[k])
        up = np.einsum("ij,ij->i", d, self.up_cam[k])
        side = np.sqrt(np.maximum(np.einsum("ij,ij->i", d, d) - forward**2 - up**2, 0.0))
        front = forward > self.size_m[k, 0] / 2 - np.float32(0.02)
        head = self.sign[k] < 0
        for lamp in range(3):
            inside = head & front & (side**2 + (up - LAMP_UP_M[lamp]) ** 2 < np.float32(LAMP_RADIUS_M**2))
            lit = inside & self.lit[k, lamp]
            image[at[inside & ~lit]] = to_uint8(UNLIT_LAMP_BGR[None, :] * np.float32(exposure))
            image[at[lit]] = to_uint8(LAMP_BGR[lamp][None, :])
        grey = ALBEDO_BGR_BY_CLASS[int(SemanticClass.TRAFFIC_SIGN)]
        for kind, (field, rim, rim_m) in enumerate(SIGN_FACES.values()):
            mine = front & (self.sign[k] == kind)
            edge = np.maximum(side - self.size_m[k, 1] / 2 + rim_m, np.abs(up) - self.size_m[k, 2] / 2 + rim_m) > 0
            for colour, where in ((field, mine & ~edge), (rim, mine & edge)):
                ratio = np.asarray(colour, np.float32) / grey  # the shaded grey plate, recoloured
                image[at[where]] = to_uint8(image[at[where]].astype(np.float32) * ratio[None, :])


def street_faces(
    instance_id: npt.NDArray[np.uint32],
    centre_map_m: npt.NDArray[np.float64],
    yaw_map_rad: npt.NDArray[np.float64],
    lwh_m: npt.NDArray[np.float64],
    shows: Sequence[Lamp | SignKind],
    cam_SE3_map: SE3,
) -> StreetFaces:
    """The heads and plates handed over in the map frame (``(K,)`` ids, ``(K, 3)`` centres,
    ``(K,)`` yaws of their fronts, ``(K, 3)`` sizes; what each shows: a head its lamp, a
    plate its sign's kind) as one camera draws them, in its optical frame."""
    k = len(shows)
    lit = np.zeros((k, 3), np.bool_)
    sign = np.full(k, -1, np.int8)
    for n, what in enumerate(shows):
        if isinstance(what, Lamp):
            lit[n, list(LIT_LAMPS[what])] = True
        else:
            sign[n] = SIGN_KINDS.index(what)
    front_map = np.column_stack([np.cos(yaw_map_rad), np.sin(yaw_map_rad), np.zeros_like(yaw_map_rad)])
    r = cam_SE3_map.rotation
    centre = cam_SE3_map.transform_from(centre_map_m).astype(np.float32)
    up = np.tile(r[:, 2], (k, 1)).astype(np.float32)  # the map's z axis in the camera frame
    front = (front_map @ r.T).astype(np.float32)
    return StreetFaces(instance_id, centre, front, up, lwh_m.astype(np.float32), lit, sign)


@dataclass(frozen=True, slots=True)
class Shading:
    """What a frame's image is made from: ``normal: (H * W, 3) float32`` the surface normal
    per pixel (map frame, row-major), ``map_R_cam: (3, 3) float32`` the camera's orientation,
    the camera model, its range, the weather and the seed of the image noise (None: no noise)."""

    pinhole: Pinhole
    range_m: float
    map_R_cam: npt.NDArray[np.float32]
    normal: npt.NDArray[np.float32]
    weather: Weather
    noise_seed: int | None
    faces: StreetFaces | None = None  # signal heads and signs whose fronts it draws (None: none in view)
    # the realistic style's inputs (None: the flat style): the part per pixel, the camera's
    # position, the sun's visibility per pixel, the boxes of agents in view, sub-pixel rays
    part: npt.NDArray[np.uint8] | None = None
    origin_map_m: npt.NDArray[np.float64] | None = None
    sun_lit: npt.NDArray[np.bool_] | None = None
    boxes: AgentBoxes | None = None
    extra: Supersamples | None = None
    shutter_s: float = 0.0  # motion blur over the exposure (0: none), from the ego's and the agents' motion
    ego_velocity_map_mps: npt.NDArray[np.float64] | None = None

    def __post_init__(self) -> None:
        pixels = self.pinhole.width_px * self.pinhole.height_px
        check_arrays(self, map_R_cam=(np.float32, (3, 3)), normal=(np.float32, (pixels, 3)))


@dataclass(frozen=True, slots=True)
class CameraFrame:
    """One rendered frame: ``depth_m: (H, W) float32`` z-depth along the optical axis (0: no
    hit within range), ``instance_id: (H, W) uint32`` (0: static world or nothing),
    ``semantic_class: (H, W) uint8`` (0: nothing), and what its colour image is shaded from
    (:func:`shade_frame`)."""

    depth_m: npt.NDArray[np.float32]
    instance_id: npt.NDArray[np.uint32]
    semantic_class: npt.NDArray[np.uint8]
    shading: Shading

    def __post_init__(self) -> None:
        check_arrays(self, depth_m=(np.float32, ("H", "W")), instance_id=(np.uint32, ("H", "W")),
                     semantic_class=(np.uint8, ("H", "W")))  # fmt: skip

    @property
    def hit(self) -> npt.NDArray[np.bool_]:
        return self.depth_m > 0


def shade_frame(frame: CameraFrame) -> npt.NDArray[np.uint8]:
    """The shaded ``(H, W, 3) uint8`` image of a rendered frame (see :class:`Shading`):
    realistic (:func:`shade_photo`, with :mod:`sensors.photo`) or flat."""
    sh = frame.shading
    if sh.part is not None:
        return shade_photo(frame)
    dirs_cam = sh.pinhole.image_directions()
    depth = frame.depth_m.ravel()
    hit = depth > 0
    range_m = depth / dirs_cam[:, 2]
    dirs_map = turned_directions(sh.map_R_cam, dirs_cam)
    classes, instances = frame.semantic_class.ravel(), frame.instance_id.ravel()
    noise = None if sh.noise_seed is None else image_noise(sh.weather, np.random.default_rng(sh.noise_seed), len(depth))
    image = np.empty((len(depth), 3), np.uint8)
    for start in range(0, len(depth), STRIPE_PX):
        part = slice(start, start + STRIPE_PX)
        stripe = RayHits(
            range_m[part], classes[part], instances[part], sh.normal[part], FLAT_PARTS[: len(classes[part])]
        )
        shaded = shade(stripe, dirs_map[part], hit[part], dirs_cam[part, 2], sh.weather, sh.range_m)
        if noise is not None:
            shaded += noise[part, None]
        image[part] = to_uint8(shaded)
    if sh.faces is not None:
        street = (classes == SemanticClass.TRAFFIC_LIGHT) | (classes == SemanticClass.TRAFFIC_SIGN)
        pixels = np.flatnonzero(street & hit)
        points = dirs_cam[pixels] * range_m[pixels, None]
        sh.faces.paint(image, points, instances[pixels], pixels, sh.weather.exposure)
    return image.reshape(*frame.depth_m.shape, 3)


def shade_photo(frame: CameraFrame) -> npt.NDArray[np.uint8]:
    """The realistic ``(H, W, 3) uint8`` image of a rendered frame (materials, light and the
    camera's optics as :mod:`sensors.photo` models them)."""
    sh = frame.shading
    assert sh.part is not None and sh.origin_map_m is not None and sh.sun_lit is not None
    h, w = frame.depth_m.shape
    dirs_cam = sh.pinhole.image_directions()
    depth = frame.depth_m.ravel()
    range_m = shade_kernels.ray_range(depth, dirs_cam)
    dirs_map = turned_directions(sh.map_R_cam, dirs_cam)
    classes, instances = frame.semantic_class.ravel(), frame.instance_id.ravel()
    normal = rounded_normals(sh.normal, dirs_map, frame.instance_id, frame.depth_m, sh.pinhole.focal_px)
    normal = leafy_normals(normal, classes, dirs_map, range_m, sh.origin_map_m)
    sky_open = sky_light(dirs_map, range_m, classes, instances, sh.origin_map_m, sh.boxes)
    lamp = lamp_rays(dirs_map, range_m, instances, sh.part, sh.origin_map_m, sh.boxes, sh.weather, classes)
    linear = radiance(
        ShadedRays(dirs_map, range_m, classes, instances, sh.part, normal, sh.sun_lit, dirs_cam[:, 2], sky_open, lamp),
        sh.origin_map_m,
        sh.weather,
        sh.range_m,
        sh.boxes,
    )
    extra = sh.extra
    if extra is not None and len(extra.pixel):
        sub = len(extra.range_m) // len(extra.pixel)
        sub_dirs = turned_directions(sh.map_R_cam, extra.dirs_cam)
        sub_open = sky_light(
            sub_dirs, extra.range_m, extra.semantic_class, extra.instance_id, sh.origin_map_m, sh.boxes
        )
        sub_lamp = lamp_rays(
            sub_dirs, extra.range_m, extra.instance_id, extra.part, sh.origin_map_m, sh.boxes, sh.weather,
            extra.semantic_class,
        )  # fmt: skip
        sub_normal = leafy_normals(extra.normal.copy(), extra.semantic_class, sub_dirs, extra.range_m, sh.origin_map_m)
        sub_rays = ShadedRays(sub_dirs, extra.range_m, extra.semantic_class, extra.instance_id, extra.part,
                              sub_normal, extra.sun_lit, extra.dirs_cam[:, 2], sub_open, sub_lamp)  # fmt: skip
        sub_lin = radiance(sub_rays, sh.origin_map_m, sh.weather, sh.range_m, sh.boxes)
        shade_kernels.add_subsamples(linear, np.asarray(extra.pixel, np.int64), sub_lin, sub)
    if sh.shutter_s > 0 and sh.ego_velocity_map_mps is not None:
        motion = image_motion_px(
            sh.pinhole, dirs_cam, range_m, instances, sh.map_R_cam, sh.boxes, sh.ego_velocity_map_mps, sh.shutter_s
        )
        linear = motion_blur(linear.reshape(h, w, 3), motion.reshape(h, w, 2)).reshape(-1, 3)
    lens = np.asarray(cv2.GaussianBlur(linear.reshape(h, w, 3), (0, 0), LENS_BLUR_PX), np.float32)
    curve = tone_curve(bloom(lens).reshape(-1, 3), sh.weather.exposure, vignette(h, w))
    seed = sh.noise_seed if sh.noise_seed is not None else (int(instances.sum()) + h * w)
    sigma = np.float32(np.hypot(READ_NOISE, sh.weather.noise_sigma))
    out = finished_bytes(curve, sh.weather.saturation, seed, sigma)  # auto levels, noise (numpy's default_rng(seed))
    if sh.faces is not None:
        light, sign = int(SemanticClass.TRAFFIC_LIGHT), int(SemanticClass.TRAFFIC_SIGN)
        pixels = shade_kernels.street_pixels(classes, depth, light, sign)
        points = dirs_cam[pixels] * range_m[pixels, None]
        sh.faces.paint(out, points, instances[pixels], pixels, sh.weather.exposure)
    return out.reshape(h, w, 3)


FLAT_PARTS = np.zeros(STRIPE_PX, np.uint8)
"""The flat style colours by class: every pixel's part is the surface's."""


def to_uint8(image: npt.NDArray[np.float32]) -> npt.NDArray[np.uint8]:
    return np.asarray(np.clip(image + np.float32(0.5), 0.0, 255.0).astype(np.uint8))


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
    sun_cos = normal @ (sun / np.linalg.norm(sun))
    np.negative(sun_cos, out=sun_cos, where=facing > 0)  # the lit side is the one the ray sees
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
    f = haze_fraction(weather, hits.range_m, range_m)
    # lit albedo blended into haze in one pass: albedo * 255 * exposure * light * (1 - f) + haze * f
    image = surface_albedo(hits.semantic_class, hits.instance_id)
    image *= (np.float32(255.0 * weather.exposure) * light * (np.float32(1.0) - f))[:, None]
    image += f[:, None] * (np.asarray(weather.haze_bgr, np.float32) * np.float32(weather.exposure))
    miss = np.flatnonzero(~hit)
    image[miss] = sky_bgr(weather, dirs_map[miss, 2]) * np.float32(weather.exposure)
    return image

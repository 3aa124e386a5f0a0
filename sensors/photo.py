"""The realistic camera image: materials per part, sun and sky light with shadows, textures,
reflections, lamps, anti-aliased edges, exposure, a filmic tone curve, the camera's auto
contrast and colour saturation, vignetting and noise.

Light is computed in linear units and tone-mapped at the end. Per sample (a pixel's centre ray,
plus four sub-pixel rays where the pixel holds an edge):

- albedo: the static world's by class with procedural textures (:mod:`sensors.textures`);
  agents' by part (:mod:`sensors.parts`: paint in real-world colour frequencies, dark glass,
  rubber, chrome, lamps, skin, cloth);
- sky light from above, darkened near and under vehicles (contact shadows from their boxes)
  and at their lower parts; the sun through a shadow ray cast by the camera
  (:attr:`Shading.sun_lit`); a Blinn-Phong highlight; the sky and the ground reflected by
  paint and glass with Schlick's Fresnel term;
- emission: head and tail lamps (bright at night), lit windows at night, street light;
- haze with distance, a sky with clouds where nothing is hit.

The labels never come from here: masks, depth and boxes use the centre rays only.
:func:`sensors.shading.shade_photo` makes the image with these functions.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from networks.classes import SemanticClass
from networks.records import check_arrays
from sensors import shade_kernels as kernels
from sensors import textures
from sensors.agents import rows_of_ids
from sensors.materials import ALBEDO_BGR_BY_CLASS
from sensors.parts import (
    ALBEDO_BGR_BY_PART,
    EMISSIVE_BY_PART,
    MIRROR_BY_PART,
    PALETTE_SALT,
    PALETTES,
    SHININESS_BY_PART,
    SPECULAR_BY_PART,
    Part,
)
from sensors.pinhole import Pinhole
from sensors.weather import Weather

F32 = npt.NDArray[np.float32]
F64 = npt.NDArray[np.float64]
GAMMA = np.float32(2.2)
EXPOSURE_SCALE = np.float32(1.8)
"""Linear scene light to the tone curve's input: a sunlit mid-grey road lands near 105 of 255."""
VIGNETTE = np.float32(0.28)
"""Light lost at the image's corners (cos^4-like falloff of a real lens)."""
LENS_BLUR_PX = 0.65
"""The optics' and demosaicing's blur (Gaussian sigma, pixels) before the sensor's noise: a
real camera does not resolve single pixels. Measured on KITTI's colour images: the ratio of
second to first derivative across the strongest edges (0.116) lies between our images blurred
by 0.5 px (0.185) and by 0.8 px (0.089); unblurred 0.262."""
READ_NOISE = 1.2
"""Sensor noise (0..255) of every image, on top of the weather's."""
BLACK_PERCENTILE = 2.0
"""The camera's auto contrast: the frame's darkest this many per cent (by grey level) are set
to black and the rest stretched over 0..255, as a camera's processing sets its black level
from the frame. Without it our frames' darkest 5 % sat at 37-74 of 255 (real KITTI frames:
9-10): a veil of ambient and sky light over everything."""
BLACK_TOE = 8.0
"""The grey level the frame's black level is set to, the darker greys kept in order below it: a
camera's black is never one flat level (real KITTI frames' darkest 1 % sit at 7-9; setting the
darkest 2 % to 0 flattened 1.4-2.8 % of our frames, dark cars' shaded sides, tyres and windows,
into one black)."""
MAX_REFLECTION = 0.45
"""The most of the surroundings a surface mirrors, even at grazing angles (clear coat and
glass are not perfect mirrors: dirt, curvature and roughness blur and dim what they show)."""
WET_MIN_UP = np.float32(0.5)
"""Water lies on paved surfaces facing up (the normal towards the camera's side with z at least
this): a bridge deck's underside and sides, classed road, stay dry."""
CONTACT_M = 0.45
"""How far from a vehicle's footprint its contact shadow fades out."""
STREET_LIGHT = np.float32(0.18)
"""Light from street lamps at night (of the sun's 2.2 by day), on surfaces facing up most."""
STREET_LIGHT_FADE_M = 60.0
STREET_LIGHT_BGR = np.array([0.55, 0.8, 1.0], np.float32)
"""Warm white (LED and sodium street lamps)."""


@dataclass(frozen=True, slots=True)
class AgentBoxes:
    """Boxes of the agents in view (map frame): ``instance_id (K,) uint32``, ``centre_m
    (K, 3) float64``, ``lwh_m (K, 3) float64``, ``yaw_rad (K,) float64``: their contact shadows
    on the ground and the darker lower parts; ``lamps (K,) uint8``: which lamps are lit
    (:class:`sensors.agents.Lamp` bits); ``velocity_mps (K, 3) float64`` (map frame): their
    motion blur."""

    instance_id: npt.NDArray[np.uint32]
    centre_m: npt.NDArray[np.float64]
    lwh_m: npt.NDArray[np.float64]
    yaw_rad: npt.NDArray[np.float64]
    lamps: npt.NDArray[np.uint8]
    velocity_mps: npt.NDArray[np.float64]

    def __post_init__(self) -> None:
        check_arrays(
            self,
            instance_id=(np.uint32, ("K",)),
            centre_m=(np.float64, ("K", 3)),
            lwh_m=(np.float64, ("K", 3)),
            yaw_rad=(np.float64, ("K",)),
            lamps=(np.uint8, ("K",)),
            velocity_mps=(np.float64, ("K", 3)),
        )

    def rows_of(self, instance: npt.NDArray[np.uint32]) -> npt.NDArray[np.intp]:
        """Each given instance's row here (-1 where it has none)."""
        return rows_of_ids(self.instance_id, instance)


@dataclass(frozen=True, slots=True)
class Supersamples:
    """Extra rays at the pixels holding an edge: ``pixel (K,) int64`` (row-major index),
    per sub-ray ``(K * S,)`` arrays (sub-rays of a pixel together): unit directions in the
    camera's optical frame ``dirs_cam (K * S, 3)``, range, class, instance, part, normal (map
    frame) and the sun's visibility; a sub-ray with nothing within the camera's range is a miss,
    as a centre ray is (range inf; class, instance and part 0)."""

    pixel: npt.NDArray[np.int64]
    dirs_cam: F32
    range_m: F32
    semantic_class: npt.NDArray[np.uint8]
    instance_id: npt.NDArray[np.uint32]
    part: npt.NDArray[np.uint8]
    normal: F32
    sun_lit: npt.NDArray[np.bool_]


@dataclass(frozen=True, slots=True)
class ShadedRays:
    """What :func:`radiance` shades, one row per ray: unit directions ``dirs_map (N, 3)`` (map
    frame), ``range_m (N,)`` (inf: nothing hit), class, instance, part, ``normal (N, 3)`` (map
    frame), ``sun_lit (N,)``, ``forward (N,)`` (the ray's cosine to the optical axis),
    ``sky_open (N,)`` (the share of sky light reaching each hit, :func:`contact_light`) and
    ``lamp (N,)`` (the light its lamp sends out, :func:`lamp_light`)."""

    dirs_map: F32
    range_m: F32
    cls: npt.NDArray[np.uint8]
    instance: npt.NDArray[np.uint32]
    part: npt.NDArray[np.uint8]
    normal: F32
    sun_lit: npt.NDArray[np.bool_]
    forward: F32
    sky_open: F32
    lamp: F32

    def rows(self, s: slice) -> ShadedRays:
        """The rays in ``s`` (views, no copies)."""
        return ShadedRays(*(getattr(self, name)[s] for name in self.__dataclass_fields__))


SUBPIXEL_OFFSETS = np.array([[-0.25, -0.25], [0.25, -0.25], [-0.25, 0.25], [0.25, 0.25]], np.float64)
"""Sub-ray offsets in pixels (a 2x2 grid) at edge pixels."""


def to_linear(bgr_255: tuple[float, float, float] | F32) -> F32:
    return np.asarray((np.asarray(bgr_255, np.float32) / np.float32(255.0)) ** GAMMA, np.float32)


def sky_linear(weather: Weather, dirs: F32) -> F32:
    """``(N, 3)`` sky radiance (linear) along unit map-frame ``dirs``, with clouds."""
    horizon, zenith = to_linear(weather.sky_horizon_bgr), to_linear(weather.sky_zenith_bgr)
    return kernels.sky(np.ascontiguousarray(dirs, np.float32), horizon, zenith, _CLOUD_SEEDS, np.float32(1.875))


def sky_linear_at(weather: Weather, dirs: F32, rows: npt.NDArray[np.int64], out: F32) -> None:
    """``out[rows] = sky_linear(weather, dirs[rows])`` in place (``dirs`` and ``out`` ``(N, 3)``
    float32, contiguous)."""
    horizon, zenith = to_linear(weather.sky_horizon_bgr), to_linear(weather.sky_zenith_bgr)
    kernels.sky_rows(dirs, rows, horizon, zenith, _CLOUD_SEEDS, np.float32(1.875), out)


_CLOUD_SEEDS = np.array([textures._seed32(61 + o) for o in range(4)], np.uint64)
"""The clouds' four octaves of :func:`sensors.textures.fbm` (seed 61, as :func:`sensors.textures.clouds`)."""


def _part_linear() -> tuple[F32, F32, npt.NDArray[np.int64], npt.NDArray[np.int64], npt.NDArray[np.uint64]]:
    """:func:`sensors.parts.part_albedo`'s tables in linear units (each colour to the power
    :data:`GAMMA`, as numpy raises the picked colours) for :func:`sensors.shade_kernels.part_rows`:
    the colour by part, the palettes one after another, each part's first row and size in them
    (size 0: no palette) and its salt."""
    first, size = np.zeros(256, np.int64), np.zeros(256, np.int64)
    salt = np.zeros(256, np.uint64)
    at = 0
    for part, palette in PALETTES.items():
        first[part], size[part], salt[part] = at, len(palette), PALETTE_SALT[part]
        at += len(palette)
    palettes = np.concatenate(list(PALETTES.values())).astype(np.float32)
    return ALBEDO_BGR_BY_PART**GAMMA, palettes**GAMMA, first, size, salt


_PART_LINEAR = _part_linear()


_GROUND = {
    int(SemanticClass.ROAD),
    int(SemanticClass.PARKING),
    int(SemanticClass.CROSSING),
    int(SemanticClass.SIDEWALK),
    int(SemanticClass.CURB),
    int(SemanticClass.TERRAIN),
    int(SemanticClass.LANE_MARKING),
    int(SemanticClass.LANE_MARKING_YELLOW),
}
_IS_GROUND = np.zeros(256, np.bool_)
_IS_GROUND[list(_GROUND)] = True
_IS_PAVED = _IS_GROUND.copy()
_IS_PAVED[int(SemanticClass.TERRAIN)] = False


def static_albedo(cls: npt.NDArray[np.uint8], points: F32, normal: F32) -> tuple[F32, F32, F32]:
    """Linear albedo ``(N, 3)`` of static-world surfaces with their textures, their mirror
    strength ``(N,)`` and emission at night ``(N,)`` (lit windows)."""
    albedo = kernels.rows_taken(ALBEDO_BGR_BY_CLASS, cls)  # a new array, np.take(ALBEDO_BGR_BY_CLASS, cls, axis=0)
    mirror = np.zeros(len(cls), np.float32)
    glow = np.zeros(len(cls), np.float32)
    order, end = kernels.class_order(cls)  # each class's rows in order, as np.flatnonzero(cls == c)
    points = np.ascontiguousarray(points, np.float32)

    def rows_of(c: int) -> npt.NDArray[np.int64]:
        return np.asarray(order[end[c - 1] if c > 0 else 0 : end[c]], np.int64)

    for c, fn in (
        (SemanticClass.ROAD, textures.asphalt),
        (SemanticClass.PARKING, textures.asphalt),
        (SemanticClass.CROSSING, textures.asphalt),
        (SemanticClass.SIDEWALK, textures.paving),
        (SemanticClass.CURB, textures.kerb),
    ):
        at = rows_of(c)
        if len(at):
            kernels.scale_rows(albedo, at, np.ascontiguousarray(fn(kernels.rows_taken(points, at)), np.float32))
    normal = np.ascontiguousarray(normal, np.float32)
    at = rows_of(SemanticClass.VEGETATION)
    if len(at):
        leaves = textures.foliage(kernels.rows_taken(points, at), kernels.rows_taken(normal, at), 71)
        kernels.scale_rows(albedo, at, np.ascontiguousarray(leaves, np.float32))
    at = rows_of(SemanticClass.TERRAIN)
    if len(at):
        kernels.tint_rows(albedo, at, textures.grass(kernels.rows_taken(points, at), 73))
    at = rows_of(SemanticClass.TRUNK)
    if len(at):
        kernels.scale_rows(albedo, at, np.ascontiguousarray(textures.bark(kernels.rows_taken(points, at)), np.float32))
    for c in (SemanticClass.LANE_MARKING, SemanticClass.LANE_MARKING_YELLOW):
        at = rows_of(c)
        if len(at):
            p = kernels.rows_taken(points, at)
            wear = textures.fbm(p[:, 0] * 2, p[:, 1] * 2, 81, 2)
            kernels.scale_rows(albedo, at, np.asarray(np.float32(0.6) + np.float32(0.45) * wear, np.float32))
    at = rows_of(SemanticClass.BUILDING)
    if len(at):
        facing = kernels.rows_taken(normal, at)
        wall, glass, lit = textures.facade(kernels.rows_taken(points, at), facing)
        kernels.facade_rows(albedo, mirror, glow, at, wall, glass, lit, np.float32(0.35))
    np.clip(albedo, 0.0, 1.0, out=albedo)
    return np.power(albedo, GAMMA, out=albedo), mirror, glow


def contact_light(
    points: F32, cls: npt.NDArray[np.uint8], instance: npt.NDArray[np.uint32], boxes: AgentBoxes | None
) -> F32:
    """``(N,)`` share of sky light reaching each point: less on the ground near and under
    vehicles and people (their contact shadows) and on agents' own lowest parts."""
    points = np.ascontiguousarray(points, np.float32)
    return sky_light(points, np.ones(len(cls), np.float32), cls, instance, np.zeros(3), boxes)


def sky_light(
    dirs_map: F32,
    range_m: F32,
    cls: npt.NDArray[np.uint8],
    instance: npt.NDArray[np.uint32],
    origin_map_m: npt.NDArray[np.float64],
    boxes: AgentBoxes | None,
) -> F32:
    """``(N,)`` share of sky light at each ray's hit (``origin_map_m + dirs_map * range_m``; 1
    for misses): :func:`contact_light` over a whole frame at once, the hit points made on the fly."""
    light = np.ones(len(cls), np.float32)
    if boxes is None or len(boxes.instance_id) == 0:
        return light
    dirs = np.ascontiguousarray(dirs_map, np.float32)
    origin = np.asarray(origin_map_m).astype(np.float32)
    length, w = boxes.lwh_m[:, 0], boxes.lwh_m[:, 1]
    reach = np.array([0.5 * np.hypot(a, b) + CONTACT_M for a, b in zip(length, w, strict=True)], np.float64)
    cs = np.array([np.float32(np.cos(y)) for y in boxes.yaw_rad], np.float32)
    sn = np.array([np.float32(np.sin(y)) for y in boxes.yaw_rad], np.float32)
    near, k, ax, ay = kernels.contact_pairs(
        dirs, range_m, cls, instance, _IS_GROUND, origin, np.ascontiguousarray(boxes.centre_m[:, 0]),
        np.ascontiguousarray(boxes.centre_m[:, 1]), reach, cs, sn,
    )  # fmt: skip
    half_l, half_w = (length / 2).astype(np.float32)[k], (w / 2).astype(np.float32)[k]
    out = np.hypot(np.maximum(ax - half_l, 0), np.maximum(ay - half_w, 0))
    inside = np.minimum(half_l - ax, half_w - ay)
    depth = np.clip(inside / np.float32(0.6), 0.0, 1.0)  # darkest well under the body
    occ = np.where(
        out > 0,
        np.float32(0.6) * np.exp(-out / np.float32(CONTACT_M * 0.4)),
        np.float32(0.6) + np.float32(0.35) * depth,
    )
    kernels.minimum_at(light, near, np.asarray(np.float32(1.0) - occ, np.float32))
    order = np.argsort(boxes.instance_id)
    floor_z = (boxes.centre_m[:, 2] - boxes.lwh_m[:, 2] / 2).astype(np.float32)
    kernels.agents_low_light(light, dirs, range_m, instance, origin, boxes.instance_id[order], floor_z[order])
    return light


LAMP_BGR = np.zeros((256, 3), np.float32)
LAMP_BGR[Part.HEADLAMP] = (0.85, 0.93, 1.0)  # linear colours of the light lamps send out
LAMP_BGR[Part.TAIL_LAMP] = (0.02, 0.02, 1.0)
LAMP_BGR[Part.INDICATOR] = (0.0, 0.32, 1.0)
LAMP_BGR[Part.GLASS] = (0.75, 0.9, 1.0)  # a bus's lit interior seen through its windows
LAMP_BGR[Part.DISPLAY] = (0.0, 0.45, 1.0)
LAMP_BGR[Part.SIDE_MARKER] = (0.0, 0.4, 1.0)
LAMP_BGR[Part.FRONT_OUTLINE] = (0.85, 0.93, 1.0)
LAMP_BGR[Part.REAR_OUTLINE] = (0.02, 0.02, 1.0)
HEADLAMP_DAY, HEADLAMP_NIGHT = np.float32(0.5), np.float32(5.0)  # daytime running lamps; dipped beams
TAIL_NIGHT, BRAKE_DAY, BRAKE_NIGHT = np.float32(0.6), np.float32(1.8), np.float32(2.5)
INDICATOR_DAY, INDICATOR_NIGHT = np.float32(1.8), np.float32(2.5)
CABIN_NIGHT = np.float32(0.15)
"""A bus in service keeps its interior lit after dark: its windows glow (buses only; cars'
and trucks' cabins stay dark), the interior's layout in them (:func:`bus_cabin`)."""
CABIN_DRAWN_H_M = 3.1
"""The bus height the interior's layout is drawn for (a city bus's); taller or lower buses
have it scaled with their height."""
SEAT_PITCH_M, SEAT_TOP_M = 0.8, 1.32
"""Seat rows' spacing along the bus and the height of the seat backs' tops."""
SEATED_SHARE, STANDING_SHARE = 0.45, 0.12
"""Shares of window seats with a passenger and of standing places along the aisle with one."""
DISPLAY_DAY, DISPLAY_NIGHT = np.float32(0.6), np.float32(1.2)
"""A bus's destination display shines while its lights are on, bright enough to read by day."""
MARKER_NIGHT = np.float32(1.2)
"""Buses' and trucks' marker lamps (side markers, end-outline lamps) glow while their lights are
on: position lamps, dimmer than the tail lamps' brake light."""
_MARKERS = (Part.SIDE_MARKER, Part.FRONT_OUTLINE, Part.REAR_OUTLINE)


_EMITS_BY_PART = EMISSIVE_BY_PART > 0


def _emits(part: npt.NDArray[np.uint8], cls: npt.NDArray[np.uint8] | None, night: float) -> npt.NDArray[np.bool_]:
    """Hits that may send out light: lamps, and by night a bus's windows (where ``cls`` is given)."""
    emits = _EMITS_BY_PART[part]  # a new array
    if cls is not None and night > 0:
        emits |= (part == Part.GLASS) & (cls == SemanticClass.BUS)
    return np.asarray(emits, np.bool_)


def lamp_light(
    points: F32, instance: npt.NDArray[np.uint32], part: npt.NDArray[np.uint8], boxes: AgentBoxes | None,
    night: float, cls: npt.NDArray[np.uint8] | None = None,
) -> F32:  # fmt: skip
    """``(N,)`` light each hit on a vehicle's lamp sends out (times its colour,
    :data:`LAMP_BGR`), from its vehicle's :class:`sensors.agents.Lamp` bits: head and tail lamps when its lights are on
    (headlamps dimly by day), a bus's destination display and by night heavy vehicles' marker lamps, brake lamps by
    day and night, an indicator when its side flashes and is lit (left and right from the hit's side of its box); by
    night a bus's windows
    (:data:`CABIN_NIGHT`, where ``cls`` gives the hits' classes). Zero elsewhere."""
    from sensors.agents import Lamp

    gain = np.zeros(len(part), np.float32)
    at = np.flatnonzero(_emits(part, cls, night))
    if len(at) == 0:
        return gain
    if boxes is None:
        return gain
    rows = boxes.rows_of(instance[at])
    known = rows >= 0
    at, rows = at[known], rows[known]
    lamps, pt, nt = boxes.lamps[rows], part[at], np.float32(night)
    on = (lamps & Lamp.LIGHTS) > 0
    head = (pt == Part.HEADLAMP) & on
    gain[at[head]] += HEADLAMP_DAY + nt * HEADLAMP_NIGHT
    tail = pt == Part.TAIL_LAMP
    gain[at[tail & on]] += nt * TAIL_NIGHT
    cabin = at[(pt == Part.GLASS) & on]
    if len(cabin):
        gain[cabin] += nt * CABIN_NIGHT * bus_cabin(points[cabin], instance[cabin], boxes)
    gain[at[(pt == Part.DISPLAY) & on]] += DISPLAY_DAY + nt * DISPLAY_NIGHT
    gain[at[np.isin(pt, _MARKERS) & on]] += nt * MARKER_NIGHT
    gain[at[tail & ((lamps & Lamp.BRAKE) > 0)]] += BRAKE_DAY + nt * BRAKE_NIGHT
    ind = np.flatnonzero((pt == Part.INDICATOR) & ((lamps & Lamp.FLASH) > 0))
    if len(ind):
        across = _own_frame(points[at[ind]], instance[at[ind]], boxes)[3]  # every one has its box
        side = np.where(across > 0, int(Lamp.LEFT), int(Lamp.RIGHT))
        lit = ind[(lamps[ind] & side) > 0]
        gain[at[lit]] += INDICATOR_DAY + nt * INDICATOR_NIGHT
    return gain


def _own_frame(
    points: F32, instance: npt.NDArray[np.uint32], boxes: AgentBoxes
) -> tuple[npt.NDArray[np.bool_], npt.NDArray[np.intp], F64, F64, F64]:  # fmt: skip
    """Hits (map frame, on the agents ``instance``) in their agent's own frame: which have a box
    (``known``), its row, and per known hit its distance along the box's heading and across it
    (left) from the box's centre and its height above the box's bottom (m, float64)."""
    rows = boxes.rows_of(instance)
    known = rows >= 0
    r = rows[known]
    yaw = boxes.yaw_rad[r]
    rel = points[known].astype(np.float64) - boxes.centre_m[r]
    along = rel[:, 0] * np.cos(yaw) + rel[:, 1] * np.sin(yaw)
    across = -rel[:, 0] * np.sin(yaw) + rel[:, 1] * np.cos(yaw)
    return known, r, along, across, rel[:, 2] + boxes.lwh_m[r, 2] / 2


def bus_cabin(points: F32, instance: npt.NDArray[np.uint32], boxes: AgentBoxes) -> F32:
    """``(N,)`` how bright a lit bus's interior shows through its windows at each hit (map frame,
    on the buses ``instance``): brighter towards the ceiling's lights, the seat backs' rows dark
    below :data:`SEAT_TOP_M` with the lit aisle between them, seated passengers' heads and
    shoulders and standing passengers dark against the light. Drawn in the bus's own frame
    (along its side; across its front and rear windows), so the same passengers ride in the same
    seats in every frame, and a different set in each bus. 1 for hits off any known bus."""
    out = np.ones(len(points), np.float32)
    known, r, along, across, up = _own_frame(points, instance, boxes)
    if not known.any():
        return out
    lwh = boxes.lwh_m[r]
    z = up * (CABIN_DRAWN_H_M / lwh[:, 2])  # up from the box's floor, on the drawn bus
    end = np.abs(across) < 0.4 * lwh[:, 1]  # the windscreen and the rear window
    s = np.where(end, across, along)
    side = np.where(end, np.where(along > 0, 2, 3), np.where(across > 0, 0, 1)).astype(np.int64)
    bus_id = instance[known].astype(np.int64)
    seat_row = np.floor(s / SEAT_PITCH_M).astype(np.int64)
    u = (s / SEAT_PITCH_M - seat_row - 0.3) * SEAT_PITCH_M  # from the seat's middle, m
    glow = np.clip(0.75 + 0.5 * (z - SEAT_TOP_M), 0.6, 1.35)
    light = np.where(z < SEAT_TOP_M, np.where(np.abs(u) < 0.25, 0.2, 0.55), glow)
    seated = textures.hash01(bus_id * 8 + side, seat_row, 41) < SEATED_SHARE
    head = ((u / 0.11) ** 2 + ((z - 1.52) / 0.13) ** 2 < 1.0) | ((np.abs(u) < 0.2) & (z >= 1.28) & (z < 1.42))
    place = np.floor(s / 0.6).astype(np.int64)
    v = (s / 0.6 - place - 0.5) * 0.6
    standing = ~end & (textures.hash01(bus_id * 8 + side, place, 43) < STANDING_SHARE)
    stood = ((np.abs(v) < 0.18) & (z < 1.9)) | ((v / 0.1) ** 2 + ((z - 2.0) / 0.12) ** 2 < 1.0)
    out[known] = np.where((seated & head) | (standing & stood), 0.12, light)
    return out


def lamp_rays(
    dirs_map: F32, range_m: F32, instance: npt.NDArray[np.uint32], part: npt.NDArray[np.uint8],
    origin_map_m: npt.NDArray[np.float64], boxes: AgentBoxes | None, weather: Weather,
    cls: npt.NDArray[np.uint8] | None = None,
) -> F32:  # fmt: skip
    """``(N,)`` :func:`lamp_light` at each ray's hit (0 for misses) over a whole frame."""
    out = np.zeros(len(part), np.float32)
    night = night_of(weather)
    at = kernels.emitting_rows(
        range_m, part, part if cls is None else cls, _EMITS_BY_PART, cls is not None and night > 0,
        int(Part.GLASS), int(SemanticClass.BUS),
    )  # fmt: skip  # the rows _emits picks, with a finite range
    points = kernels.hit_points(at, dirs_map, range_m, origin_map_m.astype(np.float32))
    out[at] = lamp_light(points, instance[at], part[at], boxes, night, None if cls is None else cls[at])
    return out


def night_of(weather: Weather) -> float:
    """0 by day, 1 by night: how much lamps and street lights count."""
    return float(1.0 - np.clip(weather.sun_gain / 0.3, 0.0, 1.0))


PLATE_CHAR_M = 0.062
"""A number plate's character pitch (eight characters on a 520 mm European plate)."""


def plate_ink(points: F32, instance: npt.NDArray[np.uint32], boxes: AgentBoxes) -> npt.NDArray[np.bool_]:
    """``(N,)`` whether each hit on a number plate (map frame, on the agents ``instance``) falls on
    a character's dark ink: marks inside character cells across the plate, spaces between them,
    fixed to the vehicle (placed in its own frame, across and up) and different from one vehicle
    to the next, so a plate reads the same in every frame of its track."""
    out = np.zeros(len(points), np.bool_)
    known, _, _, across, up = _own_frame(points, instance, boxes)
    if not known.any():
        return out
    cell = (across / PLATE_CHAR_M) % 1.0
    shift = (instance[known] % 251).astype(np.float64) * 3.7  # each vehicle's own characters
    marks = textures.value_noise(
        (across * 40.0 + shift).astype(np.float32), (up * 30.0).astype(np.float32), 91
    )  # fmt: skip
    out[known] = (cell > 0.14) & (cell < 0.86) & (marks > np.float32(0.5))
    return out


def radiance(
    rays: ShadedRays, origin_map_m: npt.NDArray[np.float64], weather: Weather, max_range_m: float,
    boxes: AgentBoxes | None = None,
) -> F32:  # fmt: skip
    """``(N, 3)`` linear BGR radiance reaching the camera along each ray. Each ray's on its own:
    many rays are taken :data:`STRIPE_PX` at a time, whose arrays stay in the CPU's cache
    through every step."""
    n = len(rays.cls)
    out = np.empty((n, 3), np.float32)
    light = _Light.of(weather, origin_map_m)
    for start in range(0, n, STRIPE_PX):
        s = slice(start, start + STRIPE_PX)
        _radiance(rays.rows(s), weather, max_range_m, boxes, light, out[s])
    return out


@dataclass(frozen=True, slots=True)
class _Light:
    """:func:`_radiance`'s constants of a weather and a camera position: the unit vector to the
    sun, the lighting constants of :func:`sensors.shade_kernels.lit_colour`, the lit windows'
    light, the sun's glint, the ground's light seen in reflections below the horizon and the
    haze's colour (linear)."""

    origin: F32
    sun: F32
    light_k: F32
    window: F32
    glint: np.float32
    below: np.float32
    haze: F32

    @staticmethod
    def of(weather: Weather, origin_map_m: npt.NDArray[np.float64]) -> _Light:
        sun = np.asarray(weather.sun_dir_map, np.float32)
        sun /= np.linalg.norm(sun)
        night = np.float32(night_of(weather))
        light_k = np.array(
            [
                np.float32(weather.ambient) * np.float32(1.6),
                np.float32(weather.sun_gain) * np.float32(2.2),
                np.float32(weather.headlight_gain) * np.float32(1.6),
                np.float32(weather.headlight_range_m),
                np.float32(origin_map_m[2]),
                night * STREET_LIGHT,
                np.float32(weather.lamp_key_gain) * np.float32(2.2),
                float(weather.headlight_gain > 0),
                float(weather.lamp_key_gain > 0),
                STREET_LIGHT_FADE_M,
                DIPPED_CUTOFF_M,
                DIPPED_ABOVE,
                LAMP_LIT_UP_TO_M,
                LAMP_FADE_M,
            ],
            np.float32,
        )
        window = (
            night * np.float32(0.25) * np.array([0.25, 0.55, 0.9], np.float32) if night > 0 else np.zeros(3, np.float32)
        )
        glint = np.float32(weather.sun_gain + weather.lamp_key_gain)
        below = np.float32(0.04) * (np.float32(weather.ambient) + np.float32(weather.sun_gain))
        return _Light(origin_map_m.astype(np.float32), sun, light_k, window, glint, below, to_linear(weather.haze_bgr))


def _radiance(
    rays: ShadedRays, weather: Weather, max_range_m: float, boxes: AgentBoxes | None, light: _Light, out: F32
) -> None:
    """The light of one stripe of rays into ``out`` (``(N, 3)``, C-contiguous): misses see the
    sky; hits' albedo, mirror and glow by numpy (textures, parts), their lighting by compiled
    loops (:mod:`sensors.shade_kernels`)."""
    dirs_map, range_m, cls, instance, part = rays.dirs_map, rays.range_m, rays.cls, rays.instance, rays.part
    at, miss, c, inst, pt, p, nrm, cos_v = kernels.split_hits_geometry(
        range_m, np.float32(max_range_m), cls, instance, part, dirs_map, rays.normal, light.origin
    )
    if len(miss):
        sky_linear_at(weather, np.ascontiguousarray(dirs_map, np.float32), miss, out)
    if len(at) == 0:
        return

    albedo, mirror, glow = static_albedo(c, p, nrm)
    wet = np.zeros(0, np.intp)
    if weather.wet_ground > 0:  # water lies on paved surfaces facing up: not under a bridge's deck nor on its sides
        wet = np.flatnonzero(_IS_PAVED[c] & (pt == 0) & (nrm[:, 2] >= WET_MIN_UP))
    mirror[wet] = np.float32(weather.wet_ground)
    agent = pt > 0
    if agent.any():
        ai = np.flatnonzero(agent)
        kernels.part_rows(albedo, ai, pt[ai], inst[ai], *_PART_LINEAR)
        mirror[ai] = MIRROR_BY_PART[pt[ai]]
        glow[ai] = 0.0
        plate = ai[pt[ai] == Part.PLATE]
        if len(plate) and boxes is not None:
            albedo[plate[plate_ink(p[plate], inst[plate], boxes)]] = np.float32(0.003)
    none = np.zeros(0, np.float32)
    head = rays.forward[at] ** 6 if weather.headlight_gain > 0 else none  # the headlights' cone
    pool = lamp_pools(p) if weather.lamp_key_gain > 0 else none
    colour, shiny_at, refl, half_cos, shininess, away = kernels.lit_colour(
        at, dirs_map, range_m, part, instance, rays.sun_lit, rays.sky_open, p, nrm, cos_v,
        np.ascontiguousarray(albedo, np.float32), mirror, head, pool, light.sun, light.light_k, STREET_LIGHT_BGR,
        SPECULAR_BY_PART, SHININESS_BY_PART,
    )  # fmt: skip
    # highlights, and the sky and the ground reflected by paint and glass (Schlick's Fresnel term)
    highlight = half_cos**shininess
    grazing = away**5
    env = sky_linear(weather, refl)
    kernels.below_horizon(env, refl, light.below)
    if len(wet):  # a wet road mirrors the sky only as far as it sees it: less under and beside vehicles
        film = np.flatnonzero(_IS_PAVED[c[shiny_at]] & (pt[shiny_at] == 0) & (nrm[shiny_at, 2] >= WET_MIN_UP))
        env[film] *= rays.sky_open[at[shiny_at[film]]][:, None]
    kernels.finish_colour(
        colour, shiny_at, highlight, grazing, env, mirror, at, part, rays.sun_lit, rays.lamp, glow, SPECULAR_BY_PART,
        LAMP_BGR, light.glint, light.window, _haze_at(weather, at, range_m, max_range_m), light.haze, out,
    )  # fmt: skip


def _haze_at(weather: Weather, at: npt.NDArray[np.int64], range_m: F32, max_range_m: float) -> F32:
    """:func:`sensors.weather.haze_fraction` of the rays ``at`` (the same float32 results; the exp
    numpy's)."""
    fade = np.exp(kernels.haze_exponent(at, range_m, np.float32(weather.haze_m)))
    return kernels.haze_blend(at, range_m, fade, np.float32(0.8 * max_range_m), np.float32(0.2 * max_range_m))


MAX_BLUR_SAMPLES = 12
"""Most samples along a pixel's motion (each about a pixel apart up to this many pixels)."""


def image_motion_px(
    pinhole: Pinhole, dirs_cam: F32, range_m: F32, instance: npt.NDArray[np.uint32], map_R_cam: F32,
    boxes: AgentBoxes | None, ego_velocity_map_mps: npt.NDArray[np.float64], shutter_s: float,
) -> F32:  # fmt: skip
    """``(N, 2)`` how far (pixels) each pixel's surface moves across the image while the shutter
    is open: its agent's velocity (0 for the static world) less the ego's, over ``shutter_s``
    centred on the frame's instant (the ego's turning is not included); 0 for the sky."""
    n = len(range_m)
    motion = np.zeros((n, 2), np.float32)
    hit = np.flatnonzero(np.isfinite(range_m))
    if len(hit) == 0:
        return motion
    velocity = np.broadcast_to(-np.asarray(ego_velocity_map_mps, np.float32), (len(hit), 3)).copy()
    if boxes is not None and len(boxes.instance_id):
        rows = boxes.rows_of(instance[hit])
        moving = rows >= 0
        velocity[moving] += boxes.velocity_mps[rows[moving]].astype(np.float32)
    half = (velocity @ map_R_cam) * np.float32(shutter_s / 2.0)  # camera frame
    p = dirs_cam[hit] * range_m[hit, None]
    a, b = p - half, p + half
    a[:, 2] = np.maximum(a[:, 2], np.float32(0.1))
    b[:, 2] = np.maximum(b[:, 2], np.float32(0.1))
    motion[hit] = (pinhole.project(b.astype(np.float64)) - pinhole.project(a.astype(np.float64))).astype(np.float32)
    return motion


def motion_blur(linear: F32, motion_px: F32) -> F32:
    """``(H, W, 3)`` the image averaged along each pixel's own motion ``(H, W, 2)`` (samples
    from -1/2 to +1/2 of it, bilinear): a gather, so a moving object smears within its own
    outline and its edges fade into what lies behind them."""
    import cv2

    longest = float(np.abs(motion_px).max()) if motion_px.size else 0.0
    steps = min(max(math.ceil(longest), 1), MAX_BLUR_SAMPLES)
    if steps <= 1:
        return linear
    h, w = linear.shape[:2]
    v, u = np.mgrid[0:h, 0:w].astype(np.float32)
    out = np.zeros_like(linear)
    for t in np.linspace(-0.5, 0.5, steps, dtype=np.float32):
        out += cv2.remap(linear, u + t * motion_px[..., 0], v + t * motion_px[..., 1], cv2.INTER_LINEAR,
                         borderMode=cv2.BORDER_REPLICATE)  # fmt: skip
    return np.asarray(out / np.float32(steps), np.float32)


LAMP_LIT_UP_TO_M, LAMP_FADE_M = 3.0, 6.0
"""Street lamps light what stands up to this high over the camera (about 4.6 m over the road),
fading out over the next 6 m: facades above the street stay dark."""
DIPPED_CUTOFF_M, DIPPED_ABOVE = 0.5, np.float32(0.2)
"""Dipped headlights light what lies below the cutoff (this high over the camera) and send a
fifth of that above it."""


LAMP_SPACING_M, LAMP_POOL_M, LAMP_BETWEEN = 28.0, 7.0, np.float32(0.2)
"""Street lamps stand every 28 m (a square grid in the map frame); each lights a pool about
7 m in radius (Gaussian sigma) and a fifth of its light reaches halfway between lamps."""


def lamp_pools(points: F32) -> F32:
    """``(N,)`` how much of the street lamps' light reaches ``points``: 1 under a lamp, falling
    to :data:`LAMP_BETWEEN` between them (the pools of light along a lit street at night)."""
    d2 = kernels.lamp_offsets_sq(np.ascontiguousarray(points, np.float32), np.float32(LAMP_SPACING_M))
    pool = np.exp(-d2 / np.float32(2.0 * LAMP_POOL_M**2))
    return np.asarray(LAMP_BETWEEN + (np.float32(1.0) - LAMP_BETWEEN) * pool, np.float32)


def _dipped(above_m: F32) -> F32:
    """``(N,)`` share of the headlights' light at points ``above_m`` over the camera."""
    return np.where(above_m < np.float32(DIPPED_CUTOFF_M), np.float32(1.0), DIPPED_ABOVE).astype(np.float32)


BLOOM_THRESHOLD = np.float32(1.6)
BLOOM_SIGMA_PX = 5.0
BLOOM_GAIN = np.float32(0.6)


def bloom(linear: F32) -> F32:
    """Light beyond :data:`BLOOM_THRESHOLD` spread around its source (lamps at night, sun
    glints), as a lens and sensor do: ``(H, W, 3)`` ``linear`` in place (and returned)."""
    r0, r1, c0, c1 = kernels.over_span(linear, BLOOM_THRESHOLD)
    if r0 < 0:
        return linear
    m = math.ceil(3.0 * BLOOM_SIGMA_PX)
    h, w = linear.shape[:2]
    rows, cols = slice(max(r0 - m, 0), min(r1 + m + 1, h)), slice(max(c0 - m, 0), min(c1 + m + 1, w))
    bright = np.maximum(linear[rows, cols] - BLOOM_THRESHOLD, np.float32(0.0))
    linear[rows, cols] += BLOOM_GAIN * soft_blur(bright, BLOOM_SIGMA_PX)
    return linear


def soft_blur(image: F32, sigma_px: float) -> F32:
    """Gaussian blur of ``(H, W[, C])`` by ``sigma_px``; wide ones are done at half or a quarter
    of the resolution and scaled back (the same light spread, a fraction of the work)."""
    import cv2

    h, w = image.shape[:2]
    step = 4 if sigma_px >= 6.0 else 2 if sigma_px >= 3.0 else 1
    if step == 1 or h < 4 * step or w < 4 * step:
        return np.asarray(cv2.GaussianBlur(image, (0, 0), sigma_px), np.float32)
    small = cv2.resize(image, (max(w // step, 1), max(h // step, 1)), interpolation=cv2.INTER_AREA)
    spread = math.sqrt(max(sigma_px**2 - (step / 2.0) ** 2, 0.25)) / step  # the area average spreads by about step / 2
    blurred = cv2.GaussianBlur(small, (0, 0), spread)
    return np.asarray(cv2.resize(blurred, (w, h), interpolation=cv2.INTER_LINEAR), np.float32).reshape(image.shape)


def tone_curve(linear: F32, exposure: float, keep: F32 | None = None) -> F32:
    """Filmic tone curve (Narkowicz's fit of ACES) and display gamma of ``(N, 3)`` ``linear`` times
    ``keep (N,)`` (the light kept through the lens, :func:`vignette`; None: all): values 0..1
    (:func:`finished_bytes` scales them to 0..255)."""
    linear = np.ascontiguousarray(linear, np.float32).reshape(-1, 3)
    keep = np.ones(len(linear), np.float32) if keep is None else np.ascontiguousarray(keep, np.float32)
    y = kernels.filmic(linear, keep, np.float32(EXPOSURE_SCALE * np.float32(exposure)))
    np.power(y, np.float32(1.0) / GAMMA, out=y)
    return y


def finished_bytes(curve: F32, saturation: float, seed: int, sigma: np.float32) -> npt.NDArray[np.uint8]:
    """``(N, 3) uint8`` of :func:`tone_curve`'s ``curve``: scaled to display values 0..255, the
    frame's black level set (:data:`BLACK_PERCENTILE` to :data:`BLACK_TOE`, the darker greys kept
    in order below it; the grey stretched, not the colours: a veiled rain frame's black level
    near 60 would push its colours 1.3 times further from grey, the grass neon), colours
    ``saturation`` times further from their grey, as a camera's colour processing does (the
    weather's; by day 1.3: our frames' mean saturation was 27-33 against 72-85 in real KITTI
    frames; at night 1.0, where cameras' colour fades), plus ``sigma`` times a draw per pixel of
    ``np.random.default_rng(seed).standard_normal(N, dtype=np.float32)``, rounded and clipped;
    in one pass over the image (and one over every :data:`BLACK_STEP`-th pixel's grey, for the
    black level)."""
    k = np.float32(255.0)
    black, scale = _black_of(kernels.grey_sample(curve, k, BLACK_STEP))
    return kernels.scaled_levelled_bytes(
        curve, k, black, scale, np.float32(saturation), np.float32(BLACK_TOE), _pcg64_words(seed), sigma
    )


BLACK_STEP = 7
"""The black level is measured on every this many-th pixel's grey."""


def _black_of(sample: F32) -> tuple[np.float32, np.float32]:
    """The black level of the greys ``sample`` (:data:`BLACK_PERCENTILE`) and the stretch of the
    greys above it."""
    black = np.float32(np.percentile(sample, BLACK_PERCENTILE))
    toe = np.float32(BLACK_TOE)
    scale = (np.float32(255.0) - toe) / (np.float32(255.0) - black) if black > 0 else np.float32(1.0)
    return black, scale


def _pcg64_words(seed: int) -> npt.NDArray[np.uint64]:
    """The state of ``np.random.PCG64(seed)`` as :func:`sensors.shade_kernels._pcg64_next32`'s six words."""
    state = np.random.PCG64(seed).state
    pcg, low = state["state"], (1 << 64) - 1
    words = [pcg["state"] >> 64, pcg["state"] & low, pcg["inc"] >> 64, pcg["inc"] & low]
    return np.array([*words, state["has_uint32"], state["uinteger"]], np.uint64)


@functools.lru_cache(maxsize=4)
def vignette(height: int, width: int) -> F32:
    """``(H * W,)`` light kept at each pixel (read-only: one array per image size)."""
    v, u = np.mgrid[0:height, 0:width].astype(np.float32)
    r2 = ((u - (width - 1) / 2) ** 2 + (v - (height - 1) / 2) ** 2) / np.float32((width / 2) ** 2 + (height / 2) ** 2)
    out = np.asarray(np.float32(1.0) - VIGNETTE * r2, np.float32).ravel()
    out.flags.writeable = False
    return out


STRIPE_PX = 1 << 15
"""Rays shaded at a time: a stripe's arrays stay in the CPU cache through every step."""


ROUNDING_M = 0.12
"""Agents' normals are averaged over about this much of their surface: flat faces meet in
rounded edges, as pressed sheet metal and bodies do (the mesh itself stays as it is)."""
ROUNDING_LEVELS_PX = (1.5, 4.0, 10.0)


LEAF_TILT = np.float32(1.0)  # how far a crown's leaf clumps turn its normals (see textures.leaf_tilt)


def leafy_normals(
    normal: F32, cls: npt.NDArray[np.uint8], dirs_map: F32, range_m: F32, origin_map_m: npt.NDArray[np.float64]
) -> F32:
    """``normal`` (written in place and returned) with the crowns' (VEGETATION) ones tilted clump
    by clump (:func:`textures.leaf_tilt` times :data:`LEAF_TILT`, unit length again, still facing
    the camera); the rest as they were."""
    at = np.flatnonzero(cls == SemanticClass.VEGETATION)
    if at.size == 0:
        return normal
    points = kernels.hit_points(at, dirs_map, range_m, np.asarray(origin_map_m, np.float32))
    kernels.bent_rows(normal, at, textures.leaf_tilt(points, 67), dirs_map, LEAF_TILT)
    return normal


def rounded_normals(normal: F32, dirs_map: F32, instance: npt.NDArray[np.uint32], depth_m: F32, focal_px: float) -> F32:
    """``(N, 3)`` normals facing the camera, agents' ones averaged over :data:`ROUNDING_M` of
    surface (in the image, at each pixel's depth) among the pixels of agents."""

    h, w = depth_m.shape
    ids, depth = np.ascontiguousarray(instance).ravel(), np.ascontiguousarray(depth_m, np.float32).ravel()
    out, ratio = kernels.turned_and_ratios(
        np.ascontiguousarray(normal, np.float32), np.ascontiguousarray(dirs_map, np.float32), ids, depth,
        np.float32(focal_px * ROUNDING_M), np.float32(0.1), np.asarray(ROUNDING_LEVELS_PX, np.float32),
    )  # fmt: skip  # normals facing the camera; the pixels ROUNDING_M spans on each agent's pixel over each level's
    if len(ratio) == 0:  # no agent in view
        return out
    grid = out.reshape(h, w, 3)  # a view: agents' pixels are written back through it
    instance = ids.reshape(h, w)
    level = kernels.nearest_levels(ids, np.log(ratio)).reshape(h, w)  # the nearest in scale; -1 off agents
    spans = kernels.level_spans(level, len(ROUNDING_LEVELS_PX))
    for k, sigma in enumerate(ROUNDING_LEVELS_PX):
        r0, r1, c0, c1 = (int(v) for v in spans[k])
        if r0 < 0:
            continue
        m = math.ceil(3.0 * sigma)  # the rows and columns of the level's pixels, widened by 3 sigma
        row0, row1, col0, col1 = max(r0 - m, 0), min(r1 + m + 1, h), max(c0 - m, 0), min(c1 + m + 1, w)
        weighted, near = kernels.agent_weighted(grid, instance, row0, row1, col0, col1)
        num = soft_blur(weighted, sigma)  # agents' normals (others' weighed 0) blurred, and their weights
        den = soft_blur(near, sigma)
        kernels.blurred_unit(grid, row0, col0, level, k, num, den)
    return out


_ = Part  # the part enum documents the tables this module reads

"""Surface parts: what each agent triangle is made of, and the one material table that the
camera, the LiDAR and the radar read.

The static world's triangles are :attr:`Part.SURFACE`: their material is their class's
(:mod:`sensors.materials`). An agent's triangles carry the part they belong to (paint, glass,
tyre, lamp, plate, skin, cloth, ...), so a car's windows look dark and glossy to the camera,
return weakly to the LiDAR, and its plate shines back to both.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum

import numpy as np
import numpy.typing as npt

from sensors.materials import RADAR_REFLECTIVITY_BY_CLASS


class Part(IntEnum):
    """What a triangle is made of (uint8 per triangle, per ray hit)."""

    SURFACE = 0  # the static world: material by class
    PAINT = 1  # vehicle body paint, colour per instance
    GLASS = 2
    TYRE = 3
    RIM = 4
    HEADLAMP = 5
    TAIL_LAMP = 6
    PLATE = 7  # retro-reflective number plate
    TRIM = 8  # black plastic: bumpers' lower parts, grilles, mirrors' housings, seats
    CHROME = 9
    SKIN = 10
    HAIR = 11
    TOP = 12  # upper clothes, colour per instance
    TROUSERS = 13  # lower clothes, colour per instance
    SHOES = 14  # shoes, boots and riding gloves: dark leather
    FRAME = 15  # bicycle and motorcycle frames, painted: colour per instance (dark most)
    CARGO = 16  # box bodies of trucks, light colours per instance
    UNDERBODY = 17  # the dark underside and arch linings
    INDICATOR = 18  # amber direction indicators, front and rear corners
    SAFETY_ORANGE = 19  # traffic cones' and barriers' orange-red plastic
    RETRO_WHITE = 20  # retro-reflective white sheeting: cone collars, barrier and work-vehicle stripes
    SAFETY_YELLOW = 21  # construction vehicles' yellow paint
    LIVERY = 22  # white paint: emergency vehicles, box trucks' rear doors
    BEACON = 23  # emergency vehicles' blue light bars (not lit: SUMO drives them as cars)
    CAB = 24  # trucks' cab paint, colour per instance from trucks' colours (white most)
    ENGINE = 25  # motorcycles' engine blocks and cylinders: dark cast metal
    JACKET = 26  # motorcyclists' riding jackets, colour per instance (black and dark most)
    HELMET = 27  # motorcyclists' helmets, colour per instance (black and white most)
    RETRO_YELLOW = 28  # yellow retro-reflective contour marking on heavy vehicles (UN ECE R48, R104)
    DISPLAY = 29  # a bus's amber LED destination display
    SIDE_MARKER = 30  # amber side marker lamps along buses and trucks (UN ECE R48: over 6 m long)
    FRONT_OUTLINE = 31  # white end-outline marker lamps at the top of a bus's or truck's front (R48: over 2.1 m wide)
    REAR_OUTLINE = 32  # red end-outline marker lamps at the top of its rear


@dataclass(frozen=True, slots=True)
class PartMaterial:
    """A part's material: ``albedo_bgr`` (0..1; None: a colour per instance from a palette),
    ``specular`` (0..1 strength of the sun's highlight), ``shininess`` (Blinn-Phong exponent),
    ``mirror`` (0..1 of the surroundings reflected at normal incidence, rising to 1 at grazing
    angles), ``emissive`` (0..1: glows by night), LiDAR ``reflectivity`` (0..1) and
    ``radar`` (0..1, relative cross-section per unit area)."""

    albedo_bgr: tuple[float, float, float] | None
    specular: float
    shininess: float
    mirror: float
    emissive: float
    reflectivity: float
    radar: float


# Sources for the LiDAR column: automotive paint returns 0.3-0.6 at 905 nm by colour, glass
# mostly transmits (a weak return), tyres (carbon black) about 0.05, retro-reflective plates
# saturate; skin 0.4-0.5, cloth 0.2-0.6 (Velodyne calibrated-reflectivity notes; Kashani et al.,
# "A review of LiDAR radiometric processing", Sensors 2015).
MATERIALS: dict[Part, PartMaterial] = {
    Part.PAINT: PartMaterial(None, 0.6, 60.0, 0.08, 0.0, 0.45, 1.0),
    Part.GLASS: PartMaterial((0.05, 0.05, 0.045), 0.9, 200.0, 0.06, 0.0, 0.08, 0.3),
    Part.TYRE: PartMaterial((0.05, 0.05, 0.05), 0.05, 8.0, 0.0, 0.0, 0.05, 0.2),
    Part.RIM: PartMaterial((0.38, 0.38, 0.4), 0.5, 40.0, 0.1, 0.0, 0.6, 1.0),
    Part.HEADLAMP: PartMaterial((0.8, 0.8, 0.78), 0.9, 150.0, 0.3, 1.0, 0.7, 0.5),
    Part.TAIL_LAMP: PartMaterial((0.05, 0.04, 0.38), 0.8, 120.0, 0.15, 1.0, 0.6, 0.5),
    Part.INDICATOR: PartMaterial((0.1, 0.35, 0.6), 0.8, 120.0, 0.15, 1.0, 0.6, 0.5),
    Part.PLATE: PartMaterial((0.85, 0.85, 0.85), 0.2, 20.0, 0.0, 0.0, 0.95, 0.8),
    Part.TRIM: PartMaterial((0.07, 0.07, 0.075), 0.15, 15.0, 0.0, 0.0, 0.1, 0.6),
    Part.CHROME: PartMaterial((0.6, 0.6, 0.62), 0.9, 120.0, 0.5, 0.0, 0.7, 1.0),
    Part.SKIN: PartMaterial(None, 0.1, 10.0, 0.0, 0.0, 0.45, 0.15),
    Part.HAIR: PartMaterial(None, 0.2, 20.0, 0.0, 0.0, 0.2, 0.1),
    Part.TOP: PartMaterial(None, 0.05, 5.0, 0.0, 0.0, 0.4, 0.15),
    Part.TROUSERS: PartMaterial(None, 0.05, 5.0, 0.0, 0.0, 0.3, 0.15),
    Part.SHOES: PartMaterial((0.08, 0.08, 0.09), 0.2, 20.0, 0.0, 0.0, 0.15, 0.1),
    Part.FRAME: PartMaterial(None, 0.5, 40.0, 0.05, 0.0, 0.5, 0.8),
    Part.CARGO: PartMaterial(None, 0.2, 20.0, 0.0, 0.0, 0.55, 1.0),
    Part.UNDERBODY: PartMaterial((0.04, 0.04, 0.04), 0.0, 1.0, 0.0, 0.0, 0.05, 0.8),
    # Cones and barriers: orange PVC and polyethylene, bright at 905 nm but a weak radar target;
    # their white bands are retro-reflective sheeting (EN 13422 cones, EN 12899 signs), which
    # returns like a number plate.
    Part.SAFETY_ORANGE: PartMaterial((0.05, 0.3, 0.95), 0.25, 20.0, 0.0, 0.0, 0.5, 0.1),
    Part.RETRO_WHITE: PartMaterial((0.9, 0.9, 0.9), 0.3, 30.0, 0.0, 0.0, 0.95, 0.1),
    Part.SAFETY_YELLOW: PartMaterial((0.05, 0.65, 0.92), 0.5, 50.0, 0.06, 0.0, 0.43, 1.0),  # body paint
    Part.LIVERY: PartMaterial((0.9, 0.9, 0.9), 0.6, 60.0, 0.08, 0.0, 0.68, 1.0),  # as white body paint
    Part.BEACON: PartMaterial((0.75, 0.3, 0.05), 0.8, 120.0, 0.15, 0.0, 0.5, 0.5),  # blue polycarbonate
    Part.CAB: PartMaterial(None, 0.6, 60.0, 0.08, 0.0, 0.45, 1.0),  # as body paint
    Part.ENGINE: PartMaterial((0.07, 0.07, 0.075), 0.4, 30.0, 0.03, 0.0, 0.3, 1.0),
    Part.JACKET: PartMaterial(None, 0.08, 10.0, 0.0, 0.0, 0.3, 0.15),  # textile and leather
    Part.HELMET: PartMaterial(None, 0.7, 80.0, 0.08, 0.0, 0.45, 0.3),  # glossy shell
    Part.RETRO_YELLOW: PartMaterial((0.08, 0.72, 0.92), 0.3, 30.0, 0.0, 0.0, 0.95, 0.1),  # as the white sheeting
    Part.DISPLAY: PartMaterial((0.05, 0.45, 0.95), 0.3, 40.0, 0.0, 1.0, 0.3, 0.5),  # LEDs behind glass
    Part.SIDE_MARKER: PartMaterial((0.1, 0.35, 0.6), 0.8, 120.0, 0.15, 1.0, 0.6, 0.5),  # lenses as the lamps'
    Part.FRONT_OUTLINE: PartMaterial((0.8, 0.8, 0.78), 0.8, 120.0, 0.15, 1.0, 0.6, 0.5),
    Part.REAR_OUTLINE: PartMaterial((0.05, 0.04, 0.38), 0.8, 120.0, 0.15, 1.0, 0.6, 0.5),
}

# Car paint by real-world frequency (BASF/Axalta global colour popularity reports, 2020-2024:
# white about 35 %, black 20 %, grey 18 %, silver 9 %, blue 8 %, red 7 %, others 3 %): BGR 0..1.
PAINT_PALETTE: tuple[tuple[tuple[float, float, float], float], ...] = (
    ((0.86, 0.86, 0.85), 0.21), ((0.93, 0.93, 0.94), 0.14),   # white, pearl
    ((0.04, 0.04, 0.045), 0.14), ((0.08, 0.07, 0.07), 0.06),  # black, dark
    ((0.36, 0.36, 0.37), 0.10), ((0.22, 0.22, 0.23), 0.08),   # grey, graphite
    ((0.62, 0.62, 0.63), 0.09),                               # silver
    ((0.45, 0.22, 0.08), 0.05), ((0.25, 0.12, 0.05), 0.03),   # blue, dark blue
    ((0.07, 0.07, 0.55), 0.05), ((0.06, 0.05, 0.3), 0.02),    # red, dark red
    ((0.15, 0.3, 0.15), 0.01), ((0.45, 0.55, 0.6), 0.01), ((0.05, 0.45, 0.75), 0.01),  # green, beige, orange
)  # fmt: skip
CARGO_PALETTE: tuple[tuple[tuple[float, float, float], float], ...] = (
    ((0.9, 0.9, 0.9), 0.5), ((0.75, 0.76, 0.78), 0.2), ((0.55, 0.3, 0.1), 0.1), ((0.1, 0.35, 0.75), 0.1),
    ((0.2, 0.45, 0.2), 0.1),
)  # fmt: skip
# Truck cabs: white far more often than on cars, then the primary colours of fleet liveries,
# rarely black.
CAB_PALETTE: tuple[tuple[tuple[float, float, float], float], ...] = (
    ((0.88, 0.88, 0.87), 0.45), ((0.62, 0.62, 0.63), 0.1), ((0.08, 0.08, 0.6), 0.12),  # white, silver, red
    ((0.5, 0.25, 0.08), 0.1), ((0.3, 0.14, 0.05), 0.05), ((0.06, 0.06, 0.065), 0.06),  # blue, dark blue, black
    ((0.18, 0.4, 0.15), 0.04), ((0.05, 0.45, 0.85), 0.04), ((0.05, 0.7, 0.9), 0.04),  # green, orange, yellow
)  # fmt: skip
SKIN_PALETTE = (
    ((0.55, 0.66, 0.85), 0.4),
    ((0.42, 0.55, 0.75), 0.3),
    ((0.3, 0.42, 0.6), 0.2),
    ((0.18, 0.26, 0.38), 0.1),
)
HAIR_PALETTE = (((0.05, 0.06, 0.07), 0.5), ((0.08, 0.15, 0.25), 0.3), ((0.3, 0.5, 0.65), 0.1), ((0.6, 0.6, 0.6), 0.1))
TOP_PALETTE = (
    ((0.1, 0.1, 0.1), 0.25), ((0.85, 0.85, 0.85), 0.12), ((0.45, 0.25, 0.1), 0.15), ((0.3, 0.3, 0.32), 0.12),
    ((0.15, 0.15, 0.6), 0.08), ((0.2, 0.4, 0.2), 0.07), ((0.6, 0.65, 0.75), 0.08), ((0.1, 0.5, 0.8), 0.05),
    ((0.5, 0.2, 0.5), 0.04), ((0.15, 0.6, 0.85), 0.04),
)  # fmt: skip
TROUSERS_PALETTE = (((0.35, 0.2, 0.1), 0.4), ((0.08, 0.08, 0.08), 0.3), ((0.3, 0.3, 0.3), 0.15),
                    ((0.45, 0.55, 0.6), 0.15))  # fmt: skip


# Bicycle frames: black and dark colours most, then silver and white, some bright ones.
FRAME_PALETTE = (
    ((0.05, 0.05, 0.055), 0.3), ((0.22, 0.22, 0.23), 0.12), ((0.6, 0.6, 0.62), 0.1), ((0.85, 0.85, 0.85), 0.1),
    ((0.3, 0.12, 0.04), 0.1), ((0.06, 0.06, 0.5), 0.1), ((0.12, 0.25, 0.08), 0.06), ((0.6, 0.35, 0.08), 0.05),
    ((0.05, 0.5, 0.85), 0.04), ((0.1, 0.75, 0.85), 0.03),
)  # fmt: skip
# Riding jackets: black most, dark grey and dark blue, some in colours (red, white, hi-vis yellow).
JACKET_PALETTE = (
    ((0.04, 0.04, 0.045), 0.5), ((0.15, 0.15, 0.16), 0.15), ((0.22, 0.1, 0.04), 0.1), ((0.08, 0.08, 0.5), 0.08),
    ((0.7, 0.7, 0.7), 0.07), ((0.1, 0.75, 0.8), 0.05), ((0.3, 0.3, 0.3), 0.05),
)  # fmt: skip
# Helmets: black and white most, then silver and colours.
HELMET_PALETTE = (
    ((0.04, 0.04, 0.045), 0.38), ((0.88, 0.88, 0.88), 0.27), ((0.55, 0.55, 0.57), 0.12), ((0.08, 0.08, 0.6), 0.08),
    ((0.5, 0.22, 0.06), 0.08), ((0.05, 0.6, 0.85), 0.07),
)  # fmt: skip


def _palette(entries: tuple[tuple[tuple[float, float, float], float], ...], size: int = 64) -> npt.NDArray[np.float32]:
    """``(size, 3)`` colours in proportion to their weights: index by ``instance % size``."""
    weights = np.asarray([w for _, w in entries], np.float64)
    counts = np.floor(weights / weights.sum() * size).astype(int)
    counts[np.argmax(weights)] += size - counts.sum()
    rows = np.concatenate([np.repeat([c], n, axis=0) for (c, _), n in zip(entries, counts, strict=True)])
    order = np.random.default_rng(7).permutation(size)  # neighbouring ids do not share a colour
    return rows[order].astype(np.float32)


PALETTES: dict[Part, npt.NDArray[np.float32]] = {
    Part.PAINT: _palette(PAINT_PALETTE),
    Part.CARGO: _palette(CARGO_PALETTE),
    Part.CAB: _palette(CAB_PALETTE),
    Part.SKIN: _palette(SKIN_PALETTE),
    Part.HAIR: _palette(HAIR_PALETTE),
    Part.TOP: _palette(TOP_PALETTE),
    Part.TROUSERS: _palette(TROUSERS_PALETTE),
    Part.FRAME: _palette(FRAME_PALETTE),
    Part.JACKET: _palette(JACKET_PALETTE),
    Part.HELMET: _palette(HELMET_PALETTE),
}
"""Colours of the parts coloured per instance; each part hashes the id differently."""

PALETTE_SALT = {
    Part.PAINT: 0, Part.CARGO: 11, Part.SKIN: 23, Part.HAIR: 31, Part.TOP: 41, Part.TROUSERS: 53, Part.CAB: 61,
    Part.FRAME: 5, Part.JACKET: 17, Part.HELMET: 37,
}  # fmt: skip


def _column(name: str) -> npt.NDArray[np.float32]:
    out = np.zeros(256, np.float32)
    for part, m in MATERIALS.items():
        out[int(part)] = getattr(m, name)
    return out


SPECULAR_BY_PART = _column("specular")
SHININESS_BY_PART = np.maximum(_column("shininess"), 1.0)
MIRROR_BY_PART = _column("mirror")
EMISSIVE_BY_PART = _column("emissive")
REFLECTIVITY_BY_PART = _column("reflectivity")
RADAR_BY_PART = _column("radar")
HAS_PALETTE = np.zeros(256, np.bool_)
HAS_PALETTE[[int(p) for p in PALETTES]] = True
ALBEDO_BGR_BY_PART = np.zeros((256, 3), np.float32)
for _part, _m in MATERIALS.items():
    if _m.albedo_bgr is not None:
        ALBEDO_BGR_BY_PART[int(_part)] = _m.albedo_bgr


# Paint at 905 nm follows its colour (white about 0.7, black and dark blue under 0.1: Velodyne
# calibrated-reflectivity notes; Kashani et al. 2015): the LiDAR reflectivity of painted parts
# (body paint, cargo panels; livery and construction yellow in the table likewise) is 0.05 + 0.7 x
# the mean of the instance's albedo. That clear-coated body paint mostly reads 0 in real KITTI
# scans is the clear coat's doing, not its colour's: it mirrors the beam away unless it glints
# back (the kitti reading, sensors.lidar.IntensityResponse.glint_chance).
PAINT_REFLECTIVITY_FLOOR = 0.05
PAINT_REFLECTIVITY_PER_ALBEDO = 0.7
COLOURED_BY_PAINT = (Part.PAINT, Part.CARGO, Part.CAB)
RETRO_PARTS = (Part.PLATE, Part.RETRO_WHITE, Part.RETRO_YELLOW)


def radar_reflectivity(semantic_class: npt.NDArray[np.uint8], part: npt.NDArray[np.uint8]) -> npt.NDArray[np.float32]:
    """``(N,)`` relative radar cross-section per unit area: by part on agents (metal strong,
    people and glass weak), by class on the static world."""
    return np.where(part > 0, RADAR_BY_PART[part], RADAR_REFLECTIVITY_BY_CLASS[semantic_class]).astype(np.float32)


def part_albedo(part: npt.NDArray[np.uint8], instance_id: npt.NDArray[np.uint32]) -> npt.NDArray[np.float32]:
    """``(N, 3)`` BGR albedo of agent parts (0 rows for :attr:`Part.SURFACE`)."""
    out = np.take(ALBEDO_BGR_BY_PART, part, axis=0)  # a new array
    for p, palette in PALETTES.items():
        mine = np.flatnonzero(part == p)
        if len(mine):
            key = (instance_id[mine].astype(np.uint64) * np.uint64(2654435761) >> np.uint64(7)) + np.uint64(
                PALETTE_SALT[p]
            )
            out[mine] = palette[(key % np.uint64(palette.shape[0])).astype(np.intp)]
    return out

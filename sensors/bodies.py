"""Body types of road users: meshes with the parts detectors learn, generated here.

Every body is drawn in metres at its nominal size (x forward, y left, z up from the ground,
centred in x and y), every triangle tagged with its :class:`~sensors.parts.Part`, then
normalised into the unit box ``[-0.5, 0.5]^3``: scaled to an agent's l/w/h it stays inside
its box, so every LiDAR point of an agent stays inside its label.

Cars come as sedan, hatchback, estate, SUV, van and pickup; trucks as a box truck and a
tractor with a semi-trailer; buses as a city bus and a coach; motorcycles and bicycles with a
rider (the cyclist pedalling); pedestrians in a walking cycle; trailers as a centre-axle box
trailer; construction zones' objects as a work truck, a road cone and a water-filled barrier.
An agent's body type is the one whose nominal size fits its l/w/h best, ties broken by its
instance id, so it is stable over its track (:func:`body_of`).
"""

from __future__ import annotations

import functools
import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import shapely
from shapely.geometry import Polygon
from shapely.geometry.polygon import orient

from networks.classes import SemanticClass
from sensors.parts import Part

F64 = npt.NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class Piece:
    """Triangles in metres: ``vertices (V, 3)``, ``triangles (T, 3) int32``, ``parts (T,) uint8``."""

    vertices: F64
    triangles: npt.NDArray[np.int32]
    parts: npt.NDArray[np.uint8]


def merge(pieces: list[Piece]) -> Piece:
    offsets = np.cumsum([0] + [p.vertices.shape[0] for p in pieces[:-1]])
    return Piece(
        np.concatenate([p.vertices for p in pieces]),
        np.concatenate([p.triangles + o for p, o in zip(pieces, offsets, strict=True)]).astype(np.int32),
        np.concatenate([p.parts for p in pieces]).astype(np.uint8),
    )


PartOf = int | Callable[[float, float], int]
"""A part, or a function of a side face's outward normal (x, z) giving its part."""


def prism(
    outline_xz: list[tuple[float, float]],
    half_width: float | Callable[[float], float],
    cap: int,
    side: PartOf,
    y_centre: float = 0.0,
    hole: list[tuple[float, float]] | None = None,
) -> Piece:
    """A side outline (any simple polygon, optionally with one hole) extruded across y,
    ``half_width`` a constant or a function of z (tumblehome). ``cap``: the part of the two
    flat faces; ``side``: the part of the faces around the outline."""
    poly = orient(Polygon(outline_xz, [hole] if hole else None), 1.0)
    rings = [np.asarray(poly.exterior.coords[:-1])] + [np.asarray(r.coords[:-1]) for r in poly.interiors]
    pts = np.concatenate(rings)
    index = {(round(x, 9), round(z, 9)): i for i, (x, z) in enumerate(pts)}
    k = pts.shape[0]
    hw = np.array([half_width(z) if callable(half_width) else half_width for z in pts[:, 1]])
    left = np.column_stack([pts[:, 0], y_centre + hw, pts[:, 1]])
    right = np.column_stack([pts[:, 0], y_centre - hw, pts[:, 1]])
    tris, parts = [], []
    for t in shapely.constrained_delaunay_triangles(poly).geoms:
        a, b, c = (index[(round(x, 9), round(z, 9))] for x, z in t.exterior.coords[:3])
        tris += [(a, b, c), (k + a, k + c, k + b)]
        parts += [cap, cap]
    start = 0
    for ring in rings:
        n = ring.shape[0]
        for j in range(n):
            a, b = start + j, start + (j + 1) % n
            dx, dz = pts[b] - pts[a]
            length = math.hypot(dx, dz) or 1.0
            part = side(dz / length, -dx / length) if callable(side) else side
            tris += [(a, k + a, b), (b, k + a, k + b)]
            parts += [part, part]
        start += n
    return Piece(np.concatenate([left, right]), np.asarray(tris, np.int32), np.asarray(parts, np.uint8))


def box(x0: float, x1: float, y0: float, y1: float, z0: float, z1: float, part: int) -> Piece:
    return prism([(x0, z0), (x1, z0), (x1, z1), (x0, z1)], (y1 - y0) / 2, part, part, (y0 + y1) / 2)


def circle(cx: float, cz: float, r: float, sides: int, start: float = 0.0) -> list[tuple[float, float]]:
    return [
        (cx + r * math.cos(start + 2 * math.pi * i / sides), cz + r * math.sin(start + 2 * math.pi * i / sides))
        for i in range(sides)
    ]


def tube(p0: F64, p1: F64, r0: float, r1: float, part: int, sides: int = 6, flat: float = 1.0) -> Piece:
    """A tapered rod between two 3D points, closed at both ends; ``flat`` < 1 squeezes its
    cross-section into an ellipse (for a rod along z: as deep along x as ``flat`` times its
    width along y)."""
    a, b = np.asarray(p0, np.float64), np.asarray(p1, np.float64)
    axis = b - a
    axis /= np.linalg.norm(axis) or 1.0
    helper = np.array([0.0, 0.0, 1.0]) if abs(axis[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    u = np.cross(axis, helper)
    u /= np.linalg.norm(u)
    v = np.cross(axis, u)
    ang = 2 * np.pi * np.arange(sides) / sides
    ring = np.cos(ang)[:, None] * u + flat * np.sin(ang)[:, None] * v
    verts = np.concatenate([a + r0 * ring, b + r1 * ring])
    j = np.arange(sides)
    jn = (j + 1) % sides
    sides_t = np.concatenate([np.stack([j, jn, sides + j], 1), np.stack([jn, sides + jn, sides + j], 1)])
    i = np.arange(1, sides - 1)
    caps = np.concatenate(
        [np.stack([np.zeros_like(i), i + 1, i], 1), np.stack([np.full_like(i, sides), sides + i, sides + i + 1], 1)]
    )
    tris = np.concatenate([sides_t, caps]).astype(np.int32)
    return Piece(verts, tris, np.full(tris.shape[0], part, np.uint8))


def blob(
    centre: tuple[float, float, float], radii: tuple[float, float, float], part: int, rings: int = 4, segments: int = 8
) -> Piece:
    """A low-poly ellipsoid (heads, helmets)."""
    verts = [(0.0, 0.0, -1.0)]
    for i in range(1, rings):
        phi = -np.pi / 2 + np.pi * i / rings
        for s in range(segments):
            th = 2 * np.pi * s / segments
            verts.append((math.cos(phi) * math.cos(th), math.cos(phi) * math.sin(th), math.sin(phi)))
    verts.append((0.0, 0.0, 1.0))
    v = np.asarray(verts) * np.asarray(radii) + np.asarray(centre)
    tris = []
    top = len(verts) - 1
    for s in range(segments):
        sn = (s + 1) % segments
        tris.append((0, 1 + sn, 1 + s))
        for i in range(rings - 2):
            a, b = 1 + i * segments, 1 + (i + 1) * segments
            tris += [(a + s, a + sn, b + s), (a + sn, b + sn, b + s)]
        last = 1 + (rings - 2) * segments
        tris.append((last + s, last + sn, top))
    t = np.asarray(tris, np.int32)
    return Piece(v, t, np.full(t.shape[0], part, np.uint8))


def wheel(
    x: float, r: float, y_in: float, y_out: float, sides: int = 14, rim_share: float = 0.62, hub: int = Part.TRIM
) -> list[Piece]:
    """A tyre with a rim on its outer face (``y_out`` is the outer face, either side);
    ``rim_share`` is the rim's radius as a share of the tyre's; ``hub`` the hub cap's part."""
    width = abs(y_out - y_in)
    sign = 1.0 if y_out > y_in else -1.0
    # outwards, each face a few millimetres beyond the last (no two parts share a plane)
    tyre = prism(circle(x, r, r, sides), width / 2 - 0.008, Part.TYRE, Part.TYRE, (y_in + y_out) / 2 - sign * 0.008)
    rim = prism(circle(x, r, rim_share * r, sides), 0.011, Part.RIM, Part.RIM, y_out - sign * 0.014)
    cap = prism(circle(x, r, 0.18 * r, 6), 0.0025, hub, hub, y_out + sign * 0.0015)
    return [tyre, rim, cap]


BICYCLE_TYRE_M = 0.045
"""A bicycle tyre's depth from tread to rim (a city or trekking tyre: 40-50 mm)."""


def ring_wheel(x: float, r: float, half_width: float, sides: int = 20) -> list[Piece]:
    """A bicycle wheel: a black tyre :data:`BICYCLE_TYRE_M` deep on a silver rim, open
    spokes, a hub."""
    inner = r - BICYCLE_TYRE_M
    tyre = prism(circle(x, r, r, sides), half_width, Part.TYRE, Part.TYRE, hole=circle(x, r, inner, sides))
    rim = prism(circle(x, r, inner + 0.004, sides), half_width * 0.6, Part.CHROME, Part.CHROME,
                hole=circle(x, r, inner - 0.025, sides))  # fmt: skip
    hub = prism(circle(x, r, 0.03, 6), half_width * 1.5, Part.CHROME, Part.CHROME)
    return [tyre, rim, hub]


def _under(nx: float, nz: float) -> int:
    return int(Part.UNDERBODY) if nz < -0.6 else int(Part.PAINT)


@dataclass(frozen=True, slots=True)
class CarShape:
    """A car's side profile in metres; x forward from the centre, z up from the ground."""

    length: float
    width: float
    height: float
    wheel_r: float
    axle_front: float  # x of the front axle
    axle_rear: float
    clearance: float  # sill height
    nose_z: float  # top of the front face
    belt_z: float  # bonnet's rear end, at the windscreen's base
    windscreen_x: float  # x of the windscreen's base
    roof_front_x: float
    roof_rear_x: float
    rear_glass_x: float  # x of the rear window's base
    deck_z: float  # height of the boot lid / tailgate top at the rear
    tail_slope: float = 0.12  # how far back the rear face leans (m)
    bed: bool = False  # a pickup's load bed behind the cab


CAR_SHAPES: dict[str, CarShape] = {
    "sedan": CarShape(4.7, 1.82, 1.45, 0.32, 1.42, -1.38, 0.2, 0.72, 0.9, 0.95, -0.15, -1.05, -1.65, 0.95),
    "hatchback": CarShape(4.1, 1.78, 1.48, 0.31, 1.3, -1.25, 0.2, 0.72, 0.9, 0.8, -0.2, -1.5, -1.95, 0.98, 0.05),
    "estate": CarShape(4.8, 1.83, 1.5, 0.32, 1.45, -1.4, 0.2, 0.74, 0.92, 0.95, -0.1, -2.05, -2.28, 1.0, 0.04),
    "suv": CarShape(4.6, 1.88, 1.72, 0.37, 1.38, -1.35, 0.3, 0.95, 1.08, 0.85, -0.1, -1.85, -2.2, 1.15, 0.04),
    "van": CarShape(4.9, 1.95, 1.95, 0.33, 1.6, -1.5, 0.26, 1.0, 1.12, 1.45, 0.95, -2.33, -2.36, 1.2, 0.02),
    "pickup": CarShape(5.3, 1.9, 1.8, 0.38, 1.75, -1.6, 0.32, 1.0, 1.1, 1.15, 0.25, -0.65, -0.72, 1.1, 0.02, True),
}


def _arch(cx: float, r: float, reverse: bool = False) -> list[tuple[float, float]]:
    """An arch's outline over a wheel at ``cx`` (radius ``r`` plus clearance), rear to front."""
    ra = r + 0.06
    pts = [(cx + ra * math.cos(a), r + ra * math.sin(a)) for a in np.linspace(math.pi, 0.0, 7)]
    return pts[::-1] if reverse else pts


def car(s: CarShape) -> Piece:
    hl, hw = s.length / 2, s.width / 2 - 0.07  # the door mirrors reach the full width
    r = s.wheel_r
    bl = hl - 0.03  # the body's ends: lamps, plates and bumpers stand out of them to the full length
    deck_x = -bl + s.tail_slope
    lower = [
        (-bl, s.clearance + 0.14),
        (-bl + 0.25, s.clearance),
        *_arch(s.axle_rear, r),
        (s.axle_rear + r + 0.2, s.clearance - 0.02),
        (s.axle_front - r - 0.2, s.clearance - 0.02),
        *_arch(s.axle_front, r),
        (bl - 0.2, s.clearance + 0.06),
        (bl, s.clearance + 0.22),
        (bl - 0.02, s.nose_z - 0.06),
        (bl - 0.18, s.nose_z),
        (s.windscreen_x, s.belt_z),
        (s.rear_glass_x, s.belt_z + 0.04),
        (deck_x, s.deck_z),
        (-bl, s.deck_z - 0.12),
    ]
    if s.bed:
        lower = [*lower[:-3], (s.rear_glass_x, s.belt_z), (-bl, s.belt_z)]
    body_hw = hw

    def tumble(z: float) -> float:
        return body_hw - max(0.0, z - s.belt_z + 0.15) * 0.15

    pieces = [prism(lower, tumble, Part.PAINT, _under)]
    roof_z = s.height
    green = [
        (s.rear_glass_x, s.belt_z + 0.03),
        (s.windscreen_x, s.belt_z - 0.01),
        (s.roof_front_x, roof_z),
        (s.roof_rear_x, roof_z),
    ]
    cabin_hw0 = tumble(s.belt_z) - 0.03

    def cabin(z: float) -> float:
        return cabin_hw0 - (z - s.belt_z) * 0.28

    def glass_or_roof(nx: float, nz: float) -> int:
        # the roof (level) and the rear face are paint: the rear window is a panel set into it;
        # a windscreen raked as far as 14 degrees from level stays glass
        return int(Part.PAINT) if nz > 0.97 or nz < -0.85 or nx < -0.2 else int(Part.GLASS)

    pieces.append(prism(green, cabin, Part.GLASS, glass_or_roof))
    # the rear window: narrower than the rear face, framed by thick pillars, inset from the roof
    a = np.array([s.rear_glass_x, s.belt_z + 0.03])
    b = np.array([s.roof_rear_x, roof_z])
    along = (b - a) / np.linalg.norm(b - a)
    outward = np.array([-along[1], along[0]])
    if outward[0] > 0:
        outward = -outward
    a0, b0 = a + along * 0.05 + outward * 0.003, b - along * 0.07 + outward * 0.003
    a1, b1 = a0 + outward * 0.006, b0 + outward * 0.006
    pieces.append(
        prism([tuple(a0), tuple(b0), tuple(b1), tuple(a1)], lambda z: 0.86 * cabin(z), Part.GLASS, Part.GLASS)
    )
    # pillars over the side glass: A along the windscreen, B in the middle, C at the rear
    out = 0.006

    def pillar_w(z: float) -> float:
        return cabin(z) + out

    t = 0.07
    pieces.append(
        prism(
            [
                (s.windscreen_x, s.belt_z),
                (s.windscreen_x - t * 1.6, s.belt_z),
                (s.roof_front_x - t, roof_z - 0.02),
                (s.roof_front_x + 0.01, roof_z - 0.02),
            ],
            pillar_w,
            Part.PAINT,
            Part.PAINT,
        )
    )
    bx = (s.windscreen_x + s.roof_rear_x) / 2 - 0.1
    pieces.append(
        prism(
            [
                (bx - 0.05, s.belt_z + 0.005),
                (bx + 0.05, s.belt_z + 0.005),
                (bx + 0.05, roof_z - 0.027),
                (bx - 0.05, roof_z - 0.027),
            ],
            lambda z: pillar_w(z) + 0.004,  # over the A pillar where they meet under the roof
            Part.TRIM,
            Part.TRIM,
        )
    )
    c_len = 0.3 if s.roof_rear_x - s.rear_glass_x > 0.25 else 0.12
    pieces.append(
        prism(
            [
                (s.rear_glass_x, s.belt_z + 0.03),
                (s.rear_glass_x + c_len + 0.25, s.belt_z + 0.03),
                (s.roof_rear_x + c_len * 0.5, roof_z - 0.02),
                (s.roof_rear_x, roof_z - 0.02),
            ],
            pillar_w,
            Part.PAINT,
            Part.PAINT,
        )
    )
    # body-colour skirt line, bumpers' black lower parts
    pieces.append(box(bl - 0.11, hl - 0.005, -hw + 0.05, hw - 0.05, s.clearance + 0.02, s.clearance + 0.3, Part.TRIM))
    pieces.append(box(-hl + 0.005, -bl + 0.14, -hw + 0.05, hw - 0.05, s.clearance + 0.02, s.clearance + 0.2, Part.TRIM))
    # front: grille, headlamps, plate
    fz = s.clearance + 0.22
    nose = s.nose_z - 0.06
    pieces.append(box(bl - 0.06, hl - 0.01, -0.42 * hw, 0.42 * hw, fz + 0.1, nose - 0.06, Part.TRIM))
    for side in (-1.0, 1.0):
        # headlamps out to the front corners, the indicator at their outer end
        y0, y1 = sorted((side * 0.48 * hw, side * 0.84 * hw))
        pieces.append(box(bl - 0.12, hl - 0.015, y0, y1, nose - 0.26, nose - 0.03, Part.HEADLAMP))
        y0, y1 = sorted((side * (0.84 * hw + 0.01), side * 0.97 * hw))
        pieces.append(box(bl - 0.12, hl - 0.015, y0, y1, nose - 0.2, nose - 0.03, Part.INDICATOR))
        # tail lamps across the rear's outer thirds, wrapping round onto the flanks
        ty0, ty1 = sorted((side * 0.42 * hw, side * 0.86 * hw))
        tz = min(s.deck_z - 0.16, s.belt_z) if not s.bed else s.belt_z - 0.2
        pieces.append(box(-hl + 0.005, -bl + 0.08, ty0, ty1, tz - 0.26, tz, Part.TAIL_LAMP))
        ty0, ty1 = sorted((side * (0.86 * hw + 0.01), side * 0.98 * hw))
        pieces.append(box(-hl + 0.005, -bl + 0.08, ty0, ty1, tz - 0.2, tz, Part.INDICATOR))
        wy0, wy1 = sorted((side * (hw - 0.02), side * (hw + 0.006)))
        pieces.append(box(-bl + 0.03, -bl + 0.3, wy0, wy1, tz - 0.15, tz - 0.01, Part.TAIL_LAMP))
        # door mirrors standing out of the body's sides on short arms
        my0, my1 = sorted((side * (hw - 0.05), side * (s.width / 2 - 0.004)))
        pieces.append(
            box(s.windscreen_x - 0.24, s.windscreen_x - 0.06, my0, my1, s.belt_z + 0.02, s.belt_z + 0.16, Part.PAINT)
        )
        ay0, ay1 = sorted((side * (hw - 0.04), side * (hw + 0.01)))
        pieces.append(
            box(s.windscreen_x - 0.15, s.windscreen_x - 0.08, ay0, ay1, s.belt_z - 0.04, s.belt_z + 0.05, Part.TRIM)
        )
        # door shut lines (front door from the A pillar to the B pillar, the rear door behind) and handles
        gy0, gy1 = sorted((side * (hw - 0.01), side * (hw + 0.003)))
        rear_door = bx - min(0.9, (bx - s.rear_glass_x) * 0.65)
        for gx in (s.windscreen_x + 0.05, bx, rear_door):
            pieces.append(box(gx - 0.006, gx + 0.006, gy0, gy1, s.clearance + 0.12, s.belt_z - 0.02, Part.TRIM))
        for hx in (bx + 0.12, rear_door + 0.12):
            pieces.append(box(hx - 0.07, hx + 0.07, gy0, gy1, s.belt_z - 0.12, s.belt_z - 0.09, Part.TRIM))
    pieces.append(box(hl - 0.04, hl, -0.26, 0.26, fz - 0.04, fz + 0.07, Part.PLATE))
    pieces.append(box(-hl, -hl + 0.04, -0.26, 0.26, s.clearance + 0.25, s.clearance + 0.37, Part.PLATE))
    if s.bed:  # the open bed's floor, seen from above, and its tailgate
        pieces.append(
            box(-hl + 0.05, s.rear_glass_x - 0.05, -hw + 0.08, hw - 0.08, s.belt_z - 0.02, s.belt_z + 0.005, Part.TRIM)
        )
    for x in (s.axle_front, s.axle_rear):
        for side in (-1.0, 1.0):
            pieces += wheel(x, r, side * (hw - 0.24), side * (hw - 0.02))
    # the underside between the wheels, dark
    pieces.append(box(s.axle_rear + r, s.axle_front - r, -hw + 0.15, hw - 0.15, 0.12, s.clearance, Part.UNDERBODY))
    return merge(pieces)


def _rear_doors(x: float, hw: float, z0: float, z1: float) -> list[Piece]:
    """The two doors of a box body's rear face at ``x`` (facing -x): frame, seam, lock rods."""
    frame = [(-hw + 0.02, -hw + 0.09, z0, z1), (hw - 0.09, hw - 0.02, z0, z1), (-hw + 0.09, hw - 0.09, z1 - 0.1, z1),
             (-hw + 0.09, hw - 0.09, z0, z0 + 0.12), (-0.02, 0.02, z0 + 0.12, z1 - 0.1)]  # fmt: skip
    pieces = [box(x - 0.012, x - 0.002, y0, y1, za, zb, Part.TRIM) for y0, y1, za, zb in frame]
    for y in (-hw + 0.4, -0.3, 0.3, hw - 0.4):  # lock rods, standing out of the doors
        pieces.append(box(x - 0.03, x - 0.016, y - 0.02, y + 0.02, z0 + 0.16, z1 - 0.14, Part.CHROME))
    return pieces


def _contour_marking(x0: float, x1: float, hw: float, z0: float, h: float) -> list[Piece]:
    """Yellow retro-reflective tape along the outline of a box body's rear face (at ``x0``) and
    of its sides (``x0`` to ``x1``, bottom ``z0``, top ``h``), a few millimetres proud of them."""
    rear = (x0 + 0.002, x0 + 0.006)
    pieces = [box(*rear, -hw + 0.03, hw - 0.03, z0 + 0.03, z0 + 0.09, Part.RETRO_YELLOW),
              box(*rear, -hw + 0.03, hw - 0.03, h - 0.085, h - 0.035, Part.RETRO_YELLOW)]  # fmt: skip
    for side in (-1.0, 1.0):
        y0, y1 = sorted((side * (hw - 0.075), side * (hw - 0.025)))
        pieces.append(box(*rear, y0, y1, z0 + 0.09, h - 0.085, Part.RETRO_YELLOW))
        y0, y1 = sorted((side * (hw + 0.002), side * (hw + 0.006)))
        pieces.append(box(x0 + 0.03, x1 - 0.03, y0, y1, z0 + 0.02, z0 + 0.08, Part.RETRO_YELLOW))
        pieces.append(box(x0 + 0.03, x1 - 0.03, y0, y1, h - 0.085, h - 0.035, Part.RETRO_YELLOW))
        for xa, xb in ((x0 + 0.03, x0 + 0.08), (x1 - 0.08, x1 - 0.03)):
            pieces.append(box(xa, xb, y0, y1, z0 + 0.08, h - 0.085, Part.RETRO_YELLOW))
    return pieces


SIDE_MARKER_SPACING_M = 3.0
"""Side marker lamps along a heavy vehicle's side at most this far apart (UN ECE R48: 3 m)."""


def _side_markers(x0: float, x1: float, y: float, z: float, clear: list[tuple[float, float]]) -> list[Piece]:
    """Amber side marker lamps (10 x 5 cm, 1.5 cm proud of the side at ``|y|``) from ``x0`` to
    ``x1`` at height ``z``, at most :data:`SIDE_MARKER_SPACING_M` apart, none in the ``clear``
    spans along the body (wheel arches, doors)."""
    steps = np.linspace(x0, x1, round((x1 - x0) / 0.1) + 1)
    free = [x for x in steps if not any(a - 0.1 < x < b + 0.1 for a, b in clear)]
    xs = free[:1]
    while free and free[-1] > xs[-1]:  # each next lamp as far on as the spacing allows, or past a clear span
        near = [x for x in free if xs[-1] < x <= xs[-1] + SIDE_MARKER_SPACING_M]
        xs.append(near[-1] if near else next(x for x in free if x > xs[-1]))
    pieces = []
    for side in (-1.0, 1.0):
        y0, y1 = sorted((side * (y - 0.015), side * y))
        pieces += [box(x - 0.05, x + 0.05, y0, y1, z - 0.025, z + 0.025, Part.SIDE_MARKER) for x in xs]
    return pieces


def _outline_lamps(x0: float, x1: float, hw: float, z: float, part: int) -> list[Piece]:
    """A pair of end-outline marker lamps (white ahead, red behind) at a body's top corners: from
    ``x0`` to ``x1`` along it, 10 cm wide, 5 cm inside ``hw`` of its centre line, 5 cm tall under ``z``."""
    pieces = []
    for side in (-1.0, 1.0):
        y0, y1 = sorted((side * (hw - 0.15), side * (hw - 0.05)))
        pieces.append(box(x0, x1, y0, y1, z - 0.05, z, part))
    return pieces


def box_truck(length: float = 8.0, width: float = 2.5, h: float = 3.5, trailer: bool = False) -> Piece:
    """A rigid box truck, or a tractor with a box semi-trailer."""
    hl, hw = length / 2, width / 2 - 0.01
    cab_l = 2.2
    cab_x1 = hl
    cab_x0 = hl - cab_l
    cab_top = min(h - 0.05, 3.0) if not trailer else min(h - 0.2, 3.1)
    face = cab_x1 - 0.02  # the cab's front: lamps, plate, grille and bumper stand out of it
    front_axle = hl - 1.2
    r = 0.52
    arch = _arch(front_axle, r)  # the front wheel's arch cut into the cab's lower edge
    cab = [(cab_x0, r), *arch, (face, r), (face, 1.5), (face - 0.12, 2.4), (face - 0.3, cab_top), (cab_x0, cab_top)]

    def cab_side(nx: float, nz: float) -> int:
        return int(Part.UNDERBODY) if nz < -0.6 else int(Part.CAB)

    pieces = [prism(cab, hw - 0.03, Part.CAB, cab_side)]
    # windscreen and side windows over the cab
    pieces.append(
        prism(
            [(face - 0.02, 1.55), (face + 0.004, 1.55), (face - 0.116, 2.38), (face - 0.14, 2.38)],
            hw - 0.12,
            Part.GLASS,
            Part.GLASS,
        )
    )
    pieces.append(box(cab_x0 + 0.75, face - 0.2, -hw + 0.005, hw - 0.005, 1.5, 2.4, Part.GLASS))  # doors' windows
    # the grille: dark slats across the front under the windscreen, the cab's colour between them
    for k in range(5):
        z = 0.95 + 0.11 * k
        pieces.append(box(cab_x1 - 0.05, cab_x1 - 0.01, -0.72 * hw, 0.72 * hw, z, z + 0.07, Part.TRIM))
    pieces.append(box(cab_x1 - 0.05, cab_x1 - 0.01, -0.55 * hw, 0.55 * hw, 0.72, 0.92, Part.TRIM))
    visor = (cab_top - 0.18, cab_top - 0.06)
    pieces.append(box(face - 0.33, face - 0.1, -hw + 0.04, hw - 0.04, *visor, Part.TRIM))
    for side in (-1.0, 1.0):
        # wind deflectors down the cab's front corners, the steps under the doors
        y0, y1 = sorted((side * (hw - 0.1), side * (hw - 0.01)))
        pieces.append(box(face - 0.3, face - 0.01, y0, y1, 1.0, cab_top - 0.25, Part.TRIM))
        s0, s1 = sorted((side * (hw - 0.25), side * (hw - 0.02)))
        step_x = (cab_x0 + 0.05, front_axle - r - 0.1)  # behind the front wheel's arch
        pieces.append(box(*step_x, s0, s1, 0.3, 0.5, Part.TRIM))
        pieces.append(box(*step_x, s0, s1, 0.62, 0.74, Part.TRIM))
    for side in (-1.0, 1.0):
        y0, y1 = sorted((side * 0.72 * hw, side * 0.86 * hw))
        pieces.append(box(cab_x1 - 0.05, cab_x1, y0, y1, 0.72, 0.9, Part.HEADLAMP))
        y0, y1 = sorted((side * (0.86 * hw + 0.01), side * 0.95 * hw))
        pieces.append(box(cab_x1 - 0.05, cab_x1, y0, y1, 0.72, 0.9, Part.INDICATOR))
        m0, m1 = sorted((side * (hw - 0.06), side * hw))
        pieces.append(box(cab_x1 - 0.4, cab_x1 - 0.3, m0, m1, 1.63, 2.2, Part.TRIM))  # mirror arms
    pieces.append(box(cab_x1 - 0.04, cab_x1, -0.26, 0.26, 0.58, 0.69, Part.PLATE))
    pieces.append(box(cab_x1 - 0.15, cab_x1 - 0.005, -hw + 0.02, hw - 0.02, 0.45, 0.7, Part.TRIM))  # bumper
    gap = 0.35
    box_x1 = cab_x0 - (0.9 if trailer else gap)
    box_z0 = 1.3 if trailer else 1.2
    inset = 0.025  # the box's panels sit inside its aluminium frame
    pieces.append(box(-hl + 0.02, box_x1, -hw + inset, hw - inset, box_z0, h - 0.06, Part.CARGO))
    # the frame: bottom rail, roof rail, corner posts
    pieces.append(box(-hl + 0.015, box_x1 + 0.005, -hw, hw, box_z0 - 0.02, box_z0 + 0.16, Part.CHROME))
    pieces.append(box(-hl + 0.015, box_x1 + 0.005, -hw, hw, h - 0.1, h, Part.CHROME))
    for x0, x1 in ((-hl + 0.015, -hl + 0.09), (box_x1 - 0.07, box_x1 + 0.005)):
        for side in (-1.0, 1.0):
            y0, y1 = sorted((side * (hw - 0.07), side * hw))
            pieces.append(box(x0, x1, y0, y1, box_z0 + 0.16, h - 0.1, Part.CHROME))
    pieces.append(box(-hl + 0.2, hl - 0.3, -0.45, 0.45, 0.5, box_z0 - 0.03, Part.UNDERBODY))  # chassis
    pieces += _contour_marking(-hl, box_x1, hw, box_z0, h)
    pieces += _outline_lamps(-hl - 0.002, -hl + 0.03, hw, h - 0.12, Part.REAR_OUTLINE)  # under the roof's tape
    pieces += _outline_lamps(face - 0.12, face - 0.09, hw, cab_top - 0.07, Part.FRONT_OUTLINE)  # on the sun visor
    if h - 0.06 - cab_top > 0.15:  # a deflector on the cab's roof, rising to the box's front
        ramp = [(face - 0.5, cab_top - 0.02), (cab_x0 + 0.02, cab_top - 0.02), (cab_x0 + 0.02, h - 0.11),
                (cab_x0 + 0.45, h - 0.11)]  # fmt: skip
        pieces.append(prism(ramp, hw - 0.16, Part.CAB, Part.CAB))
    rear_axle = -hl + (1.3 if trailer else 1.8)
    rear_axles = [-hl + 1.3, -hl + 2.6, -hl + 3.9] if trailer else [rear_axle]
    drive_axle = front_axle - 3.6  # a tractor's wheelbase: its drive axle under the trailer's front
    guard = (rear_axles[-1] + r + 0.15, drive_axle - r - 0.15) if trailer else (rear_axle + r + 0.15, hl - 1.9)
    for side in (-1.0, 1.0):  # side guards (two rails) between the wheels, rear lamps
        y0, y1 = sorted((side * (hw - 0.09), side * (hw - 0.05)))
        for z in (0.5, 0.78):
            pieces.append(box(*guard, y0, y1, z, z + 0.12, Part.TRIM))
        t0, t1 = sorted((side * 0.7 * hw, side * 0.84 * hw))
        pieces.append(box(-hl, -hl + 0.05, t0, t1, box_z0 - 0.3, box_z0 - 0.12, Part.TAIL_LAMP))
        t0, t1 = sorted((side * (0.84 * hw + 0.01), side * 0.95 * hw))
        pieces.append(box(-hl, -hl + 0.05, t0, t1, box_z0 - 0.3, box_z0 - 0.12, Part.INDICATOR))
        # mudguards over the rear wheels
        g0, g1 = sorted((side * (hw - 0.36), side * (hw - 0.02)))
        for x in rear_axles:
            pieces.append(box(x - r - 0.08, x + r + 0.08, g0, g1, 2 * r + 0.04, 2 * r + 0.1, Part.TRIM))
    # the fuel tank on the left behind the cab, the battery box on the right
    tank_x1 = front_axle - r - 0.25
    pieces.append(box(tank_x1 - 1.1, tank_x1, 0.5, hw - 0.12, 0.42, 0.95, Part.CHROME))
    pieces.append(box(tank_x1 - 0.8, tank_x1, -hw + 0.12, -0.5, 0.45, 0.95, Part.TRIM))
    pieces.append(box(-hl + 0.01, -hl + 0.06, -hw + 0.05, hw - 0.05, box_z0 - 0.35, box_z0 - 0.05, Part.TRIM))
    pieces.append(box(-hl, -hl + 0.04, -0.26, 0.26, box_z0 - 0.48, box_z0 - 0.36, Part.PLATE))
    # the rear doors in unpainted white whatever the box's colour
    dy = hw - inset - 0.01
    pieces.append(box(-hl + 0.011, -hl + 0.019, -dy, dy, box_z0 + 0.165, h - 0.105, Part.LIVERY))
    pieces += _rear_doors(-hl + 0.02, hw, box_z0 + 0.17, h - 0.11)
    # mudflaps behind the rear wheels
    for side in (-1.0, 1.0):
        f0, f1 = sorted((side * (hw - 0.36), side * (hw - 0.04)))
        x = rear_axles[0] - r - 0.15
        pieces.append(box(x - 0.02, x, f0, f1, 0.25, 2 * r + 0.05, Part.TRIM))
    pieces.append(box(-hl + 0.12, -hl + 0.24, -hw + 0.2, hw - 0.2, 0.42, 0.56, Part.TRIM))  # underrun guard
    axles = [front_axle, *rear_axles]
    if trailer:
        axles.append(drive_axle)
    # under the box's bottom rail, over the rear wheels' guards, from the rear to behind the cab's wheel
    pieces += _side_markers(-hl + 0.3, front_axle - r - 0.3, hw, box_z0 - 0.05, [])
    for x in axles:
        for side in (-1.0, 1.0):
            pieces += wheel(x, r, side * (hw - 0.32), side * (hw - 0.04), rim_share=0.62, hub=Part.CHROME)
    return merge(pieces)


BUS_MIRROR_REACH_M = 0.32
"""A bus's mirrors hang on arms this far ahead of its front face (inside its box)."""


def _bus_front(face: float, hw: float, floor: float, top: float, coach: bool) -> list[Piece]:
    """A bus's front at ``face`` (facing +x): a windscreen down to the bumper, above it the
    destination display (orange LED text on black), wipers, lamp clusters in dark housings,
    and the mirrors hanging on arms from the roof's front corners ("rabbit ears")."""
    pieces = []
    win0, win1 = (0.95, top - 0.52) if not coach else (1.3, top - 0.45)
    pieces.append(box(face + 0.002, face + 0.01, -hw + 0.07, hw - 0.07, win0, win1, Part.GLASS))
    d0, d1 = win1 + 0.05, top - 0.1  # the display's glass band over the windscreen
    pieces.append(box(face + 0.002, face + 0.01, -hw + 0.12, hw - 0.12, d0, d1, Part.GLASS))
    zc, tall = (d0 + d1) / 2, min(0.2, 0.6 * (d1 - d0))
    # the route number on the left (seen from ahead), the destination's letters to its right
    blocks = [(0.62, 0.72), (0.76, 0.86)] + [(0.47 - 0.1 * k, 0.54 - 0.1 * k) for k in range(10) if k != 4]
    for y0, y1 in blocks:
        t = tall if y0 > 0.6 else 0.7 * tall
        pieces.append(box(face + 0.011, face + 0.015, -y1, -y0, zc - t / 2, zc + t / 2, Part.DISPLAY))
    for y in (-0.55, 0.25):  # wipers resting along the windscreen's base, tilted up
        a, b = np.array([face + 0.016, y, win0 + 0.06]), np.array([face + 0.016, y + 0.75, win0 + 0.2])
        pieces.append(tube(a, b, 0.014, 0.01, Part.TRIM, sides=4))
    for side in (-1.0, 1.0):
        h0, h1 = sorted((side * (hw - 0.04), side * (hw - 0.52)))  # the lamps' dark housing
        pieces.append(box(face + 0.002, face + 0.012, h0, h1, floor + 0.28, floor + 0.58, Part.TRIM))
        for yc in (hw - 0.34, hw - 0.18):
            l0, l1 = sorted((side * (yc - 0.065), side * (yc + 0.065)))
            pieces.append(box(face + 0.013, face + 0.02, l0, l1, floor + 0.36, floor + 0.5, Part.HEADLAMP))
        i0, i1 = sorted((side * (hw - 0.1), side * (hw - 0.05)))
        pieces.append(box(face + 0.013, face + 0.02, i0, i1, floor + 0.32, floor + 0.54, Part.INDICATOR))
        # the mirror's arm from the roof's corner, forward and down; its head in front of the
        # windscreen's upper corner
        root = np.array([face - 0.1, side * (hw - 0.12), top - 0.08])
        elbow = np.array([face + BUS_MIRROR_REACH_M - 0.04, side * (hw - 0.1), top - 0.2])
        pieces.append(tube(root, elbow, 0.025, 0.025, Part.TRIM, sides=4))
        m0, m1 = sorted((side * (hw - 0.3), side * hw))
        x0 = face + BUS_MIRROR_REACH_M - 0.09
        pieces.append(box(x0, x0 + 0.09, m0, m1, top - 0.75, top - 0.2, Part.TRIM))
    return pieces


def bus(length: float = 12.0, width: float = 2.55, h: float = 3.2, coach: bool = False) -> Piece:
    hl, hw = (length - BUS_MIRROR_REACH_M) / 2, width / 2 - 0.01  # the body; the mirrors reach ahead of it
    floor = 0.35 if not coach else 0.45
    r = 0.5
    axles = (hl - 2.6, -hl + 3.2) if not coach else (hl - 2.6, -hl + 2.6, -hl + 3.9)
    bl = hl - 0.02  # the body's ends: lamps, glass, plates stand out of them
    bottom: list[tuple[float, float]] = [(-bl, floor)]
    for x in sorted(axles):
        bottom += [(x - r - 0.06, floor), *_arch(x, r)[1:-1], (x + r + 0.06, floor)]
    top = h - 0.16 if not coach else h  # a city bus carries its air conditioning on the roof
    body = [*bottom, (bl, floor), (bl, top - 0.12), (bl - 0.08, top), (-bl + 0.1, top), (-bl, top - 0.2)]

    def livery(nx: float, nz: float) -> int:
        return int(Part.UNDERBODY) if nz < -0.6 else int(Part.CARGO)

    pieces = [prism(body, hw - 0.02, Part.CARGO, livery)]  # buses in fleet colours, not car paint
    win0, win1 = (1.05, top - 0.3) if not coach else (1.75, top - 0.25)
    # side windows as glass panels with pillars, a windscreen to low down, doors on the right
    for side in (-1.0, 1.0):
        g0, g1 = sorted((side * (hw - 0.018), side * (hw - 0.004)))
        pieces.append(box(-hl + 0.6, hl - 0.8, g0, g1, win0, win1, Part.GLASS))
        p0, p1 = sorted((side * (hw - 0.021), side * hw))
        for x in np.arange(-hl + 0.6, hl - 0.7, 1.4 if not coach else 1.2):
            pieces.append(
                box(
                    x - 0.06,
                    x + 0.06,
                    p0,
                    p1,
                    win0 + 0.002,
                    win1 - 0.002,
                    Part.TRIM,
                )
            )
        r0, r1 = sorted((side * 0.8 * hw, side * 0.97 * hw))  # tall lamp clusters at the rear corners
        pieces.append(box(-hl, -hl + 0.03, r0, r1, floor + 0.3, floor + 0.9, Part.TAIL_LAMP))
        pieces.append(box(-hl, -hl + 0.03, r0, r1, floor + 0.92, floor + 1.15, Part.INDICATOR))
    pieces += _bus_front(bl, hw, floor, top, coach)
    pieces += _outline_lamps(bl - 0.06, bl + 0.012, hw, top, Part.FRONT_OUTLINE)  # over the mirrors' arms
    pieces += _outline_lamps(-hl, -bl + 0.02, hw, top - 0.22, Part.REAR_OUTLINE)
    doors = [(x - 0.6, x + 0.6) for x in (hl - 1.4, 0.3)] if not coach else []
    arches = [(x - r - 0.1, x + r + 0.1) for x in axles]
    pieces += _side_markers(-hl + 0.5, hl - 0.6, hw + 0.008, floor + 0.2, arches + doors)
    pieces.append(box(-hl, -bl - 0.002, -hw + 0.22, hw - 0.22, top - 1.25, top - 0.55, Part.GLASS))
    pieces.append(box(-hl, -bl - 0.002, -0.6, 0.6, top - 0.48, top - 0.3, Part.TRIM))  # route number
    for k in range(5):  # the engine hatch's grille
        z = floor + 0.75 + 0.12 * k
        pieces.append(box(-hl + 0.004, -bl - 0.001, -0.85, 0.85, z, z + 0.06, Part.TRIM))
    pieces.append(box(-hl + 0.005, -bl + 0.1, -hw + 0.01, hw - 0.01, floor + 0.01, floor + 0.28, Part.TRIM))  # bumper
    if not coach:
        pieces.append(box(-hl * 0.55, hl * 0.35, -hw + 0.35, hw - 0.35, top - 0.01, h, Part.CARGO))  # roof unit
    if not coach:
        for x in (hl - 1.4, 0.3):  # doors on the kerb side (right)
            pieces.append(box(x - 0.6, x + 0.6, -hw + 0.002, -hw + 0.025, floor + 0.05, top - 0.35, Part.GLASS))
    else:
        pieces.append(box(-hl + 2.5, hl - 3.0, -hw, hw, floor + 0.1, 1.3, Part.CARGO))  # luggage bay doors
    pieces.append(box(hl - 0.04, hl, -0.26, 0.26, floor + 0.12, floor + 0.24, Part.PLATE))
    pieces.append(box(-hl, -hl + 0.04, -0.26, 0.26, floor + 0.38, floor + 0.5, Part.PLATE))
    pieces.append(box(hl - 0.1, hl - 0.008, -hw + 0.01, hw - 0.01, floor + 0.01, floor + 0.25, Part.TRIM))
    for x in axles:
        for side in (-1.0, 1.0):
            pieces += wheel(x, r, side * (hw - 0.32), side * (hw - 0.03))
    return merge(pieces)


# People -----------------------------------------------------------------------------------

GAIT_PHASES = 8
"""Walking and pedalling poses per cycle (plus one standing pose)."""
STEP_PER_HEIGHT = 0.415
"""A step (heel to heel, half a gait cycle) at the preferred pace, over the walker's height (the
pedometer rule: 0.415 for men, 0.413 for women)."""
PREFERRED_PACE_MPS = 1.34
"""The walking speed of that step (adults' preferred pace, about 1.3-1.4 m/s)."""
STEP_SPEED_EXPONENT = 0.42
"""Step length grows as speed^0.42 (Grieve 1968; Kuo 2001, J. Biomech. Eng. 123: 264-269); the
cadence makes up the rest of the speed."""
PACES_MPS = (0.5, 0.8, 1.1, 1.4)
"""Walking paces drawn (each in :data:`GAIT_PHASES` poses): a walker is drawn at the nearest;
faster walkers take the fastest pace's steps, at a higher cadence."""
WALKER_LENGTH_PER_HEIGHT = 0.570
"""A walker's box length over its height: the body's extent along its heading over every gait
phase at the fastest pace (feet and swinging arms: 1.00 m for a walker 1.75 m tall), so that the box
holds the stride and the body is drawn at its own proportions (tested)."""
STANCE = 0.6
"""Share of the gait cycle a foot is on the ground (heel strike at 0, toe off at 0.6)."""


def step_m(height_m: float, speed_mps: float) -> float:
    """A walker's step length (m, heel to heel) at a speed (clamped to the drawn paces)."""
    pace = min(max(speed_mps, PACES_MPS[0]), PACES_MPS[-1])
    return float(STEP_PER_HEIGHT * height_m * (pace / PREFERRED_PACE_MPS) ** STEP_SPEED_EXPONENT)


def stride_m(height_m: float, speed_mps: float) -> float:
    """The distance a walker covers over one gait cycle (two steps)."""
    return 2.0 * step_m(height_m, speed_mps)


def pace_index(speed_mps: float) -> int:
    """The drawn pace (index into :data:`PACES_MPS`) nearest a speed."""
    return int(np.argmin([abs(speed_mps - p) for p in PACES_MPS]))


def walker_length_m(height_m: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """Box lengths (m, to the centimetre) that hold walkers' strides, from their heights."""
    return np.round(WALKER_LENGTH_PER_HEIGHT * np.asarray(height_m, np.float64), 2)


def _rot(theta: float, dx: float, dz: float) -> tuple[float, float]:
    """(dx, dz) turned by ``theta`` in the x-z plane (toe up for positive angles)."""
    c, s = math.cos(theta), math.sin(theta)
    return c * dx - s * dz, s * dx + c * dz


def foot_pose(u: float, step: float, s: float) -> tuple[float, float, float]:
    """Where a walking foot is at its leg's phase ``u`` (cycles from its heel strike, 0-1): the
    ankle's x (ahead of the hips) and height, and the foot's pitch (radians, toe up positive).
    On the ground (0 to :data:`STANCE`) the heel strikes toe up, the foot rolls flat and moves
    back under the walker at its speed, then rolls over the toe, the heel rising; in the swing
    it is carried forward, lifted, to the next heel strike. ``step``: the step length; ``s``:
    the walker's scale (height over 1.75 m)."""
    stride = 2.0 * step
    heel, toe = (-0.06 * s, -0.07 * s), (0.16 * s, -0.07 * s)  # the sole's ends from the ankle
    strike_pitch, off_pitch, flat_at, roll_at = 0.3, -0.9, 0.08, 0.4

    def on_heel(x_heel: float, pitch: float) -> tuple[float, float, float]:
        dx, dz = _rot(pitch, *heel)
        return x_heel - dx, -dz, pitch

    def on_toe(x_toe: float, pitch: float) -> tuple[float, float, float]:
        dx, dz = _rot(pitch, *toe)
        return x_toe - dx, -dz, pitch

    def heel_x(v: float) -> float:  # the heel on the ground, moving back at the walker's speed
        return step / 2.0 + heel[0] - stride * v  # the hips midway between the ankles at heel strike

    u %= 1.0
    if u < flat_at:
        return on_heel(heel_x(u), strike_pitch * (1.0 - u / flat_at))
    if u < roll_at:
        return on_heel(heel_x(u), 0.0)
    toe_at_roll = heel_x(roll_at) - heel[0] + toe[0]
    if u < STANCE:
        w = (u - roll_at) / (STANCE - roll_at)
        return on_toe(toe_at_roll - stride * (u - roll_at), off_pitch * w)
    x0, z0, _ = on_toe(toe_at_roll - stride * (STANCE - roll_at), off_pitch)
    x1, z1, _ = on_heel(heel_x(0.0), strike_pitch)
    w = (u - STANCE) / (1.0 - STANCE)
    ease = w * w * (3.0 - 2.0 * w)
    lift = 0.09 * s * math.sin(math.pi * w)
    return x0 + (x1 - x0) * ease, z0 + (z1 - z0) * ease + lift, off_pitch + (strike_pitch - off_pitch) * ease


RIDER_LEAN_RAD = {"bicycle": math.radians(36.0), "motorcycle": math.radians(38.0)}
"""How far a rider's trunk leans forward from the hips (its length kept)."""
CRANK_M = 0.17
"""A bicycle's crank length (the pedals' circle's radius)."""


def person(
    phase: float | None, height: float = 1.75, build: float = 1.0, seated: str | None = None, pedal_phase: float = 0.0,
    pace: float = PREFERRED_PACE_MPS,
) -> list[Piece]:  # fmt: skip
    """A person standing (``phase`` None) or walking at gait ``phase`` (radians: the left foot's
    heel strikes at 0, the right's at pi) at ``pace`` (m/s), centred at the hips in x-y, feet on
    z = 0; ``seated``: 'bicycle' or 'motorcycle' for a rider (hips at the seat, x = 0 at the
    seat, trunk leaning forward, hands forward): a cyclist's feet on the pedals (the crank's
    axle 0.18 m ahead of the hips, 0.3 m up, at ``pedal_phase``), in everyday clothes; a
    motorcyclist's feet on the footrests, in a riding jacket, gloves, boots and a full-face helmet
    with a dark visor."""
    s = height / 1.75
    hip_z = 0.92 * s
    shoulder_z = 1.45 * s
    hip_w = 0.1 * s * build
    sh_w = 0.19 * s * build
    pieces: list[Piece] = []
    leg_len_thigh, leg_len_shin = 0.45 * s, 0.45 * s
    moto = seated == "motorcycle"
    top = Part.JACKET if moto else Part.TOP
    hand_part = Part.SHOES if moto else Part.SKIN  # riding gloves
    if seated is None:
        legs = _legs(phase, pace, s, build, hip_z, hip_w)
        pieces += legs[0]
        hip_z += legs[1]  # the hips ride lower while both feet are on the ground
        shoulder_z += legs[1]
    else:
        seat = np.array([0.0, 0.0, hip_z])
        for side in (1.0, -1.0):
            if seated == "bicycle":
                ph = pedal_phase + (0 if side > 0 else math.pi)
                foot = np.array([0.18 + CRANK_M * math.cos(ph), side * 0.12 * s, 0.3 + CRANK_M * math.sin(ph)])
            else:
                foot = np.array([0.2, side * 0.2 * s, hip_z - 0.5 * s])
            hip = seat + np.array([0.0, side * hip_w, 0.0])
            d = np.linalg.norm(foot - hip)
            reach = leg_len_thigh + leg_len_shin
            mid = (hip + foot) / 2
            bend = math.sqrt(max(float(reach**2 / 4 - d**2 / 4), 0.0))
            knee = mid + np.array([bend, 0.0, 0.3 * bend])
            pieces.append(tube(hip, knee, 0.085 * s, 0.06 * s, Part.TROUSERS))
            pieces.append(tube(knee, foot, 0.06 * s, 0.045 * s, Part.TROUSERS))
            pieces.append(
                box(
                    foot[0] - 0.05,
                    foot[0] + 0.13,
                    foot[1] - 0.04,
                    foot[1] + 0.04,
                    foot[2] - 0.06,
                    foot[2] + (0.06 if moto else 0.02),  # boots up the ankle
                    Part.SHOES,
                )
            )
    if seated is None:
        chest = np.array([0.0, 0.0, shoulder_z])
        waist = np.array([0.0, 0.0, hip_z + 0.2 * s])
    else:  # the trunk turned forward about the hips
        lean = RIDER_LEAN_RAD[seated]
        trunk = shoulder_z - hip_z
        chest = np.array([math.sin(lean) * trunk, 0.0, hip_z + math.cos(lean) * trunk])
        waist = np.array([math.sin(lean) * 0.2 * s, 0.0, hip_z + math.cos(lean) * 0.2 * s])
    # the trunk: hips, a narrower waist, a chest wider than deep, rounded shoulders
    hips = np.array([0.0, 0.0, hip_z - 0.05 * s])
    pieces.append(tube(hips, waist, 0.16 * s * build, 0.145 * s * build, top, sides=10, flat=0.7))
    pieces.append(tube(waist, chest - np.array([0, 0, 0.06 * s]), 0.145 * s * build, 0.19 * s * build, top,
                       sides=10, flat=0.62))  # fmt: skip
    pieces.append(blob(tuple(chest - np.array([0, 0, 0.06 * s])), (0.12 * s * build, 0.19 * s * build, 0.07 * s),
                       top, rings=4, segments=10))  # fmt: skip
    neck = chest + np.array([0.0, 0.0, 0.06 * s])
    head_c = neck + np.array([0.02, 0.0, 0.13 * s])
    pieces.append(tube(chest, neck, 0.05 * s, 0.05 * s, top if moto else Part.SKIN))
    if moto:  # a full-face helmet over the head, its dark visor across the front
        centre = head_c + np.array([0.0, 0.0, 0.01 * s])
        pieces.append(blob(tuple(centre), (0.14 * s, 0.12 * s, 0.135 * s), Part.HELMET, rings=5, segments=10))
        pieces.append(blob(tuple(centre + np.array([0.08 * s, 0.0, 0.0])), (0.07 * s, 0.1 * s, 0.065 * s),
                           Part.GLASS, rings=4, segments=10))  # fmt: skip
    else:
        pieces.append(blob(tuple(head_c), (0.1 * s, 0.085 * s, 0.115 * s), Part.SKIN))
        pieces.append(
            blob(tuple(head_c + np.array([-0.015, 0.0, 0.035 * s])), (0.1 * s, 0.09 * s, 0.09 * s), Part.HAIR)
        )
    for side in (1.0, -1.0):
        shoulder = chest + np.array([0.0, side * sh_w, -0.07 * s])
        if seated is None:  # arms hang clear of the waist, swinging against the legs
            # each arm swings against its own side's leg: furthest back as that heel strikes
            swing = 0.35 * step_m(1.0, pace) / step_m(1.0, PREFERRED_PACE_MPS)
            a = 0.0 if phase is None else -swing * math.cos(phase + (0 if side > 0 else math.pi))
            elbow = shoulder + 0.3 * s * np.array([math.sin(a), 0.1 * side, -math.cos(a)])
            hand = elbow + 0.27 * s * np.array([math.sin(a + 0.25 * abs(a) + 0.1), 0.06 * side, -math.cos(a + 0.1)])
        else:
            hand = (
                np.array([0.68, side * 0.27, hip_z + 0.06 * s])  # on the bicycle's bars
                if seated == "bicycle"
                else np.array([0.76, side * 0.31, hip_z + 0.25 * s])  # on the motorcycle's bars
            )
            elbow = (shoulder + hand) / 2 + np.array([0.0, side * 0.04, -0.08])
        pieces.append(tube(shoulder, elbow, 0.05 * s * build, 0.042 * s * build, top))
        pieces.append(tube(elbow, hand, 0.042 * s * build, 0.035 * s, top))
        pieces.append(blob(tuple(hand), (0.04 * s, 0.03 * s, 0.045 * s), hand_part, rings=3, segments=6))
    return pieces


def _legs(
    phase: float | None, pace: float, s: float, build: float, hip_z: float, hip_w: float
) -> tuple[list[Piece], float]:  # fmt: skip
    """A walker's trouser legs and shoes, and how far its hips are lowered (m, <= 0): each foot
    where :func:`foot_pose` puts it, each knee bent forward so thigh and shin reach it (the hips
    lowered where the two feet, a step apart, need it)."""
    thigh, shin = 0.44 * s, 0.41 * s  # hip to knee, knee to ankle: the ankle 7 cm up standing
    reach = 0.995 * (thigh + shin)  # the knee never quite straight
    feet = []
    for sgn in (1.0, -1.0):
        if phase is None:
            feet.append((0.0, 0.07 * s, 0.0))
        else:
            u = (phase / (2 * math.pi) + (0.0 if sgn > 0 else 0.5)) % 1.0
            feet.append(foot_pose(u, step_m(1.75 * s, pace), s))
    drop = 0.0
    if phase is not None:
        top = min(z + math.sqrt(max(reach**2 - x**2, 0.0)) for x, z, _ in feet)
        drop = min(top - hip_z, 0.0)
    pieces: list[Piece] = []
    for (x, z, pitch), side in zip(feet, (1.0, -1.0), strict=True):
        hip = np.array([0.0, side * hip_w, hip_z + drop])
        ankle = np.array([x, side * hip_w, z])
        d_vec = ankle - hip
        d = float(np.linalg.norm(d_vec))
        e = d_vec / d
        if d >= thigh + shin - 1e-9:
            knee = hip + e * thigh
        else:
            along = (thigh**2 - shin**2 + d**2) / (2 * d)
            knee = hip + e * along + np.array([-e[2], 0.0, e[0]]) * math.sqrt(max(thigh**2 - along**2, 0.0))
        # trouser legs: about 20 cm across at the thigh (the two meet at the crotch), 15 cm
        # at the knee, 12 cm at the hem
        pieces.append(tube(hip, knee, 0.1 * s * build, 0.075 * s * build, Part.TROUSERS))
        pieces.append(tube(knee, ankle, 0.075 * s * build, 0.058 * s, Part.TROUSERS))
        sole = [(-0.06 * s, -0.07 * s), (0.16 * s, -0.07 * s), (0.16 * s, 0.02 * s), (-0.06 * s, 0.02 * s)]
        outline = [(x + dx, z + dz) for dx, dz in (_rot(pitch, *c) for c in sole)]
        pieces.append(prism(outline, 0.045 * s, Part.SHOES, Part.SHOES, side * hip_w))
    return pieces, drop


def pedestrian(phase: float | None, build: float = 1.0, pace: float = PREFERRED_PACE_MPS) -> Piece:
    return merge(person(phase, 1.75, build, pace=pace))


def _arc(cx: float, cz: float, r0: float, r1: float, a0: float, a1: float, n: int = 8) -> list[tuple[float, float]]:
    """The outline of a ring's sector in x-z (angles in radians from +x, counter-clockwise)."""
    angles = [a0 + (a1 - a0) * i / n for i in range(n + 1)]
    outer = [(cx + r1 * math.cos(t), cz + r1 * math.sin(t)) for t in angles]
    inner = [(cx + r0 * math.cos(t), cz + r0 * math.sin(t)) for t in reversed(angles)]
    return outer + inner


def bicycle(pedal_phase: float) -> Piece:
    """A city bicycle (28-inch wheels, 4.5 cm tyres on silver rims, a diamond frame of 3.6 cm
    tubes painted in the frame's colour, saddle, bars, cranks and pedals) with its rider
    pedalling at ``pedal_phase`` (radians)."""
    wheel_r = 0.35
    rear, front = -0.5, 0.55
    rider_h = 1.78
    seat = np.array([-0.18, 0.0, 0.93])  # the saddle's top, under the rider's hips
    lift = seat[2] + 0.03 - 0.92 * rider_h / 1.75  # the rider's z in the bicycle's
    bb = np.array([0.0, 0.0, 0.3 + lift - 0.075])  # the crank's axle under the pedalling feet
    pieces = ring_wheel(rear, wheel_r, 0.022) + ring_wheel(front, wheel_r, 0.022)
    axle_r = np.array([rear, 0.0, wheel_r])
    axle_f = np.array([front, 0.0, wheel_r])
    seat_top = bb + 0.8 * (seat - bb)  # the seat tube's top
    head_top, head_bottom = np.array([0.4, 0.0, 0.78]), np.array([0.46, 0.0, 0.62])

    def rod(p: F64, q: F64, r: float, part: int = Part.FRAME) -> None:
        pieces.append(tube(np.asarray(p, float), np.asarray(q, float), r, r, part, sides=6))

    rod(bb, seat_top, 0.017)  # seat tube
    rod(seat_top, head_top + np.array([0.0, 0.0, -0.02]), 0.017)  # top tube
    rod(bb, head_bottom + np.array([-0.01, 0.0, 0.03]), 0.02)  # down tube
    rod(head_bottom, head_top, 0.02)  # head tube
    for side in (1.0, -1.0):
        y = np.array([0.0, side * 0.055, 0.0])
        rod(bb + y * 0.6, axle_r + y, 0.011)  # chainstays
        rod(seat_top + y * 0.3, axle_r + y, 0.01)  # seatstays
        rod(head_bottom + y * 0.6, axle_f + y * 0.8, 0.012)  # fork legs
    rod(seat_top, seat + np.array([0.0, 0.0, -0.01]), 0.012, Part.CHROME)  # seat post
    stem = np.array([0.43, 0.0, 0.93])
    bar = np.array([0.5, 0.0, 0.985])
    rod(head_top, stem, 0.014, Part.CHROME)
    rod(stem, bar, 0.013, Part.CHROME)
    pieces.append(tube(bar + np.array([0.0, -0.2, 0.0]), bar + np.array([0.0, 0.2, 0.0]), 0.012, 0.012, Part.CHROME))
    for side in (1.0, -1.0):  # grips
        pieces.append(tube(bar + np.array([0.0, side * 0.19, 0.0]), bar + np.array([0.0, side * 0.3, 0.0]), 0.017,
                           0.017, Part.TRIM))  # fmt: skip
    pieces.append(prism([(seat[0] - 0.11, seat[2] - 0.045), (seat[0] + 0.13, seat[2] - 0.03),
                         (seat[0] + 0.13, seat[2] - 0.005), (seat[0] - 0.1, seat[2] + 0.005)], 0.075, Part.TRIM,
                        Part.TRIM))  # saddle  # fmt: skip
    pieces.append(prism(circle(bb[0], bb[2], 0.1, 16), 0.004, Part.CHROME, Part.CHROME, -0.075,
                        hole=circle(bb[0], bb[2], 0.07, 16)))  # chainring  # fmt: skip
    for side in (1.0, -1.0):  # cranks and pedals, under the shoes
        ph = pedal_phase + (0 if side > 0 else math.pi)
        pedal = bb + np.array([CRANK_M * math.cos(ph), 0.0, CRANK_M * math.sin(ph)])
        rod(bb + np.array([0.0, side * 0.085, 0.0]), pedal + np.array([0.0, side * 0.085, 0.0]), 0.012, Part.CHROME)
        y0, y1 = sorted((side * 0.09, side * 0.15))
        pieces.append(box(pedal[0] - 0.05, pedal[0] + 0.05, y0, y1, pedal[2] - 0.014, pedal[2] + 0.004, Part.TRIM))
    rider = person(None, rider_h, 1.0, "bicycle", pedal_phase)
    rider = [Piece(p.vertices + np.array([seat[0], 0.0, lift]), p.triangles, p.parts) for p in rider]
    return merge(pieces + rider)


def spoked_wheel(x: float, r: float, half_width: float, spokes: int = 5) -> list[Piece]:
    """A motorcycle's wheel: a deep tyre ring on a narrow rim, open between cast spokes (the
    road behind shows through), a hub and a brake disc."""
    tyre = prism(circle(x, r, r, 18), half_width, Part.TYRE, Part.TYRE, hole=circle(x, r, 0.7 * r, 18))
    rim = prism(circle(x, r, 0.705 * r, 18), 0.55 * half_width, Part.RIM, Part.RIM, hole=circle(x, r, 0.62 * r, 18))
    hub = prism(circle(x, r, 0.14 * r, 8), 0.8 * half_width, Part.ENGINE, Part.ENGINE)
    disc = prism(circle(x, r, 0.45 * r, 12), 0.008, Part.CHROME, Part.CHROME, 0.9 * half_width,
                 hole=circle(x, r, 0.3 * r, 12))  # fmt: skip
    pieces = [tyre, rim, hub, disc]
    centre = np.array([x, 0.0, r])
    for k in range(spokes):
        a = 2 * math.pi * k / spokes + 0.3
        along = np.array([math.cos(a), 0.0, math.sin(a)])
        pieces.append(tube(centre + 0.13 * r * along, centre + 0.64 * r * along, 0.022, 0.016, Part.RIM, sides=4))
    return pieces


def motorcycle() -> Piece:
    """A naked road motorcycle with its rider: a dark engine (crankcase and a forward-leaning
    cylinder block) with its exhaust, a painted tank, seat and tail, front fender, round
    headlamp, forks, bars and mirrors, the frame and swingarm in the frame's colour; the rider
    leaning to the bars, feet on the footrests."""
    r = 0.31
    rear, front = -0.72, 0.75
    pieces = spoked_wheel(rear, r, 0.08) + spoked_wheel(front, r, 0.06)

    def rod(p: tuple[float, float, float], q: tuple[float, float, float], rad: float, part: int,
            sides: int = 6) -> None:  # fmt: skip
        pieces.append(tube(np.array(p), np.array(q), rad, rad, part, sides=sides))

    pieces.append(prism([(-0.3, 0.26), (0.28, 0.24), (0.36, 0.4), (0.3, 0.52), (-0.22, 0.6), (-0.32, 0.45)], 0.13,
                        Part.ENGINE, Part.ENGINE))  # crankcase  # fmt: skip
    pieces.append(prism([(0.02, 0.5), (0.28, 0.46), (0.42, 0.66), (0.16, 0.74)], 0.165, Part.ENGINE, Part.ENGINE))
    for dz in (0.53, 0.58, 0.63):  # the cylinders' cooling fins
        pieces.append(prism([(0.05 + 0.5 * (dz - 0.5), dz), (0.33 + 0.5 * (dz - 0.5), dz - 0.02),
                             (0.34 + 0.5 * (dz - 0.5), dz), (0.06 + 0.5 * (dz - 0.5), dz + 0.015)], 0.175,
                            Part.CHROME, Part.CHROME))  # fmt: skip
    for side in (1.0, -1.0):  # exhaust headers from the cylinders' front down under the engine
        rod((0.4, side * 0.07, 0.6), (0.38, side * 0.09, 0.26), 0.024, Part.CHROME)
        rod((0.38, side * 0.09, 0.26), (0.0, -0.14, 0.22), 0.024, Part.CHROME)
    rod((0.0, -0.14, 0.22), (-0.2, -0.17, 0.3), 0.035, Part.CHROME)
    pieces.append(tube(np.array([-0.2, -0.17, 0.3]), np.array([-0.7, -0.21, 0.46]), 0.05, 0.058, Part.CHROME, sides=8))
    # the frame: steering head to swingarm pivot, rails under the seat, the swingarm and shocks
    rod((0.52, 0.0, 0.96), (-0.2, 0.0, 0.74), 0.035, Part.FRAME)
    for side in (1.0, -1.0):
        rod((0.52, side * 0.04, 0.93), (0.36, side * 0.1, 0.42), 0.022, Part.FRAME)
        rod((-0.2, side * 0.11, 0.7), (-0.82, side * 0.1, 0.78), 0.016, Part.FRAME)
        rod((-0.2, side * 0.11, 0.7), (-0.22, side * 0.12, 0.36), 0.025, Part.FRAME)
        rod((-0.22, side * 0.125, 0.36), (rear, side * 0.125, r), 0.03, Part.FRAME)
        rod((-0.55, side * 0.15, 0.33), (-0.4, side * 0.15, 0.74), 0.022, Part.CHROME, sides=8)  # shock
        rod((-0.1, side * 0.14, 0.265), (-0.1, side * 0.25, 0.265), 0.012, Part.TRIM)  # footrest
    pieces.append(blob((0.2, 0.0, 0.83), (0.29, 0.17, 0.13), Part.PAINT, rings=5, segments=12))  # tank
    pieces.append(prism([(-0.8, 0.73), (-0.1, 0.71), (-0.02, 0.79), (-0.3, 0.81), (-0.78, 0.86)], 0.13, Part.TRIM,
                        Part.TRIM))  # seat  # fmt: skip
    pieces.append(prism([(-1.0, 0.72), (-0.25, 0.6), (-0.12, 0.74), (-0.8, 0.79), (-1.0, 0.82)], 0.1, Part.PAINT,
                        Part.PAINT))  # tail  # fmt: skip
    pieces.append(box(-1.02, -0.99, -0.07, 0.07, 0.73, 0.79, Part.TAIL_LAMP))
    pieces.append(box(-1.005, -0.985, -0.09, 0.09, 0.5, 0.62, Part.PLATE))
    rod((-0.99, 0.0, 0.62), (-0.93, 0.0, 0.72), 0.012, Part.TRIM)  # the plate's bracket
    pieces.append(prism(_arc(rear, r, r + 0.02, r + 0.045, math.radians(70), math.radians(150)), 0.075, Part.TRIM,
                        Part.TRIM))  # rear hugger  # fmt: skip
    pieces.append(prism(_arc(front, r, r + 0.025, r + 0.05, math.radians(25), math.radians(150)), 0.068, Part.PAINT,
                        Part.PAINT))  # front fender  # fmt: skip
    for side in (1.0, -1.0):  # forks, risers, mirrors on stalks over the bar's ends, indicators
        rod((front, side * 0.085, r), (0.52, side * 0.085, 1.0), 0.03, Part.CHROME)
        rod((0.52, side * 0.07, 1.0), (0.44, side * 0.07, 1.04), 0.015, Part.CHROME)
        rod((0.4, side * 0.27, 1.05), (0.42, side * 0.32, 1.24), 0.01, Part.TRIM, sides=4)
        pieces.append(blob((0.43, side * 0.33, 1.27), (0.025, 0.055, 0.035), Part.TRIM, rings=3, segments=6))
        pieces.append(box(0.62, 0.66, side * 0.14 - 0.02, side * 0.14 + 0.02, 0.9, 0.93, Part.INDICATOR))
        pieces.append(box(-0.96, -0.92, side * 0.13 - 0.02, side * 0.13 + 0.02, 0.7, 0.725, Part.INDICATOR))
    rod((0.44, -0.36, 1.04), (0.44, 0.36, 1.04), 0.014, Part.TRIM)  # handlebar
    rod((0.58, 0.0, 0.93), (0.7, 0.0, 0.93), 0.095, Part.TRIM, sides=12)  # headlamp shell
    rod((0.69, 0.0, 0.93), (0.72, 0.0, 0.93), 0.08, Part.HEADLAMP, sides=12)
    rider = person(None, 1.75, 1.1, "motorcycle")
    rider = [Piece(p.vertices + np.array([-0.32, 0.0, 0.79 - 0.92]), p.triangles, p.parts) for p in rider]
    return merge(pieces + rider)


def _recoloured(piece: Piece, parts: dict[int, int]) -> Piece:
    out = piece.parts.copy()
    for old, new in parts.items():
        out[piece.parts == old] = new
    return Piece(piece.vertices, piece.triangles, out)


def work_truck(length: float = 7.0, width: float = 2.5, h: float = 3.2) -> Piece:
    """A construction site's truck: a box truck in safety yellow with retro-reflective stripes
    along its sides and an amber beacon on the cab roof."""
    body = _recoloured(
        box_truck(length, width, h),
        {int(Part.CAB): int(Part.SAFETY_YELLOW), int(Part.CARGO): int(Part.SAFETY_YELLOW)},
    )
    hl, hw = length / 2, width / 2 - 0.01
    pieces = [body]
    for side in (-1.0, 1.0):  # stripes on the box's sides, standing 4 mm out of them
        y0, y1 = sorted((side * (hw + 0.002), side * (hw + 0.006)))
        pieces.append(box(-hl + 0.3, hl - 2.9, y0, y1, 1.3, 1.45, Part.RETRO_WHITE))
    cab_x0, roof = hl - 2.2, min(h - 0.05, 3.0) + 0.003  # the beacon's base stands just off the cab's roof
    pieces.append(box(cab_x0 + 0.8, cab_x0 + 1.1, -0.15, 0.15, roof, roof + 0.04, Part.TRIM))
    pieces.append(tube(np.array([cab_x0 + 0.95, 0.0, roof + 0.043]), np.array([cab_x0 + 0.95, 0.0, h]), 0.09, 0.08,
                       Part.INDICATOR, sides=10))  # fmt: skip
    return merge(pieces)


def centre_axle_trailer(length: float = 7.0, width: float = 2.5, h: float = 3.4) -> Piece:
    """A box trailer on a tandem axle near its middle (its drawbar is not drawn: it would
    reach out of the trailer's box towards the truck's)."""
    hl, hw = length / 2, width / 2 - 0.01
    z0 = 1.15
    pieces = [box(-hl + 0.02, hl - 0.02, -hw, hw, z0, h, Part.CARGO)]
    pieces.append(box(-hl + 0.3, hl - 0.3, -0.45, 0.45, 0.55, z0 - 0.01, Part.UNDERBODY))  # chassis
    pieces.append(box(hl - 0.015, hl, -hw + 0.1, hw - 0.1, z0 + 0.1, h - 0.1, Part.TRIM))  # front wall's frame
    for side in (-1.0, 1.0):
        t0, t1 = sorted((side * 0.7 * hw, side * 0.84 * hw))
        pieces.append(box(-hl, -hl + 0.05, t0, t1, z0 - 0.3, z0 - 0.12, Part.TAIL_LAMP))
        t0, t1 = sorted((side * (0.84 * hw + 0.01), side * 0.95 * hw))
        pieces.append(box(-hl, -hl + 0.05, t0, t1, z0 - 0.3, z0 - 0.12, Part.INDICATOR))
        y0, y1 = sorted((side * (hw - 0.09), side * (hw - 0.05)))
        pieces.append(box(0.9, hl - 0.4, y0, y1, 0.5, z0 - 0.02, Part.TRIM))  # side guards
    pieces.append(box(-hl + 0.01, -hl + 0.06, -hw + 0.05, hw - 0.05, z0 - 0.35, z0 - 0.05, Part.TRIM))
    pieces.append(box(-hl, -hl + 0.04, -0.26, 0.26, z0 - 0.48, z0 - 0.36, Part.PLATE))
    pieces += _rear_doors(-hl + 0.02, hw, z0, h)
    pieces.append(box(-hl + 0.12, -hl + 0.24, -hw + 0.2, hw - 0.2, 0.42, 0.56, Part.TRIM))  # underrun guard
    pieces += _outline_lamps(-hl - 0.002, -hl + 0.03, hw, h - 0.12, Part.REAR_OUTLINE)
    pieces += _side_markers(-hl + 0.3, hl - 0.3, hw + 0.008, z0 + 0.12, [(-1.2, 1.2)])  # clear of the wheels
    for x in (-0.65, 0.65):
        for side in (-1.0, 1.0):
            pieces += wheel(x, 0.45, side * (hw - 0.32), side * (hw - 0.04))
    return merge(pieces)


EMERGENCY_BAR_M = 0.1
"""An emergency vehicle's light bar stands this high on its roof."""


def emergency_car(shape: CarShape, ambulance: bool = False) -> Piece:
    """A police car (a sedan) or an ambulance (a van) in white livery, with a blue light bar on
    the roof and, on the ambulance, a yellow band along each side."""
    body = _recoloured(car(shape), {int(Part.PAINT): int(Part.LIVERY)})
    roof, hw = shape.height + 0.003, shape.width / 2
    x = (shape.roof_front_x + shape.roof_rear_x) / 2 if not ambulance else shape.roof_front_x - 0.2
    pieces = [body, box(x - 0.12, x + 0.12, -0.5 * hw, 0.5 * hw, roof, roof + 0.03, Part.TRIM)]
    for side in (-1.0, 1.0):
        y0, y1 = sorted((side * 0.05, side * 0.5 * hw))
        pieces.append(box(x - 0.1, x + 0.1, y0, y1, roof + 0.033, shape.height + EMERGENCY_BAR_M, Part.BEACON))
    if ambulance:
        v = body.vertices
        for side in (-1.0, 1.0):  # just proud of the body's widest point at that height
            at = (v[:, 2] > 0.85) & (v[:, 2] < 1.0)
            y_out = float(np.abs(v[at, 1]).max()) + 0.002
            y0, y1 = sorted((side * y_out, side * (y_out + 0.004)))
            pieces.append(box(shape.axle_rear - 0.3, shape.axle_front - 0.3, y0, y1, 0.88, 0.98, Part.SAFETY_YELLOW))
    return merge(pieces)


def traffic_cone(height: float = 0.75) -> Piece:
    """A road cone (EN 13422's 750 mm class): a black square base, an orange shell with two
    white retro-reflective collars, each a few millimetres proud of the shell."""
    base_hw, r0, r1, z0 = 0.2, 0.16, 0.03, 0.035
    pieces = [box(-base_hw, base_hw, -base_hw, base_hw, 0.0, z0, Part.TRIM)]

    def radius(z: float) -> float:
        return r0 + (r1 - r0) * (z - z0) / (height - z0)

    cuts = [z0, 0.38 * height, 0.52 * height, 0.62 * height, 0.74 * height, height]
    for k, (za, zb) in enumerate(itertools.pairwise(cuts)):
        white = k in (1, 3)
        lift, trim = (0.004, 0.002) if white else (0.0, 0.0)  # collars: no face in the shell's planes
        za, zb = (za + 0.002, zb) if k == 0 else (za + trim, zb - trim)
        pieces.append(tube(np.array([0.0, 0.0, za]), np.array([0.0, 0.0, zb]), radius(za) + lift, radius(zb) + lift,
                           Part.RETRO_WHITE if white else Part.SAFETY_ORANGE, sides=16))  # fmt: skip
    return merge(pieces)


def barrier(length: float = 2.0, width: float = 0.5, h: float = 1.0) -> Piece:
    """A water-filled plastic road barrier: a tapering block in alternating orange-red and white
    sections, a retro-reflective band along both faces near the top."""
    hl, hw = length / 2, width / 2
    top_hw = 0.4 * hw

    def half_width(z: float) -> float:
        return hw + (top_hw - hw) * z / h

    sections = 4
    step = length / sections
    pieces = []
    for k in range(sections):
        x0, x1 = -hl + k * step + (0.003 if k else 0.0), -hl + (k + 1) * step  # 3 mm joints: no shared faces
        # the side outline: a foot recess at the bottom, a rounded top
        outline = [(x0, 0.0), (x0 + 0.12 * step, 0.0), (x0 + 0.18 * step, 0.12), (x1 - 0.18 * step, 0.12),
                   (x1 - 0.12 * step, 0.0), (x1, 0.0), (x1, 0.9 * h), (x1 - 0.05 * step, 0.97 * h),
                   (x1 - 0.2 * step, h), (x0 + 0.2 * step, h), (x0 + 0.05 * step, 0.97 * h), (x0, 0.9 * h)]  # fmt: skip
        part = Part.SAFETY_ORANGE if k % 2 == 0 else Part.RETRO_WHITE
        pieces.append(prism(outline, half_width, part, part))
    for side in (-1.0, 1.0):
        za, zb = 0.72 * h, 0.8 * h
        y_out = half_width(zb) + 0.006
        y0, y1 = sorted((side * (half_width(za) - 0.02), side * y_out))
        pieces.append(box(-hl + 0.05, hl - 0.05, y0, y1, za, zb, Part.RETRO_WHITE))
    return merge(pieces)


def _emergency(shape: CarShape, ambulance: bool) -> Callable[[int], Piece]:
    def one(_pose: int) -> Piece:
        return emergency_car(shape, ambulance)

    return one


def _rigid(build: Callable[[CarShape], Piece], shape: CarShape) -> Callable[[int], Piece]:
    """A builder of one pose: the same mesh whatever the pose index."""

    def one(_pose: int) -> Piece:
        return build(shape)

    return one


# Body types per class ----------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class Body:
    """A body type: its name, nominal l/w/h (m), share among its class, and its mesh builder
    (given a pose index: the gait or pedal phase, a truck's proportions, or 0 for rigid bodies)."""

    name: str
    lwh_m: tuple[float, float, float]
    share: float
    build: Callable[[int], Piece]
    poses: int = 1
    proportions: bool = False  # poses differ in proportions (each fills the box), not in motion


TRUCK_LENGTH_PER_HEIGHT = (1.6, 2.0, 2.5, 3.1, 3.8, 4.6)
"""A truck's length over its height in each of its body's proportions (poses): a truck is
drawn in the one nearest its box's (:func:`pose_of`), so its wheels stay round and its cab
as long as a real one of its height, however long its box."""


def _proportioned(
    width: float, h: float, lengths: tuple[float, float], trailer: bool = False
) -> Callable[[int], Piece]:
    """A truck body's builder by proportion: pose ``k`` is :func:`box_truck` built
    :data:`TRUCK_LENGTH_PER_HEIGHT` [k] times ``h`` long (within ``lengths``)."""

    def one(pose: int) -> Piece:
        return box_truck(float(np.clip(TRUCK_LENGTH_PER_HEIGHT[pose] * h, *lengths)), width, h, trailer)

    return one


WALKER_POSES = 1 + GAIT_PHASES * len(PACES_MPS)
"""A walker's poses: standing, then each pace's gait phases."""


def _walker(pose: int, build: float = 1.0) -> Piece:
    """A walker in a pose (:data:`WALKER_POSES`: 0 standing, then pace by pace, phase by phase)."""
    if pose == 0:
        return pedestrian(None, build)
    pace, k = divmod(pose - 1, GAIT_PHASES)
    return pedestrian(2 * math.pi * k / GAIT_PHASES, build, PACES_MPS[pace])


BODIES: dict[int, tuple[Body, ...]] = {
    int(SemanticClass.CAR): tuple(
        Body(name, (s.length, s.width, s.height), share, _rigid(car, s))
        for name, s, share in (
            ("sedan", CAR_SHAPES["sedan"], 0.3),
            ("hatchback", CAR_SHAPES["hatchback"], 0.25),
            ("estate", CAR_SHAPES["estate"], 0.12),
            ("suv", CAR_SHAPES["suv"], 0.2),
            ("van", CAR_SHAPES["van"], 0.07),
            ("pickup", CAR_SHAPES["pickup"], 0.06),
        )
    )
    + tuple(
        Body(name, (s.length, s.width, s.height + EMERGENCY_BAR_M), share, _emergency(s, amb))
        for name, s, amb, share in (
            ("police", CAR_SHAPES["sedan"], False, 0.008),  # about 0.8 % of the cars each (measured)
            ("ambulance", CAR_SHAPES["van"], True, 0.003),
        )
    ),
    int(SemanticClass.TRUCK): (
        Body(
            "box_truck",
            (8.0, 2.5, 3.4),
            0.6,
            _proportioned(2.5, 3.4, (5.0, 12.0)),
            len(TRUCK_LENGTH_PER_HEIGHT),
            True,
        ),
        Body(
            "semi_trailer",
            (11.5, 2.5, 3.8),
            0.4,
            _proportioned(2.5, 3.8, (11.0, 16.5), True),
            len(TRUCK_LENGTH_PER_HEIGHT),
            True,
        ),
    ),
    int(SemanticClass.BUS): (
        Body("city_bus", (12.0, 2.55, 3.1), 0.7, lambda _p: bus(12.0, 2.55, 3.1)),
        Body("coach", (12.5, 2.55, 3.3), 0.3, lambda _p: bus(12.5, 2.55, 3.3, coach=True)),
    ),
    int(SemanticClass.MOTORCYCLE): (Body("motorcycle", (2.1, 0.75, 1.7), 1.0, lambda _p: motorcycle()),),
    int(SemanticClass.BICYCLE): (
        Body("bicycle", (1.75, 0.6, 1.76), 1.0, lambda p: bicycle(2 * math.pi * p / GAIT_PHASES), GAIT_PHASES),
    ),
    int(SemanticClass.PEDESTRIAN): (
        Body("adult", (1.0, 0.5, 1.75), 0.7, _walker, WALKER_POSES),
        Body("adult_broad", (1.0, 0.6, 1.75), 0.3, lambda p: _walker(p, 1.15), WALKER_POSES),
    ),
    int(SemanticClass.TRAILER): (Body("box_trailer", (7.0, 2.5, 3.4), 1.0, lambda _p: centre_axle_trailer()),),
    int(SemanticClass.CONSTRUCTION_VEHICLE): (Body("work_truck", (7.0, 2.5, 3.2), 1.0, lambda _p: work_truck()),),
    int(SemanticClass.TRAFFIC_CONE): (Body("cone", (0.4, 0.4, 0.75), 1.0, lambda _p: traffic_cone()),),
    int(SemanticClass.BARRIER): (Body("water_barrier", (2.0, 0.5, 1.0), 1.0, lambda _p: barrier()),),
}
"""Body types per agent class; classes not here are drawn as their box."""


FIT_SLACK = 0.12
"""Body types within this much of the best fit (sum of |log| size ratios) are all candidates."""


def body_of(semantic_class: int, lwh_m: F64, instance_id: int) -> int:
    """The index in :data:`BODIES` of an agent's body type: the best fit to its size, chosen
    among the near-best by its id, weighted by the types' shares (stable over its track)."""
    if len(BODIES.get(int(semantic_class), ())) <= 1:
        return 0
    size = np.asarray(lwh_m)
    if size.dtype != np.float64 or size.shape != (3,):
        return _fit(int(semantic_class), size, int(instance_id))
    length, width, height = (float(x) for x in size)
    return _kept_fit(int(semantic_class), length, width, height, int(instance_id))


@functools.lru_cache(maxsize=4096)
def _kept_fit(semantic_class: int, length: float, width: float, height: float, instance_id: int) -> int:
    """:func:`_fit` of a float64 size, kept for the agents seen lately (each asks every frame)."""
    return _fit(semantic_class, np.array([length, width, height]), instance_id)


def _fit(semantic_class: int, lwh_m: npt.NDArray[np.floating], instance_id: int) -> int:
    bodies = BODIES[semantic_class]
    nominal = np.log(np.asarray([b.lwh_m for b in bodies]))
    misfit = np.abs(nominal - np.log(np.maximum(lwh_m, 1e-3))[None, :]).sum(axis=1)
    near = np.flatnonzero(misfit <= misfit.min() + FIT_SLACK)
    shares = np.asarray([bodies[i].share for i in near])
    u = ((int(instance_id) * 2654435761) % 2**32) / 2**32
    return int(near[min(int(np.searchsorted(np.cumsum(shares) / shares.sum(), u, side="right")), len(near) - 1)])


def pose_of(
    semantic_class: int, speed_mps: float, along_m: float, height_m: float = 1.75, gait_cycles: float = math.nan,
    length_m: float = math.nan,
) -> int:  # fmt: skip
    """The pose index of a walking pedestrian, a pedalling cyclist or a truck. A walker: 0
    (standing) below 0.2 m/s, else its pace's (:func:`pace_index`) gait phase from the gait
    cycles it has walked (``gait_cycles``: its distance walked over its stride, summed as it
    goes), or where not given from the distance it has come along its heading (``along_m``) over
    its stride (:func:`stride_m`). A cyclist: the crank's phase from ``along_m``. A truck: the
    proportion (:data:`TRUCK_LENGTH_PER_HEIGHT`) nearest its ``length_m`` over its ``height_m``
    (the middle one where its length is not given)."""
    if semantic_class == int(SemanticClass.TRUCK):
        if not (math.isfinite(length_m) and length_m > 0 and height_m > 0):
            return len(TRUCK_LENGTH_PER_HEIGHT) // 2
        ratio = math.log(length_m / height_m)
        return min(range(len(TRUCK_LENGTH_PER_HEIGHT)), key=lambda k: abs(math.log(TRUCK_LENGTH_PER_HEIGHT[k]) - ratio))
    if semantic_class == int(SemanticClass.PEDESTRIAN):
        if speed_mps < 0.2:
            return 0
        cycles = gait_cycles if math.isfinite(gait_cycles) else along_m / stride_m(height_m, speed_mps)
        return 1 + pace_index(speed_mps) * GAIT_PHASES + math.floor(cycles * GAIT_PHASES) % GAIT_PHASES
    if semantic_class == int(SemanticClass.BICYCLE):
        return math.floor(along_m / 2.2 * GAIT_PHASES) % GAIT_PHASES  # one crank turn per 2.2 m
    return 0

"""Buildings beside the streets, in the style of their district.

A town's buildings follow its districts: **downtown** (around the town's signalised centre, all
of a town whose lights stand as densely as a city centre's:
blocks of offices and flats 18-60 m tall, some set back above a podium, close together),
**residential** (houses and small blocks 5-9 m to the eaves, most with a pitched roof, gardens
between them), **industrial** (halls 25-60 m long and 7-12 m high, flat or shallow roofs, in
patches away from the centre) and **village** (a network without traffic lights: small houses
with steep pitched roofs, far apart). Roads without sidewalks as fast as 60 km/h or more are
motorways and their ramps: no building stands along them, nor within 15 m of their lanes.

Every building is a closed solid over the ground: walls around its footprint and a flat top, a
top tier, or a gable roof (two slopes and two gable ends), all classed BUILDING.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import shapely
import sumolib
from shapely.geometry import LineString, Polygon, box
from shapely.prepared import prep

from networks.classes import SemanticClass
from networks.mesh import ClassedMesh, merge, prism

BUILDING_GAP_M = 1.5  # between a building and any paved surface
BUILDING_SPACING_M = 0.5  # between two buildings
MOTORWAY_MPS = 16.6  # a road without sidewalks this fast (60 km/h) or faster is a motorway or its ramp
MOTORWAY_GAP_M = 15.0  # no building stands closer to a motorway lane's centre
DOWNTOWN_SHARE = 0.45  # of the distance from the centre of the lights to the farthest light (at least)
DOWNTOWN_LIGHTS_PER_KM2 = 150.0  # lights this dense (or denser) make the whole town downtown
INDUSTRIAL_CELL_M, INDUSTRIAL_SHARE = 250.0, 0.2  # outside downtown, this share of such squares is industrial


@dataclass(frozen=True, slots=True)
class Style:
    """How a district builds (metres): ranges drawn per building."""

    frontage_m: tuple[float, float]
    depth_m: tuple[float, float]
    height_m: tuple[float, float]  # to the eaves or the top
    setback_m: tuple[float, float]  # from the road's edge
    gap_m: tuple[float, float]  # between neighbours along the road
    pitched: float  # share with a gable roof
    roof_m: tuple[float, float]  # a gable's height above the eaves
    l_shaped: float  # share with one corner cut out (flat roofs only)
    tiered: float  # share with a narrower top tier (flat roofs only)


STYLES = {
    "downtown": Style((14.0, 32.0), (14.0, 26.0), (18.0, 60.0), (2.5, 4.5), (0.6, 2.5), 0.0, (0.0, 0.0), 0.3, 0.35),
    "residential": Style((9.0, 15.0), (8.0, 12.0), (5.0, 9.0), (4.0, 8.0), (2.5, 7.0), 0.65, (2.0, 3.5), 0.2, 0.0),
    "industrial": Style((25.0, 60.0), (20.0, 40.0), (7.0, 12.0), (6.0, 12.0), (6.0, 14.0), 0.25, (1.0, 2.0), 0.1, 0.0),
    "village": Style((7.0, 12.0), (7.0, 10.0), (4.0, 6.5), (3.0, 7.0), (5.0, 16.0), 0.9, (3.0, 5.0), 0.1, 0.0),
}
DISTRICTS = tuple(STYLES)


@dataclass(frozen=True, slots=True)
class Building:
    footprint: Polygon
    height_m: float  # its highest point above the ground
    mesh: ClassedMesh


def is_motorway(edge: sumolib.net.edge.Edge) -> bool:
    """A road without sidewalks as fast as :data:`MOTORWAY_MPS` or faster (motorways and ramps)."""
    lanes = edge.getLanes()
    walkable = any(lane.getPermissions() == {"pedestrian"} for lane in lanes)
    return not walkable and edge.getSpeed() >= MOTORWAY_MPS


@dataclass(frozen=True, slots=True)
class Districts:
    """Which district a place is in: ``village`` everywhere in a network without traffic
    lights; else ``downtown`` within :data:`DOWNTOWN_SHARE` of the lights' extent from their
    centre (all of it where the lights stand as densely as a city centre's,
    :data:`DOWNTOWN_LIGHTS_PER_KM2`), ``industrial`` in a seeded share of 250 m squares,
    ``residential`` elsewhere."""

    centre_xy: tuple[float, float] | None
    downtown_m: float
    seed: int

    @staticmethod
    def of(net: sumolib.net.Net, seed: int) -> Districts:
        lights = [
            tls.getConnections()[0][0].getEdge().getToNode() for tls in net.getTrafficLights() if tls.getConnections()
        ]
        if not lights:
            return Districts(None, 0.0, seed)
        xy = np.array([node.getCoord()[:2] for node in lights], dtype=np.float64)
        centre = xy.mean(axis=0)
        reach = max(float(np.linalg.norm(xy - centre, axis=1).max()), 100.0)
        density = len(xy) / (math.pi * (reach / 1000.0) ** 2)
        share = max(DOWNTOWN_SHARE, min(density / DOWNTOWN_LIGHTS_PER_KM2, 1.2))
        return Districts((float(centre[0]), float(centre[1])), share * reach, seed)

    def at(self, x: float, y: float) -> str:
        if self.centre_xy is None:
            return "village"
        if math.hypot(x - self.centre_xy[0], y - self.centre_xy[1]) <= self.downtown_m:
            return "downtown"
        cell = (math.floor(x / INDUSTRIAL_CELL_M), math.floor(y / INDUSTRIAL_CELL_M))
        draw = np.random.default_rng([self.seed, 0x1D57, cell[0] & 0xFFFF, cell[1] & 0xFFFF]).random()
        return "industrial" if draw < INDUSTRIAL_SHARE else "residential"


def place_buildings(
    net: sumolib.net.Net, paved: shapely.Geometry, rng: np.random.Generator, districts: Districts, z0_m: float
) -> list[Building]:
    """Street-facing buildings along every normal edge but motorways, in their district's
    style, set back from the paved area and apart from each other."""
    motorways = [lane.getShape() for e in net.getEdges(withInternal=False) if not e.getFunction() and is_motorway(e)
                 for lane in e.getLanes()]  # fmt: skip
    away = shapely.union_all([LineString([p[:2] for p in shape]).buffer(MOTORWAY_GAP_M) for shape in motorways])
    keep_out = prep(shapely.union(paved.buffer(BUILDING_GAP_M), away))
    placed = FootprintGrid()
    chosen: list[tuple[Polygon, str]] = []
    for edge in sorted(net.getEdges(withInternal=False), key=lambda e: e.getID()):
        if edge.getFunction() or is_motorway(edge):
            continue
        line = LineString(np.asarray(edge.getShape())[:, :2])
        half_width = sum(lane.getWidth() for lane in edge.getLanes()) / 2.0
        mid = line.interpolate(0.5, normalized=True)
        style = districts.at(mid.x, mid.y)
        for side in (1.0, -1.0):
            chosen += [
                (fp, style) for fp in _row_of_buildings(line, half_width, side, STYLES[style], rng, keep_out, placed)
            ]
    return [_building(footprint, STYLES[style], rng, z0_m) for footprint, style in chosen]


def _row_of_buildings(
    line: LineString,
    half_width_m: float,
    side: float,
    style: Style,
    rng: np.random.Generator,
    keep_out: object,
    placed: FootprintGrid,
) -> list[Polygon]:
    """Buildings along one side of ``line``, each added to ``placed`` unless it would stand on
    the paved area or within ``BUILDING_SPACING_M`` of a building placed before."""
    added = []
    s = float(rng.uniform(2.0, 8.0))
    while s < line.length:
        frontage = float(rng.uniform(*style.frontage_m))
        depth = float(rng.uniform(*style.depth_m))
        setback = half_width_m + float(rng.uniform(*style.setback_m))
        cut = rng.random() < style.l_shaped
        footprint = _footprint(line, s + frontage / 2.0, side * (setback + depth / 2.0), frontage, depth, cut)
        s += frontage + float(rng.uniform(*style.gap_m))
        if footprint is None or keep_out.intersects(footprint):  # type: ignore[attr-defined]
            continue
        if placed.any_within(footprint, BUILDING_SPACING_M):
            continue
        placed.add(footprint)
        added.append(footprint)
    return added


def _footprint(
    line: LineString, s_m: float, offset_m: float, frontage_m: float, depth_m: float, l_shaped: bool
) -> Polygon | None:
    """A box or L-shaped footprint centred ``offset_m`` to the left of ``line`` at ``s_m``."""
    if s_m + 1.0 >= line.length:
        return None
    p0, p1 = line.interpolate(s_m), line.interpolate(min(s_m + 1.0, line.length))
    heading = math.atan2(p1.y - p0.y, p1.x - p0.x)
    cx = p0.x - math.sin(heading) * offset_m
    cy = p0.y + math.cos(heading) * offset_m
    shape = box(-frontage_m / 2, -depth_m / 2, frontage_m / 2, depth_m / 2)
    if l_shaped:  # cut one corner out
        shape = shape.difference(box(0.0, 0.0, frontage_m / 2, depth_m / 2))
    shape = shapely.affinity.rotate(shape, heading, origin=(0, 0), use_radians=True)
    return shapely.affinity.translate(shape, cx, cy)


def _building(footprint: Polygon, style: Style, rng: np.random.Generator, z0_m: float) -> Building:
    """A building's solid on its footprint: a gable roof on a rectangle (by the style's share),
    else flat, with a narrower top tier on some downtown blocks."""
    height = float(rng.uniform(*style.height_m))
    rectangle = len(footprint.exterior.coords) == 5
    if rectangle and rng.random() < style.pitched:
        ridge = float(rng.uniform(*style.roof_m))
        return Building(footprint, height + ridge, gabled(footprint, z0_m, height, ridge, SemanticClass.BUILDING))
    parts = [prism(footprint, z0_m, height, SemanticClass.BUILDING)]
    top = height
    if rng.random() < style.tiered:
        tier = footprint.buffer(-float(rng.uniform(2.0, 4.0)), join_style="mitre")
        if isinstance(tier, Polygon) and not tier.is_empty and tier.area > 40.0:
            extra = height * float(rng.uniform(0.3, 0.8))
            parts.append(prism(tier, z0_m + height, extra, SemanticClass.BUILDING))
            top = height + extra
    return Building(footprint, top, merge(parts))


def gabled(footprint: Polygon, z0_m: float, eaves_m: float, ridge_m: float, cls: SemanticClass) -> ClassedMesh:
    """A closed house on a rectangular footprint: walls up to ``eaves_m`` above ``z0_m``, a
    ridge ``ridge_m`` above the eaves along the rectangle's longer side, two roof slopes and two
    gable ends (no floor, as every solid of the world: the ground is under it)."""
    c = np.asarray(footprint.exterior.coords)[:4]
    if np.linalg.norm(c[1] - c[0]) < np.linalg.norm(c[2] - c[1]):
        c = np.roll(c, -1, axis=0)  # c0-c1 a long side
    eaves, top = z0_m + eaves_m, z0_m + eaves_m + ridge_m
    r0, r1 = (c[3] + c[0]) / 2.0, (c[1] + c[2]) / 2.0  # the ridge's ends, above the short sides' middles
    v = np.array(
        [[*c[0], z0_m], [*c[1], z0_m], [*c[2], z0_m], [*c[3], z0_m],
         [*c[0], eaves], [*c[1], eaves], [*c[2], eaves], [*c[3], eaves],
         [*r0, top], [*r1, top]], dtype=np.float64,
    )  # fmt: skip
    walls = [(i, (i + 1) % 4, 4 + (i + 1) % 4) for i in range(4)] + [(i, 4 + (i + 1) % 4, 4 + i) for i in range(4)]
    roof = [(4, 5, 9), (4, 9, 8), (6, 7, 8), (6, 8, 9), (5, 6, 9), (7, 4, 8)]  # two slopes, two gables
    tris = np.asarray(walls + roof, dtype=np.int64)
    if shapely.Polygon(c).exterior.is_ccw is False:
        tris = tris[:, ::-1]  # faces outwards whichever way the footprint winds
    return ClassedMesh(v, tris, np.full(len(tris), cls, np.uint8))


class FootprintGrid:
    """Footprints in the cells of a square grid they overlap, so that a new one is checked
    against its neighbours only (a road of 1,000 km has about 100,000 buildings)."""

    def __init__(self, cell_m: float = 50.0) -> None:
        self.footprints: list[Polygon] = []
        self._cell_m = cell_m
        self._cells: dict[tuple[int, int], list[int]] = {}

    def _keys(self, bounds: tuple[float, float, float, float], margin_m: float) -> list[tuple[int, int]]:
        xmin, ymin, xmax, ymax = bounds
        x0, y0 = math.floor((xmin - margin_m) / self._cell_m), math.floor((ymin - margin_m) / self._cell_m)
        x1, y1 = math.floor((xmax + margin_m) / self._cell_m), math.floor((ymax + margin_m) / self._cell_m)
        return [(i, j) for i in range(x0, x1 + 1) for j in range(y0, y1 + 1)]

    def add(self, footprint: Polygon) -> None:
        for key in self._keys(footprint.bounds, 0.0):
            self._cells.setdefault(key, []).append(len(self.footprints))
        self.footprints.append(footprint)

    def any_within(self, footprint: Polygon, distance_m: float) -> bool:
        near = {i for key in self._keys(footprint.bounds, distance_m) for i in self._cells.get(key, ())}
        if not near:
            return False
        others = np.asarray([self.footprints[i] for i in sorted(near)], dtype=object)
        return bool(np.any(shapely.dwithin(others, footprint, distance_m)))

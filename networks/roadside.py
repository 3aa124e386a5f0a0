"""What stands by the roads besides buildings and trees: motorway guardrails and median
barriers (FENCE), and street furniture by the sidewalks: benches, bins and bus shelters
(OTHER_OBJECT), bollards (POLE).

Guardrails: a steel W-beam 0.45-0.75 m above the road on posts every 4 m (0.75 m high), 0.6 m
beyond the outer edge of every motorway carriageway and ramp (roads without sidewalks as fast as
60 km/h or more, :func:`networks.buildings.is_motorway`), broken where other roads join. Where
two carriageways run less than :data:`MEDIAN_M` apart, a concrete median barrier (0.6 m wide at
the foot, 0.81 m high, the New Jersey profile's size) stands halfway between them instead.

Street furniture, just beyond the sidewalk's outer edge (pedestrians walk the whole sidewalk),
clear of buildings: per sidewalk, by its district (:mod:`networks.buildings`), a bench with a
bin beside it, a row of three bollards near one of its ends, and on sidewalks 80 m long or more
a bus shelter (back wall, roof, bench and a sign on its pole).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import shapely
import sumolib
from shapely.geometry import LineString, Point
from shapely.ops import nearest_points
from shapely.prepared import prep

from networks.buildings import Districts, is_motorway
from networks.classes import SemanticClass
from networks.geometry import arc_lengths
from networks.mesh import BOX_TRIANGLES, ClassedMesh, merge, polyline_normals, prism

RAIL_OFFSET_M = 0.6  # a guardrail's face beyond the carriageway's edge
RAIL_Z_M = (0.45, 0.75)  # the W-beam's lower and upper edge above the road
POST_SPACING_M = 4.0
MEDIAN_M = 4.0  # carriageways closer than this share one concrete barrier between them
BARRIER_FOOT_M, BARRIER_TOP_M, BARRIER_HEIGHT_M = 0.6, 0.2, 0.81
STEP_M = 2.0  # barriers follow their road at this spacing
FURNITURE = {  # per sidewalk: chance of a bench and bin, of a row of bollards, of a bus shelter
    "downtown": (0.7, 0.6, 0.35),
    "residential": (0.4, 0.3, 0.25),
    "industrial": (0.1, 0.2, 0.1),
    "village": (0.35, 0.1, 0.15),
}


def motorway_barriers(net: sumolib.net.Net, paved: shapely.Geometry) -> list[ClassedMesh]:
    """Guardrails along motorway carriageways' outer edges, median barriers between
    carriageways close together."""
    edges = sorted(
        (e for e in net.getEdges(withInternal=False) if not e.getFunction() and is_motorway(e)), key=lambda e: e.getID()
    )
    if not edges:
        return []
    footprints = {e.getID(): shapely.union_all([_lane_area(lane) for lane in e.getLanes()]) for e in edges}
    axes = {e.getID(): LineString([p[:2] for p in e.getLanes()[0].getShape()]) for e in edges}
    tree_ids = list(footprints)
    tree = shapely.STRtree([footprints[i] for i in tree_ids])
    clear = prep(paved.buffer(RAIL_OFFSET_M - 0.1))
    parts: list[ClassedMesh] = []
    for edge in edges:
        own = footprints[edge.getID()]
        for border in _borders(edge, own):
            rail: list[np.ndarray] = []
            median: list[np.ndarray] = []
            for p, outward, heading in border:
                spot = p[:2] + outward * RAIL_OFFSET_M
                other = _facing(tree, tree_ids, footprints, axes, edge.getID(), Point(spot), heading)
                if other is not None:
                    _run_break(rail, parts, _guardrail)
                    if edge.getID() < other[0]:  # one barrier for the two carriageways
                        median.append(np.array([*((p[:2] + other[1]) / 2.0), p[2]]))
                    else:
                        _run_break(median, parts, _median_barrier)
                    continue
                _run_break(median, parts, _median_barrier)
                if clear.intersects(Point(spot)):  # another road joins here: no rail across it
                    _run_break(rail, parts, _guardrail)
                else:
                    rail.append(np.array([*spot, p[2]]))
            _run_break(rail, parts, _guardrail)
            _run_break(median, parts, _median_barrier)
    return parts


def _lane_area(lane: sumolib.net.lane.Lane) -> shapely.Geometry:
    return LineString([p[:2] for p in lane.getShape()]).buffer(lane.getWidth() / 2.0, cap_style="flat")


def _borders(
    edge: sumolib.net.edge.Edge, own: shapely.Geometry
) -> list[list[tuple[np.ndarray, np.ndarray, np.ndarray]]]:
    """The carriageway's two outer edges: points every ``STEP_M`` along them (3D, at the road's
    height) with the outward unit normal and the unit direction of travel at each."""
    lanes = edge.getLanes()
    out = []
    for lane in {id(lanes[0]): lanes[0], id(lanes[-1]): lanes[-1]}.values():
        shape = np.asarray(lane.getShape3D(), dtype=np.float64)
        line = LineString(shape[:, :2])
        if line.length < STEP_M:
            continue
        s = np.arange(0.0, line.length, STEP_M)
        xy = np.array([line.interpolate(v).coords[0] for v in s])
        along = arc_lengths(shape)
        z = np.interp(s, along, shape[:, 2])
        normals = polyline_normals(xy)
        normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-9)
        for side in (1.0, -1.0):
            probe = xy[len(xy) // 2] + side * normals[len(xy) // 2] * (lane.getWidth() / 2.0 + 0.3)
            if own.buffer(0.05).contains(Point(probe)):
                continue  # another lane of the carriageway lies on this side
            edge_pts = xy + side * normals * (lane.getWidth() / 2.0)
            heading = np.column_stack([normals[:, 1], -normals[:, 0]])  # the left normal turned back
            out.append([(np.array([*edge_pts[i], z[i]]), side * normals[i], heading[i]) for i in range(len(xy))])
    return out


def _facing(
    tree: shapely.STRtree, ids: list[str], footprints: dict[str, shapely.Geometry], axes: dict[str, LineString],
    own_id: str, spot: Point, heading: np.ndarray,
) -> tuple[str, np.ndarray] | None:  # fmt: skip
    """A motorway carriageway of the other direction within :data:`MEDIAN_M` of ``spot`` (its id,
    and its nearest point): the two share a median barrier."""
    for k in tree.query(spot.buffer(MEDIAN_M)):
        other = ids[int(k)]
        geom = footprints[other]
        if other == own_id or geom.distance(spot) > MEDIAN_M:
            continue
        axis = axes[other]
        s = axis.project(spot)
        a, b = axis.interpolate(max(s - 1.0, 0.0)), axis.interpolate(min(s + 1.0, axis.length))
        if float(np.dot([b.x - a.x, b.y - a.y], heading)) < 0.0:  # it runs the other way
            nearest = nearest_points(geom, spot)[0]
            return other, np.array([nearest.x, nearest.y])
    return None


def _run_break(run: list[np.ndarray], parts: list[ClassedMesh], build: Callable[[np.ndarray], ClassedMesh]) -> None:
    """End a run of barrier points: build it if it has two points or more, then start anew."""
    if len(run) >= 2:
        parts.append(build(np.asarray(run)))
    run.clear()


def _strip(points: np.ndarray, offset_m: float, z0_m: float, z1_m: float, cls: SemanticClass) -> ClassedMesh:
    """A vertical strip from ``z0_m`` to ``z1_m`` above a ``(K, 3)`` polyline, ``offset_m`` to its left."""
    n = polyline_normals(points[:, :2])
    xy = points[:, :2] + n * offset_m
    k = len(points)
    verts = np.concatenate([np.column_stack([xy, points[:, 2] + z0_m]), np.column_stack([xy, points[:, 2] + z1_m])])
    i = np.arange(k - 1)
    tris = np.concatenate([np.stack([i, i + 1, k + i + 1], 1), np.stack([i, k + i + 1, k + i], 1)])
    return ClassedMesh(verts, tris, np.full(len(tris), cls, np.uint8))


def _guardrail(points: np.ndarray) -> ClassedMesh:
    parts = [_strip(points, 0.0, *RAIL_Z_M, SemanticClass.FENCE)]
    line = LineString(points[:, :2])
    along = arc_lengths(points)
    for s in np.arange(POST_SPACING_M / 2, line.length, POST_SPACING_M):
        p = line.interpolate(float(s))
        z = float(np.interp(s, along, points[:, 2]))
        parts.append(prism(Point(p.x, p.y).buffer(0.07, quad_segs=1), z, RAIL_Z_M[1], SemanticClass.FENCE))
    return merge(parts)


def _median_barrier(points: np.ndarray) -> ClassedMesh:
    """A closed concrete barrier: sloped sides from a wide foot to a narrow top."""
    n = polyline_normals(points[:, :2])
    k = len(points)
    z = points[:, 2]
    rings = [
        np.column_stack([points[:, :2] + n * BARRIER_FOOT_M / 2, z - 0.1]),
        np.column_stack([points[:, :2] + n * BARRIER_TOP_M / 2, z + BARRIER_HEIGHT_M]),
        np.column_stack([points[:, :2] - n * BARRIER_TOP_M / 2, z + BARRIER_HEIGHT_M]),
        np.column_stack([points[:, :2] - n * BARRIER_FOOT_M / 2, z - 0.1]),
    ]
    verts = np.concatenate(rings)
    i = np.arange(k - 1)
    tris = []
    for a in range(3):  # left slope, top, right slope
        lo, hi = a * k, (a + 1) * k
        tris += [np.stack([lo + i, lo + i + 1, hi + i + 1], 1), np.stack([lo + i, hi + i + 1, hi + i], 1)]
    for end in (0, k - 1):  # the two ends
        tris.append(np.array([[end, k + end, 2 * k + end], [end, 2 * k + end, 3 * k + end]]))
    t = np.concatenate(tris)
    return ClassedMesh(verts, t, np.full(len(t), SemanticClass.FENCE, np.uint8))


# --- street furniture ----------------------------------------------------------------------


SIZE_M = {"shelter": (4.4, 1.8), "bench": (3.6, 1.0), "bollards": (2.9, 0.3)}  # along the sidewalk, deep


def street_furniture(
    net: sumolib.net.Net, paved: shapely.Geometry, buildings: list[shapely.Geometry], districts: Districts,
    rng: np.random.Generator, z0_m: float,
) -> tuple[list[ClassedMesh], list[shapely.Geometry]]:  # fmt: skip
    """Benches and bins, bollards and bus shelters just beyond the sidewalks (see the module),
    and their footprints."""
    keep_out = prep(paved.buffer(0.3))
    blocked = shapely.STRtree(buildings) if buildings else None
    parts: list[ClassedMesh] = []
    taken: list[shapely.Geometry] = []
    for edge in sorted(net.getEdges(withInternal=False), key=lambda e: e.getID()):
        if edge.getFunction():
            continue
        for lane in edge.getLanes():
            if lane.getPermissions() != {"pedestrian"}:
                continue
            line = LineString(np.asarray(lane.getShape())[:, :2])
            if line.length < 30.0:
                continue
            mid = line.interpolate(0.5, normalized=True)
            bench, bollards, shelter = FURNITURE[districts.at(mid.x, mid.y)]
            draws = rng.random(3)
            wanted = []
            if line.length >= 80.0 and draws[2] < shelter:
                wanted.append(("shelter", float(rng.uniform(0.35, 0.65)) * line.length))
            if draws[0] < bench:
                wanted.append(("bench", float(rng.uniform(0.15, 0.85)) * line.length))
            if draws[1] < bollards:
                wanted.append(("bollards", float(rng.choice([4.0, line.length - 4.0]))))
            for kind, s in wanted:
                offset = lane.getWidth() / 2.0 + 0.45 + SIZE_M[kind][1] / 2.0
                placed = _furniture(kind, line, s, offset, keep_out, blocked, taken, z0_m)
                if placed is not None:
                    parts.append(placed)
    return parts, taken


def _furniture(
    kind: str, line: LineString, s_m: float, offset_m: float, keep_out: object, blocked: shapely.STRtree | None,
    taken: list[shapely.Geometry], z0_m: float,
) -> ClassedMesh | None:  # fmt: skip
    """One piece of furniture at ``s_m`` along a sidewalk, on the side away from the paving,
    clear of buildings and at least 1 m from the furniture placed before (None: no room)."""
    p0, p1 = line.interpolate(max(s_m - 0.25, 0.0)), line.interpolate(min(s_m + 0.25, line.length))
    heading = math.atan2(p1.y - p0.y, p1.x - p0.x)
    along_m, deep_m = SIZE_M[kind]
    for side in (-1.0, 1.0):
        normal = np.array([-math.sin(heading), math.cos(heading)]) * side
        centre = np.array([p0.x, p0.y]) + normal * offset_m
        area = shapely.affinity.rotate(
            shapely.box(-along_m / 2, -deep_m / 2, along_m / 2, deep_m / 2), heading, origin=(0, 0), use_radians=True
        )
        area = shapely.affinity.translate(area, *centre)
        if keep_out.intersects(area):  # type: ignore[attr-defined]
            continue
        if blocked is not None and len(blocked.query(area, predicate="intersects")):
            continue
        if any(t.distance(area) < 1.0 for t in taken):
            continue
        taken.append(area)
        facing = math.atan2(-normal[1], -normal[0])  # towards the sidewalk
        return {"shelter": _shelter, "bench": _bench_and_bin, "bollards": _bollards}[kind](centre, facing, z0_m)
    return None


def _box(centre_xy: np.ndarray, facing: float, local: tuple[float, float], lwh: tuple[float, float, float],
         z0_m: float, cls: SemanticClass) -> ClassedMesh:  # fmt: skip
    """A box ``lwh`` (``l`` across the facing direction, ``w`` along it, ``h`` up) standing at
    ``z0_m``, its centre ``local`` (across, along) from ``centre_xy`` in the object's frame."""
    half = np.asarray(lwh) / 2.0
    corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], np.float64) * half
    corners[:, 2] += half[2]
    corners[:, 0] += local[0]
    corners[:, 1] += local[1]
    # object frame: x across (to the left of the facing direction), y along the facing direction
    fx, fy = math.cos(facing), math.sin(facing)
    across = np.array([-fy, fx])
    xy = centre_xy + corners[:, :1] * across + corners[:, 1:2] * np.array([fx, fy])
    verts = np.column_stack([xy, corners[:, 2] + z0_m])
    return ClassedMesh(verts, np.asarray(BOX_TRIANGLES, np.int32), np.full(12, cls, np.uint8))


def _bench(centre: np.ndarray, facing: float, z0: float, dx: float = 0.0, dy: float = 0.0) -> list[ClassedMesh]:
    o = SemanticClass.OTHER_OBJECT
    return [
        _box(centre, facing, (dx, dy), (1.8, 0.45, 0.45), z0, o),  # seat (on its legs: a solid block)
        _box(centre, facing, (dx, dy - 0.2), (1.8, 0.06, 0.9), z0, o),  # backrest
    ]


def _bench_and_bin(centre: np.ndarray, facing: float, z0: float) -> ClassedMesh:
    fx, fy = math.cos(facing), math.sin(facing)
    bin_xy = centre + np.array([-fy, fx]) * 1.4
    return merge([*_bench(centre, facing, z0), prism(Point(*bin_xy).buffer(0.28, quad_segs=2), z0, 1.0,
                                                      SemanticClass.OTHER_OBJECT)])  # fmt: skip


def _bollards(centre: np.ndarray, facing: float, z0: float) -> ClassedMesh:
    fx, fy = math.cos(facing), math.sin(facing)
    along = np.array([-fy, fx])
    return merge([prism(Point(*(centre + along * d)).buffer(0.08, quad_segs=2), z0, 0.9, SemanticClass.POLE)
                  for d in (-1.3, 0.0, 1.3)])  # fmt: skip


def _shelter(centre: np.ndarray, facing: float, z0: float) -> ClassedMesh:
    o = SemanticClass.OTHER_OBJECT
    fx, fy = math.cos(facing), math.sin(facing)
    pole_xy = centre + np.array([-fy, fx]) * 2.8 + np.array([fx, fy]) * 0.6
    return merge(
        [
            _box(centre, facing, (0.0, -0.7), (4.0, 0.08, 2.4), z0, o),  # back wall
            _box(centre, facing, (0.0, 0.0), (4.2, 1.6, 0.12), z0 + 2.4, o),  # roof
            _box(centre, facing, (-2.0, 0.0), (0.08, 1.4, 2.4), z0, o),  # side walls
            _box(centre, facing, (2.0, 0.0), (0.08, 1.4, 2.4), z0, o),
            *_bench(centre, facing, z0, 0.0, -0.35),
            prism(Point(*pole_xy).buffer(0.05, quad_segs=2), z0, 2.6, SemanticClass.POLE),
            _box(pole_xy, facing, (0.0, 0.0), (0.45, 0.04, 0.45), z0 + 2.6, o),  # the stop's sign
        ]
    )

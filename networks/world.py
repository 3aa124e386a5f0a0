"""The static world: a classed triangle mesh built from a SUMO network.

Lane surfaces keep the network's z; sidewalks and walking areas are raised by a
curb; junctions are triangulated from their outlines; buildings fill the free
space beside the streets (never on a lane or sidewalk); a terrain plane lies
under the rest. Deterministic by seed, cached by the network's content.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import shapely
import sumolib
from shapely.geometry import LineString, Polygon, box
from shapely.prepared import prep

from networks.cache import cache_dir, digest
from networks.classes import SemanticClass
from networks.errors import NetworkError
from networks.mesh import ClassedMesh, flat_polygon, merge, prism, ribbon

WORLD_VERSION = "1"
CURB_HEIGHT_M = 0.15


@dataclass(frozen=True, slots=True)
class StaticWorld:
    mesh: ClassedMesh
    bounds_m: tuple[float, float, float, float]  # xmin, ymin, xmax, ymax in the map frame
    num_buildings: int


def load_net(net_path: Path) -> sumolib.net.Net:
    try:
        return sumolib.net.readNet(str(net_path), withInternal=True, withPedestrianConnections=True)
    except Exception as err:  # sumolib raises plain Exceptions from its SAX handlers
        raise NetworkError(f"{net_path}: cannot read SUMO network: {err}") from err


def build_world(net_path: Path, seed: int = 0) -> StaticWorld:
    """Build (or load from the cache) the static world of a SUMO network."""
    key = digest(WORLD_VERSION, net_path.read_bytes(), str(seed))
    cached = cache_dir("worlds", key) / "world.npz"
    if cached.exists():
        with np.load(cached) as data:
            mesh = ClassedMesh(data["vertices_m"], data["triangles"], data["triangle_class"])
            return StaticWorld(mesh, tuple(data["bounds_m"].tolist()), int(data["num_buildings"]))  # type: ignore[arg-type]
    world = _build(load_net(net_path), seed)
    tmp = cached.with_suffix(".partial.npz")
    np.savez_compressed(
        tmp,
        vertices_m=world.mesh.vertices_m,
        triangles=world.mesh.triangles,
        triangle_class=world.mesh.triangle_class,
        bounds_m=np.asarray(world.bounds_m),
        num_buildings=world.num_buildings,
    )
    tmp.replace(cached)
    return world


def _lane_class(lane: sumolib.net.lane.Lane, function: str) -> SemanticClass:
    if function == "crossing":
        return SemanticClass.CROSSING
    if function == "walkingarea" or lane.getPermissions() == {"pedestrian"}:
        return SemanticClass.SIDEWALK
    return SemanticClass.ROAD


def _build(net: sumolib.net.Net, seed: int) -> StaticWorld:
    parts: list[ClassedMesh] = []
    footprints: list[Polygon] = []
    z_values: list[float] = []
    for edge in net.getEdges(withInternal=True):
        function = edge.getFunction()
        if function == "internal":
            continue  # junction surfaces cover internal lanes
        for lane in edge.getLanes():
            shape = np.asarray(lane.getShape3D(), dtype=np.float64)
            if shape.shape[0] < 2:
                continue
            cls = _lane_class(lane, function)
            z_values.extend(shape[:, 2].tolist())
            footprints.append(LineString(shape[:, :2]).buffer(lane.getWidth() / 2.0, cap_style="flat"))
            if cls == SemanticClass.SIDEWALK:
                parts.append(ribbon(shape, lane.getWidth(), cls, CURB_HEIGHT_M, CURB_HEIGHT_M))
            elif cls == SemanticClass.CROSSING:
                parts.append(ribbon(shape, lane.getWidth(), cls, 0.01))
            else:
                parts.append(ribbon(shape, lane.getWidth(), cls))
    for node in net.getNodes():
        outline = node.getShape3D()
        if len(outline) < 3:
            continue
        polygon = Polygon([(x, y) for x, y, _ in outline]).buffer(0)
        z = float(np.mean([p[2] for p in outline]))
        footprints.append(polygon)
        for piece in shapely.get_parts(polygon):
            parts.append(flat_polygon(piece, z, SemanticClass.ROAD))
    if not footprints:
        raise NetworkError("the network has no lanes to build a world from")
    paved = shapely.union_all(footprints)
    xmin, ymin, xmax, ymax = paved.bounds
    ground_z = min(z_values) if z_values else 0.0
    buildings = _place_buildings(net, paved, np.random.default_rng(seed), ground_z)
    parts.extend(prism(fp, ground_z - 0.05, h, SemanticClass.BUILDING) for fp, h in buildings)
    margin = 150.0
    terrain = box(xmin - margin, ymin - margin, xmax + margin, ymax + margin)
    parts.append(flat_polygon(terrain, ground_z - 0.05, SemanticClass.TERRAIN))
    bounds = (xmin - margin, ymin - margin, xmax + margin, ymax + margin)
    return StaticWorld(merge(parts), bounds, len(buildings))


def _place_buildings(
    net: sumolib.net.Net, paved: shapely.Geometry, rng: np.random.Generator, ground_z: float
) -> list[tuple[Polygon, float]]:
    """Street-facing buildings along every normal edge, set back from the paved area."""
    del ground_z
    keep_out = prep(paved.buffer(1.5))
    placed: list[Polygon] = []
    for edge in sorted(net.getEdges(withInternal=False), key=lambda e: e.getID()):
        if edge.getFunction():
            continue
        line = LineString(np.asarray(edge.getShape())[:, :2])
        half_width = sum(lane.getWidth() for lane in edge.getLanes()) / 2.0
        for side in (1.0, -1.0):
            placed.extend(_row_of_buildings(line, half_width, side, rng, keep_out, placed))
    return [(fp, float(rng.uniform(6.0, 28.0))) for fp in placed]


def _row_of_buildings(
    line: LineString,
    half_width_m: float,
    side: float,
    rng: np.random.Generator,
    keep_out: object,
    placed: list[Polygon],
) -> list[Polygon]:
    row: list[Polygon] = []
    s = float(rng.uniform(2.0, 8.0))
    while s < line.length:
        frontage = float(rng.uniform(8.0, 20.0))
        depth = float(rng.uniform(8.0, 16.0))
        setback = half_width_m + float(rng.uniform(3.0, 6.0))
        footprint = _footprint(line, s + frontage / 2.0, side * (setback + depth / 2.0), frontage, depth, rng)
        s += frontage + float(rng.uniform(1.0, 6.0))
        if footprint is None or keep_out.intersects(footprint):  # type: ignore[attr-defined]
            continue
        if any(footprint.intersects(other) for other in placed[-60:] + row):
            continue
        row.append(footprint)
    return row


def _footprint(
    line: LineString, s_m: float, offset_m: float, frontage_m: float, depth_m: float, rng: np.random.Generator
) -> Polygon | None:
    """A box or L-shaped footprint centred ``offset_m`` to the left of ``line`` at ``s_m``."""
    if s_m + 1.0 >= line.length:
        return None
    p0, p1 = line.interpolate(s_m), line.interpolate(min(s_m + 1.0, line.length))
    heading = math.atan2(p1.y - p0.y, p1.x - p0.x)
    cx = p0.x - math.sin(heading) * offset_m
    cy = p0.y + math.cos(heading) * offset_m
    shape = box(-frontage_m / 2, -depth_m / 2, frontage_m / 2, depth_m / 2)
    if rng.random() < 0.35:  # L-shape: cut one corner out
        cut = box(0.0, 0.0, frontage_m / 2, depth_m / 2)
        shape = shape.difference(cut)
    shape = shapely.affinity.rotate(shape, heading, origin=(0, 0), use_radians=True)
    return shapely.affinity.translate(shape, cx, cy)

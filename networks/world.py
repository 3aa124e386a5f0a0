"""The static world: a classed triangle mesh built from a SUMO network.

Lane surfaces keep the network's z; sidewalks and walking areas are raised by a
curb; junctions are triangulated from their outlines; buildings in their
district's style fill the free space beside the streets (never on a lane or
sidewalk, none along motorways: :mod:`networks.buildings`); guardrails and median
barriers line the motorways, benches, bins, bus shelters and bollards the
sidewalks (:mod:`networks.roadside`), trees and street lights too; a terrain plane
lies under the rest. Deterministic by seed, cached by the network's content.
"""

from __future__ import annotations

import dataclasses
import math
import os
import xml.etree.ElementTree as ET
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import shapely
import sumolib
from shapely.geometry import LineString, Point, Polygon, box
from shapely.prepared import prep

from networks.buildings import Districts, place_buildings
from networks.cache import cache_dir, digest, intact, place
from networks.classes import SemanticClass
from networks.errors import NetworkError
from networks.markings import MARKINGS_VERSION, is_left_hand, marking_mesh, read_road_marks
from networks.mesh import (
    ClassedMesh,
    box_mesh,
    draped_polygon,
    flat_polygon,
    merge,
    prism,
    raised_polygon,
    ribbon,
)
from networks.roadside import motorway_barriers, street_furniture
from networks.street import STREET_VERSION, pole_mesh, read_signs, street_objects
from networks.trees import street_tree

WORLD_VERSION = "17"  # 15: tree trunks their own class (TRUNK); 16: parking lanes (PARKING); 17: tree kinds
CURB_HEIGHT_M = 0.15
CURB_WALL_M = CURB_HEIGHT_M + 0.15  # curbs reach below the road and the terrain: no ray slips under a sidewalk
ROAD_SKIRT_M = 0.15  # below a road's outer edges, deeper than the terrain lies under it
SEAM_OVERLAP_M = 0.1  # driving-lane strips are this much wider and longer than the lane (no cracks at seams)
PARKING_LIFT_M = 0.002  # a parking lane's strip lies on its neighbours' overlap: its class holds up to its seam
ELEVATED_M = 2.0  # a lane this far above the ground is a bridge deck (with sides and piers)
DECK_DEPTH_M = 0.8
PIER_SPACING_M = 30.0
PIER_CLEARANCE_M = 1.0  # between a pier and a lane or sidewalk under the bridge
PROP_GAP_M = 0.4  # between a pole or tree and any paved surface
CONIFER_ROOM_M = 4.0  # a conifer stands only where no building is this near


@dataclass(frozen=True, slots=True)
class StaticWorld:
    mesh: ClassedMesh
    bounds_m: tuple[float, float, float, float]  # xmin, ymin, xmax, ymax in the map frame
    num_buildings: int
    path: Path | None = None  # the cached world file, readable with :func:`read_world`
    notice: str = ""  # what the user should know about how the world was built ('' if nothing)


def _notice_line(problem: str) -> str:
    return f"note: {problem}" if problem else ""


def lane_footprint(lane: sumolib.net.lane.Lane) -> Polygon:
    """The lane's area in the plane: its centre line widened to its width, ends cut square."""
    return LineString([p[:2] for p in lane.getShape()]).buffer(lane.getWidth() / 2.0, cap_style="flat")


def read_world(path: Path) -> StaticWorld:
    """A static world written by :func:`build_world` (its ``path``)."""
    try:
        with np.load(path) as data:
            mesh = ClassedMesh(data["vertices_m"], data["triangles"], data["triangle_class"])
            bounds = tuple(float(v) for v in data["bounds_m"].tolist())
            return StaticWorld(mesh, bounds, int(data["num_buildings"]), path)  # type: ignore[arg-type]
    except (OSError, KeyError, ValueError, EOFError, zipfile.BadZipFile) as err:
        raise NetworkError(f"{path}: not a readable world file ({err})") from err


def lane_types(net_path: Path) -> dict[str, str]:
    """Lane id -> OpenDRIVE lane type as recorded by netconvert (sumolib does not keep it)."""
    out: dict[str, str] = {}
    try:
        for _event, elem in ET.iterparse(net_path, events=("end",)):
            if elem.tag == "lane" and elem.get("type"):
                out[elem.get("id", "")] = elem.get("type", "")
            if elem.tag in ("edge", "junction", "connection"):
                elem.clear()
    except (OSError, ET.ParseError) as err:
        raise NetworkError(f"{net_path}: cannot read SUMO network: {err}") from err
    return out


def load_net(net_path: Path) -> sumolib.net.Net:
    try:
        return sumolib.net.readNet(str(net_path), withInternal=True, withPedestrianConnections=True)
    except Exception as err:  # sumolib raises plain Exceptions from its SAX handlers
        raise NetworkError(f"{net_path}: cannot read SUMO network: {err}") from err


def build_world(
    net_path: Path, seed: int = 0, props: bool = True, markings: bool = True, xodr_path: Path | None = None,
    traffic_lights: bool = True, signs: bool = True,
) -> StaticWorld:  # fmt: skip
    """Build (or load from the cache) the static world of a SUMO network; ``props`` adds
    street lights and trees along the sidewalks, ``markings`` the road markings (from the
    ``roadMark`` records of ``xodr_path``, the OpenDRIVE file the network was converted from,
    where it has them; see :mod:`networks.markings`), ``traffic_lights`` and ``signs`` the poles
    of the signal heads and signs (:mod:`networks.street`)."""
    source = xodr_path.read_bytes() if (markings or signs) and xodr_path is not None else b""
    key = digest(WORLD_VERSION, net_path.read_bytes(), str(seed), str(props), str(markings), MARKINGS_VERSION, source,
                 str(traffic_lights), str(signs), STREET_VERSION)  # fmt: skip
    folder = cache_dir("worlds", key)
    cached = folder / "world.npz"
    if intact(cached):
        notice = folder / "notice.txt"
        return dataclasses.replace(read_world(cached), notice=notice.read_text() if notice.exists() else "")
    net = load_net(net_path)
    types = lane_types(net_path)
    world = _build(net, seed, props, types)
    problems = []
    if traffic_lights or signs:
        poles = pole_mesh(street_objects(net, is_left_hand(net_path), traffic_lights, signs, xodr_path))
        world = dataclasses.replace(world, mesh=merge([world.mesh, poles]))
        problems.append(read_signs(xodr_path).problem if signs else "")
    if markings:
        marks = read_road_marks(xodr_path)
        paint = marking_mesh(net, marks, is_left_hand(net_path), types)
        world = dataclasses.replace(world, mesh=merge([world.mesh, paint]))
        problems.append(marks.problem)
    lines = "\n".join(_notice_line(p) for p in problems if p)
    if lines:
        world = dataclasses.replace(world, notice=lines)
        (folder / "notice.txt").write_text(lines)
    tmp = cached.with_suffix(f".{os.getpid()}.partial.npz")  # one per process: others may write it too
    np.savez_compressed(
        tmp,
        vertices_m=world.mesh.vertices_m,
        triangles=world.mesh.triangles,
        triangle_class=world.mesh.triangle_class,
        bounds_m=np.asarray(world.bounds_m),
        num_buildings=world.num_buildings,
    )
    place(tmp, cached)
    return dataclasses.replace(world, path=cached)


def _lane_class(lane: sumolib.net.lane.Lane, function: str, types: dict[str, str]) -> SemanticClass:
    if function == "crossing":
        return SemanticClass.CROSSING
    if function == "walkingarea" or lane.getPermissions() == {"pedestrian"}:
        return SemanticClass.SIDEWALK
    if types.get(lane.getID()) == "parking":
        return SemanticClass.PARKING
    return SemanticClass.ROAD


def _build(net: sumolib.net.Net, seed: int, props: bool, types: dict[str, str]) -> StaticWorld:
    parts, footprints, z_values = _lane_surfaces(net, types)
    parts += _junction_surfaces(net, footprints)
    if not footprints:
        raise NetworkError("the network has no lanes to build a world from")
    paved = shapely.union_all(footprints)
    xmin, ymin, xmax, ymax = paved.bounds
    ground_z = min(z_values) if z_values else 0.0
    rng = np.random.default_rng(seed)
    districts = Districts.of(net, seed)
    buildings = place_buildings(net, paved, rng, districts, ground_z - 0.05)
    parts.extend(b.mesh for b in buildings)
    parts += motorway_barriers(net, paved)
    if props:
        blocked = [b.footprint for b in buildings]
        furniture, taken = street_furniture(net, paved, blocked, districts, rng, ground_z - 0.05)
        parts += furniture
        parts += _street_props(net, paved, blocked + taken, rng, ground_z - 0.05, seed)
    margin = 150.0
    terrain = box(xmin - margin, ymin - margin, xmax + margin, ymax + margin)
    parts.append(flat_polygon(terrain, ground_z - 0.05, SemanticClass.TERRAIN))
    bounds = (xmin - margin, ymin - margin, xmax + margin, ymax + margin)
    return StaticWorld(merge(parts), bounds, len(buildings))


def _lane_surfaces(net: sumolib.net.Net, types: dict[str, str]) -> tuple[list[ClassedMesh], list[Polygon], list[float]]:
    """Lane, sidewalk and crossing strips (with curbs, and bridge decks where a lane passes
    over another), raised walking areas, their 2D footprints and all their heights."""
    parts: list[ClassedMesh] = []
    footprints: list[Polygon] = []
    shapes: list[tuple[np.ndarray, float]] = []
    walking: list[np.ndarray] = []
    inside: list[ClassedMesh] = []
    for edge in net.getEdges(withInternal=True):
        function = edge.getFunction()
        for lane in edge.getLanes():
            shape = np.asarray(lane.getShape3D(), dtype=np.float64)
            if shape.shape[0] < 2:
                continue
            if function == "walkingarea":  # its shape is an outline, not a centre line
                walking.append(shape)
                continue
            if function == "internal":  # junction surfaces cover most, not all (long ramp links)
                if lane.getPermissions() - {"pedestrian"}:
                    inside.append(_road_strip(shape, lane.getWidth(), SemanticClass.ROAD))
                continue
            cls = _lane_class(lane, function, types)
            footprints.append(lane_footprint(lane))
            shapes.append((shape, lane.getWidth()))
            if cls == SemanticClass.SIDEWALK:
                parts.append(ribbon(shape, lane.getWidth(), cls, CURB_HEIGHT_M, CURB_WALL_M))
            elif cls == SemanticClass.CROSSING:
                parts.append(ribbon(shape, lane.getWidth(), cls, 0.01))
            else:  # a little wider and longer: neighbours overlap instead of leaving cracks
                lift = PARKING_LIFT_M if cls == SemanticClass.PARKING else 0.0
                parts.append(_road_strip(shape, lane.getWidth(), cls, lift))
                outer = lane.getIndex() == 0, lane.getIndex() == len(edge.getLanes()) - 1
                if any(outer):  # the road's own edge: a skirt, so grazing rays do not slip under it
                    width = lane.getWidth() + SEAM_OVERLAP_M
                    parts.append(_side_walls(shape, width, ROAD_SKIRT_M, left=outer[1], right=outer[0]))
    z_values = [float(z) for shape, _ in shapes for z in shape[:, 2]]
    ground = min(z_values) if z_values else 0.0
    low = [fp for fp, (shape, _) in zip(footprints, shapes, strict=True) if shape[:, 2].max() < ground + ELEVATED_M]
    below = prep(shapely.union_all(low).buffer(PIER_CLEARANCE_M)) if low else None
    for k in _lanes_over_others(footprints, [shape for shape, _ in shapes]):
        parts.append(_bridge_deck(shapes[k][0], shapes[k][1], ground, below))
    parts += inside
    driven = _driven_area(net)
    for outline in walking:
        area = Polygon(outline[:, :2]).buffer(0)
        footprints.append(area)
        corner = area.difference(driven)
        top = float(np.mean(outline[:, 2])) + CURB_HEIGHT_M
        parts += [raised_polygon(p, top, CURB_WALL_M, SemanticClass.SIDEWALK) for p in shapely.get_parts(corner)]
    return parts, footprints, z_values


def _road_strip(shape_m: np.ndarray, width_m: float, cls: SemanticClass, lift_m: float = 0.0) -> ClassedMesh:
    return ribbon(_extended(shape_m, SEAM_OVERLAP_M), width_m + SEAM_OVERLAP_M, cls, lift_m)


def _extended(shape_m: np.ndarray, length_m: float) -> np.ndarray:
    """A ``(K, 3)`` polyline lengthened by ``length_m`` straight on at both ends (where two
    strips meet at an angle, the outer side of the bend would otherwise open a wedge)."""
    step = np.diff(shape_m[:, :2], axis=0)
    norms = np.linalg.norm(step, axis=1)
    if not np.any(norms > 1e-6):
        return shape_m
    first, last = step[np.argmax(norms > 1e-6)], step[len(step) - 1 - np.argmax(norms[::-1] > 1e-6)]
    head = shape_m[0].copy()
    head[:2] -= first / np.linalg.norm(first) * length_m
    tail = shape_m[-1].copy()
    tail[:2] += last / np.linalg.norm(last) * length_m
    return np.vstack([head, shape_m, tail])


def _driven_area(net: sumolib.net.Net) -> shapely.Geometry:
    """Where vehicles drive, junctions' internal lanes included: a walking area's corner is
    raised as a sidewalk only outside it."""
    strips = []
    for edge in net.getEdges(withInternal=True):
        if edge.getFunction() not in ("", "internal"):
            continue
        for lane in edge.getLanes():
            if len(lane.getShape()) >= 2 and lane.getPermissions() - {"pedestrian"}:
                strips.append(lane_footprint(lane))
    return shapely.union_all(strips) if strips else Polygon()


def _lanes_over_others(footprints: list[Polygon], shapes: list[np.ndarray]) -> list[int]:
    """Indices of lanes that cross above another lane (a bridge deck)."""
    tree = shapely.STRtree(footprints)
    pairs = tree.query(footprints, predicate="intersects")
    top = np.array([float(s[:, 2].max()) for s in shapes])
    low = np.array([float(s[:, 2].min()) for s in shapes])
    over = pairs[:, top[pairs[0]] - top[pairs[1]] > ELEVATED_M]
    return sorted({int(i) for i, j in over.T if low[j] < top[i] - ELEVATED_M})


def _bridge_deck(shape_m: np.ndarray, width_m: float, ground_z_m: float, below: object) -> ClassedMesh:
    """The deck's sides under an elevated lane, and piers down to the ground (POLE), but
    not onto the roads and sidewalks underneath (``below``, prepared, or None)."""
    high = shape_m[:, 2] - ground_z_m > ELEVATED_M + DECK_DEPTH_M
    parts = [ribbon(shape_m, width_m + 0.02, SemanticClass.ROAD, -DECK_DEPTH_M, 0.0)]
    parts[0] = merge([parts[0], _deck_sides(shape_m, width_m)])
    line = LineString(shape_m[:, :2])
    for s in np.arange(PIER_SPACING_M / 2, line.length, PIER_SPACING_M):
        i = int(np.argmin(np.linalg.norm(shape_m[:, :2] - np.asarray(line.interpolate(s).coords[0]), axis=1)))
        if not high[i] or (below is not None and below.intersects(Point(shape_m[i, 0], shape_m[i, 1]))):  # type: ignore[attr-defined]
            continue
        height = float(shape_m[i, 2] - DECK_DEPTH_M - ground_z_m)
        pier = box_mesh((0.8, 0.8, height), SemanticClass.POLE)
        offset = np.array([shape_m[i, 0], shape_m[i, 1], ground_z_m + height / 2.0])
        parts.append(ClassedMesh(pier.vertices_m + offset, pier.triangles, pier.triangle_class))
    return merge(parts)


def _deck_sides(shape_m: np.ndarray, width_m: float) -> ClassedMesh:
    """Vertical faces along both edges of the deck, ``DECK_DEPTH_M`` deep."""
    return _side_walls(shape_m, width_m, DECK_DEPTH_M, left=True, right=True)


def _side_walls(shape_m: np.ndarray, width_m: float, depth_m: float, left: bool, right: bool) -> ClassedMesh:
    """ROAD faces hanging ``depth_m`` below the chosen edges of a lane's strip."""
    strip = ribbon(shape_m, width_m, SemanticClass.ROAD)
    k = strip.vertices_m.shape[0] // 2
    if k < 2:
        return ClassedMesh.empty()
    edges = strip.vertices_m[:k].astype(np.float64), strip.vertices_m[k:].astype(np.float64)
    return merge([_hanging_wall(e, depth_m) for e, wanted in zip(edges, (left, right), strict=True) if wanted])


def _hanging_wall(top: np.ndarray, depth_m: float) -> ClassedMesh:
    k = top.shape[0]
    verts = np.concatenate([top, top - np.array([0.0, 0.0, depth_m])])
    i = np.arange(k - 1)
    tris = np.concatenate([np.stack([i, i + 1, k + i], 1), np.stack([i + 1, k + i + 1, k + i], 1)])
    return ClassedMesh(verts, tris, np.full(tris.shape[0], SemanticClass.ROAD, np.uint8))


def _junction_surfaces(net: sumolib.net.Net, footprints: list[Polygon]) -> list[ClassedMesh]:
    """Junction areas, each vertex at its outline point's height (a junction on a slope,
    where a ramp meets a bridge, is not flat), with a skirt around them."""
    parts = []
    for node in net.getNodes():
        outline = np.asarray(node.getShape3D(), dtype=np.float64)
        if len(outline) < 3:
            continue
        polygon = Polygon(outline[:, :2]).buffer(0)
        footprints.append(polygon)
        for piece in shapely.get_parts(polygon):
            parts.append(draped_polygon(piece, outline, SemanticClass.ROAD))
        parts.append(_hanging_wall(np.concatenate([outline, outline[:1]]), ROAD_SKIRT_M))
    return parts


def _street_props(
    net: sumolib.net.Net, paved: shapely.Geometry, buildings: list[Polygon], rng: np.random.Generator, z0_m: float,
    seed: int,
) -> list[ClassedMesh]:  # fmt: skip
    """Street lights (POLE) and trees (:func:`networks.trees.street_tree`: TRUNK forking into a
    VEGETATION crown; conifers only where no building stands within :data:`CONIFER_ROOM_M`) just
    outside the sidewalks."""
    keep_out = prep(paved.buffer(PROP_GAP_M))
    tree = shapely.STRtree(buildings) if buildings else None
    parts: list[ClassedMesh] = []
    for edge in sorted(net.getEdges(withInternal=False), key=lambda e: e.getID()):
        for lane in edge.getLanes():
            if edge.getFunction() or lane.getPermissions() != {"pedestrian"}:
                continue
            line = LineString(np.asarray(lane.getShape())[:, :2])
            for s in np.arange(float(rng.uniform(3.0, 12.0)), line.length - 3.0, float(rng.uniform(18.0, 30.0))):
                spot = _beside(line, float(s), lane.getWidth() / 2.0 + PROP_GAP_M + 0.6, keep_out)
                if spot is None or (tree is not None and len(tree.query(spot.buffer(2.0), predicate="intersects"))):
                    continue
                if rng.random() < 0.6:
                    roomy = tree is None or not len(tree.query(spot.buffer(CONIFER_ROOM_M), predicate="intersects"))
                    parts.append(street_tree(spot.x, spot.y, z0_m, seed, conifer_fits=roomy))
                else:
                    parts.append(_pole(spot, z0_m))
    return parts


def _beside(line: LineString, s_m: float, offset_m: float, keep_out: object) -> Point | None:
    """A point ``offset_m`` to either side of ``line`` at ``s_m`` that is clear of ``keep_out``."""
    p0, p1 = line.interpolate(s_m), line.interpolate(min(s_m + 0.5, line.length))
    heading = math.atan2(p1.y - p0.y, p1.x - p0.x)
    for side in (-1.0, 1.0):
        spot = Point(p0.x - side * math.sin(heading) * offset_m, p0.y + side * math.cos(heading) * offset_m)
        if not keep_out.intersects(spot.buffer(0.5)):  # type: ignore[attr-defined]
            return spot
    return None


def _pole(spot: Point, z0_m: float) -> ClassedMesh:
    return prism(spot.buffer(0.12, quad_segs=1), z0_m, 7.0, SemanticClass.POLE)

"""The built-in towns: generated, written as OpenDRIVE, imported back, and built as worlds."""

import time
from pathlib import Path

import numpy as np
import pytest
import shapely
import shapely.prepared
import sumolib
from shapely.geometry import LineString, Polygon

from networks.buildings import is_motorway
from networks.classes import SemanticClass
from networks.convert import import_opendrive
from networks.towns import TOWNS, town_opendrive, town_parking_edges
from networks.world import StaticWorld, build_world, lane_footprint, load_net

BUILT_IN = ["town03", "town05", "town06", "town07", "town10"]


@pytest.fixture(scope="module", params=BUILT_IN)
def town(request: pytest.FixtureRequest) -> tuple[str, Path, sumolib.net.Net, StaticWorld]:
    name = request.param
    net_path = import_opendrive(town_opendrive(name))
    return name, net_path, load_net(net_path), build_world(net_path)


def _lanes(net: sumolib.net.Net, pedestrian: bool) -> list[sumolib.net.lane.Lane]:
    return [
        lane
        for edge in net.getEdges(withInternal=False)
        if not edge.getFunction()
        for lane in edge.getLanes()
        if (lane.getPermissions() == {"pedestrian"}) == pedestrian
    ]


def _building_footprints(world: StaticWorld) -> shapely.Geometry:
    """2D union of the building triangles that are not vertical walls (roofs)."""
    mesh = world.mesh
    tris = mesh.vertices_m[mesh.triangles[mesh.triangle_class == SemanticClass.BUILDING]][:, :, :2]
    polys = [Polygon(t) for t in tris.astype(np.float64)]
    return shapely.union_all([p for p in polys if p.area > 1e-3])


def test_every_town_is_registered_and_generated_by_its_own_generator():
    for name in BUILT_IN:
        assert not TOWNS[name].stand_in
    assert "skeleton" in TOWNS


def test_town_generation_is_deterministic_by_seed():
    for name in BUILT_IN:
        info = TOWNS[name]
        assert info.build(3) == info.build(3)
        assert info.build(3).nodes_xml() != info.build(4).nodes_xml()


def test_a_town_made_in_two_caches_is_the_same_file(tmp_path, monkeypatch):
    """The manifest's network_sha256 of a built-in town is the same wherever it was made:
    the OpenDRIVE header carries no date (netconvert writes its clock time there)."""
    made = []
    for cache in ("a", "b"):
        monkeypatch.setenv("SUMO_DATASET_CACHE", str(tmp_path / cache))
        made.append(town_opendrive("skeleton").read_bytes())
        time.sleep(1.1)  # netconvert's date has whole seconds
    header = made[0].split(b"<road", 1)[0]
    assert b"<header" in header and b"date=" not in header
    assert made[0] == made[1]


def test_town_converts_with_crossings_and_pedestrian_lanes(town):
    _, net_path, net, _ = town
    text = net_path.read_text()
    assert text.count('function="crossing"') >= 4
    assert len(_lanes(net, pedestrian=True)) >= 10
    assert len(_lanes(net, pedestrian=False)) >= 10


def test_urban_towns_have_signalised_junctions(town):
    name, _, net, _ = town
    if name != "town07":  # the village has priority junctions only
        assert len(net.getTrafficLights()) >= 2


def test_no_building_stands_on_a_lane_or_sidewalk(town):
    _, _, net, world = town
    lanes = [lane_footprint(lane) for lane in _lanes(net, True) + _lanes(net, False)]
    buildings = _building_footprints(world)
    assert world.num_buildings > 50
    hits = [poly for poly in lanes if poly.intersects(buildings) and poly.intersection(buildings).area > 1e-3]
    assert hits == []


def test_world_of_a_town_stays_coarse(town):
    _, _, _, world = town
    assert world.mesh.num_triangles < 300_000
    classes = set(np.unique(world.mesh.triangle_class).tolist())
    assert {SemanticClass.ROAD, SemanticClass.SIDEWALK, SemanticClass.BUILDING, SemanticClass.TERRAIN} <= classes


def test_motorway_has_no_sidewalks_or_pedestrians():
    net = load_net(import_opendrive(town_opendrive("town06")))
    fast = [
        e
        for e in net.getEdges(withInternal=False)
        if not e.getFunction() and max(lane.getSpeed() for lane in e.getLanes()) > 20.0
    ]
    assert fast
    assert not any(lane.allows("pedestrian") for e in fast for lane in e.getLanes())


def test_overpass_deck_is_hit_from_above_and_below():
    world = build_world(import_opendrive(town_opendrive("town06")))
    mesh = world.mesh
    road = mesh.triangle_class == SemanticClass.ROAD
    tris = mesh.vertices_m[mesh.triangles[road]].astype(np.float64)
    high = tris[tris[:, :, 2].min(axis=1) > 4.0]
    assert len(high) > 0
    # A vertical ray through the middle of a raised road triangle meets road twice above
    # the ground (the deck's top and its underside) and the road or terrain below.
    x, y = high[len(high) // 2, :, :2].mean(axis=0)
    zs = _vertical_hits(tris, x, y)
    assert sum(z > 2.0 for z in zs) >= 2


def _vertical_hits(tris: np.ndarray, x: float, y: float) -> list[float]:
    a, b, c = tris[:, 0], tris[:, 1], tris[:, 2]
    d = (b[:, 1] - c[:, 1]) * (a[:, 0] - c[:, 0]) + (c[:, 0] - b[:, 0]) * (a[:, 1] - c[:, 1])
    ok = np.abs(d) > 1e-9
    l1 = ((b[:, 1] - c[:, 1]) * (x - c[:, 0]) + (c[:, 0] - b[:, 0]) * (y - c[:, 1])) / np.where(ok, d, 1.0)
    l2 = ((c[:, 1] - a[:, 1]) * (x - c[:, 0]) + (a[:, 0] - c[:, 0]) * (y - c[:, 1])) / np.where(ok, d, 1.0)
    l3 = 1.0 - l1 - l2
    inside = ok & (l1 >= 0) & (l2 >= 0) & (l3 >= 0)
    z = l1 * a[:, 2] + l2 * b[:, 2] + l3 * c[:, 2]
    return sorted(z[inside].tolist())


def test_urban_towns_expose_street_parking_edges():
    for name in ("town03", "town05", "town10"):
        assert len(town_parking_edges(name)) > 4


def _driving_lane_points(net: sumolib.net.Net, rng: np.random.Generator, count: int) -> np.ndarray:
    """``(count, 3)`` random points on the driving surface (lanes and junction links),
    anywhere across each lane's width, weighted by length."""
    lanes = [
        lane
        for edge in net.getEdges(withInternal=True)
        if edge.getFunction() in ("", "internal")
        for lane in edge.getLanes()
        if lane.allows("passenger") and len(lane.getShape()) >= 2
    ]
    lengths = np.array([lane.getLength() for lane in lanes])
    points = []
    for k in rng.choice(len(lanes), size=count, p=lengths / lengths.sum()):
        shape = np.asarray(lanes[k].getShape3D(), dtype=np.float64)
        line = LineString(shape[:, :2])
        s = float(rng.uniform(0.0, line.length))
        ahead, behind = line.interpolate(min(s + 0.5, line.length)), line.interpolate(max(s - 0.5, 0.0))
        direction = np.array([ahead.x - behind.x, ahead.y - behind.y])
        left = np.array([-direction[1], direction[0]]) / max(float(np.linalg.norm(direction)), 1e-9)
        along = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(shape[:, :2], axis=0), axis=1))])
        centre = line.interpolate(s)
        xy = np.array([centre.x, centre.y]) + left * rng.uniform(-0.45, 0.45) * lanes[k].getWidth()
        points.append((*xy, float(np.interp(s, along, shape[:, 2]))))
    return np.asarray(points)


def _cast(world: StaticWorld, origins: np.ndarray, directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distance to the first hit (inf if none) and the class hit, per ray."""
    from sensors.o3d import RaycastingScene, o3c

    mesh = world.mesh
    scene = RaycastingScene()
    scene.add_triangles(o3c.Tensor.from_numpy(mesh.vertices_m), o3c.Tensor.from_numpy(mesh.triangles.astype(np.uint32)))
    rays = np.hstack([origins, directions]).astype(np.float32)
    result = scene.cast_rays(o3c.Tensor.from_numpy(rays))
    t_hit = result["t_hit"].numpy()
    row = np.minimum(result["primitive_ids"].numpy(), mesh.num_triangles - 1)
    return t_hit, np.where(np.isfinite(t_hit), mesh.triangle_class[row], SemanticClass.NONE)


def test_the_road_under_a_car_is_solid_wherever_it_drives(town):
    """Straight down from 1.5 m above any point a car can drive on, the first surface is
    the road itself (or its paint): no hole, no sidewalk or junction slab above or below the lane."""
    _, _, net, world = town
    points = _driving_lane_points(net, np.random.default_rng(0), 4000)
    down = np.tile([0.0, 0.0, -1.0], (len(points), 1))
    t_hit, cls = _cast(world, points + np.array([0.0, 0.0, 1.5]), down)
    surface_dz = 1.5 - t_hit
    paved = [SemanticClass.ROAD, SemanticClass.CROSSING, SemanticClass.LANE_MARKING, SemanticClass.LANE_MARKING_YELLOW]
    on_road = np.isin(cls, paved) & (np.abs(surface_dz) < 0.1)
    assert np.isfinite(t_hit).all()
    assert not np.any(cls == SemanticClass.TERRAIN)
    assert on_road.mean() > 0.999, points[~on_road][:5]


def test_no_lidar_ray_from_a_car_passes_under_the_road(town):
    """Rays from 1.8 m above the driving surface, all round and 4 to 25 degrees down (the
    LiDAR's lower beams), never reach the terrain where a road at ground level lies above
    it: no crack between lane strips, junctions and curbs lets a ray slip under the road."""
    _, _, net, world = town
    rng = np.random.default_rng(1)
    origins = np.repeat(_driving_lane_points(net, rng, 1000), 50, axis=0) + np.array([0.0, 0.0, 1.8])
    azimuth = rng.uniform(0.0, 2.0 * np.pi, len(origins))
    elevation = np.radians(rng.uniform(-25.0, -4.0, len(origins)))
    directions = np.column_stack(
        [np.cos(elevation) * np.cos(azimuth), np.cos(elevation) * np.sin(azimuth), np.sin(elevation)]
    )
    t_hit, cls = _cast(world, origins, directions)
    assert np.isfinite(t_hit).all()
    ground_level = [
        lane_footprint(lane)
        for edge in net.getEdges(withInternal=True)
        if edge.getFunction() != "walkingarea"
        for lane in edge.getLanes()
        if len(lane.getShape()) >= 2 and max(p[2] for p in lane.getShape3D()) < 0.5
    ]
    paved = shapely.union_all(ground_level).buffer(-0.3)
    terrain = cls == SemanticClass.TERRAIN
    hits = origins[terrain] + directions[terrain] * t_hit[terrain, None]
    under_road = shapely.contains_xy(paved, hits[:, 0], hits[:, 1])
    assert not under_road.any(), hits[under_road][:5]


def test_motorway_ends_turn_back_on_loops_as_wide_as_the_carriageways():
    """town06's end loops keep every lane (a one-lane loop made all traffic merge into the
    leftmost lane at the motorway's end) and are real roads, not squashed into a junction."""
    net = load_net(import_opendrive(town_opendrive("town06")))
    loops = [
        e
        for e in net.getEdges(withInternal=False)
        if not e.getFunction() and e.getSpeed() < 15.0 and not e.allows("pedestrian") and e.getLaneNumber() >= 3
    ]
    assert len(loops) >= 2
    for edge in loops:
        assert edge.getLength() > 50.0, edge.getID()
        for after in edge.getOutgoing():
            assert len(edge.getConnections(after)) == edge.getLaneNumber(), (edge.getID(), after.getID())


def test_motorways_have_barriers_beside_them_and_no_buildings_and_furniture_stands_off_the_paving(town):
    """Guardrails and median barriers (FENCE) line the motorways, off the carriageway; no
    building stands along a motorway; benches, bins and shelters (OTHER_OBJECT) stand beyond
    the sidewalks, off every lane."""
    name, _, net, world = town
    mesh = world.mesh
    centroid = mesh.vertices_m[mesh.triangles].mean(axis=1).astype(np.float64)
    motorway = [e for e in net.getEdges(withInternal=False) if not e.getFunction() and is_motorway(e)]
    fence = centroid[mesh.triangle_class == SemanticClass.FENCE]
    assert bool(motorway) == (len(fence) > 0), name
    furniture = centroid[mesh.triangle_class == SemanticClass.OTHER_OBJECT]
    assert len(furniture) > 0, name
    lanes = _lanes(net, True) + _lanes(net, False)
    for high in (False, True):  # a guardrail passes under a bridge: lanes at their own height only
        level = [lane_footprint(ln) for ln in lanes if (np.asarray(ln.getShape3D())[:, 2].max() > 2.0) == high]
        inner = shapely.prepared.prep(shapely.union_all(level).buffer(-0.05))
        points = np.concatenate([fence, furniture])[::7]
        points = points[(points[:, 2] > 2.0) == high]
        assert not any(inner.contains(shapely.Point(p[:2])) for p in points), (name, high)
    if motorway:
        lanes = shapely.union_all([lane_footprint(lane) for e in motorway for lane in e.getLanes()])
        along = [p for p in shapely.get_parts(_building_footprints(world)) if p.distance(lanes) < 5.0]
        assert sum(p.area for p in along) < 0.01 * _building_footprints(world).area, name

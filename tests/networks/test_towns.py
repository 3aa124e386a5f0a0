"""The built-in towns: generated, written as OpenDRIVE, imported back, and built as worlds."""

from pathlib import Path

import numpy as np
import pytest
import shapely
import sumolib
from shapely.geometry import LineString, Polygon

from networks.classes import SemanticClass
from networks.convert import import_opendrive
from networks.towns import TOWNS, town_opendrive, town_parking_edges
from networks.world import StaticWorld, build_world, load_net

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
    lanes = [
        LineString(np.asarray(lane.getShape())[:, :2]).buffer(lane.getWidth() / 2.0, cap_style="flat")
        for lane in _lanes(net, True) + _lanes(net, False)
    ]
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

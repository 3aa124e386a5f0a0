"""Buildings placed beside the streets in their district's style: off the paved area, apart from each other, found
among their neighbours only (a road of 1,000 km has about 100,000 of them)."""

from dataclasses import dataclass

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st
from shapely.geometry import LineString, box

from networks.buildings import BUILDING_GAP_M, BUILDING_SPACING_M, Districts, FootprintGrid, place_buildings


@dataclass
class Lane:
    """sumolib's lane, edge and net, as far as building placement reads them."""

    width_m: float

    def getWidth(self) -> float:
        return self.width_m

    def getPermissions(self) -> set[str]:
        return {"passenger"}


@dataclass
class Edge:
    edge_id: str
    shape: list[tuple[float, float]]

    def getID(self) -> str:
        return self.edge_id

    def getFunction(self) -> str:
        return ""

    def getShape(self) -> list[tuple[float, float]]:
        return self.shape

    def getLanes(self) -> list[Lane]:
        return [Lane(3.5), Lane(3.5)]

    def getSpeed(self) -> float:
        return 13.9


class Net:
    def __init__(self, edges: list[Edge]) -> None:
        self.edges = edges

    def getEdges(self, withInternal: bool = True) -> list[Edge]:
        return self.edges


def test_buildings_along_a_road_of_200_km_stand_apart_and_off_the_road():
    """Each building used to be checked against every one placed before it: 100 km took 27 s in
    a run, 1,000 km over 400 s. Here 200 km place in about two seconds."""
    road = [(0.0, 0.0), (200_000.0, 0.0)]
    net = Net([Edge("road", road)])
    paved = LineString(road).buffer(3.5)
    placed = place_buildings(net, paved, np.random.default_rng(0), Districts(None, 0.0, 0), 0.0)  # type: ignore[arg-type]
    buildings = [b.footprint for b in placed]
    assert len(buildings) > 15_000  # both sides, village houses about one per 20 m
    assert not any(fp.intersects(paved.buffer(BUILDING_GAP_M)) for fp in buildings)
    tree = shapely.STRtree(buildings)
    pairs = tree.query(buildings, predicate="dwithin", distance=BUILDING_SPACING_M)
    assert (pairs[0] == pairs[1]).all()  # every building is near itself only


BOXES = st.lists(
    st.tuples(st.floats(-300, 300), st.floats(-300, 300), st.floats(2, 40), st.floats(2, 40)), min_size=1, max_size=60
)


@settings(max_examples=40, deadline=None)
@given(BOXES, st.floats(0.0, 30.0))
def test_the_grid_finds_a_footprint_near_another_exactly_when_one_is(boxes, distance_m):
    footprints = [box(x, y, x + w, y + h) for x, y, w, h in boxes]
    grid = FootprintGrid(cell_m=25.0)
    for i, fp in enumerate(footprints[:-1]):
        expected = any(fp.distance(other) <= distance_m for other in footprints[:i])
        assert grid.any_within(fp, distance_m) == expected
        grid.add(fp)
    assert grid.footprints == footprints[:-1]


def test_a_gable_house_is_closed_faces_outwards_and_its_roof_is_inside_it():
    from collections import Counter

    from networks.buildings import gabled
    from networks.classes import SemanticClass
    from sensors.solids import Solids

    footprint = shapely.affinity.rotate(box(0.0, 0.0, 10.0, 6.0), 30.0, origin=(0, 0))
    house = gabled(footprint, 0.0, 5.0, 3.0, SemanticClass.BUILDING)
    v, t = house.vertices_m.astype(np.float64), house.triangles
    edges = Counter(tuple(sorted(e)) for tri in t for e in ((tri[0], tri[1]), (tri[1], tri[2]), (tri[2], tri[0])))
    assert sorted(Counter(edges.values()).items()) == [(1, 4), (2, len(edges) - 4)]  # open only at the ground
    a, b, c = v[t[:, 0]], v[t[:, 1]], v[t[:, 2]]
    volume = np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0
    assert volume == pytest.approx(60.0 * 5.0 + 60.0 * 3.0 / 2.0, rel=1e-6)  # walls' box plus the roof's prism
    centre = np.asarray(footprint.centroid.coords[0])
    ridge_dir = np.array([np.cos(np.radians(30.0)), np.sin(np.radians(30.0))])
    across = np.array([-ridge_dir[1], ridge_dir[0]])
    points = np.array(
        [[*centre, 7.5], [*(centre + across * 2.5), 7.5], [*centre, 2.0], [*(centre + across * 4.0), 2.0]]
    )
    inside = Solids(house).inside(points)
    assert inside.tolist() == [SemanticClass.BUILDING, 0, SemanticClass.BUILDING, 0]  # under the ridge; above a slope


def test_districts_are_village_without_lights_downtown_at_the_centre_and_partly_industrial_around():
    assert Districts(None, 0.0, 0).at(5.0, 5.0) == "village"
    town = Districts((0.0, 0.0), 300.0, 7)
    assert town.at(100.0, -50.0) == "downtown"
    around = [town.at(x, y) for x in np.arange(-5000.0, 5000.0, 250.0) for y in np.arange(-5000.0, 5000.0, 250.0)]
    assert set(around) == {"downtown", "industrial", "residential"}
    assert 0.1 < around.count("industrial") / len(around) < 0.3


def test_each_district_builds_in_its_style():
    from networks.buildings import STYLES, _building

    rng = np.random.default_rng(3)
    fp = box(0.0, 0.0, 12.0, 9.0)
    heights = {d: [_building(fp, STYLES[d], rng, 0.0).height_m for _ in range(200)] for d in STYLES}
    assert min(heights["downtown"]) >= 18.0 > max(heights["residential"])
    pitched = {
        d: np.mean([len(_building(fp, STYLES[d], rng, 0.0).mesh.triangles) == 14 for _ in range(200)]) for d in STYLES
    }
    assert pitched["village"] > 0.8 and pitched["downtown"] == 0.0 and 0.5 < pitched["residential"] < 0.8

"""Buildings placed beside the streets: off the paved area, apart from each other, found
among their neighbours only (a road of 1,000 km has about 100,000 of them)."""

from dataclasses import dataclass

import numpy as np
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st
from shapely.geometry import LineString, box

from networks.world import BUILDING_GAP_M, BUILDING_SPACING_M, FootprintGrid, _place_buildings


@dataclass
class Lane:
    """sumolib's lane, edge and net, as far as building placement reads them."""

    width_m: float

    def getWidth(self) -> float:
        return self.width_m


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
    buildings = [fp for fp, _ in _place_buildings(net, paved, np.random.default_rng(0))]  # type: ignore[arg-type]
    assert len(buildings) > 20_000  # both sides, about one per 17 m
    assert not any(fp.intersects(paved.buffer(BUILDING_GAP_M)) for fp in buildings)
    tree = shapely.STRtree(buildings)
    pairs = tree.query(buildings, predicate="dwithin", distance=BUILDING_SPACING_M)
    assert (pairs[0] == pairs[1]).all()  # every building is near itself only


BOXES = st.lists(st.tuples(st.floats(-300, 300), st.floats(-300, 300), st.floats(2, 40), st.floats(2, 40)),
                 min_size=1, max_size=60)  # fmt: skip


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

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


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**31 - 1))
def test_a_tree_crown_is_closed_faces_outwards_and_rests_on_the_trunk(seed):
    from collections import Counter

    from shapely.geometry import Point

    from networks.classes import SemanticClass
    from networks.mesh import ellipsoid_mesh
    from networks.world import _tree

    rng = np.random.default_rng(seed)
    radii = tuple(rng.uniform(0.5, 3.0, 3))
    crown = ellipsoid_mesh((1.0, 2.0, 5.0), radii, SemanticClass.VEGETATION, rng.uniform(0.8, 1.1, (5, 9)), 6, 9)
    v, t = crown.vertices_m.astype(np.float64), crown.triangles
    edges = Counter(tuple(sorted(e)) for tri in t for e in ((tri[0], tri[1]), (tri[1], tri[2]), (tri[2], tri[0])))
    assert set(edges.values()) == {2}  # closed: every edge between two triangles
    a, b, c = v[t[:, 0]] - (1.0, 2.0, 5.0), v[t[:, 1]] - (1.0, 2.0, 5.0), v[t[:, 2]] - (1.0, 2.0, 5.0)
    assert np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0 > 0  # outward normals enclose a positive volume
    tree = _tree(Point(3.0, -2.0), 0.1, rng).vertices_m.astype(np.float64)
    trunk_top = tree[np.isclose(np.hypot(tree[:, 0] - 3.0, tree[:, 1] + 2.0), 0.18, atol=0.01), 2].max()
    above = tree[tree[:, 2] > trunk_top + 1e-4]
    assert np.all(np.hypot(above[:, 0] - 3.0, above[:, 1] + 2.0) <= 2.5 * 1.12 + 1e-4)
    assert len(above) > 60 and above[:, 2].min() > trunk_top  # nothing of the crown hangs below the trunk top

"""The HD map of a network whose junction outlines take any shape: SUMO's outline of a junction
may cross or touch itself (map editors' junctions), which makes several polygons or a polygon
with a hole."""

import json
import re
from pathlib import Path

import numpy as np
import pytest
import shapely
from shapely.geometry import Polygon

from networks.convert import import_opendrive
from networks.geometry import SE3
from networks.hdmap import RASTER_LAYERS, build_map
from networks.towns import town_opendrive
from networks.world import build_world, load_net


def _ring(points: list[tuple[float, float]], centre: tuple[float, float]) -> str:
    return " ".join(f"{x + centre[0]:.2f},{y + centre[1]:.2f}" for x, y in points)


# Two squares touching at a corner (a figure eight): two polygons.
FIGURE_EIGHT = [(-12, -12), (0, -12), (0, 0), (12, 0), (12, 12), (0, 12), (0, 0), (-12, 0)]
# A square whose outline runs in along a slit and round an inner square: one polygon, one hole.
WITH_HOLE = [(-12, -12), (12, -12), (12, 12), (-12, 12), (-12, 0), (-4, 0), (-4, 4), (4, 4), (4, -4), (-4, -4),
             (-4, 0), (-12, 0)]  # fmt: skip


@pytest.fixture(scope="module")
def odd_junctions(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, str]]:
    """The skeleton town with two junction outlines replaced: a figure eight and one with a hole."""
    text = import_opendrive(town_opendrive("skeleton")).read_text()
    junctions = re.findall(
        r'<junction id="([^":]+)" type="(?:traffic_light|priority)" x="([-\d.]+)" y="([-\d.]+)"', text
    )
    (eight, ex, ey), (hole, hx, hy) = junctions[:2]
    shapes = {eight: _ring(FIGURE_EIGHT, (float(ex), float(ey))), hole: _ring(WITH_HOLE, (float(hx), float(hy)))}
    for jid, shape in shapes.items():
        text = re.sub(rf'(<junction id="{re.escape(jid)}" [^>]*?shape=")[^"]*"', rf'\g<1>{shape}"', text)
    net_path = tmp_path_factory.mktemp("odd-junctions") / "net.net.xml"
    net_path.write_text(text)
    return net_path, {"eight": eight, "hole": hole}


def test_map_json_keeps_every_part_and_hole_of_a_junction(odd_junctions):
    net_path, ids = odd_junctions
    hdmap = build_map(load_net(net_path), None, left_hand=False)
    junctions = {j["id"]: j["polygons"] for j in json.loads(json.dumps(hdmap.static_json()))["junctions"]}
    eight, hole = junctions[ids["eight"]], junctions[ids["hole"]]
    assert len(eight) == 2 and all(len(rings) == 1 for rings in eight)  # two polygons, no holes
    assert [Polygon(rings[0]).area for rings in eight] == pytest.approx([144.0, 144.0], abs=0.01)
    assert len(hole) == 1 and len(hole[0]) == 2  # one polygon: its outline and one hole
    assert Polygon(hole[0][0], [hole[0][1]]).area == pytest.approx(576.0 - 64.0, abs=0.01)
    assert all(len(rings) >= 1 for polygons in junctions.values() for rings in polygons)


def test_the_frame_map_and_world_are_built_over_odd_junctions(odd_junctions):
    """The map's areas keep the junctions' shapes, the frame's vectors and raster are made around
    them, and the world mesh is built."""
    net_path, ids = odd_junctions
    net = load_net(net_path)
    hdmap = build_map(net, None, left_hand=False)
    areas = dict(hdmap.junctions)
    assert shapely.get_num_geometries(areas[ids["eight"]]) == 2
    assert shapely.get_num_interior_rings(areas[ids["hole"]]) == 1
    for jid in ids.values():
        x, y = net.getNode(jid).getCoord()
        map_SE3_ego = SE3(np.eye(3), np.array([x, y, 0.0]))
        view = hdmap.view(map_SE3_ego, 30.0, 15.0)
        layers = hdmap.raster(map_SE3_ego, 30.0, 15.0, 0.5, view)
        assert view and layers[RASTER_LAYERS.index("drivable")].any()
    assert build_world(net_path).mesh.num_triangles > 0

"""Road markings: from a file's roadMark records where it has them, from the lane rules where
not; zebra stripes, stop lines; a malformed record falls back with one notice."""

import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import sumolib

from cosim.parking import find_parking_areas
from networks.classes import SemanticClass
from networks.convert import import_opendrive
from networks.geometry import arc_lengths
from networks.markings import PARKING_SPACE_M, parking_space_centres, read_road_marks
from networks.mesh import polyline_normals
from networks.towns import town_opendrive
from networks.world import StaticWorld, build_world, lane_types, load_net

PAINT = (SemanticClass.LANE_MARKING, SemanticClass.LANE_MARKING_YELLOW)


_SCENES: dict[int, tuple[StaticWorld, Any]] = {}  # each world's raycasting scene, built once


def _down(world: StaticWorld, xy: np.ndarray, z0: float = 200.0) -> np.ndarray:
    """The class of the first surface straight below each point."""
    from sensors.o3d import RaycastingScene, o3c

    mesh = world.mesh
    if id(world) not in _SCENES:
        built = RaycastingScene()
        built.add_triangles(
            o3c.Tensor.from_numpy(mesh.vertices_m), o3c.Tensor.from_numpy(mesh.triangles.astype(np.uint32))
        )
        _SCENES[id(world)] = (world, built)  # the world is kept: its id is not reused
    scene = _SCENES[id(world)][1]
    rays = np.zeros((len(xy), 6), np.float32)
    rays[:, :2], rays[:, 2], rays[:, 5] = xy, z0, -1.0
    result = scene.cast_rays(o3c.Tensor.from_numpy(rays))
    row = np.minimum(result["primitive_ids"].numpy(), mesh.num_triangles - 1)
    return np.where(np.isfinite(result["t_hit"].numpy()), mesh.triangle_class[row], SemanticClass.NONE)


def _carla_style(source: Path, out: Path, centre_type: str = "solid solid") -> Path:
    """The town's file with the centre lines of its roads rewritten as a CARLA export paints
    them: yellow, double."""
    text = source.read_text()

    def centre(match: re.Match[str]) -> str:
        return re.sub(
            r"<roadMark [^>]*/>",
            f'<roadMark sOffset="0" type="{centre_type}" weight="standard" color="yellow" width="0.15"/>',
            match.group(0),
        )

    out.write_text(re.sub(r"<center>.*?</center>", centre, text, flags=re.DOTALL))
    return out


@pytest.fixture(scope="module")
def town05() -> tuple[sumolib.net.Net, StaticWorld]:
    xodr = town_opendrive("town05")
    net_path = import_opendrive(xodr)
    return load_net(net_path), build_world(net_path, xodr_path=xodr)


def test_every_crossing_is_painted_as_stripes_not_a_slab(town05):
    net, world = town05
    crossings = [
        lane for e in net.getEdges(withInternal=True) if e.getFunction() == "crossing" for lane in e.getLanes()
    ]
    assert len(crossings) > 20
    for lane in crossings:
        line = np.asarray(lane.getShape(), np.float64)
        s = np.linspace(0.0, 1.0, 200)
        along = np.column_stack([np.interp(s, np.linspace(0, 1, len(line)), line[:, k]) for k in (0, 1)])
        painted = np.isin(_down(world, along), PAINT)
        stripes = int(np.sum(painted[1:] & ~painted[:-1])) + int(painted[0])
        length = float(np.linalg.norm(np.diff(line, axis=0), axis=1).sum())
        assert stripes == int((length + 0.5) // 1.0), lane.getID()  # one 0.5 m bar every metre
        assert 0.35 < painted.mean() < 0.65


def test_lanes_entering_a_signalised_junction_end_at_a_stop_line(town05):
    net, world = town05
    checked = 0
    for edge in net.getEdges(withInternal=False):
        for lane in edge.getLanes():
            if not (lane.getPermissions() - {"pedestrian"}) or not any(c.getTLSID() for c in lane.getOutgoing()):
                continue
            shape = np.asarray(lane.getShape(), np.float64)
            end, heading = shape[-1], (shape[-1] - shape[-2]) / np.linalg.norm(shape[-1] - shape[-2])
            before = end - heading * np.linspace(0.33, 0.57, 5)[:, None]  # the line: 0.3 m wide, 0.3 m before the end
            assert np.all(np.isin(_down(world, before), PAINT)), lane.getID()
            checked += 1
    assert checked > 50


def _along(shape: np.ndarray, s: np.ndarray, offset: float = 0.0) -> np.ndarray:
    """Points ``s`` along a ``(K, 2)`` polyline, ``offset`` to its left."""
    along, normal = arc_lengths(shape), polyline_normals(shape)
    xy = np.column_stack([np.interp(s, along, shape[:, k]) for k in (0, 1)])
    return xy + np.column_stack([np.interp(s, along, normal[:, k]) for k in (0, 1)]) * offset


def test_parking_lanes_have_a_line_between_their_spaces_and_none_where_a_car_stands(town05):
    net, world = town05
    net_path = import_opendrive(town_opendrive("town05"))
    parking = [net.getLane(i) for i, kind in lane_types(net_path).items() if kind == "parking"]
    assert len(parking) > 10
    spaces = {a.lane_id: a.spaces for a in find_parking_areas(net, lane_types(net_path))}
    lines = stands = 0
    for lane in parking:
        shape = np.asarray(lane.getShape(), np.float64)
        centres = np.asarray(parking_space_centres(float(arc_lengths(shape)[-1])))
        if not len(centres):
            continue
        ends = np.r_[centres - PARKING_SPACE_M / 2, centres[-1] + PARKING_SPACE_M / 2]
        for offset in (-0.3 * lane.getWidth(), 0.0, 0.3 * lane.getWidth()):  # across the lane's width
            assert np.all(_down(world, _along(shape, ends, offset)) == SemanticClass.LANE_MARKING), lane.getID()
            assert np.all(_down(world, _along(shape, centres, offset)) == SemanticClass.PARKING), lane.getID()
        lines += len(ends)
        # the traffic's spaces (where parked vehicles stand) are these, midway between two lines
        driving = net.getLane(f"{lane.getEdge().getID()}_{lane.getIndex() + 1}")
        if driving.getID() in spaces:
            xy = np.asarray([p[:2] for p in spaces[driving.getID()]])
            assert np.allclose(xy, _along(shape, centres), atol=0.02)
            stands += len(xy)
    assert lines > 100 and stands > 100


def test_markings_follow_the_files_roadmarks_colour_and_doubling(tmp_path):
    xodr = _carla_style(town_opendrive("skeleton"), tmp_path / "carla_style.xodr")
    net_path = import_opendrive(xodr)
    world = build_world(net_path, xodr_path=xodr)
    plain = build_world(import_opendrive(town_opendrive("skeleton")), xodr_path=town_opendrive("skeleton"))
    yellow = world.mesh.triangle_class == SemanticClass.LANE_MARKING_YELLOW
    assert yellow.sum() > 20 and not np.any(plain.mesh.triangle_class == SemanticClass.LANE_MARKING_YELLOW)
    # Across the middle of a two-way road: two yellow lines with asphalt between, centred on the road's axis.
    net = load_net(net_path)
    edge = max((e for e in net.getEdges(withInternal=False) if not e.getFunction()), key=lambda e: e.getLength())
    inner = max(edge.getLanes(), key=lambda lane: lane.getIndex())
    shape = np.asarray(inner.getShape(), np.float64)
    mid = shape[0] + (shape[-1] - shape[0]) / 2.0
    heading = (shape[-1] - shape[0]) / np.linalg.norm(shape[-1] - shape[0])
    left = np.array([-heading[1], heading[0]])
    axis = mid + left * inner.getWidth() / 2.0
    across = axis + np.linspace(-0.4, 0.4, 161)[:, None] * left
    cls = _down(world, across)
    yellow_runs = int(
        np.sum((cls[1:] == SemanticClass.LANE_MARKING_YELLOW) & (cls[:-1] != SemanticClass.LANE_MARKING_YELLOW))
    )
    assert yellow_runs == 2
    assert cls[80] == SemanticClass.ROAD  # the gap between the two lines


def test_a_malformed_roadmark_falls_back_to_the_lane_rules_with_one_notice(tmp_path):
    text = town_opendrive("skeleton").read_text()
    broken = re.sub(r'type="broken"', 'type="zigzag"', text, count=1)
    broken = re.sub(r'width="0.13"', 'width="wide"', broken, count=3)
    xodr = tmp_path / "broken_marks.xodr"
    xodr.write_text(broken)
    marks = read_road_marks(xodr)
    assert "zigzag" in marks.problem or "wide" in marks.problem
    world = build_world(import_opendrive(xodr), xodr_path=xodr)
    assert world.notice.startswith(f"note: {xodr}: ") and "\n" not in world.notice
    plain = build_world(import_opendrive(town_opendrive("skeleton")), xodr_path=town_opendrive("skeleton"))
    painted, as_filed = (np.sum(w.mesh.triangle_class == SemanticClass.LANE_MARKING) for w in (world, plain))
    assert 0.9 * as_filed < painted < 1.1 * as_filed  # the broken roads painted by the rules


def test_markings_can_be_turned_off():
    xodr = town_opendrive("skeleton")
    world = build_world(import_opendrive(xodr), markings=False, xodr_path=xodr)
    assert not np.any(np.isin(world.mesh.triangle_class, PAINT))

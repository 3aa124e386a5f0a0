"""Small road networks of the kinds users try first (one road, a curve, a crest, one junction,
a merge without sidewalks, a lane-width change, left-hand traffic, a dead end) each make a
dataset: an ego, traffic in view, notices instead of errors, scene cuts where the road ends."""

import json
import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from cosim.loop import run
from cosim.net_index import index_net
from cosim.scenario import load_scenario
from gtgen.load import iter_messages, load_labels
from networks.plain import PlainEdge, PlainNetwork, PlainNode, write_opendrive
from networks.world import load_net

pytestmark = pytest.mark.slow
LIGHT_RIG = ("sensors.cameras=[]", "outputs.kitti=false", "outputs.yolo=false")
VEHICLES = ("car", "truck", "bus", "motorcycle", "bicycle")
FAST = {"speed_mps": 27.0, "sidewalk_width_m": 0.0, "spread": "center"}


def two_way(a: str, b: str, **kw) -> tuple[PlainEdge, PlainEdge]:
    return PlainEdge(f"{a}_{b}", a, b, **kw), PlainEdge(f"{b}_{a}", b, a, **kw)


def shaped(points: list[tuple[float, float, float]]) -> tuple[PlainEdge, PlainEdge]:
    return PlainEdge("ab", "a", "b", shape=tuple(points)), PlainEdge("ba", "b", "a", shape=tuple(points[::-1]))


def networks() -> dict[str, PlainNetwork]:
    N = PlainNode
    quarter = [(150 * math.sin(t), 150 - 150 * math.cos(t), 0.0) for t in np.linspace(0, math.pi / 2, 13)]
    crest = [(x, 0.0, 8.0 * math.sin(math.pi * x / 400)) for x in range(0, 401, 25)]
    ends = (N("a", 0, 0), N("b", 400, 0))
    return {
        "straight": PlainNetwork(ends, two_way("a", "b")),
        "curve": PlainNetwork((N("a", 0, 0), N("b", 150, 150)), shaped(quarter)),
        "crest": PlainNetwork(ends, shaped(crest)),
        "junction": PlainNetwork(
            (N("c", 0, 0), N("w", -200, 0), N("e", 200, 0), N("n", 0, 200)),
            two_way("w", "c") + two_way("c", "e") + two_way("c", "n"),
        ),
        "merge_no_sidewalks": PlainNetwork(
            (N("a", 0, 0), N("m", 300, 0), N("b", 800, 0), N("r", 0, -80)),
            (
                PlainEdge("am", "a", "m", num_lanes=2, **FAST),
                PlainEdge("mb", "m", "b", num_lanes=2, **FAST),
                PlainEdge("rm", "r", "m", **FAST),
            ),
        ),
        "lane_width_change": PlainNetwork(
            (N("a", 0, 0), N("m", 200, 0), N("b", 400, 0)),
            two_way("a", "m", num_lanes=2, lane_width_m=3.6) + two_way("m", "b", lane_width_m=2.8),
        ),
        "left_hand": PlainNetwork(ends, two_way("a", "b"), netconvert_options=("--lefthand", "true")),
        "dead_end": PlainNetwork((N("a", 0, 0), N("b", 150, 0)), (PlainEdge("ab", "a", "b", spread="center"),)),
    }


@pytest.fixture(scope="module")
def maps(tmp_path_factory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("small_maps")
    return {name: write_opendrive(net, root / name, root / f"{name}.xodr") for name, net in networks().items()}


def drive(xodr: Path, out: Path, frames: int = 200) -> Path:
    scene = out.parent / f"{out.name}.yaml"
    scene.write_text(f"network: {xodr}\nframes: {frames}\nseed: 1\n")
    run(load_scenario(str(scene), list(LIGHT_RIG)), out, progress=False)
    return out


@pytest.fixture(scope="module")
def drives(maps, tmp_path_factory) -> Callable[[str], Path]:
    """The 200-frame drive on each small network, made once for the tests that read it."""
    root = tmp_path_factory.mktemp("small_drives")
    done: dict[str, Path] = {}

    def drive_on(name: str) -> Path:
        if name not in done:
            done[name] = drive(maps[name], root / name)
        return done[name]

    return drive_on


def ego_xy(out: Path) -> np.ndarray:
    return np.array([(m.transforms[0].translation.x, m.transforms[0].translation.y)
                     for _, _, m in iter_messages(out / "run.mcap", ["/tf"])])  # fmt: skip


@pytest.mark.parametrize("name", list(networks()))
def test_a_small_network_makes_200_frames_with_traffic_in_view(name, drives):
    out = drives(name)
    labels = load_labels(out / "labels.csv")
    seen_vehicles = labels[(labels["seen"] == 1) & labels["type"].isin(VEHICLES)]
    frames_with_traffic = seen_vehicles["frame"].nunique()
    assert frames_with_traffic >= 0.6 * 200, f"{name}: another vehicle seen in {frames_with_traffic} of 200 frames"
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["frames"] == 200
    assert ego_xy(out).shape == (200, 2)


@pytest.mark.parametrize("name", ["straight", "crest", "lane_width_change", "left_hand"])
def test_the_ego_drives_on_a_road_without_junctions(name, drives):
    ego = ego_xy(drives(name))[:100]  # the first 100 frames (5 s) of the drive
    assert np.linalg.norm(np.diff(ego, axis=0), axis=1).sum() > 20.0


def test_a_network_without_sidewalks_has_no_pedestrians_and_says_so(maps, tmp_path, capsys):
    out = drive(maps["merge_no_sidewalks"], tmp_path / "merge", frames=20)
    assert "the network has no sidewalks or footpaths; the scene has no pedestrians" in capsys.readouterr().err
    assert not (load_labels(out / "labels.csv")["type"] == "pedestrian").any()


def test_the_ego_at_a_dead_end_starts_again_and_the_frame_is_marked_as_a_scene_cut(drives):
    out = drives("dead_end")
    cuts = json.loads((out / "manifest.json").read_text())["scene_cuts"]
    assert cuts, "the ego should run out of the 150 m road within 10 s"
    flagged = [m["frame"] for _, _, m in iter_messages(out / "run.mcap", ["/gt/labels"]) if m["scene_cut"]]
    assert flagged == cuts
    x = [m.transforms[0].translation.x for _, _, m in iter_messages(out / "run.mcap", ["/tf"])]
    for frame in cuts:  # the new ego starts back at the start of the road
        assert x[frame] < x[frame - 1] - 50.0


def test_entries_and_exits_are_where_traffic_enters_and_leaves_the_network(maps):
    from networks.convert import import_opendrive

    index = index_net(load_net(import_opendrive(maps["merge_no_sidewalks"])))
    shapes = index.edge_shape_xy
    entries, exits = index.entries_by_vclass["passenger"], index.exits_by_vclass["passenger"]
    west = min(p[0] for shape in shapes.values() for p in shape)
    east = max(p[0] for shape in shapes.values() for p in shape)
    assert len(entries) == 2 and all(abs(shapes[e][0][0] - west) < 1.0 for e in entries)  # the road and the ramp
    assert len(exits) == 1 and abs(shapes[exits[0]][-1][0] - east) < 1.0

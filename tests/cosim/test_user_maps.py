"""A user's OpenDRIVE file drives like a built-in town: traffic, an ego, labelled frames."""

from pathlib import Path

import numpy as np
import pytest

from cosim.loop import run
from cosim.scenario import load_scenario
from gtgen.load import iter_messages, load_labels, load_map_frame

pytestmark = pytest.mark.slow
XODR = Path(__file__).resolve().parents[1] / "data" / "xodr"
LIGHT_RIG = ("sensors.cameras=[]", "outputs.kitti=false", "outputs.yolo=false")


@pytest.mark.parametrize("name", ["spiral_parampoly3.xodr", "left_hand_traffic.xodr", "elevation_superelevation.xodr"])
def test_a_drive_on_a_users_map_writes_labelled_frames(name, tmp_path, capsys):
    scene = tmp_path / "scene.yaml"
    traffic = "{vehicles: 10, pedestrians: 5, parked: 4}"
    scene.write_text(f"network: {XODR / name}\nframes: 60\nwarmup_s: 20\ntraffic: {traffic}\n")
    summary = run(load_scenario(str(scene), list(LIGHT_RIG)), tmp_path / "out", progress=False)
    assert summary.frames == 60
    assert "traffic.parked asks for 4 parked vehicles; the network has no parking lanes" in capsys.readouterr().err
    labels = load_labels(tmp_path / "out" / "labels.csv")
    assert len(labels) > 0 and labels["lidar_points"].sum() > 0
    ego = np.array([(m.transforms[0].translation.x, m.transforms[0].translation.y)
                    for _, _, m in iter_messages(tmp_path / "out" / "run.mcap", ["/tf"])])  # fmt: skip
    assert ego.shape == (60, 2)
    assert np.linalg.norm(ego[-1] - ego[0]) > 5.0  # the ego drove
    vectors, layers = load_map_frame(tmp_path / "out", 59)  # map ground truth on a user's map too
    kinds = {e["type"] for e in vectors["elements"]}
    assert {"road_boundary", "lane_centre"} <= kinds and vectors["ego_lane"] and layers["drivable"].any()


def test_a_users_roadmarks_reach_the_lidar_bright_and_classed(tmp_path):
    """A CARLA-style file (yellow double centre lines): paint points in every frame, yellow
    ones among them, at least twice as intense as the road at the same range."""
    import re

    from gtgen.load import lidar_points
    from networks.classes import SemanticClass
    from networks.towns import town_opendrive

    text = town_opendrive("skeleton").read_text()
    double_yellow = '<roadMark sOffset="0" type="solid solid" weight="standard" color="yellow" width="0.15"/>'
    text = re.sub(r"<center>.*?</center>", lambda m: re.sub(r"<roadMark [^>]*/>", double_yellow, m.group(0)), text,
                  flags=re.DOTALL)  # fmt: skip
    xodr = tmp_path / "carla_style.xodr"
    xodr.write_text(text)
    scene = tmp_path / "scene.yaml"
    scene.write_text(f"network: {xodr}\nframes: 40\nwarmup_s: 20\ntraffic: {{vehicles: 20, pedestrians: 5}}\n")
    run(load_scenario(str(scene), list(LIGHT_RIG)), tmp_path / "out", progress=False)
    frames_with_yellow = 0
    for _, _, cloud in iter_messages(tmp_path / "out" / "run.mcap", ["/lidar"]):
        p = lidar_points(cloud)
        paint = np.isin(p["class"], [SemanticClass.LANE_MARKING, SemanticClass.LANE_MARKING_YELLOW])
        assert paint.sum() > 50
        frames_with_yellow += int(np.any(p["class"] == SemanticClass.LANE_MARKING_YELLOW))
        near = np.hypot(p["x"], p["y"]) < 15.0
        road = near & (p["class"] == SemanticClass.ROAD)
        assert p["intensity"][near & paint].mean() >= 2.0 * p["intensity"][road].mean()
    assert frames_with_yellow >= 20

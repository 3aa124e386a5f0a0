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


MOTORWAY_MAPS = sorted((XODR / "motorway").glob("*.xodr"))


@pytest.mark.parametrize("xodr", MOTORWAY_MAPS, ids=lambda p: p.stem)
def test_maps_with_motorway_roads_drive(xodr, tmp_path):
    """Maps whose motorway roads carry sidewalks and bicycle lanes (their driving lanes closed to
    bicycles and pedestrians) drive, with bicycles and pedestrians in the traffic asked for."""
    scene = tmp_path / "scene.yaml"
    traffic = "{vehicles: 20, pedestrians: 10, mix: {car: 0.6, truck: 0.1, bicycle: 0.3}}"
    scene.write_text(f"network: {xodr}\nframes: 30\nwarmup_s: 20\ntraffic: {traffic}\n")
    summary = run(load_scenario(str(scene), list(LIGHT_RIG)), tmp_path / "out", progress=False)
    assert summary.frames == 30
    ego = np.array([(m.transforms[0].translation.x, m.transforms[0].translation.y)
                    for _, _, m in iter_messages(tmp_path / "out" / "run.mcap", ["/tf"])])  # fmt: skip
    labels = load_labels(tmp_path / "out" / "labels.csv")
    moving = np.hypot(labels["vx"], labels["vy"]) > 2.0  # relative to the ego, which may wait at a light
    assert np.linalg.norm(ego[-1] - ego[0]) > 5.0 or moving[labels["type"] == "car"].any()


def test_a_network_sumo_refuses_is_one_line_with_sumos_reason_and_the_file(tmp_path):
    """A cached network SUMO does not load (left by an earlier version) stops the run with one
    line: the network file and SUMO's own first error (libsumo itself says only 'Process
    Error')."""
    import os
    import subprocess
    import sys

    from networks.cache import seal

    env = {**os.environ, "SUMO_DATASET_CACHE": str(tmp_path / "cache")}
    xodr = XODR / "motorway" / "motorway_split.xodr"
    convert = f"import pathlib, networks.convert as c; print(c.import_opendrive(pathlib.Path('{xodr}')))"
    net = Path(subprocess.run([sys.executable, "-c", convert], env=env, capture_output=True, text=True,
                              check=True).stdout.strip())  # fmt: skip
    net.write_text(net.read_text().replace('allow="pedestrian"', 'allow=""'))
    seal(net)
    scene = tmp_path / "scene.yaml"
    scene.write_text(f"network: {xodr}\nframes: 5\nwarmup_s: 2\n")
    proc = subprocess.run([sys.executable, "-m", "cosim", "run", str(scene), "--out", str(tmp_path / "out"),
                           "--no-progress", *(f"--set={s}" for s in LIGHT_RIG)],
                          env=env, capture_output=True, text=True, check=False)  # fmt: skip
    errors = [line for line in proc.stderr.splitlines() if line.startswith("error")]
    assert proc.returncode == 2
    assert errors == [
        f"error: {net}: SUMO could not load the network: An unknown lane ('-41_0') was tried to be "
        "set as incoming to junction '41.end'."
    ]

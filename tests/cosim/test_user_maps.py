"""A user's OpenDRIVE file drives like a built-in town: traffic, an ego, labelled frames."""

from pathlib import Path

import numpy as np
import pytest

from cosim.loop import run
from cosim.scenario import load_scenario
from gtgen.load import iter_messages, load_labels

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

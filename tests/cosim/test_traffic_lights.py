"""Traffic lights: every head's state in the labels is libsumo's at that step, and the camera
shows the lamp of that state."""

from pathlib import Path

import cv2
import libsumo
import numpy as np
import pandas as pd
import pytest

from cosim.loop import run
from cosim.scenario import load_scenario
from cosim.sumo import traffic as traffic_module
from cosim.world_setup import prepare_network
from gtgen.load import load_labels

pytestmark = pytest.mark.slow
DATA = Path(__file__).resolve().parents[1] / "data"
STATE_OF_LETTER = {"r": "red", "y": "yellow", "G": "green", "g": "green", "s": "green", "u": "red_yellow",
                   "o": "off", "O": "off"}  # fmt: skip


LIGHT_LIDAR = "sensors.lidars=[{name: lidar, beams: 16, azimuth_steps: 256}]"


@pytest.fixture(scope="module")
def signalised_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[float, dict[str, str]]]:
    """400 frames on the skeleton grid (a signalised centre), with libsumo's states recorded
    at every step, straight from libsumo, beside the run. The states come from the traffic,
    not the sensors: a light LiDAR alone."""
    out = tmp_path_factory.mktemp("lights")
    seen: dict[float, dict[str, str]] = {}
    step = traffic_module.Traffic.step

    def recording_step(self: traffic_module.Traffic) -> None:
        step(self)
        t = round(libsumo.simulation.getTime(), 3)
        seen[t] = {tls: libsumo.trafficlight.getRedYellowGreenState(tls) for tls in libsumo.trafficlight.getIDList()}

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(traffic_module.Traffic, "step", recording_step)
        overrides = ["frames=400", "outputs.kitti=false", "outputs.yolo=false", "outputs.mcap=false",
                     "sensors.cameras=[]", "sensors.radars=[]", LIGHT_LIDAR]  # fmt: skip
        run(load_scenario(str(DATA / "tiny.yaml"), overrides), out, progress=False, one_process=True)
    return out, seen


@pytest.fixture(scope="module")
def camera_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The first 30 frames of the same drive with the realistic camera (its lamps are under
    test): the ego faces a signal head at the grid's centre in its first 25 frames."""
    out = tmp_path_factory.mktemp("lamps")
    camera = "sensors.cameras=[{name: camera, width_px: 640, height_px: 360}]"  # a quarter of the pixels: faster
    overrides = ["frames=30", "outputs.yolo=false", "outputs.mcap=false", "sensors.radars=[]", LIGHT_LIDAR, camera]
    run(load_scenario(str(DATA / "tiny.yaml"), overrides), out, progress=False)
    return out


def test_every_heads_state_is_libsumos_at_every_frame(signalised_run):
    out, seen = signalised_run
    table = pd.read_csv(out / "lights_and_signs.csv", keep_default_na=False)
    lights = table[table["type"] == "traffic_light"]
    assert (lights["subtype"] == "signal_head").all() and (
        table.loc[table["type"] != "traffic_light", "state"] == ""
    ).all()
    assert lights["frame"].nunique() >= 300  # heads in range in most frames
    assert {"red", "green"} <= set(lights["state"]) and "yellow" in set(lights["state"])
    net = prepare_network(load_scenario(str(DATA / "tiny.yaml"))).net
    checked = 0
    for row in lights.itertuples():
        lanes = row.lanes.split()
        links = [c for lane in lanes for c in net.getLane(lane).getOutgoing() if c.getTLSID() == str(row.junction)]
        straight = [c for c in links if c.getDirection() == "s"] or sorted(links, key=lambda c: c.getTLLinkIndex())
        letter = seen[round(row.timestamp, 3)][str(row.junction)][straight[0].getTLLinkIndex()]
        assert row.state == STATE_OF_LETTER[letter], (row.frame, row.id)
        checked += 1
    assert checked == len(lights) > 400
    labels = load_labels(out / "labels.csv")
    heads = labels[labels["type"] == "traffic_light"]
    assert len(heads) == len(lights)  # every head labelled is in the table, and the other way round


LAMP_BGR = {"red": (40, 40, 255), "yellow": (0, 200, 255), "green": (90, 255, 60)}


def test_each_visible_head_shows_the_lamp_of_its_state(camera_run):
    out = camera_run
    lights = pd.read_csv(out / "lights_and_signs.csv", keep_default_na=False)
    lights = lights[lights["type"] == "traffic_light"]
    labels = load_labels(out / "labels.csv").set_index(["frame", "id"])
    checked = 0
    for row in lights[(lights["camera_visible_px"] >= 60) & lights["state"].isin(list(LAMP_BGR))].itertuples():
        box = labels.loc[(row.frame, row.id)]
        towards_ego = -np.array([box["x"], box["y"]]) / np.hypot(box["x"], box["y"])
        if np.cos(box["rotation_z"]) * towards_ego[0] + np.sin(box["rotation_z"]) * towards_ego[1] < 0.7:
            continue  # seen from the side or the back: its lamps face away
        if box["truncated"] > 0 or row.distance < 8.0:
            continue  # partly out of the picture, or overhead
        image = cv2.imread(str(out / "kitti" / "image_2" / f"{row.frame:06d}.png"))
        left, top = int(box["modal_left"]), int(box["modal_top"])
        patch = image[top : int(box["modal_bottom"]) + 1, left : int(box["modal_right"]) + 1].reshape(-1, 3)
        near = {s: int(np.sum(np.abs(patch.astype(int) - bgr).max(axis=1) <= 12)) for s, bgr in LAMP_BGR.items()}
        assert near[row.state] >= 2, (row.frame, row.id, row.state, near)
        assert all(n == 0 for s, n in near.items() if s != row.state), (row.frame, row.id, row.state, near)
        checked += 1
    assert checked >= 15  # 20 in these 30 frames

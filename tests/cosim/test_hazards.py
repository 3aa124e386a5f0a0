"""Hazard scenes: events made near the ego, their criticality labels and events.csv."""

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from cosim.loop import run
from cosim.scenario import load_scenario
from gtgen.criticality import time_to_collision
from gtgen.load import load_labels

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT / "tests" / "data"
# the catalog's hard-braking scene up to its second event, with a LiDAR alone (faster)
LIGHT = ["frames=620", "sensors.cameras=[]", "sensors.radars=[]", "outputs.kitti=false", "outputs.yolo=false",
         "outputs.mcap=false", "outputs.map=false"]  # fmt: skip


def ttc_by_hand(x: float, y: float, vx: float, vy: float, r: float) -> float:
    """When the point (x, y) moving at (vx, vy) first comes within r of the origin (nan: never)."""
    if x * x + y * y <= r * r:
        return 0.0
    a, b, c = vx * vx + vy * vy, 2 * (x * vx + y * vy), x * x + y * y - r * r
    if a == 0 or b >= 0 or b * b < 4 * a * c:
        return math.nan
    return (-b - math.sqrt(b * b - 4 * a * c)) / (2 * a)


def test_time_to_collision_closing_passing_and_receding():
    p = np.array([[20.0, 0.0], [20.0, 10.0], [20.0, 0.0], [1.0, 0.0]])
    v = np.array([[-5.0, 0.0], [-5.0, 0.0], [5.0, 0.0], [0.0, 0.0]])
    ttc = time_to_collision(p, v, np.full(4, 5.0))
    assert ttc[0] == pytest.approx(3.0) and np.isnan(ttc[1]) and np.isnan(ttc[2]) and ttc[3] == 0.0


@pytest.mark.slow
def test_hazard_events_are_labelled_and_the_same_for_the_same_seed(tmp_path):
    outs = []
    for k in range(2):
        out = tmp_path / f"run{k}"
        run(load_scenario("town05_hard_braking", LIGHT), out, progress=False)
        outs.append(out)
    first, second = ((o / "events.csv").read_text() for o in outs)
    assert first == second  # determinism: same seed, same events
    events = pd.read_csv(outs[0] / "events.csv")
    assert list(events["kind"]) == ["hard_brake", "hard_brake"]
    assert (events["min_distance"] <= 60).all() and (events["min_ttc"] < 4.0).all() and not events["ego_collided"].any()
    labels = load_labels(outs[0] / "labels.csv")
    marked = labels[labels["hazard_event"].notna()]
    for _, event in events.iterrows():  # the labels mark the event's actors over its frames
        rows = marked[marked["hazard_event"] == event["event"]]
        assert rows["frame"].min() == event["first_frame"] and rows["frame"].max() <= event["last_frame"]
        assert {int(a) for a in str(event["actors"]).split()} >= set(rows["id"].astype(int))
    # the time to collision in labels.csv, computed again from its positions and velocities
    expected = np.array([ttc_by_hand(*row) for row in labels[["x", "y", "vx", "vy", "collision_radius"]].to_numpy()])
    got = labels["ttc"].to_numpy(float)
    assert np.array_equal(np.isnan(expected), np.isnan(got))
    both = ~np.isnan(expected)
    assert both.sum() > 100
    assert np.all(np.abs(got[both] - expected[both]) <= np.maximum(1e-3, 0.01 * expected[both]))


@pytest.mark.slow
def test_a_hazard_the_network_cannot_have_stops_the_run_before_frame_0_with_one_line(tmp_path):
    scene = tmp_path / "spiral.yaml"
    scene.write_text(f"network: {DATA / 'xodr' / 'spiral_parampoly3.xodr'}\nframes: 5\n"
                     "hazards: [{kind: red_light, per_minute: 2}]\n")  # fmt: skip
    proc = subprocess.run([sys.executable, "-m", "cosim", "run", str(scene), "--out", str(tmp_path / "o")],
                          capture_output=True, text=True, cwd=ROOT, check=False)  # fmt: skip
    lines = [line for line in proc.stderr.strip().splitlines() if line.startswith("error")]
    assert proc.returncode != 0
    assert lines == ["error: hazards: red_light needs signalised junctions; this network has no traffic lights"]
    assert not (tmp_path / "o").exists()


@pytest.mark.slow
def test_a_jaywalker_is_a_pedestrian_hidden_behind_a_parked_car_then_in_the_open(tmp_path):
    run(load_scenario("town05_jaywalkers", [*LIGHT[1:], "frames=515"]), tmp_path, progress=False)
    events = pd.read_csv(tmp_path / "events.csv")
    assert list(events["kind"]) == ["jaywalker"]
    labels = load_labels(tmp_path / "labels.csv")
    actor = labels[labels["hazard_event"] == events["event"][0]].sort_values("frame")
    assert set(actor["type"]) == {"pedestrian"}
    points = actor["lidar_points"].to_numpy()
    assert points[0] == 0 and points[-1] > 3  # hidden from the LiDAR by the parked car, then not

"""Hazard scenes: events made near the ego, their criticality labels and events.csv."""

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import shapely

from cosim.hazards.plan import Schedule, Sight
from cosim.loop import run
from cosim.scenario import load_scenario
from cosim.state import WorldState
from cosim.sumo.hazards import roads
from cosim.sumo.traffic import Traffic
from cosim.traffic_feed import TrafficInline
from cosim.world_setup import prepare_network
from gtgen.criticality import time_to_collision
from gtgen.load import load_labels
from networks.sumo_tools import sumo_home

sumo_home()  # exports SUMO_HOME before libsumo loads
import libsumo  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT / "tests" / "data"
# the catalog's hard-braking scene, 30 s, with a LiDAR alone (faster)
LIGHT = ["frames=600", "sensors.cameras=[]", "sensors.radars=[]", "outputs.kitti=false", "outputs.yolo=false",
         "outputs.mcap=false", "outputs.map=false"]  # fmt: skip


def _touch_times(row: pd.Series, times: np.ndarray) -> np.ndarray:
    """Whether the object's footprint, moved by its relative velocity for each time, touches
    the ego's (shapely polygons: a reading of the labels independent of the SAT in criticality)."""
    ego = shapely.box(-row.ego_length / 2, -row.ego_width / 2, row.ego_length / 2, row.ego_width / 2)
    c, s = math.cos(row.rotation_z), math.sin(row.rotation_z)
    half = np.array([[1, 1], [1, -1], [-1, -1], [-1, 1]]) * [row.l / 2, row.w / 2]
    corners = half @ np.array([[c, s], [-s, c]])  # (4, 2): the rectangle turned by its yaw
    centres = np.array([row.x, row.y]) + times[:, None] * [row.vx, row.vy]
    return shapely.intersects(ego, shapely.polygons(centres[:, None, :] + corners[None]))


def check_ttc_by_hand(row: pd.Series) -> bool:
    """labels.csv's ttc against the footprints: no touch before it (scanned every 5 ms), a
    touch within 1e-3 s or 1 % after it; no touch in the next minute when it is empty."""
    if math.isnan(row.ttc):
        return not _touch_times(row, np.arange(0.0, 60.0, 0.005)).any()
    slack = max(1e-3, 0.01 * row.ttc)
    before = _touch_times(row, np.arange(0.0, max(row.ttc - slack, 0.0), 0.005))
    after = _touch_times(row, np.linspace(row.ttc, row.ttc + slack, 20))
    return not before.any() and bool(after.any())


def test_time_to_collision_closing_passing_beside_and_receding():
    p = np.array([[20.0, 0.0], [20.0, 3.5], [20.0, 0.0], [1.0, 0.0], [0.0, 3.5], [10.0, 10.0]])
    v = np.array([[-5.0, 0.0], [-5.0, 0.0], [5.0, 0.0], [0.0, 0.0], [0.0, 0.0], [-1.0, -1.0]])
    yaw = np.array([0.0, 0.0, 0.0, 0.0, 0.0, math.pi / 2])
    lw = np.full((6, 2), [4.0, 2.0])
    ttc = time_to_collision(p, v, yaw, lw, np.array([4.0, 2.0]))
    assert ttc[0] == pytest.approx(16.0 / 5.0)  # bumper to bumper: 20 m less two half lengths
    assert np.isnan(ttc[1])  # overtaken in the next lane (3.5 m beside): passes, no collision
    assert np.isnan(ttc[2]) and ttc[3] == 0.0 and np.isnan(ttc[4])  # receding; overlapping; beside, still
    assert ttc[5] == pytest.approx(7.0)  # coming in diagonally, turned across: corner meets corner


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
    assert list(events["kind"]) == ["hard_brake"] * 3  # 6 a minute: one due in each 10 s
    assert (events["min_distance"] <= 60).all() and (events["min_ttc"] < 4.0).all() and not events["ego_collided"].any()
    labels = load_labels(outs[0] / "labels.csv")
    marked = labels[labels["hazard_event"].notna()]
    for _, event in events.iterrows():  # the labels mark the event's actors over its frames
        rows = marked[marked["hazard_event"] == event["event"]]
        assert rows["frame"].min() == event["first_frame"] and rows["frame"].max() <= event["last_frame"]
        assert {int(a) for a in str(event["actors"]).split()} >= set(rows["id"].astype(int))
    # the time to collision in labels.csv, checked against the footprints it is between
    rows = labels.sample(n=400, random_state=0)
    closing = labels[labels["ttc"].notna()]
    assert len(closing) > 100
    rows = pd.concat([rows, closing.sample(n=200, random_state=0)])
    wrong = [i for i, row in rows.iterrows() if not check_ttc_by_hand(row)]
    assert not wrong, rows.loc[wrong[:5], ["x", "y", "rotation_z", "l", "w", "vx", "vy", "ttc"]]


def _run_traffic(scene: str, frames: int, *overrides: str) -> tuple[list[WorldState], float]:
    """A scene's world states (its traffic alone, no sensors), and when its events are first due
    from (the end of the warm-up)."""
    scenario = load_scenario(scene, [f"frames={frames}", *overrides])
    with TrafficInline(prepare_network(scenario).net_path, scenario, 150.0) as traffic:
        traffic.warm_up()
        states = [traffic.next() for _ in range(frames)]
    return states, states[0].time_s - scenario.step_s


def _events(states: list[WorldState]) -> dict[str, int]:
    """Each event's name and first frame."""
    first: dict[str, int] = {}
    for frame, state in enumerate(states):
        for hazard in state.hazards:
            first.setdefault(hazard.name, frame)
    return first


@pytest.mark.slow
@pytest.mark.parametrize("scene", ["town06_cut_ins", "town05_hard_braking", "town05_jaywalkers", "town05_red_light"])
def test_hazards_happen_when_due_and_the_same_for_the_same_seed(scene):
    """600 frames (30 s) of a catalog hazard scene: as many events as are due (one in each
    period of 60 / per_minute s, in its middle half, from the seed), the same in a second run."""
    states, start_s = _run_traffic(scene, 600)
    scenario = load_scenario(scene)
    hazard = scenario.hazards[0]
    schedule = Schedule(60.0 / hazard.per_minute, start_s, np.random.default_rng([scenario.seed, 0x5C4E, 0]))
    due = 0
    while schedule.due_s(due) <= states[-1].time_s:
        due += 1
    assert due - 1 <= len(_events(states)) <= due and _events(states)
    assert _events(_run_traffic(scene, 600)[0]) == _events(states)


def _made_and_gone(monkeypatch: pytest.MonkeyPatch, scene: str, *overrides: str) -> tuple[list[bool], list[bool]]:
    """Over a scene's warm-up and 400 frames of its traffic, after every SUMO step: whether the
    rig could see each actor made for an event where it entered, and each jaywalker where it left."""
    scenario = load_scenario(scene, ["frames=400", *overrides])
    prepared = prepare_network(scenario)
    traffic = Traffic(prepared.net_path, prepared.net, scenario)
    sight = Sight.of_rig(scenario.sensors)
    entered: list[bool] = []
    left: list[bool] = []
    people: dict[str, tuple[float, float]] = {}
    sumo_step = libsumo.simulationStep

    def seen(xy: tuple[float, float], radius_m: float) -> bool:
        return sight.sees(roads.in_ego_frame(traffic.ego_id, np.array(xy)), radius_m)

    def observed_step() -> None:
        nonlocal people
        sumo_step()
        if not traffic.ego_id:
            return
        made = [v for v in libsumo.simulation.getDepartedIDList() if v.startswith("hazard_")]
        entered.extend(seen(libsumo.vehicle.getPosition(v), 3.0) for v in made)
        now = {p: libsumo.person.getPosition(p) for p in libsumo.person.getIDList() if p.startswith("jaywalker_")}
        entered.extend(seen(now[p], 1.0) for p in sorted(now.keys() - people.keys()))
        left.extend(seen(people[p], 1.0) for p in sorted(people.keys() - now.keys()))
        people = now

    monkeypatch.setattr(libsumo, "simulationStep", observed_step)
    try:
        traffic.warm_up()
        for _ in range(scenario.frames):
            traffic.step()
    finally:
        traffic.close()
    return entered, left


@pytest.mark.slow
@pytest.mark.parametrize(("scene", "overrides"), [
    ("town06_cut_ins", ["traffic.vehicles_per_lane_km=1"]),
    ("town05_hard_braking", ["traffic.vehicles=0"]),  # no traffic: even a sparse one may offer a leader
    ("town05_jaywalkers", ["hazards=[{kind: jaywalker, per_minute: 3, distance_m: [12, 50], behind_parked: false}]"]),
    ("town05_red_light", ["traffic.vehicles=0"]),  # or a vehicle that could run the red
])  # fmt: skip
def test_actors_made_for_events_come_and_go_out_of_the_rigs_sight(monkeypatch, scene, overrides):
    """Where the traffic offers no actor, one is made: cars behind the ego (cut-ins), ahead of it
    (hard braking) or on a crossing approach (red-light runners), pedestrians at a kerb ahead
    (jaywalkers in the open); each enters the world where no sensor of the rig sees it and no
    label reaches, and a jaywalker leaves it only once out of sight again."""
    entered, left = _made_and_gone(monkeypatch, scene, *overrides)
    assert entered, f"{scene}: nothing was made"
    assert not any(entered) and not any(left)


@pytest.mark.slow
def test_a_hazard_the_network_cannot_have_stops_the_run_before_frame_0_with_one_line(tmp_path):
    scene = tmp_path / "spiral.yaml"
    scene.write_text(
        f"network: {DATA / 'xodr' / 'spiral_parampoly3.xodr'}\nframes: 5\n"
        "hazards: [{kind: red_light, per_minute: 2}]\n"
    )
    proc = subprocess.run([sys.executable, "-m", "cosim", "run", str(scene), "--out", str(tmp_path / "o")],
                          capture_output=True, text=True, cwd=ROOT, check=False)  # fmt: skip
    lines = [line for line in proc.stderr.strip().splitlines() if line.startswith("error")]
    assert proc.returncode != 0
    assert lines == ["error: hazards: red_light needs signalised junctions; this network has no traffic lights"]
    assert not (tmp_path / "o").exists()


@pytest.mark.slow
def test_a_jaywalker_is_a_child_hidden_behind_a_parked_car_then_in_the_open(tmp_path):
    """The catalog's jaywalker steps out in front of a parked car: no LiDAR point and no pixel
    at first (the child is lower than the car's roof), then fully visible."""
    light = ["frames=330", "sensors.radars=[]", "outputs.kitti=false", "outputs.yolo=false", "outputs.mcap=false",
             "outputs.map=false"]  # fmt: skip
    run(load_scenario("town05_jaywalkers", light), tmp_path, progress=False)
    events = pd.read_csv(tmp_path / "events.csv")
    assert list(events["kind"]) == ["jaywalker"]
    assert events["seen_lidar"][0] == 0 and events["seen_camera"][0] == 0
    labels = load_labels(tmp_path / "labels.csv")
    actor = labels[labels["hazard_event"] == events["event"][0]].sort_values("frame")
    assert set(actor["type"]) == {"pedestrian"} and set(actor["h"]) == {1.15}
    first, last = actor.iloc[0], actor.iloc[-1]
    assert first["lidar_points"] == 0 and first["camera_visible_px"] == 0 and first["visible_fraction"] == 0
    assert first["occluded"] == 3  # fully occluded
    assert last["lidar_points"] > 3 and last["visible_fraction"] > 0.9 and last["occluded"] == 0

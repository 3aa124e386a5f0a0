"""The labels' "seen by the LiDAR" agrees with casting each object alone against the full scene."""

from pathlib import Path

import numpy as np
import pytest

from cosim.loop import AGENT_MARGIN_M, on_raised_surfaces, sense_and_label
from cosim.rig import build_rig
from cosim.scenario import load_scenario
from cosim.sumo.traffic import Traffic
from cosim.world_setup import prepare_network
from sensors.scene import FrameScene, StaticCrop

DATA = Path(__file__).resolve().parents[1] / "data"
pytestmark = pytest.mark.slow


def test_lidar_seen_flags_match_a_brute_force_cast_per_object():
    scenario = load_scenario(
        str(DATA / "tiny.yaml"),
        ["sensors.cameras=[]", "sensors.radars=[]", "outputs.kitti=false", "outputs.yolo=false"],
    )
    prepared = prepare_network(scenario)
    rig = build_rig(scenario)
    crop = StaticCrop(prepared.world.mesh, rig.reach_m)
    traffic = Traffic(prepared.net_path, prepared.net, scenario)
    rng = np.random.default_rng(0)
    lidar = rig.of_kind("lidar")[0]
    checked = 0
    try:
        traffic.warm_up()
        for frame in range(4):
            for _ in range(10):
                traffic.step()
            state = traffic.world_state().near(rig.reach_m + AGENT_MARGIN_M)
            record = sense_and_label(frame, state, crop, rig, rng)
            static = crop.around(state.ego.map_SE3_ego().translation)
            state = on_raised_surfaces(state, crop)  # as the frame's scene has them
            rays = lidar.rays(state.ego.map_SE3_ego())
            nearest = FrameScene(static, state.agents).cast(rays).range_m
            for i, track_id in enumerate(record.labels.objects.track_id):
                alone = state.agents.select(state.agents.instance_id == track_id)
                t_alone = FrameScene(static, alone).cast(rays)
                on_object = t_alone.instance_id == track_id
                seen = np.any(on_object & (t_alone.range_m <= nearest + 1e-4) & (t_alone.range_m <= lidar.spec.range_m))
                assert bool(seen) == bool(record.labels.lidar_points[i] > 0), f"object {track_id} in frame {frame}"
                checked += 1
    finally:
        traffic.close()
    assert checked > 20

"""The frame loop, in one place: step SUMO -> world state -> sensors -> labels -> sinks."""

from __future__ import annotations

import hashlib
import json
import sys
from collections import Counter
from dataclasses import asdict, dataclass, field
from importlib import metadata
from pathlib import Path

import numpy as np
from tqdm import tqdm

from cosim.rig import Rig, build_rig
from cosim.scenario import Scenario
from cosim.state import WorldState
from cosim.traffic import Traffic
from cosim.world_setup import prepare_network
from gtgen.frame import CameraOutput, FrameRecord, LidarOutput, RadarOutput
from gtgen.labels import FrameLabels, SensorHits, label_frame
from gtgen.objects import ObjectBoxes
from gtgen.sinks import Sink
from gtgen.sinks.csv_sink import CsvSink
from gtgen.sinks.kitti_sink import KittiSink
from gtgen.sinks.mcap_sink import McapSink
from gtgen.sinks.yolo_sink import YoloSink
from networks.classes import SemanticClass
from networks.geometry import wrap_angle
from sensors.agents import agent_meshes
from sensors.radar import InstanceVelocities
from sensors.scene import FrameScene, StaticCrop

AGENT_MARGIN_M = 10.0


@dataclass(slots=True)
class RunSummary:
    frames: int = 0
    objects: int = 0
    seen: int = 0
    per_class: Counter[str] = field(default_factory=Counter)

    def add(self, labels: FrameLabels) -> None:
        self.frames += 1
        self.objects += len(labels)
        self.seen += int(labels.seen.sum())
        self.per_class.update(SemanticClass(int(c)).label for c in labels.objects.semantic_class[labels.seen])

    def lines(self) -> list[str]:
        n = max(self.frames, 1)
        out = [f"frames: {self.frames}", f"objects in range per frame: {self.objects / n:.1f}",
               f"objects seen per frame: {self.seen / n:.1f}"]  # fmt: skip
        out += [f"  {cls}: {count / n:.1f}" for cls, count in sorted(self.per_class.items())]
        return out


def objects_in_ego_frame(state: WorldState) -> ObjectBoxes:
    ego_SE3_map = state.map_SE3_ego().inverse()
    agents = state.agents
    return ObjectBoxes(
        track_id=agents.instance_id,
        semantic_class=agents.semantic_class,
        center_ego_m=ego_SE3_map.transform_from(agents.center_map_m),
        lwh_m=agents.lwh_m,
        yaw_ego_rad=wrap_angle(agents.yaw_map_rad - state.ego.yaw_map_rad[0]),
        velocity_ego_mps=ego_SE3_map.rotate(state.velocity_map_mps - state.ego_velocity_map_mps),
        parked=state.parked,
    )


def sense_and_label(
    frame_index: int, state: WorldState, crop: StaticCrop, rig: Rig, rng: np.random.Generator
) -> FrameRecord:
    """Cast every sensor into one scene of this frame, then label what the rays saw."""
    map_SE3_ego = state.map_SE3_ego()
    scene = FrameScene(crop.around(map_SE3_ego.translation), agent_meshes(state.agents))
    lidars = tuple(LidarOutput(li.spec, li.scan(scene, map_SE3_ego, rng, rig.weather)) for li in rig.lidars)
    cameras = tuple(CameraOutput(c.spec, c.render(scene, map_SE3_ego, rig.weather, rng)) for c in rig.cameras)
    velocities = InstanceVelocities.from_unsorted(state.agents.instance_id, state.velocity_map_mps)
    radars = tuple(
        RadarOutput(r.spec, r.scan(scene, map_SE3_ego, velocities, state.ego_velocity_map_mps, rng)) for r in rig.radars
    )
    hits = SensorHits(
        tuple(o.scan for o in lidars), tuple(o.scan for o in radars), tuple((o.spec, o.frame) for o in cameras)
    )
    timestamp_ns = round(state.time_s * 1e9)
    objects = objects_in_ego_frame(state)
    labels = label_frame(frame_index, timestamp_ns, objects, state.agents, map_SE3_ego, hits, rig.label_range_m)
    return FrameRecord(frame_index, timestamp_ns, map_SE3_ego, lidars, cameras, radars, labels)


def open_sinks(scenario: Scenario, out_dir: Path) -> list[Sink]:
    sinks: list[Sink] = []
    if scenario.outputs.mcap:
        sinks.append(McapSink(out_dir / "run.mcap"))
    if scenario.outputs.csv:
        sinks.append(CsvSink(out_dir / "labels.csv"))
    if scenario.outputs.kitti:
        sinks.append(KittiSink(out_dir / "kitti"))
    if scenario.outputs.yolo:
        sinks.append(YoloSink(out_dir / "yolo", scenario.outputs.yolo_min_visible_px))
    return sinks


def run(scenario: Scenario, out_dir: Path, progress: bool = True) -> RunSummary:
    """Produce the dataset of ``scenario`` under ``out_dir``; files appear only when complete."""
    prepared = prepare_network(scenario)
    if prepared.notice:
        print(prepared.notice, file=sys.stderr)
    rig = build_rig(scenario)
    reach = rig.reach_m
    crop = StaticCrop(prepared.world.mesh, reach)
    rng = np.random.default_rng(scenario.seed)
    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / "manifest.json").unlink(missing_ok=True)
    traffic = Traffic(prepared.net_path, prepared.net, scenario)
    sinks = open_sinks(scenario, out_dir)
    summary = RunSummary()
    try:
        traffic.warm_up()
        for notice in traffic.notices:
            print(notice, file=sys.stderr)
        bar = tqdm(range(scenario.frames), desc=scenario.name, unit="frame", disable=not progress, file=sys.stderr)
        for frame_index in bar:
            traffic.step()
            state = traffic.world_state().near(reach + AGENT_MARGIN_M)
            record = sense_and_label(frame_index, state, crop, rig, rng)
            for sink in sinks:
                sink.write(record)
            summary.add(record.labels)
        for sink in sinks:
            sink.close()
    except BaseException:
        for sink in sinks:
            sink.abort()
        for partial in out_dir.glob("*.partial"):
            if partial.is_file():
                partial.unlink()
        raise
    finally:
        traffic.close()
    write_manifest(scenario, out_dir, summary, prepared.xodr_path)
    return summary


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with path.open("rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def write_manifest(scenario: Scenario, out_dir: Path, summary: RunSummary, xodr: Path) -> None:
    versions = {}
    for dist in ("eclipse-sumo", "libsumo", "open3d-cpu", "numpy", "mcap", "sumo-dataset-factory"):
        try:
            versions[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            versions[dist] = "unknown"
    files = {
        str(p.relative_to(out_dir)): _sha256(p)
        for p in sorted(out_dir.rglob("*"))
        if p.is_file() and p.name != "manifest.json" and p.parent.name not in ("image_2", "velodyne", "images")
    }
    manifest = {
        "scenario": asdict(scenario),
        "seed": scenario.seed,
        "network_file": str(xodr),
        "frames": summary.frames,
        "objects_per_frame": summary.objects / max(summary.frames, 1),
        "versions": versions,
        "files_sha256": files,
    }
    tmp = out_dir / "manifest.json.partial"
    tmp.write_text(json.dumps(manifest, indent=2, sort_keys=True, default=str) + "\n")
    tmp.replace(out_dir / "manifest.json")

"""The run's outputs wired from its scenario: which sinks, where, in which process, and the HD
map they draw from (built once per network and kept in the cache)."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Protocol

from cosim.resume import ResumePoint
from cosim.scenario import Scenario
from cosim.world_setup import PreparedNetwork
from gtgen.frame import FrameRecord
from gtgen.sinks.background import BackgroundSinks
from gtgen.sinks.group import SinkChoice, SinkGroup
from gtgen.sinks.nuscenes_sink import NuscenesSetup
from gtgen.timing import NO_CLOCK, StageClock
from networks.cache import cache_dir, digest, intact, place
from networks.hdmap import MAP_VERSION, HdMap, build_map
from networks.markings import is_left_hand
from networks.vocabulary import SensorKind
from sensors.camera import CameraSpec
from sensors.lidar import LidarSpec
from sensors.radar import RadarSpec


class FrameSink(Protocol):
    """Where the loop hands its frames: a SinkGroup, or BackgroundSinks in a writer process.
    Used as a context manager: closed (files move into place) when the ``with`` block ends,
    aborted (nothing left that looks complete) when it raises, left as they are (every frame
    written stays, under partial names) when it raises :class:`OutputKeptError`."""

    def __enter__(self) -> FrameSink: ...

    def __exit__(self, kind: type[BaseException] | None, error: BaseException | None, *_: object) -> None: ...

    def ready(self) -> None:
        """Wait until every output has opened (raises if one could not)."""
        ...

    def write(self, record: FrameRecord) -> None: ...


def sink_choice(
    scenario: Scenario,
    out_dir: Path,
    map_world: Path | None = None,
    point: ResumePoint | None = None,
    map_json: Path | None = None,
) -> SinkChoice:
    """The run's outputs; with ``point``, those of a run that continues an earlier one."""
    o = scenario.outputs
    keep, first = (0, None) if point is None else (point.frames, point.first_map_SE3_ego)
    return SinkChoice(
        out_dir=out_dir,
        mcap=o.mcap,
        csv=o.csv,
        kitti=o.kitti,
        yolo=o.yolo,
        yolo_min_visible_px=o.yolo_min_visible_px,
        map_world=map_world,
        live=o.live_address,
        sensors=tuple((kind, spec.name) for kind, spec in rig_specs(scenario)),
        deskewed=tuple(spec.name for spec in scenario.sensors.lidars if spec.deskew),
        resume=True,
        keep_frames=keep,
        first_map_SE3_ego=first,
        kitti_native_types=o.kitti_types == "native",
        kitti_image_3=kitti_image_3(scenario),
        traffic_lights=scenario.street.traffic_lights or scenario.street.signs,
        map_json=map_json,
        nuscenes=nuscenes_setup(scenario, out_dir, map_json),
        hazards=bool(scenario.hazards),
        occupancy=o.occupancy.enabled,
    )


def kitti_image_3(scenario: Scenario) -> bool:
    """The rig's second camera fires every frame: the KITTI export writes it as ``image_3``."""
    cameras = scenario.sensors.cameras
    return len(cameras) > 1 and cameras[1].rate_hz * scenario.step_s >= 1 - 1e-9


def rig_specs(scenario: Scenario) -> list[tuple[SensorKind, LidarSpec | CameraSpec | RadarSpec]]:
    """The rig's sensor specs with their kind, in rig order (LiDARs, cameras, radars)."""
    rig = scenario.sensors
    by_kind = ((SensorKind.LIDAR, rig.lidars), (SensorKind.CAMERA, rig.cameras), (SensorKind.RADAR, rig.radars))
    return [(kind, spec) for kind, specs in by_kind for spec in specs]


def nuscenes_setup(scenario: Scenario, out_dir: Path, map_json: Path | None) -> NuscenesSetup | None:
    """What the nuScenes export needs of the run (None: not asked for). The run's folder name
    names its log and scenes."""
    if not scenario.outputs.nuscenes:
        return None
    sensors = tuple((kind, spec.name, spec.rate_hz) for kind, spec in rig_specs(scenario))
    path = scenario.network_path()
    location = scenario.network if path is None else path.stem
    return NuscenesSetup(
        name=out_dir.resolve().name, step_s=scenario.step_s, sensors=sensors, location=location, map_json=map_json
    )


def open_sinks(choice: SinkChoice, one_process: bool = False, clock: StageClock = NO_CLOCK) -> FrameSink:
    """The run's sinks: in a writer process, or in this one."""
    return SinkGroup.open(choice, clock) if one_process else BackgroundSinks(choice, clock=clock)


def prepare_map(prepared: PreparedNetwork) -> tuple[HdMap, Path]:
    """The network's HD map, and its whole-map JSON in the cache (written on first use)."""
    hdmap = build_map(prepared.net, prepared.xodr_path, is_left_hand(prepared.net_path))
    key = digest(MAP_VERSION, prepared.net_path.read_bytes(), prepared.xodr_path.read_bytes())
    path = cache_dir("maps", key) / "map.json"
    if not intact(path):
        partial = path.with_suffix(f".{os.getpid()}.partial")
        partial.write_text(json.dumps(hdmap.static_json(), separators=(",", ":")))
        place(partial, path)
    return hdmap, path

"""Scenario YAML -> frozen dataclasses.

A scenario names a built-in scene of ``cosim/catalog`` or a path to a YAML file;
paths inside a file are resolved relative to that file. Every key can be
overridden with ``--set key.path=value``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np

from cosim.config import build, read_yaml, set_override
from cosim.errors import ScenarioError
from cosim.rigs import NUSCENES_CAMERAS, NUSCENES_IMAGE, nuscenes_hfov_deg, with_rig
from gtgen.sinks.live import LiveAddress, parse_live_address
from gtgen.voxels import PRESETS, OccupancyGrid
from networks.errors import quoted
from networks.vocabulary import HazardKind
from sensors.camera import CameraSpec
from sensors.lidar import LidarSpec
from sensors.radar import RadarSpec

CATALOG_DIR = Path(__file__).parent / "catalog"
MAX_SEED = 2**31 - 1  # SUMO takes a signed 32-bit seed
AGENT_KINDS = ("car", "truck", "truck_trailer", "bus", "motorcycle", "bicycle")


def _check(ok: bool, key: str, expected: str, got: object) -> None:
    if not ok:
        raise ValueError(f"{key}: expected {expected}, got {quoted(got)}")


@dataclass(frozen=True, slots=True)
class TrafficConfig:
    vehicles_per_lane_km: float = 20.0
    vehicles: int | None = None  # a fixed count, instead of the density
    mix: dict[str, float] = field(
        default_factory=lambda: {"car": 0.8, "truck": 0.06, "bus": 0.03, "motorcycle": 0.06, "bicycle": 0.05}
    )
    pedestrians: int = 60
    parked: int = 0
    street_pedestrians: int = 0  # more, kept on the sidewalks and crossings along the ego's way (cosim/sumo/people.py)
    street_cyclists: int = 0  # cyclists kept on the roads along the ego's way

    def __post_init__(self) -> None:
        _check(self.vehicles_per_lane_km >= 0, "vehicles_per_lane_km", "a number >= 0", self.vehicles_per_lane_km)
        _check(self.vehicles is None or self.vehicles >= 0, "vehicles", "a whole number >= 0", self.vehicles)
        _check(self.pedestrians >= 0, "pedestrians", "a whole number >= 0", self.pedestrians)
        _check(self.parked >= 0, "parked", "a whole number >= 0", self.parked)
        _check(self.street_pedestrians >= 0, "street_pedestrians", "a whole number >= 0", self.street_pedestrians)
        _check(self.street_cyclists >= 0, "street_cyclists", "a whole number >= 0", self.street_cyclists)
        for kind, share in self.mix.items():
            _check(kind in AGENT_KINDS, f"mix.{kind}", "one of " + ", ".join(AGENT_KINDS), kind)
            _check(share >= 0, f"mix.{kind}", "a share >= 0", share)
        _check(sum(self.mix.values()) > 0, "mix", "at least one share > 0", self.mix)


@dataclass(frozen=True, slots=True)
class HazardConfig:
    """One kind of hazard made near the ego about ``per_minute`` times a simulated minute (an
    event starts when one is due and the traffic around the ego allows it). ``distance_m``:
    how far ahead of the ego the event starts (cut_in: the gap the cutting vehicle leaves;
    hard_brake: the gap to the braking leader; jaywalker: where the pedestrian steps out;
    red_light: the ego's distance to its green stop line). ``time_gap_s``: cut_in, the gap in
    seconds at the ego's speed. ``decel_mps2``: hard_brake's deceleration; ``to_speed_mps``:
    the speed it brakes to (0: a stop). ``walk_mps``: the jaywalker's speed;
    ``behind_parked``: the jaywalker steps out from in front of a parked vehicle when one
    stands there; ``child``: the jaywalker is a child 1.15 m tall (the size of Euro NCAP's
    child target), hidden by a parked car's roof, rather than the scene's shortest adult."""

    kind: HazardKind
    per_minute: float = 1.0
    distance_m: tuple[float, float] = (5.0, 30.0)
    time_gap_s: tuple[float, float] = (0.3, 1.5)
    decel_mps2: float = 7.0
    to_speed_mps: float = 0.0
    walk_mps: float = 1.6
    behind_parked: bool = True
    child: bool = True

    def __post_init__(self) -> None:
        _check(0 < self.per_minute <= 30, "per_minute", "events per minute in (0, 30]", self.per_minute)
        lo, hi = self.distance_m
        _check(
            0 < lo < hi <= 150, "distance_m", "a range [near, far] in metres, 0 < near < far <= 150", self.distance_m
        )
        _check(0 <= self.time_gap_s[0] < self.time_gap_s[1], "time_gap_s", "a range [low, high] in seconds",
               self.time_gap_s)  # fmt: skip
        _check(1.0 <= self.decel_mps2 <= 12.0, "decel_mps2", "a deceleration in [1, 12] m/s^2", self.decel_mps2)
        _check(self.to_speed_mps >= 0, "to_speed_mps", "a speed >= 0", self.to_speed_mps)
        _check(0.3 <= self.walk_mps <= 5.0, "walk_mps", "a walking speed in [0.3, 5] m/s", self.walk_mps)


@dataclass(frozen=True, slots=True)
class EgoConfig:
    """``route``: SUMO edge ids the ego starts on; empty: a passenger car picked after the
    warm-up where ``start`` says (``urban``: a street of at most 60 km/h, ``highway``: at
    least 80 km/h, ``on_ramp``: inserted at the start of a highway entrance ramp).
    ``max_stopped_s``: once the ego has stood (below 0.1 m/s) this long, a car on the move is
    the ego instead, picked as at the start (a scene cut; 0: the ego stands as long as traffic
    holds it; in a hazard scene, not while an event is prepared or under way)."""

    route: tuple[str, ...] = ()
    start: Literal["any", "urban", "highway", "on_ramp"] = "any"
    max_stopped_s: float = 0.0

    def __post_init__(self) -> None:
        _check(self.max_stopped_s >= 0, "max_stopped_s", "seconds >= 0 (0: no limit)", self.max_stopped_s)


@dataclass(frozen=True, slots=True)
class ConstructionConfig:
    """A construction zone closing one lane of the SUMO edge ``edge`` ("": none): lane ``lane``
    (0 is the rightmost) is closed to traffic over the whole edge, so traffic merges into the
    next lane before it; cones, barriers and a construction vehicle (``vehicle``) stand on it
    from ``start_m`` along it for about ``length_m`` (cosim/construction.py), cones every
    ``cone_spacing_m``. The edge needs another lane open to cars."""

    edge: str = ""
    lane: int = 0
    start_m: float = 5.0
    length_m: float = 60.0
    cone_spacing_m: float = 4.0
    vehicle: bool = True

    def __post_init__(self) -> None:
        _check(self.lane >= 0, "lane", "a lane index >= 0 (0: the rightmost)", self.lane)
        _check(self.start_m >= 0, "start_m", "metres >= 0 along the lane", self.start_m)
        _check(self.length_m >= 10, "length_m", "metres >= 10", self.length_m)
        _check(1.0 <= self.cone_spacing_m <= 50.0, "cone_spacing_m", "metres in [1, 50]", self.cone_spacing_m)


@dataclass(frozen=True, slots=True)
class SensorsConfig:
    """The rig: lists of sensor specs (fields and defaults in ``sensors/``)."""

    lidars: tuple[LidarSpec, ...] = (LidarSpec(),)
    cameras: tuple[CameraSpec, ...] = (CameraSpec(),)
    radars: tuple[RadarSpec, ...] = (RadarSpec(),)

    def __post_init__(self) -> None:
        names = [s.name for s in self.lidars] + [s.name for s in self.cameras] + [s.name for s in self.radars]
        _check(len(set(names)) == len(names), "name", "distinct sensor names across lidars, cameras, radars", names)
        _check(len(self.lidars) + len(self.cameras) + len(self.radars) > 0, "lidars", "at least one sensor", names)


@dataclass(frozen=True, slots=True)
class StreetConfig:
    """What stands and is painted along the streets; each can be turned off (for ablations)."""

    markings: bool = True  # lane, edge, stop and give-way lines, zebra stripes
    traffic_lights: bool = True  # a pole and a labelled signal head per signalised approach, live states
    signs: bool = True  # stop, give-way and speed-limit signs on poles, labelled


@dataclass(frozen=True, slots=True)
class OccupancyConfig:
    """3D semantic occupancy, visibility masks and flow under ``occupancy/`` (gtgen/occupancy.py):
    the grid of ``preset`` (occ3d: 0.4 m, 200 x 200 x 16; openoccupancy: 0.2 m, 512 x 512 x 40),
    or ``voxel_m`` and ``range_m`` (x_min, y_min, z_min, x_max, y_max, z_max in the ego frame)."""

    enabled: bool = False
    preset: Literal["occ3d", "openoccupancy"] = "occ3d"
    voxel_m: float = 0.0  # 0: the preset's
    range_m: tuple[float, ...] = ()  # (): the preset's

    def __post_init__(self) -> None:
        _check(self.voxel_m == 0 or 0.05 <= self.voxel_m <= 2.0, "voxel_m", "metres in [0.05, 2] (0: the preset's)",
               self.voxel_m)  # fmt: skip
        r = self.range_m
        _check(r == () or (len(r) == 6 and all(r[i] < r[i + 3] for i in range(3))), "range_m",
               "(x_min, y_min, z_min, x_max, y_max, z_max) with each min below its max", r)  # fmt: skip
        grid = self.grid
        extents = [grid.range_m[i + 3] - grid.range_m[i] for i in range(3)]
        _check(all(abs(e / grid.voxel_m - round(e / grid.voxel_m)) < 1e-6 for e in extents), "range_m",
               f"extents that are whole multiples of voxel_m ({grid.voxel_m:g} m)", grid.range_m)  # fmt: skip
        voxels = int(np.prod([round(e / grid.voxel_m) for e in extents]))
        _check(
            voxels <= 40_000_000, "voxel_m", f"a grid of at most 40 million voxels (this one: {voxels:,})", grid.voxel_m
        )

    @property
    def grid(self) -> OccupancyGrid:
        preset = PRESETS[self.preset]
        voxel = self.voxel_m or preset.voxel_m
        r = self.range_m or preset.range_m
        return OccupancyGrid(voxel, (r[0], r[1], r[2], r[3], r[4], r[5]))


@dataclass(frozen=True, slots=True)
class OutputsConfig:
    mcap: bool = True
    csv: bool = True
    kitti: bool = True
    yolo: bool = True
    yolo_min_visible_px: int = 25  # objects with fewer visible camera pixels get no YOLO box
    kitti_types: Literal["kitti", "native"] = "kitti"  # KITTI's own type names, or the simulator's
    live: str | int = ""  # serve a live view on PORT, HOST:PORT or HOST ("" = none)
    map: bool = True  # map ground truth under map/ and on /map/vectors
    map_range_m: tuple[float, float] = (30.0, 15.0)  # half extents ahead/behind and left/right of the ego
    map_resolution_m: float = 0.5  # of the rasters
    nuscenes: bool = False  # the nuScenes v1.0 layout under nuscenes/ (on with rig: nuscenes)
    occupancy: OccupancyConfig = field(default_factory=OccupancyConfig)  # occupancy/ (off by default)

    def __post_init__(self) -> None:
        rx, ry = self.map_range_m
        _check(0 < rx <= 200 and 0 < ry <= 200, "map_range_m", "two half extents in metres, each in (0, 200]",
               self.map_range_m)  # fmt: skip
        _check(0.05 <= self.map_resolution_m <= 5.0, "map_resolution_m", "metres per pixel in [0.05, 5]",
               self.map_resolution_m)  # fmt: skip
        _check(self.yolo_min_visible_px >= 1, "yolo_min_visible_px", "a whole number >= 1", self.yolo_min_visible_px)
        if self.live != "":
            try:
                parse_live_address(str(self.live))
            except ValueError as err:
                raise ValueError(f"live: expected {err}") from None

    @property
    def live_address(self) -> LiveAddress | None:
        return parse_live_address(str(self.live)) if self.live != "" else None


@dataclass(frozen=True, slots=True)
class Scenario:
    network: str
    description: str = ""
    frames: int = 200
    step_s: float = 0.05
    seed: int = 0
    warmup_s: float = 60.0
    traffic: TrafficConfig = field(default_factory=TrafficConfig)
    ego: EgoConfig = field(default_factory=EgoConfig)
    weather: Literal["day", "night", "rain", "fog"] = "day"
    engine: Literal["auto", "open3d", "mitsuba"] = "auto"  # the ray engine (see sensors/engine.py)
    rig: Literal["default", "kitti", "nuscenes"] = "default"  # a sensor rig preset (cosim/rigs.py) under `sensors`
    street: StreetConfig = field(default_factory=StreetConfig)
    hazards: tuple[HazardConfig, ...] = ()  # cut-ins, hard braking, jaywalkers, red-light runners near the ego
    construction: ConstructionConfig = field(default_factory=ConstructionConfig)  # a lane closed by a work zone
    sensors: SensorsConfig = field(default_factory=SensorsConfig)
    outputs: OutputsConfig = field(default_factory=OutputsConfig)
    name: str = "scenario"
    source_dir: str = "."

    def __post_init__(self) -> None:
        _check(self.frames > 0, "frames", "a whole number > 0", self.frames)
        millis = self.step_s * 1000.0
        _check(1 <= round(millis) <= 1000 and abs(millis - round(millis)) < 1e-6, "step_s",
               "seconds in [0.001, 1], a whole number of milliseconds (SUMO's clock)", self.step_s)  # fmt: skip
        _check(self.warmup_s >= 0, "warmup_s", "a number >= 0", self.warmup_s)
        _check(0 <= self.seed <= MAX_SEED, "seed", f"a whole number in [0, {MAX_SEED}] (SUMO's seeds)", self.seed)
        _check(bool(self.network), "network", "a town name or a path to an .xodr file", self.network)
        rig = self.sensors
        kinds = f"{len(rig.cameras)} camera(s) and {len(rig.lidars)} LiDAR(s)"
        if self.outputs.kitti and not (rig.cameras and rig.lidars):
            raise ValueError(
                f"outputs.kitti: needs a rig with a camera and a LiDAR, this one has {kinds}; set outputs.kitti=false"
            )
        if self.outputs.yolo and not rig.cameras:
            raise ValueError("outputs.yolo: needs a rig with a camera, this one has none; set outputs.yolo=false")
        frame_hz = 1.0 / self.step_s
        every_frame = f"every frame ({frame_hz:g} Hz, step_s {self.step_s:g})"
        if self.outputs.kitti:
            camera, lidar = rig.cameras[0], rig.lidars[0]
            if min(camera.rate_hz, lidar.rate_hz) < frame_hz * (1 - 1e-9):
                raise ValueError(
                    f"outputs.kitti: KITTI pairs each image with a LiDAR sweep, so the first camera "
                    f"({camera.name}, {camera.rate_hz:g} Hz) and LiDAR ({lidar.name}, "
                    f"{lidar.rate_hz:g} Hz) must fire {every_frame}; set their rate_hz, or "
                    "outputs.kitti=false"
                )
        if self.outputs.nuscenes:
            self._check_nuscenes(frame_hz, every_frame)
        for output, cameras in (("kitti", rig.cameras[:2]), ("nuscenes", rig.cameras)):
            bent = [c.name for c in cameras if c.pinhole.distorted] if getattr(self.outputs, output) else []
            if bent:
                raise ValueError(
                    f"outputs.{output}: its images are undistorted (rectified), but camera {bent[0]} has a lens "
                    f"distortion; set its distortion to zeros or outputs.{output}=false"
                )

    def _check_nuscenes(self, frame_hz: float, every_frame: str) -> None:
        rig = self.sensors
        if not rig.lidars:
            raise ValueError(
                "outputs.nuscenes: needs a LiDAR (nuScenes's keyframes are LiDAR sweeps), this rig has "
                "none; add one or set outputs.nuscenes=false"
            )
        lidar = rig.lidars[0]
        keyframe_steps = 0.5 / self.step_s
        if lidar.rate_hz < frame_hz * (1 - 1e-9) or abs(keyframe_steps - round(keyframe_steps)) > 1e-6:
            raise ValueError(
                f"outputs.nuscenes: keyframes come every 0.5 s from the first LiDAR ({lidar.name}, "
                f"{lidar.rate_hz:g} Hz): it must fire {every_frame} and 0.5 s must be a whole number "
                "of frames (step_s 0.05 or 0.1)"
            )
        if self.rig == "nuscenes":
            for camera in rig.cameras:
                own = NUSCENES_CAMERAS.get(camera.name)
                if own is not None and (
                    (camera.width_px, camera.height_px) != NUSCENES_IMAGE
                    or abs(camera.hfov_deg - nuscenes_hfov_deg(own[2])) > 1e-3
                ):
                    raise ValueError(
                        f"sensors: {camera.name}: {camera.width_px}x{camera.height_px} px, {camera.hfov_deg:g} deg "
                        f"conflicts with the nuscenes preset's {camera.name} ({NUSCENES_IMAGE[0]}x"
                        f"{NUSCENES_IMAGE[1]} px, {nuscenes_hfov_deg(own[2]):g} deg), which the export calibrates as "
                        "nuScenes's; give a camera of your own another name"
                    )

    def network_path(self) -> Path | None:
        """The user's OpenDRIVE file, resolved against the scenario file; None for a built-in town."""
        if not self.network.endswith(".xodr"):
            return None
        path = Path(self.network).expanduser()
        return path if path.is_absolute() else (Path(self.source_dir) / path).resolve()


def catalog_names() -> list[str]:
    return sorted(p.stem for p in CATALOG_DIR.glob("*.yaml"))


def catalog_description(name: str) -> str:
    return str(read_yaml(CATALOG_DIR / f"{name}.yaml").get("description", ""))


def resolve(spec: str) -> Path:
    """A catalog name or a path to a YAML file."""
    if spec.endswith((".yaml", ".yml")) or "/" in spec:
        path = Path(spec)
        if not path.is_file():
            raise ScenarioError(f"{spec}: scenario file not found")
        return path
    path = CATALOG_DIR / f"{spec}.yaml"
    if not path.is_file():
        raise ScenarioError(
            f"{spec}: unknown scenario (known: {', '.join(catalog_names())}; or give a path to a .yaml)"
        )
    return path


def load_scenario(spec: str, overrides: list[str] | tuple[str, ...] = ()) -> Scenario:
    path = resolve(spec)
    data: dict[str, Any] = read_yaml(path)
    for assignment in overrides:
        set_override(data, assignment)
    for reserved in ("name", "source_dir"):
        if reserved in data:
            raise ScenarioError(f"{path}: {reserved}: unknown key (it is set from the file's name and folder)")
    data = {**with_rig(data), "name": path.stem, "source_dir": str(path.resolve().parent)}
    scenario = build(Scenario, data, str(path))
    network = scenario.network_path()
    if network is not None and not network.is_file():
        raise ScenarioError(f"{path}: network: OpenDRIVE file {network} not found")
    return scenario

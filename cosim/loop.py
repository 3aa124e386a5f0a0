"""The frame loop, in one place: step SUMO -> world state -> sensors -> labels -> sinks."""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import signal
import sys
import threading
from collections import Counter
from collections.abc import Callable, Iterator
from dataclasses import asdict, dataclass, field, replace
from importlib import metadata
from pathlib import Path
from typing import Any, Protocol

import numpy as np
from tqdm import tqdm

from cosim.errors import CosimError, RunStoppedError, Terminated, TrafficError
from cosim.net_index import check_hazards
from cosim.occupancy_step import OccupancyStep
from cosim.resume import ResumePoint, begin, finish, kept_frames, resume_point, settle
from cosim.rig import Rig, build_rig
from cosim.scenario import Scenario
from cosim.signals import StreetObjects
from cosim.state import WorldState
from cosim.traffic_feed import TrafficFeed, TrafficInline, TrafficProcess
from cosim.world_setup import PreparedNetwork, prepare_network
from gtgen.content import STOPPED_MPS
from gtgen.errors import OutputKeptError
from gtgen.frame import FrameRecord
from gtgen.labels import FrameLabels, label_frame
from gtgen.mapgt import MapRange, map_frame
from gtgen.occ3d_export import write_occ3d_annotations
from gtgen.signals import SignalLabels
from gtgen.sinks.background import BackgroundSinks
from gtgen.sinks.group import SinkChoice, SinkGroup
from gtgen.sinks.nuscenes_sink import NuscenesSetup
from gtgen.sinks.resume_sink import RESUME_DIR
from gtgen.timing import NO_CLOCK, NoClock, StageClock
from networks.cache import cache_dir, digest, file_sha256, intact, seal
from networks.classes import SemanticClass
from networks.geometry import SE3
from networks.hdmap import MAP_VERSION, HdMap, build_map
from networks.markings import is_left_hand
from networks.street import street_objects
from networks.vocabulary import SensorKind
from sensors.camera import CameraSpec
from sensors.engine import Scene
from sensors.lidar import LidarSpec
from sensors.radar import RadarSpec
from sensors.scene import StaticCrop

AGENT_MARGIN_M = 10.0


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


class FrameProbe(StageClock, Protocol):
    """The benchmark's view into the loop: stage times, each frame's scene, frame ends."""

    def scene(self, frame_index: int, scene: Scene, map_SE3_ego: SE3) -> None: ...

    def frame_done(self, frame_index: int) -> None:
        """Called with -1 before the first frame, then after each frame, and with the frame
        count once the sinks are closed."""
        ...


class _NoProbe(NoClock):
    def scene(self, frame_index: int, scene: Scene, map_SE3_ego: SE3) -> None:
        pass

    def frame_done(self, frame_index: int) -> None:
        pass


NO_PROBE: FrameProbe = _NoProbe()


@dataclass(slots=True)
class RunSummary:
    frames: int = 0
    objects: int = 0
    seen: int = 0
    per_class: Counter[str] = field(default_factory=Counter)
    scene_cuts: list[int] = field(default_factory=list)  # frames that start a new scene
    ego_stopped: int = 0  # frames in which the ego moved slower than STOPPED_MPS

    def add(self, labels: FrameLabels, scene_cut: bool = False, ego_speed_mps: float | None = None) -> None:
        if scene_cut:
            self.scene_cuts.append(labels.frame_index)
        if ego_speed_mps is not None and ego_speed_mps < STOPPED_MPS:
            self.ego_stopped += 1
        self.frames += 1
        self.objects += len(labels)
        self.seen += int(labels.seen.sum())
        self.per_class.update(SemanticClass(int(c)).label for c in labels.objects.semantic_class[labels.seen])

    def to_dict(self) -> dict[str, Any]:
        return {"frames": self.frames, "objects": self.objects, "seen": self.seen,
                "per_class": dict(sorted(self.per_class.items())), "scene_cuts": list(self.scene_cuts),
                "ego_stopped": self.ego_stopped}  # fmt: skip

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> RunSummary:
        return cls(int(data["frames"]), int(data["objects"]), int(data["seen"]), Counter(data["per_class"]),
                   [int(f) for f in data["scene_cuts"]], int(data.get("ego_stopped", 0)))  # fmt: skip

    def lines(self) -> list[str]:
        n = max(self.frames, 1)
        out = [f"frames: {self.frames}", f"objects in range per frame: {self.objects / n:.1f}",
               f"objects seen per frame: {self.seen / n:.1f}"]  # fmt: skip
        out += [f"  {cls}: {count / n:.1f}" for cls, count in sorted(self.per_class.items())]
        out.append(f"ego stopped (below {STOPPED_MPS:g} m/s): {100 * self.ego_stopped / n:.0f} % of the frames")
        if self.scene_cuts:
            frames = ", ".join(str(f) for f in self.scene_cuts)
            out.append(f"scene cuts (the ego ran out of road and started again) at frames: {frames}")
        return out


def sense_and_label(
    frame_index: int,
    state: WorldState,
    crop: StaticCrop,
    rig: Rig,
    rng: np.random.Generator,
    probe: FrameProbe = NO_PROBE,
    signals: StreetObjects | None = None,
    hazards: bool = False,
    occupancy: OccupancyStep | None = None,
) -> FrameRecord:
    """Cast every sensor into one scene of this frame, then label what the rays saw (the
    traffic lights' heads among the objects, with ``signals``), and, with ``occupancy``, the
    frame's occupancy."""
    map_SE3_ego = state.ego.map_SE3_ego()
    with probe.stage("scene"):
        static = crop.around(map_SE3_ego.translation)
        state = on_raised_surfaces(state, crop)
        if signals is not None:
            state = signals.join(state, rig.label_range_m + AGENT_MARGIN_M)
        due = rig.due(frame_index)
        in_view = rig.agents_in_view(state.agents, map_SE3_ego, due)
        scene = rig.engine.scene(static, in_view)
    outputs = rig.sense(scene, state.ego, rng, probe, due)
    if signals is not None:
        outputs = signals.light_cameras(outputs, in_view, state, map_SE3_ego)
    probe.scene(frame_index, scene, map_SE3_ego)
    with probe.stage("labels"):
        timestamp_ns = round(state.time_s * 1e9)
        events = {a: h.name for h in state.hazards for a in h.actor_ids} if hazards else None
        labels = label_frame(frame_index, timestamp_ns, state.agents, state.ego, outputs, scene, rig.label_range_m,
                             rig.camera_names, events)  # fmt: skip
        lights = signals.labels(labels, state) if signals is not None else SignalLabels.empty()
    occupied = None
    if occupancy is not None:
        with probe.stage("occupancy"):
            occupied = occupancy.frame(static, scene, state, outputs)
    return FrameRecord(frame_index, timestamp_ns, map_SE3_ego, outputs, labels, state.scene_cut, signals=lights,
                       ego_velocity_map_mps=state.ego.velocity_map_mps, hazards=state.hazards if hazards else None,
                       ego_collided=state.ego_collided, occupancy=occupied)  # fmt: skip


def prepare_map(prepared: PreparedNetwork) -> tuple[HdMap, Path]:
    """The network's HD map, and its whole-map JSON in the cache (written on first use)."""
    hdmap = build_map(prepared.net, prepared.xodr_path, is_left_hand(prepared.net_path))
    key = digest(MAP_VERSION, prepared.net_path.read_bytes(), prepared.xodr_path.read_bytes())
    path = cache_dir("maps", key) / "map.json"
    if not intact(path):
        partial = path.with_suffix(f".{os.getpid()}.partial")
        partial.write_text(json.dumps(hdmap.static_json(), separators=(",", ":")))
        partial.replace(path)
        seal(path)
    return hdmap, path


PERSON_STEP_UP_M = 0.5  # a pedestrian stands on the highest static surface this far above its lane


def on_raised_surfaces(state: WorldState, crop: StaticCrop) -> WorldState:
    """Pedestrians standing on the world's surfaces: SUMO gives them their lane's height, the
    world raises sidewalks and walking areas by a curb (``crop`` lies around the ego)."""
    agents = state.agents
    people = np.flatnonzero(agents.semantic_class == int(SemanticClass.PEDESTRIAN))
    if people.size == 0:
        return state
    bottom = agents.center_map_m[people, 2] - agents.lwh_m[people, 2] / 2.0
    above = agents.center_map_m[people].copy()
    above[:, 2] = bottom + PERSON_STEP_UP_M
    surface = crop.surface_below(above, PERSON_STEP_UP_M + 0.05)
    center = agents.center_map_m.copy()
    center[people, 2] += np.where(np.isfinite(surface), surface - bottom, 0.0)
    return replace(state, agents=replace(agents, center_map_m=center))


def sink_choice(
    scenario: Scenario, out_dir: Path, map_world: Path | None = None, point: ResumePoint | None = None,
    map_json: Path | None = None,
) -> SinkChoice:  # fmt: skip
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
    return NuscenesSetup(out_dir.resolve().name, scenario.step_s, sensors, location, map_json)


def open_sinks(choice: SinkChoice, one_process: bool = False, clock: StageClock = NO_CLOCK) -> FrameSink:
    """The run's sinks: in a writer process, or in this one."""
    return SinkGroup.open(choice, clock) if one_process else BackgroundSinks(choice, clock=clock)


def open_traffic(
    net_path: Path, scenario: Scenario, radius_m: float, one_process: bool = False, clock: StageClock = NO_CLOCK,
    skip_frames: int = 0,
) -> TrafficFeed:  # fmt: skip
    """SUMO in a traffic process one frame ahead of the loop, or in this one; its first
    ``skip_frames`` frames are simulated and not handed out (a run that continues)."""
    if one_process:
        return TrafficInline(net_path, scenario, radius_m, clock, skip_frames)
    return TrafficProcess(net_path, scenario, radius_m, clock, skip_frames)


def run(
    scenario: Scenario,
    out_dir: Path,
    progress: bool = True,
    *,
    one_process: bool = False,
    probe: FrameProbe = NO_PROBE,
    resume: bool = False,
    summary: bool = False,
) -> RunSummary:
    """Produce the dataset of ``scenario`` under ``out_dir`` (with ``summary``, its ``summary/``
    too). SUMO and the writers run in processes of their own, beside the sensors and labels,
    unless ``one_process``: the outputs are the same. ``probe`` sees each stage of each frame
    (see :mod:`cosim.bench`). ``manifest.json`` says ``"complete": true`` once everything is
    written, the summary included.

    Interrupted (Ctrl-C, SIGTERM) or stopped by the traffic, a run closes every output with
    the frames written so far, writes ``manifest.json`` with ``"complete": false`` and raises
    :class:`RunStoppedError`; so does one interrupted while it writes the summary. A disk that
    runs out of space, or a writer process killed, leaves every frame written under the files'
    partial names (no manifest) and raises :class:`RunStoppedError` too. ``resume`` continues
    such a run from the last frame every output holds, and ends with the same data as a run
    that was never stopped."""
    settle(out_dir)
    point = resume_point(out_dir, scenario) if resume else None
    make_output_folder(out_dir)
    if progress:
        print(f"{scenario.name}: preparing the network and its world (made on first use, then cached)",
              file=sys.stderr, flush=True)  # fmt: skip
    prepared = prepare_network(scenario)
    try:
        check_hazards(scenario.hazards, prepared.net)
    except CosimError:
        with contextlib.suppress(OSError):
            out_dir.rmdir()  # made above for this run, still empty
        raise
    if prepared.notice:
        print(prepared.notice, file=sys.stderr)
    rig = build_rig(scenario)
    if rig.notice:
        print(rig.notice, file=sys.stderr)
    crop = StaticCrop(prepared.world.mesh, rig.reach_m)
    rng = np.random.default_rng(scenario.seed)
    counts, start = RunSummary(), 0
    if point is not None:
        rng.bit_generator.state = point.checkpoint["rng"]
        crop.restore(point.checkpoint["crop_center_xy_m"])
        counts, start = RunSummary.from_dict(point.checkpoint["summary"]), point.frames
    hdmap, map_json = prepare_map(prepared) if scenario.outputs.map else (None, None)
    choice = sink_choice(scenario, out_dir, prepared.world.path, point, map_json)
    signals = None
    street = scenario.street
    if street.traffic_lights or street.signs:
        left_hand = is_left_hand(prepared.net_path)
        objects = street_objects(prepared.net, left_hand, street.traffic_lights, street.signs, prepared.xodr_path)
        signals = StreetObjects(objects)
    occupancy = None
    if scenario.outputs.occupancy.enabled:
        occupancy = OccupancyStep(scenario.outputs.occupancy.grid, prepared.world.mesh, rig.engine.name)
    loop = FrameLoop(scenario, prepared.net_path, rig, crop, rng, counts, out_dir, progress, one_process, probe,
                     signals, hdmap, occupancy)  # fmt: skip
    stopped: BaseException | None = None
    held: Handlers = {}

    def started() -> None:  # every output has opened: what describes an earlier run goes
        (out_dir / "manifest.json").unlink(missing_ok=True)
        shutil.rmtree(out_dir / "summary", ignore_errors=True)
        if point is None:
            begin(out_dir, scenario)

    try:
        with partials_removed_on_error(out_dir), open_sinks(choice, one_process, probe) as sinks:
            try:
                loop.frames(start, sinks, started)
            except (KeyboardInterrupt, Terminated, TrafficError) as err:
                held = hold_interrupts()  # a second Ctrl-C must not cut the closing (or removing) short
                if counts.frames == 0:
                    raise
                stopped = err  # every output is closed with the frames written so far
    except OutputKeptError as kept:
        raise outputs_kept(kept, out_dir, scenario, continuing=point is not None) from kept
    finally:
        release_interrupts(held)
    probe.frame_done(scenario.frames)
    if scenario.outputs.nuscenes and scenario.outputs.occupancy.enabled:
        write_occ3d_annotations(out_dir, out_dir.resolve().name)
    summary_cut = summarize(out_dir, scenario) if summary else None
    in_summary = stopped is None and summary_cut is not None  # every frame is written
    stopped = stopped or summary_cut
    held = hold_interrupts()
    try:
        write_manifest(scenario, out_dir, counts, prepared.xodr_path, complete=stopped is None)
    finally:
        release_interrupts(held)
    if stopped is not None:
        raise run_stopped(stopped, out_dir, counts.frames, in_summary) from stopped
    finish(out_dir)
    return counts


def summarize(out_dir: Path, scenario: Scenario) -> BaseException | None:
    """Write ``summary/`` (it moves into place when whole); the Ctrl-C or SIGTERM that cut it
    short (the partial summary goes), else None."""
    from gtgen.summary import asked_rates, write_summary

    try:
        write_summary(out_dir, asked=asked_rates([asdict(h) for h in scenario.hazards]))
    except (KeyboardInterrupt, Terminated) as err:
        shutil.rmtree(out_dir / "summary.partial", ignore_errors=True)
        return err
    return None


Handlers = dict[int, Any]


def hold_interrupts() -> Handlers:
    """Ignore SIGINT and SIGTERM (in the main thread) while a stopped run closes its files."""
    if threading.current_thread() is not threading.main_thread():
        return {}
    return {sig: signal.signal(sig, signal.SIG_IGN) for sig in (signal.SIGINT, signal.SIGTERM)}


def release_interrupts(held: Handlers) -> None:
    for sig, handler in held.items():
        signal.signal(sig, handler)


@contextlib.contextmanager
def interrupts_after() -> Iterator[None]:
    """Run the block whole: a SIGINT or SIGTERM that arrives inside it takes effect (with the
    handler in place before) as the block ends. A frame is counted and handed to the writers
    together or not at all, so the manifest of a stopped run counts exactly the frames written."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught: list[int] = []
    held: Handlers = {int(sig): signal.signal(sig, lambda s, _frame: caught.append(s))
                      for sig in (signal.SIGINT, signal.SIGTERM)}  # fmt: skip
    try:
        yield
    finally:
        release_interrupts(held)
    if caught:
        signal.raise_signal(caught[0])


@dataclass(slots=True)
class FrameLoop:
    """What the frames of a run are made with."""

    scenario: Scenario
    net_path: Path
    rig: Rig
    crop: StaticCrop
    rng: np.random.Generator
    summary: RunSummary
    out_dir: Path
    progress: bool
    one_process: bool
    probe: FrameProbe
    signals: StreetObjects | None = None
    hdmap: HdMap | None = None
    occupancy: OccupancyStep | None = None

    def frames(self, start: int, sinks: FrameSink, started: Callable[[], None]) -> None:
        """Frames ``start`` .. the last: the traffic (simulated up to ``start`` first), sensed,
        labelled, counted and handed to ``sinks`` with the loop's checkpoint. ``started`` runs
        once the traffic has warmed up and every output has opened."""
        scenario, probe = self.scenario, self.probe
        radius_m = self.rig.reach_m + AGENT_MARGIN_M
        if self.progress:
            again = f", then again up to frame {start}" if start else ""
            print(f"{scenario.name}: warming up the traffic ({scenario.warmup_s:g} s simulated{again})",
                  file=sys.stderr, flush=True)  # fmt: skip
        with open_traffic(self.net_path, scenario, radius_m, self.one_process, probe, start) as traffic:
            for notice in traffic.warm_up():
                print(notice, file=sys.stderr)
            sinks.ready()
            started()
            bar = tqdm(range(start, scenario.frames), desc=scenario.name, unit="frame", disable=not self.progress,
                       file=sys.stderr, initial=start, total=scenario.frames)  # fmt: skip
            probe.frame_done(-1)
            for frame_index in bar:
                state = traffic.next()
                record = sense_and_label(frame_index, state, self.crop, self.rig, self.rng, probe, self.signals,
                                         bool(scenario.hazards), self.occupancy)  # fmt: skip
                if self.hdmap is not None:
                    with probe.stage("map"):
                        o = scenario.outputs
                        extent = MapRange(o.map_range_m[0], o.map_range_m[1], o.map_resolution_m)
                        ground_truth = map_frame(
                            self.hdmap,
                            frame_index,
                            record.timestamp_ns,
                            record.map_SE3_ego,
                            record.labels.objects,
                            state.ego_lane,
                            state.ego_route_ahead,
                            extent,
                        )
                        record = replace(record, map=ground_truth)
                with interrupts_after():
                    speed = float(np.linalg.norm(state.ego.velocity_map_mps))
                    self.summary.add(record.labels, record.scene_cut, speed)
                    sinks.write(replace(record, checkpoint=self.checkpoint()))
                probe.frame_done(frame_index)
                if frame_index == disk_check_frame(scenario.frames):
                    check_disk_space(self.out_dir, frame_index + 1, scenario.frames)

    def checkpoint(self) -> dict[str, Any]:
        """What the loop needs to continue after the frame just made (plain JSON data)."""
        return {"rng": self.rng.bit_generator.state, "crop_center_xy_m": self.crop.center_xy_m,
                "summary": self.summary.to_dict()}  # fmt: skip


def run_stopped(cause: BaseException, out_dir: Path, kept: int, in_summary: bool = False) -> RunStoppedError:
    """The line for a run that stopped and kept its first ``kept`` frames (``in_summary``: all
    of them, while it wrote the summary), and its exit code."""
    where = f'{out_dir} keeps frames 0 to {kept - 1} (manifest.json: "complete": false)'
    again = "run the same command with --resume to continue"
    at = f"at frame {kept}"
    if in_summary:
        at = "while writing summary/"
        where = f'{out_dir} holds all {kept} frames and no summary (manifest.json: "complete": false)'
        again = "run the same command with --resume to finish it"
    if isinstance(cause, KeyboardInterrupt):
        return RunStoppedError(f"interrupted {at}; {where}; {again}", kept, 130)
    if isinstance(cause, Terminated):
        return RunStoppedError(f"stopped (SIGTERM) {at}; {where}; {again}", kept, 143)
    return RunStoppedError(f"{cause} ({at}); {where}", kept, 2)


def outputs_kept(kept: OutputKeptError, out_dir: Path, scenario: Scenario, continuing: bool) -> RunStoppedError:
    """The line for a run whose writers stopped and kept their files (disk full, writer killed);
    a new run that kept no frame leaves nothing (there is nothing to continue)."""
    frames = kept_frames(out_dir, scenario)
    space = "free some space, then " if kept.disk_full else ""
    if frames == 0 and not continuing:
        remove_partials(out_dir)
        return RunStoppedError(f"{kept}; no frame was written; {space}run the same command again", 0, 2)
    held = f"frames 0 to {frames - 1}" if frames else "no whole frame"
    where = f"{out_dir} keeps {held} under the files' .partial names"
    return RunStoppedError(f"{kept}; {where}; {space}run the same command with --resume to continue", frames, 2)


def make_output_folder(out_dir: Path) -> None:
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        reason = err.strerror or "not a folder that can be made"
        raise CosimError(f"{out_dir}: cannot create the output folder ({err.filename}: {reason})") from err


@contextlib.contextmanager
def partials_removed_on_error(out_dir: Path) -> Iterator[None]:
    """Remove what the ``with`` block wrote under ``*.partial`` names if it raises (but for
    :class:`OutputKeptError`: the outputs keep their frames)."""
    try:
        yield
    except OutputKeptError:
        raise
    except BaseException:
        remove_partials(out_dir)
        raise


DISK_CHECK_FRAMES = 30  # the frames written before the output size is extrapolated
DISK_MARGIN = 1.1
WRITER_LAG_FRAMES = 3  # frames still in the writer's queue or buffers


def disk_check_frame(frames: int) -> int:
    """The frame after which :func:`check_disk_space` runs (-1: a run too short to check)."""
    return min(DISK_CHECK_FRAMES, frames // 2) if frames >= 2 * WRITER_LAG_FRAMES + 2 else -1


def check_disk_space(out_dir: Path, frames_done: int, frames_total: int) -> None:
    """Stop early, with one line, when the run's files (extrapolated from what the first
    frames wrote) will not fit on the disk: not after hours, with the disk full."""
    written = sum(f.stat().st_size for partial in out_dir.glob("*.partial") for f in _files(partial))
    frames_written = max(frames_done - WRITER_LAG_FRAMES, 1)
    needed = written / frames_written * frames_total
    free = shutil.disk_usage(out_dir).free
    if (needed - written) * DISK_MARGIN > free:
        raise CosimError(
            f"{out_dir}: not enough free disk space for this run: about {_size(needed)} in all "
            f"(from its first {frames_written} frames), {_size(free)} free; free some space, write "
            "fewer frames or turn outputs off (outputs.kitti=false, outputs.yolo=false, outputs.mcap=false)"
        )


def _size(n_bytes: float) -> str:
    return f"{n_bytes / 1e9:.1f} GB" if n_bytes >= 1e9 else f"{n_bytes / 1e6:.0f} MB"


def _files(path: Path) -> list[Path]:
    return [path] if path.is_file() else [f for f in path.rglob("*") if f.is_file()]


def remove_partials(out_dir: Path) -> None:
    """Remove what a failed run left: ``*.partial`` files and folders, and its resume state."""
    shutil.rmtree(out_dir / RESUME_DIR, ignore_errors=True)
    for partial in out_dir.glob("*.partial"):
        if partial.is_dir():
            shutil.rmtree(partial, ignore_errors=True)
        else:
            partial.unlink(missing_ok=True)


def write_manifest(scenario: Scenario, out_dir: Path, summary: RunSummary, xodr: Path, complete: bool = True) -> None:
    """``manifest.json``: the run's scenario, versions, counts and file hashes; ``complete``:
    whether the run wrote all its frames (false: it stopped early and kept ``frames``)."""
    versions = {}
    for dist in ("eclipse-sumo", "libsumo", "open3d-cpu", "numpy", "mcap", "sumo-dataset-factory"):
        try:
            versions[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            versions[dist] = "unknown"
    files = {
        str(p.relative_to(out_dir)): file_sha256(p)
        for p in sorted(out_dir.rglob("*"))
        if p.is_file()
        and p.name != "manifest.json"
        and p.parent.name not in ("image_2", "image_3", "velodyne", "images")
        and p.relative_to(out_dir).parts[0] not in (RESUME_DIR, "summary")
    }
    scenario_data = asdict(scenario)
    scenario_data.pop("source_dir")  # where the scenario file was: not part of the dataset
    manifest = {
        "scenario": scenario_data,
        "seed": scenario.seed,
        "network_sha256": file_sha256(xodr),  # the OpenDRIVE file driven (the town's, or the user's)
        "complete": complete,
        "frames": summary.frames,
        "objects_per_frame": summary.objects / max(summary.frames, 1),
        "seen_per_frame": summary.seen / max(summary.frames, 1),
        "ego_stopped_share": summary.ego_stopped / max(summary.frames, 1),
        "scene_cuts": summary.scene_cuts,
        "versions": versions,
        "files_sha256": files,
    }
    tmp = out_dir / "manifest.json.partial"
    tmp.write_text(json.dumps(manifest, indent=2, sort_keys=True, default=str) + "\n")
    tmp.replace(out_dir / "manifest.json")

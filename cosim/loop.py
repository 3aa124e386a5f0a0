"""The frame loop, in one place: step SUMO -> world state -> sensors -> labels -> sinks."""

from __future__ import annotations

import contextlib
import hashlib
import json
import shutil
import sys
from collections import Counter
from collections.abc import Iterator
from dataclasses import asdict, dataclass, field
from importlib import metadata
from pathlib import Path
from typing import Protocol

import numpy as np
from tqdm import tqdm

from cosim.errors import CosimError
from cosim.rig import Rig, build_rig
from cosim.scenario import Scenario
from cosim.state import WorldState
from cosim.traffic_feed import TrafficFeed, TrafficInline, TrafficProcess
from cosim.world_setup import prepare_network
from gtgen.frame import FrameRecord
from gtgen.labels import FrameLabels, label_frame
from gtgen.sinks.background import BackgroundSinks
from gtgen.sinks.group import SinkChoice, SinkGroup
from gtgen.timing import NO_CLOCK, NoClock, StageClock
from networks.classes import SemanticClass
from networks.geometry import SE3
from sensors.scene import FrameScene, StaticCrop

AGENT_MARGIN_M = 10.0


class FrameSink(Protocol):
    """Where the loop hands its frames: a SinkGroup, or BackgroundSinks in a writer process.
    Used as a context manager: closed (files move into place) when the ``with`` block ends,
    aborted (nothing left that looks complete) when it raises."""

    def __enter__(self) -> FrameSink: ...

    def __exit__(self, kind: type[BaseException] | None, *_: object) -> None: ...

    def write(self, record: FrameRecord) -> None: ...


class FrameProbe(StageClock, Protocol):
    """The benchmark's view into the loop: stage times, each frame's scene, frame ends."""

    def scene(self, frame_index: int, scene: FrameScene, map_SE3_ego: SE3) -> None: ...

    def frame_done(self, frame_index: int) -> None:
        """Called with -1 before the first frame, then after each frame, and with the frame
        count once the sinks are closed."""
        ...


class _NoProbe(NoClock):
    def scene(self, frame_index: int, scene: FrameScene, map_SE3_ego: SE3) -> None:
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

    def add(self, labels: FrameLabels, scene_cut: bool = False) -> None:
        if scene_cut:
            self.scene_cuts.append(labels.frame_index)
        self.frames += 1
        self.objects += len(labels)
        self.seen += int(labels.seen.sum())
        self.per_class.update(SemanticClass(int(c)).label for c in labels.objects.semantic_class[labels.seen])

    def lines(self) -> list[str]:
        n = max(self.frames, 1)
        out = [f"frames: {self.frames}", f"objects in range per frame: {self.objects / n:.1f}",
               f"objects seen per frame: {self.seen / n:.1f}"]  # fmt: skip
        out += [f"  {cls}: {count / n:.1f}" for cls, count in sorted(self.per_class.items())]
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
) -> FrameRecord:
    """Cast every sensor into one scene of this frame, then label what the rays saw."""
    map_SE3_ego = state.ego.map_SE3_ego()
    with probe.stage("scene"):
        scene = FrameScene(crop.around(map_SE3_ego.translation), rig.agents_in_view(state.agents, map_SE3_ego))
    outputs = rig.sense(scene, state.ego, rng, probe)
    probe.scene(frame_index, scene, map_SE3_ego)
    with probe.stage("labels"):
        timestamp_ns = round(state.time_s * 1e9)
        labels = label_frame(frame_index, timestamp_ns, state.agents, state.ego, outputs, scene, rig.label_range_m)
    return FrameRecord(frame_index, timestamp_ns, map_SE3_ego, outputs, labels, state.scene_cut)


def sink_choice(scenario: Scenario, out_dir: Path, map_world: Path | None = None) -> SinkChoice:
    o = scenario.outputs
    return SinkChoice(out_dir, o.mcap, o.csv, o.kitti, o.yolo, o.yolo_min_visible_px, map_world, o.live_address)


def open_sinks(
    scenario: Scenario,
    out_dir: Path,
    one_process: bool = False,
    clock: StageClock = NO_CLOCK,
    map_world: Path | None = None,
) -> FrameSink:
    """The run's sinks: in a writer process, or in this one."""
    choice = sink_choice(scenario, out_dir, map_world)
    return SinkGroup.open(choice, clock) if one_process else BackgroundSinks(choice, clock=clock)


def open_traffic(
    net_path: Path, scenario: Scenario, radius_m: float, one_process: bool = False, clock: StageClock = NO_CLOCK
) -> TrafficFeed:
    """SUMO in a traffic process one frame ahead of the loop, or in this one."""
    if one_process:
        return TrafficInline(net_path, scenario, radius_m, clock)
    return TrafficProcess(net_path, scenario, radius_m, clock)


def run(
    scenario: Scenario,
    out_dir: Path,
    progress: bool = True,
    *,
    one_process: bool = False,
    probe: FrameProbe = NO_PROBE,
) -> RunSummary:
    """Produce the dataset of ``scenario`` under ``out_dir``; files appear only when complete.
    SUMO and the writers run in processes of their own, beside the sensors and labels, unless
    ``one_process``: the outputs are the same. ``probe`` sees each stage of each frame (see
    :mod:`cosim.bench`)."""
    make_output_folder(out_dir)
    prepared = prepare_network(scenario)
    if prepared.notice:
        print(prepared.notice, file=sys.stderr)
    rig = build_rig(scenario)
    crop = StaticCrop(prepared.world.mesh, rig.reach_m)
    rng = np.random.default_rng(scenario.seed)
    (out_dir / "manifest.json").unlink(missing_ok=True)
    summary = RunSummary()
    with (
        partials_removed_on_error(out_dir),
        open_sinks(scenario, out_dir, one_process, probe, prepared.world.path) as sinks,
        open_traffic(prepared.net_path, scenario, rig.reach_m + AGENT_MARGIN_M, one_process, probe) as traffic,
    ):
        for notice in traffic.warm_up():
            print(notice, file=sys.stderr)
        bar = tqdm(range(scenario.frames), desc=scenario.name, unit="frame", disable=not progress, file=sys.stderr)
        probe.frame_done(-1)
        for frame_index in bar:
            record = sense_and_label(frame_index, traffic.next(), crop, rig, rng, probe)
            sinks.write(record)
            summary.add(record.labels, record.scene_cut)
            probe.frame_done(frame_index)
            if frame_index == disk_check_frame(scenario.frames):
                check_disk_space(out_dir, frame_index + 1, scenario.frames)
    probe.frame_done(scenario.frames)
    write_manifest(scenario, out_dir, summary, prepared.xodr_path)
    return summary


def make_output_folder(out_dir: Path) -> None:
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        reason = err.strerror or "not a folder that can be made"
        raise CosimError(f"{out_dir}: cannot create the output folder ({err.filename}: {reason})") from err


@contextlib.contextmanager
def partials_removed_on_error(out_dir: Path) -> Iterator[None]:
    """Remove what the ``with`` block wrote under ``*.partial`` names if it raises."""
    try:
        yield
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
    """Remove what an interrupted run left: ``*.partial`` files and folders."""
    for partial in out_dir.glob("*.partial"):
        if partial.is_dir():
            shutil.rmtree(partial, ignore_errors=True)
        else:
            partial.unlink(missing_ok=True)


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
        "scene_cuts": summary.scene_cuts,
        "versions": versions,
        "files_sha256": files,
    }
    tmp = out_dir / "manifest.json.partial"
    tmp.write_text(json.dumps(manifest, indent=2, sort_keys=True, default=str) + "\n")
    tmp.replace(out_dir / "manifest.json")

"""The frame loop, in one place: step SUMO -> world state -> sensors -> labels -> sinks."""

from __future__ import annotations

import contextlib
import shutil
import sys
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Protocol

import numpy as np
from tqdm import tqdm

from cosim.errors import CosimError, Terminated, TrafficError
from cosim.interrupts import Handlers, hold_interrupts, interrupt_behind, interrupts_after, release_interrupts
from cosim.net_index import check_hazards
from cosim.occupancy_step import OccupancyStep
from cosim.outputs import FrameSink, open_sinks, prepare_map, sink_choice
from cosim.resume import begin, finish, resume_point, settle
from cosim.rig import Rig, build_rig
from cosim.run_folder import (
    RunSummary,
    check_disk_space,
    disk_check_frame,
    make_output_folder,
    outputs_kept,
    partials_removed_on_error,
    run_stopped,
    summarize,
    write_manifest,
)
from cosim.scenario import Scenario
from cosim.signals import StreetObjects
from cosim.state import WorldState
from cosim.traffic_feed import TrafficFeed, TrafficInline, TrafficProcess
from cosim.world_setup import prepare_network
from gtgen.errors import OutputKeptError
from gtgen.frame import FrameRecord
from gtgen.labels import label_frame
from gtgen.mapgt import MapRange, map_frame
from gtgen.occ3d_export import write_occ3d_annotations
from gtgen.signals import SignalLabels
from gtgen.timing import NO_CLOCK, NoClock, StageClock
from networks.classes import SemanticClass
from networks.geometry import SE3
from networks.hdmap import HdMap
from networks.markings import is_left_hand
from networks.street import street_objects
from sensors.camera import CameraSpec
from sensors.engine import Scene
from sensors.scene import StaticCrop

AGENT_MARGIN_M = 10.0


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
        labels = label_frame(
            frame_index,
            timestamp_ns,
            state.agents,
            state.ego,
            outputs,
            scene,
            rig.label_range_m,
            rig.camera_names,
            events,
        )
        lights = signals.labels(labels, state) if signals is not None else SignalLabels.empty()
    occupied = None
    if occupancy is not None:
        with probe.stage("occupancy"):
            occupied = occupancy.frame(static, scene, state, outputs)
    return FrameRecord(
        frame_index=frame_index,
        timestamp_ns=timestamp_ns,
        map_SE3_ego=map_SE3_ego,
        sensors=outputs,
        labels=labels,
        scene_cut=state.scene_cut,
        signals=lights,
        ego_velocity_map_mps=state.ego.velocity_map_mps,
        hazards=state.hazards if hazards else None,
        ego_collided=state.ego_collided,
        occupancy=occupied,
    )


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


def open_traffic(
    net_path: Path,
    scenario: Scenario,
    radius_m: float,
    one_process: bool = False,
    clock: StageClock = NO_CLOCK,
    skip_frames: int = 0,
) -> TrafficFeed:
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
        print(
            f"{scenario.name}: preparing the network and its world (made on first use, then cached)",
            file=sys.stderr,
            flush=True,
        )
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
        rig.engine.restore(point.checkpoint.get("engine", {}))
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
        cameras = tuple(s.spec for s in rig.sensors if isinstance(s.spec, CameraSpec))
        occupancy = OccupancyStep(scenario.outputs.occupancy.grid, prepared.world.mesh, cameras)
    loop = FrameLoop(
        scenario=scenario,
        net_path=prepared.net_path,
        rig=rig,
        crop=crop,
        rng=rng,
        summary=counts,
        out_dir=out_dir,
        progress=progress,
        one_process=one_process,
        probe=probe,
        signals=signals,
        hdmap=hdmap,
        occupancy=occupancy,
    )
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
            except (KeyboardInterrupt, Terminated, TrafficError, SystemError) as err:
                cause = err if isinstance(err, TrafficError) else interrupt_behind(err)
                if cause is None:
                    raise
                held = hold_interrupts()  # a second Ctrl-C must not cut the closing (or removing) short
                if counts.frames == 0:
                    if cause is err:
                        raise
                    raise cause from None  # the interrupt, not the compiled call it cut short
                stopped = cause  # every output is closed with the frames written so far
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
            print(
                f"{scenario.name}: warming up the traffic ({scenario.warmup_s:g} s simulated{again})",
                file=sys.stderr,
                flush=True,
            )
        with open_traffic(self.net_path, scenario, radius_m, self.one_process, probe, start) as traffic:
            for notice in traffic.warm_up():
                print(notice, file=sys.stderr)
            sinks.ready()
            started()
            bar = tqdm(
                range(start, scenario.frames),
                desc=scenario.name,
                unit="frame",
                disable=not self.progress,
                file=sys.stderr,
                initial=start,
                total=scenario.frames,
            )
            probe.frame_done(-1)
            for frame_index in bar:
                state = traffic.next()
                record = sense_and_label(
                    frame_index,
                    state,
                    self.crop,
                    self.rig,
                    self.rng,
                    probe=probe,
                    signals=self.signals,
                    hazards=bool(scenario.hazards),
                    occupancy=self.occupancy,
                )
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
        return {
            "rng": self.rng.bit_generator.state,
            "crop_center_xy_m": self.crop.center_xy_m,
            "engine": self.rig.engine.checkpoint(),
            "summary": self.summary.to_dict(),
        }

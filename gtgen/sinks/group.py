"""The sinks of one run, chosen by :class:`SinkChoice` and driven together in this process."""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path

from gtgen.errors import disk_full_error, out_of_space
from gtgen.frame import FrameRecord
from gtgen.lifetime import ClosedOnExit
from gtgen.mapgt import MapSink
from gtgen.sinks import Sink
from gtgen.sinks.csv_sink import CsvSink
from gtgen.sinks.events_sink import EventsSink
from gtgen.sinks.images import FrameImages
from gtgen.sinks.kitti_sink import KittiSink
from gtgen.sinks.live import LiveAddress, LiveSink
from gtgen.sinks.mcap_sink import McapSink
from gtgen.sinks.nuscenes_sink import NuscenesSetup, NuscenesSink
from gtgen.sinks.occupancy_sink import OccupancySink
from gtgen.sinks.resume_sink import ResumeSink
from gtgen.sinks.yolo_sink import YoloSink
from gtgen.timing import NO_CLOCK, StageClock
from networks.geometry import SE3


@dataclass(frozen=True, slots=True)
class SinkChoice:
    """Which outputs to write under ``out_dir``: ``run.mcap``, ``labels.csv``, ``kitti/``, ``yolo/``,
    ``map/``, ``nuscenes/``."""

    out_dir: Path
    mcap: bool = True
    csv: bool = True
    kitti: bool = True
    yolo: bool = True
    yolo_min_visible_px: int = 25
    map_world: Path | None = None  # a static world file (networks.world.read_world) for the MCAP's /map
    live: LiveAddress | None = None  # serve the MCAP's messages to Foxglove over a WebSocket
    sensors: tuple[tuple[str, str], ...] = ()  # the rig's (kind, name) pairs: the live view's channels
    resume: bool = False  # keep .resume/states.jsonl, so that an interrupted run can continue
    keep_frames: int = 0  # continue an earlier run: keep its first frames
    first_map_SE3_ego: SE3 | None = None  # the earlier run's ego pose at frame 0 (for KITTI's poses)
    kitti_native_types: bool = False  # KITTI labels with the simulator's class names
    kitti_image_3: bool = False  # the rig's second camera fires every frame: KITTI's image_3 and P3
    traffic_lights: bool = False  # lights_and_signs.csv beside labels.csv (with csv)
    map_json: Path | None = None  # the whole map (networks.hdmap): map/ is written (frames carry their part)
    nuscenes: NuscenesSetup | None = None  # the nuScenes layout under nuscenes/
    hazards: bool = False  # the run makes hazard events: events.csv (with csv), /gt/events
    occupancy: bool = False  # occupancy/ (frames carry their occupancy)

    @property
    def map(self) -> bool:
        return self.map_json is not None

    @property
    def events(self) -> bool:
        return self.csv and self.hazards

    @property
    def lights_csv(self) -> bool:
        return self.csv and self.traffic_lights

    def partial_paths(self) -> list[Path]:
        """Where the chosen sinks write until they close (``*.partial`` files and folders)."""
        names = {"mcap": "run.mcap", "csv": "labels.csv", "lights_csv": "lights_and_signs.csv", "kitti": "kitti",
                 "yolo": "yolo", "map": "map", "nuscenes": "nuscenes",
                 "events": "event_frames.csv", "occupancy": "occupancy"}  # fmt: skip
        return [self.out_dir / f"{name}.partial" for kind, name in names.items() if getattr(self, kind)]


def _open_one(choice: SinkChoice, kind: str) -> Sink:
    out, keep = choice.out_dir, choice.keep_frames
    if kind == "mcap":
        return McapSink(out / "run.mcap", choice.map_world, keep)
    if kind == "live":
        if choice.live is None:
            raise ValueError("SinkChoice: no live address")
        return LiveSink(choice.live, choice.map_world, choice.sensors, choice.map, choice.hazards)
    if kind == "csv":
        return CsvSink(out / "labels.csv", keep)
    if kind == "lights_csv":
        return CsvSink(out / "lights_and_signs.csv", keep, signals=True)
    if kind == "kitti":
        return KittiSink(out / "kitti", keep, choice.first_map_SE3_ego, choice.kitti_native_types,
                         choice.kitti_image_3)  # fmt: skip
    if kind == "map" and choice.map_json is not None:
        return MapSink(out / "map", choice.map_json, keep)
    if kind == "events":
        return EventsSink(out, keep)
    if kind == "nuscenes" and choice.nuscenes is not None:
        return NuscenesSink(out / "nuscenes", choice.nuscenes, keep)
    if kind == "occupancy":
        return OccupancySink(out / "occupancy", keep)
    if kind == "resume":
        return ResumeSink(out, keep)
    return YoloSink(out / "yolo", choice.yolo_min_visible_px, keep)


class SinkGroup(ClosedOnExit):
    """Every chosen sink; a frame is encoded by all of them first, then written. As a context
    manager: closed when the ``with`` block ends, aborted when it raises. A disk that runs out
    of space aborts nothing: every sink keeps what it wrote (:meth:`keep`) and
    :class:`~gtgen.errors.OutputKeptError` is raised."""

    def __init__(self, sinks: list[Sink], clock: StageClock = NO_CLOCK) -> None:
        self._sinks = sinks
        self._clock = clock
        self._kept = False

    @property
    def notices(self) -> list[str]:
        """Lines for the user from the sinks (where the live view listens)."""
        return [f"live view: ws://{s.host}:{s.port} (in Foxglove: Open connection)"
                for s in self._sinks if isinstance(s, LiveSink)]  # fmt: skip

    @classmethod
    def open(cls, choice: SinkChoice, clock: StageClock = NO_CLOCK, announce: bool = True) -> SinkGroup:
        """Open the chosen sinks; if one cannot be opened, those already open are aborted.
        With ``announce``, their notices go to stderr."""
        kinds = [
            k
            for k in (
                "mcap",
                "csv",
                "lights_csv",
                "events",
                "kitti",
                "yolo",
                "map",
                "nuscenes",
                "occupancy",
                "live",
                "resume",
            )
            if getattr(choice, k)
        ]
        group = cls([], clock)
        try:
            for kind in kinds:
                group._sinks.append(_open_one(choice, kind))
        except BaseException as err:
            if out_of_space(err):  # a run that continues: its earlier frames stay
                group.keep()
                raise disk_full_error(err) from err
            group.abort()
            raise
        if announce:
            for line in group.notices:
                print(line, file=sys.stderr)
        return group

    def ready(self) -> None:
        """Every sink is open (they open in the constructor)."""

    def write(self, record: FrameRecord) -> None:
        with self._clock.stage("encode"):
            images = FrameImages(record.cameras)
            encoded = [sink.encode(record, images) for sink in self._sinks]
        with self._clock.stage("write"):
            try:
                for sink, data in zip(self._sinks, encoded, strict=True):
                    sink.write(data)
            except Exception as err:
                if out_of_space(err):
                    self.keep()
                    raise disk_full_error(err) from err
                raise

    def close(self) -> None:
        """Close every sink (files move into place); if one fails, the rest are aborted (kept,
        when the disk is full)."""
        for i, sink in enumerate(self._sinks):
            try:
                sink.close()
            except BaseException as err:
                if out_of_space(err):
                    SinkGroup(self._sinks[i:]).keep()
                    raise disk_full_error(err) from err
                SinkGroup(self._sinks[i + 1 :]).abort()
                raise

    def abort(self) -> None:
        for sink in self._sinks:
            sink.abort()

    def keep(self) -> None:
        """Stop every sink, leaving its files where and as they are (the frames written stay)."""
        if not self._kept:
            self._kept = True
            for sink in self._sinks:
                sink.keep()

"""The sinks of one run, chosen by :class:`SinkChoice` and driven together in this process."""

from __future__ import annotations

import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TypeVar

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
from networks.vocabulary import SensorKind, SinkKind

T = TypeVar("T")


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
    sensors: tuple[tuple[SensorKind, str], ...] = ()  # the rig's (kind, name) pairs: the live view's channels
    deskewed: tuple[str, ...] = ()  # the LiDARs that deskew (their /<name>/deskewed channels)
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

    def wants(self, kind: SinkKind) -> bool:
        """Whether the sink ``kind`` is chosen."""
        return bool(_CHOSEN[kind](self))

    def partial_paths(self) -> list[Path]:
        """Where the chosen sinks write until they close (``*.partial`` files and folders)."""
        return [self.out_dir / f"{name}.partial" for kind, name in OUTPUT_NAMES.items() if name and self.wants(kind)]


# Whether a sink is chosen, and what it writes under the output folder ('': nothing there).
_CHOSEN: dict[SinkKind, Callable[[SinkChoice], object]] = {
    SinkKind.MCAP: lambda c: c.mcap,
    SinkKind.CSV: lambda c: c.csv,
    SinkKind.LIGHTS_CSV: lambda c: c.lights_csv,
    SinkKind.EVENTS: lambda c: c.events,
    SinkKind.KITTI: lambda c: c.kitti,
    SinkKind.YOLO: lambda c: c.yolo,
    SinkKind.MAP: lambda c: c.map,
    SinkKind.NUSCENES: lambda c: c.nuscenes,
    SinkKind.OCCUPANCY: lambda c: c.occupancy,
    SinkKind.LIVE: lambda c: c.live,
    SinkKind.RESUME: lambda c: c.resume,
}
OUTPUT_NAMES = {
    SinkKind.MCAP: "run.mcap",
    SinkKind.CSV: "labels.csv",
    SinkKind.LIGHTS_CSV: "lights_and_signs.csv",
    SinkKind.EVENTS: "event_frames.csv",
    SinkKind.KITTI: "kitti",
    SinkKind.YOLO: "yolo",
    SinkKind.MAP: "map",
    SinkKind.NUSCENES: "nuscenes",
    SinkKind.OCCUPANCY: "occupancy",
    SinkKind.LIVE: "",
    SinkKind.RESUME: "",
}
_OPEN: dict[SinkKind, Callable[[SinkChoice], Sink]] = {
    SinkKind.MCAP: lambda c: McapSink(c.out_dir / "run.mcap", c.map_world, c.keep_frames),
    SinkKind.CSV: lambda c: CsvSink(c.out_dir / "labels.csv", c.keep_frames),
    SinkKind.LIGHTS_CSV: lambda c: CsvSink(c.out_dir / "lights_and_signs.csv", c.keep_frames, signals=True),
    SinkKind.EVENTS: lambda c: EventsSink(c.out_dir, c.keep_frames),
    SinkKind.KITTI: lambda c: KittiSink(
        c.out_dir / "kitti", c.keep_frames, c.first_map_SE3_ego, c.kitti_native_types, c.kitti_image_3
    ),
    SinkKind.YOLO: lambda c: YoloSink(c.out_dir / "yolo", c.yolo_min_visible_px, c.keep_frames),
    SinkKind.MAP: lambda c: MapSink(c.out_dir / "map", _given(c.map_json, "map_json"), c.keep_frames),
    SinkKind.NUSCENES: lambda c: NuscenesSink(c.out_dir / "nuscenes", _given(c.nuscenes, "nuscenes"), c.keep_frames),
    SinkKind.OCCUPANCY: lambda c: OccupancySink(c.out_dir / "occupancy", c.keep_frames),
    SinkKind.LIVE: lambda c: LiveSink(
        _given(c.live, "live"), c.map_world, c.sensors, c.map, c.hazards, c.deskewed, c.occupancy
    ),
    SinkKind.RESUME: lambda c: ResumeSink(c.out_dir, c.keep_frames),
}


def _given(value: T | None, name: str) -> T:
    if value is None:
        raise ValueError(f"SinkChoice: no {name}")
    return value


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
        group = cls([], clock)
        try:
            for kind in SinkKind:
                if choice.wants(kind):
                    group._sinks.append(_OPEN[kind](choice))
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

"""``run.mcap``: every sensor, transform and label, with Foxglove schemas.

Topics (sensor names from the rig; defaults shown):
``/tf`` FrameTransforms map -> ego -> each sensor; ``/lidar`` PointCloud (lidar frame at each
point's time: x, y, z, intensity, ring, class, instance, t: seconds from the sweep's start), and
with ``deskew`` ``/lidar/deskewed`` (the same points in the lidar frame at the frame's time);
``/radar`` PointCloud (radar frame: x, y, z, range, radial_velocity, azimuth, elevation, strength, instance, class);
``/camera/image`` JPEG, ``/camera/depth`` 16-bit PNG in 1/256 m (0: nothing within range), ``/camera/instance``
16-bit PNG of instance ids, ``/camera/class`` 8-bit PNG of class ids,
``/camera/calibration``, ``/camera/annotations`` tight 2D boxes; ``/gt/boxes`` SceneUpdate
(one cube per labelled object, ego frame); ``/gt/labels`` the label table as JSON;
``/map`` the static world once (SceneUpdate, map frame, one triangle list per class).
Log and publish times are simulation time in nanoseconds.
"""

from __future__ import annotations

import contextlib
import json
import math
import struct
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
from foxglove_schemas_protobuf.CameraCalibration_pb2 import CameraCalibration
from foxglove_schemas_protobuf.CompressedImage_pb2 import CompressedImage
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from foxglove_schemas_protobuf.ImageAnnotations_pb2 import ImageAnnotations
from foxglove_schemas_protobuf.PointCloud_pb2 import PointCloud
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from mcap.exceptions import McapError
from mcap.records import Channel, Message, Schema
from mcap.stream_reader import StreamReader
from mcap.writer import CompressionType
from mcap.writer import Writer as McapWriter
from mcap_protobuf.schema import build_file_descriptor_set

from gtgen import topics
from gtgen.errors import SinkError
from gtgen.frame import FrameRecord
from gtgen.signals import SIGNAL_COLUMNS, signal_table
from gtgen.sinks import foxglove as fx
from gtgen.sinks.images import FrameImages
from gtgen.sinks.layout import layout_for
from gtgen.sinks.occupancy_messages import occupancy_update, with_flow
from gtgen.static_map import static_map_update
from gtgen.table import COLUMNS, label_table
from networks.vocabulary import SensorKind
from networks.world import read_world
from sensors.sensor import SensorOutput

EVENTS_SCHEMA = {
    "type": "object",
    "properties": {
        "frame": {"type": "integer"},
        "timestamp_ns": {"type": "integer"},
        "ego_collided": {"type": "boolean"},
        "events": {"type": "array", "items": {"type": "object", "properties": {
            "name": {"type": "string"}, "kind": {"type": "string"},
            "actors": {"type": "array", "items": {"type": "integer"}}, "ego": {"type": "integer"}}}},
    },
}  # fmt: skip
LAYOUT_FILE = "foxglove_layout.json"

LABELS_SCHEMA = {
    "type": "object",
    "properties": {
        "frame": {"type": "integer"},
        "timestamp_ns": {"type": "integer"},
        "scene_cut": {"type": "boolean"},
        "objects": {"type": "array", "items": {"type": "object", "properties": {c: {} for c in COLUMNS}}},
        "lights_and_signs": {
            "type": "array",
            "items": {"type": "object", "properties": {c: {} for c in SIGNAL_COLUMNS}},
        },
    },
}


def json_column(values: npt.NDArray[np.generic]) -> list[Any]:
    """A label column as JSON values: floats rounded to 5 decimals (null if not finite),
    integers as such, anything else as text."""
    if values.dtype.kind == "f":
        return [round(v, 5) if math.isfinite(v) else None for v in values.tolist()]
    if values.dtype.kind in "iu":
        return list(values.tolist())
    return [str(v) for v in values.tolist()]


@dataclass(frozen=True, slots=True)
class McapMessage:
    """One serialized message: ``proto`` is its protobuf class (None: JSON labels)."""

    topic: str
    proto: type | None
    data: bytes


@dataclass(frozen=True, slots=True)
class McapFrame:
    timestamp_ns: int
    messages: tuple[McapMessage, ...]


@dataclass(frozen=True, slots=True)
class ChannelSchema:
    """How a topic's messages are described to a reader (MCAP file or live viewer)."""

    name: str
    encoding: str  # of the schema: "protobuf" or "jsonschema"
    data: bytes
    message_encoding: str  # "protobuf" or "json"


def channel_schema(proto: type | None, topic: str = topics.LABELS) -> ChannelSchema:
    """The schema of a topic's messages: its protobuf's file descriptors, or (``None``) the JSON
    schema of the labels (or of the events, on their topic)."""
    if proto is None and topic == topics.EVENTS:
        return ChannelSchema("gt.HazardEvents", "jsonschema", json.dumps(EVENTS_SCHEMA).encode(), "json")
    if proto is None:
        return ChannelSchema("gt.FrameLabels", "jsonschema", json.dumps(LABELS_SCHEMA).encode(), "json")
    descriptors = build_file_descriptor_set(proto).SerializeToString()
    return ChannelSchema(proto.DESCRIPTOR.full_name, "protobuf", descriptors, "protobuf")  # type: ignore[attr-defined]


def _serialized(topic: str, message: Any) -> McapMessage:
    if isinstance(message, dict):
        return McapMessage(topic, None, json.dumps(message, separators=(",", ":")).encode())
    return McapMessage(topic, type(message), message.SerializeToString())


def serialized_frame(record: FrameRecord, images: FrameImages) -> McapFrame:
    """Every message of one frame, serialized, in write order."""
    return McapFrame(record.timestamp_ns, tuple(_serialized(topic, m) for topic, m in frame_messages(record, images)))


def map_message(world_path: Path, timestamp_ns: int) -> McapMessage:
    """The static world of a world file (:func:`networks.world.read_world`) on ``/map``."""
    return _serialized(topics.MAP, static_map_update(read_world(world_path).mesh, timestamp_ns))


def frame_messages(record: FrameRecord, images: FrameImages) -> list[tuple[str, Any]]:
    """Every message of one frame, in write order, as ``(topic, protobuf message or JSON dict)``."""
    ns = record.timestamp_ns
    transforms = [fx.frame_transform(ns, "map", "ego", record.map_SE3_ego)]
    sensors: tuple[SensorOutput, ...] = (*record.lidars, *record.radars, *record.cameras)
    transforms += [fx.frame_transform(ns, "ego", o.spec.name, o.spec.ego_SE3_sensor) for o in sensors]
    out: list[tuple[str, Any]] = [(topics.TF, FrameTransforms(transforms=transforms))]
    clouds = [fx.lidar_cloud(ns, lidar) for lidar in record.lidars]
    if record.occupancy is not None:  # each point's scene flow as three more fields
        clouds = [with_flow(c, f) for c, f in zip(clouds, record.occupancy.point_flow_m, strict=True)]
    out += [(topics.cloud(lidar.spec.name), cloud) for lidar, cloud in zip(record.lidars, clouds, strict=True)]
    out += [(topics.deskewed(lidar.spec.name), fx.lidar_cloud(ns, lidar, deskewed=True)) for lidar in record.lidars
            if lidar.spec.deskew]  # fmt: skip
    out += [(topics.cloud(radar.spec.name), fx.radar_cloud(ns, radar)) for radar in record.radars]
    for index, (camera, cam_labels) in enumerate(zip(record.cameras, record.labels.cameras, strict=True)):
        name = camera.spec.name
        out += [(topics.camera(name, kind), m) for kind, m in fx.camera_messages(ns, camera, images, index).items()]
        out.append((topics.camera(name, "calibration"), fx.calibration(ns, camera)))
        out.append((topics.camera(name, "annotations"), fx.image_annotations(ns, record.labels, cam_labels)))
    out.append((topics.BOXES, fx.box_update(ns, record.labels, record.signals.state_of())))
    if record.occupancy is not None:
        out.append((topics.OCCUPANCY, occupancy_update(ns, record.occupancy)))
    if record.map is not None:
        out.append((topics.MAP_VECTORS, fx.map_lines(ns, record.map.vectors["elements"])))
    if record.hazards is not None:
        events = [
            {"name": h.name, "kind": h.kind, "actors": list(h.actor_ids), "ego": h.ego_id} for h in record.hazards
        ]
        out.append((topics.EVENTS, {"frame": record.frame_index, "timestamp_ns": ns,
                                    "ego_collided": record.ego_collided, "events": events}))  # fmt: skip
    out.append((topics.LABELS, labels_json(record)))
    return out


def planned_topics(
    sensors: tuple[tuple[SensorKind, str], ...],
    with_map: bool,
    with_map_vectors: bool = False,
    with_events: bool = False,
    deskewed: tuple[str, ...] = (),
    with_occupancy: bool = False,
) -> list[tuple[str, type | None]]:
    """Every topic a run of a rig writes, in the order :func:`frame_messages` writes them, with
    its protobuf class (None: JSON), known before its first frame. ``sensors``: (kind, name)
    pairs of the rig; ``deskewed``: the names of the LiDARs that deskew; ``with_map_vectors``:
    the run writes map ground truth; ``with_events``: the run makes hazard events;
    ``with_occupancy``: the run writes occupancy."""
    out: list[tuple[str, type | None]] = [(topics.MAP, SceneUpdate)] if with_map else []
    out.append((topics.TF, FrameTransforms))
    lidars = [name for kind, name in sensors if kind == SensorKind.LIDAR]
    out += [(topics.cloud(name), PointCloud) for name in lidars]
    out += [(topics.deskewed(name), PointCloud) for name in lidars if name in deskewed]
    out += [(topics.cloud(name), PointCloud) for kind, name in sensors if kind == SensorKind.RADAR]
    for name in (name for kind, name in sensors if kind == SensorKind.CAMERA):
        out += [(topics.camera(name, k), CompressedImage) for k in topics.CAMERA_IMAGES]
        out += [
            (topics.camera(name, "calibration"), CameraCalibration),
            (topics.camera(name, "annotations"), ImageAnnotations),
        ]
    out.append((topics.BOXES, SceneUpdate))
    out += [(topics.OCCUPANCY, SceneUpdate)] if with_occupancy else []
    out += [(topics.MAP_VECTORS, SceneUpdate)] if with_map_vectors else []
    out += [(topics.EVENTS, None)] if with_events else []
    return [*out, (topics.LABELS, None)]


def _json_rows(table: dict[str, npt.NDArray[np.generic]]) -> list[dict[str, Any]]:
    columns = [json_column(values) for values in table.values()]
    return [dict(zip(table, row, strict=True)) for row in zip(*columns, strict=True)]


def labels_json(record: FrameRecord) -> dict[str, Any]:
    """The frame's label table, and its traffic lights and signs (``lights_and_signs``)."""
    objects = _json_rows(label_table(record.labels))
    lights = _json_rows(signal_table(record.labels, record.signals))
    return {"frame": record.frame_index, "timestamp_ns": record.timestamp_ns, "scene_cut": record.scene_cut,
            "objects": objects, "lights_and_signs": lights}  # fmt: skip


def readable_records(path: Path) -> Iterator[Schema | Channel | Message]:
    """The schemas, channels and messages of an MCAP file in file order, as far as it can be
    read: a file cut short (a killed run) gives those of its complete chunks."""
    with path.open("rb") as stream:
        try:
            for record in StreamReader(stream, skip_magic=False).records:
                if isinstance(record, Schema | Channel | Message):
                    yield record
        except (McapError, struct.error, ValueError, RuntimeError):  # a record cut short (lz4 says RuntimeError)
            return


def complete_frames(path: Path) -> int:
    """How many frames an MCAP file written by :class:`McapSink` holds whole (a frame's label
    table is its last message)."""
    topic_of: dict[int, str] = {}
    frames = 0
    for record in readable_records(path):
        if isinstance(record, Channel):
            topic_of[record.id] = record.topic
        elif isinstance(record, Message) and topic_of.get(record.channel_id) == topics.LABELS:
            frames += 1
    return frames


def earlier_file(path: Path) -> Path | None:
    """The file of an earlier run that a run continuing it copies its frames from: the one
    moved aside (``.earlier``) by a continuation cut short, else the partial, else the final one."""
    for candidate in (path.with_name(path.name + ".earlier"), path.with_name(path.name + ".partial"), path):
        if candidate.exists():
            return candidate
    return None


class McapSink:
    """``run.mcap``; with ``map_world`` (a static world file), the static map goes on
    ``/map`` once, at the first frame's time. A run that continues an earlier one
    (``keep_frames``) copies the messages of the frames it keeps from the earlier file, moved
    aside meanwhile (``.earlier``; put back if the copy fails, a full disk keeps it)."""

    def __init__(self, path: Path, map_world: Path | None = None, keep_frames: int = 0) -> None:
        self._path = path
        self._map_world = map_world if keep_frames == 0 else None
        self._layout = ""  # foxglove_layout.json beside the MCAP, written on close
        self._partial = path.with_name(path.name + ".partial")
        self._kept = False
        source = self._earlier_file() if keep_frames > 0 else None
        try:
            self._stream = self._partial.open("wb")
        except OSError as err:
            raise self._failed(err, source) from err
        try:
            self._writer = McapWriter(self._stream, compression=CompressionType.LZ4)
            self._writer.start(profile="", library="sumo-dataset-factory")
            self._channels: dict[str, int] = {}
            if source is not None:
                self._copy(source, keep_frames)
        except OSError as err:
            with contextlib.suppress(OSError):
                self._stream.close()
            raise self._failed(err, source) from err
        if source is not None:
            source.unlink()

    def _failed(self, err: OSError, source: Path | None) -> SinkError:
        """The file could not be started: the earlier run's file goes back (its frames stay)."""
        if source is not None:
            source.replace(self._partial)
        return SinkError(f"{self._partial}: cannot write: {err.strerror}")

    def _earlier_file(self) -> Path | None:
        """The earlier run's file, moved aside to be copied from."""
        earlier = earlier_file(self._path)
        if earlier is None:
            return None
        aside = self._path.with_name(self._path.name + ".earlier")
        earlier.replace(aside)
        return aside

    def _copy(self, source: Path, keep_frames: int) -> None:
        schemas: dict[int, int] = {}
        channels: dict[int, int] = {}
        times: list[int] = []
        for record in readable_records(source):
            if isinstance(record, Schema) and record.id not in schemas:  # a finished file lists them again
                schemas[record.id] = self._writer.register_schema(record.name, record.encoding, record.data)
            elif isinstance(record, Channel) and record.id not in channels:
                channel = self._writer.register_channel(
                    record.topic, record.message_encoding, schemas.get(record.schema_id, 0)
                )
                channels[record.id] = self._channels[record.topic] = channel
            elif isinstance(record, Message):
                if not times or times[-1] != record.log_time:
                    times.append(record.log_time)
                if len(times) > keep_frames:
                    break
                self._writer.add_message(channels[record.channel_id], log_time=record.log_time, data=record.data,
                                         publish_time=record.publish_time)  # fmt: skip
        self._stream.flush()

    def _channel(self, message: McapMessage) -> int:
        channel = self._channels.get(message.topic)
        if channel is None:
            schema = channel_schema(message.proto, message.topic)
            schema_id = self._writer.register_schema(schema.name, schema.encoding, schema.data)
            channel = self._writer.register_channel(message.topic, schema.message_encoding, schema_id)
            self._channels[message.topic] = channel
        return channel

    def encode(self, record: FrameRecord, images: FrameImages) -> McapFrame:
        frame = serialized_frame(record, images)
        if not self._layout:
            self._layout = layout_for(record)
        if self._map_world is not None:
            frame = McapFrame(frame.timestamp_ns, (map_message(self._map_world, record.timestamp_ns), *frame.messages))
            self._map_world = None
        return frame

    def write(self, encoded: McapFrame) -> None:
        ns = encoded.timestamp_ns
        try:
            for message in encoded.messages:
                self._writer.add_message(self._channel(message), log_time=ns, data=message.data, publish_time=ns)
            self._stream.flush()  # the frame's complete chunks reach the file: a killed run keeps them
        except OSError as err:
            raise SinkError(f"{self._partial}: cannot write: {err.strerror}") from err

    def close(self) -> None:
        self._writer.finish()
        self._stream.close()
        if self._layout:
            layout = self._path.with_name(LAYOUT_FILE)
            layout.with_name(LAYOUT_FILE + ".partial").write_text(self._layout)
            layout.with_name(LAYOUT_FILE + ".partial").replace(layout)
        self._partial.replace(self._path)

    def abort(self) -> None:
        self._stream.close()
        self._partial.unlink(missing_ok=True)

    def keep(self) -> None:
        """Finish the file (its index) where the disk lets it, under its partial name."""
        if self._kept:
            return
        self._kept = True
        with contextlib.suppress(OSError):
            self._writer.finish()
        with contextlib.suppress(OSError):
            self._stream.close()

"""``run.mcap``: every sensor, transform and label, with Foxglove schemas.

Topics (sensor names from the rig; defaults shown):
``/tf`` FrameTransforms map -> ego -> each sensor; ``/lidar`` PointCloud (lidar frame:
x, y, z, intensity, ring, class, instance); ``/radar`` PointCloud (radar frame: x, y, z,
range, radial_velocity, azimuth, elevation, strength, instance, class);
``/camera/image`` JPEG, ``/camera/depth`` 16-bit PNG in 1/256 m (0: nothing within range), ``/camera/instance``
16-bit PNG of instance ids, ``/camera/class`` 8-bit PNG of class ids,
``/camera/calibration``, ``/camera/annotations`` tight 2D boxes; ``/gt/boxes`` SceneUpdate
(one cube per labelled object, ego frame); ``/gt/labels`` the label table as JSON.
Log and publish times are simulation time in nanoseconds.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from mcap.writer import CompressionType
from mcap.writer import Writer as McapWriter
from mcap_protobuf.schema import register_schema

from gtgen.frame import FrameRecord
from gtgen.sinks import foxglove as fx
from gtgen.table import COLUMNS, label_table

LABELS_SCHEMA = {
    "type": "object",
    "properties": {
        "frame": {"type": "integer"},
        "timestamp_ns": {"type": "integer"},
        "objects": {"type": "array", "items": {"type": "object", "properties": {c: {} for c in COLUMNS}}},
    },
}


def _json_value(value: Any) -> Any:
    if isinstance(value, np.floating):
        return None if not np.isfinite(value) else round(float(value), 5)
    if isinstance(value, np.integer):
        return int(value)
    return str(value)


class McapSink:
    def __init__(self, path: Path) -> None:
        self._path = path
        self._partial = path.with_name(path.name + ".partial")
        self._stream = self._partial.open("wb")
        self._writer = McapWriter(self._stream, compression=CompressionType.LZ4)
        self._writer.start(profile="", library="sumo-dataset-factory")
        self._channels: dict[str, int] = {}

    def _channel(self, topic: str, message: Any) -> int:
        channel = self._channels.get(topic)
        if channel is None:
            if isinstance(message, dict):
                schema = self._writer.register_schema(
                    "gt.FrameLabels", "jsonschema", json.dumps(LABELS_SCHEMA).encode()
                )
                channel = self._writer.register_channel(topic, "json", schema)
            else:
                channel = self._writer.register_channel(topic, "protobuf", register_schema(self._writer, type(message)))
            self._channels[topic] = channel
        return channel

    def _put(self, topic: str, message: Any, ns: int) -> None:
        data = (
            json.dumps(message, separators=(",", ":")).encode()
            if isinstance(message, dict)
            else message.SerializeToString()
        )
        self._writer.add_message(self._channel(topic, message), log_time=ns, data=data, publish_time=ns)

    def write(self, record: FrameRecord) -> None:
        ns = record.timestamp_ns
        transforms = [fx.frame_transform(ns, "map", "ego", record.map_SE3_ego)]
        transforms += [fx.frame_transform(ns, "ego", o.spec.name, o.spec.ego_SE3_sensor) for o in record.lidars]
        transforms += [fx.frame_transform(ns, "ego", o.spec.name, o.spec.ego_SE3_sensor) for o in record.radars]
        transforms += [fx.frame_transform(ns, "ego", c.spec.name, c.spec.ego_SE3_cam) for c in record.cameras]
        self._put("/tf", FrameTransforms(transforms=transforms), ns)
        for lidar in record.lidars:
            self._put(f"/{lidar.spec.name}", fx.lidar_cloud(ns, lidar), ns)
        for radar in record.radars:
            self._put(f"/{radar.spec.name}", fx.radar_cloud(ns, radar), ns)
        for camera, cam_labels in zip(record.cameras, record.labels.cameras, strict=True):
            base = f"/{camera.spec.name}"
            for kind, message in fx.camera_messages(ns, camera).items():
                self._put(f"{base}/{kind}", message, ns)
            self._put(f"{base}/calibration", fx.calibration(ns, camera), ns)
            self._put(f"{base}/annotations", fx.image_annotations(ns, record.labels, cam_labels), ns)
        self._put("/gt/boxes", fx.box_update(ns, record.labels), ns)
        self._put("/gt/labels", self._labels_json(record), ns)

    @staticmethod
    def _labels_json(record: FrameRecord) -> dict[str, Any]:
        table = label_table(record.labels)
        objects = [{c: _json_value(table[c][i]) for c in COLUMNS} for i in range(len(record.labels))]
        return {"frame": record.frame_index, "timestamp_ns": record.timestamp_ns, "objects": objects}

    def close(self) -> None:
        self._writer.finish()
        self._stream.close()
        self._partial.replace(self._path)

    def abort(self) -> None:
        self._stream.close()

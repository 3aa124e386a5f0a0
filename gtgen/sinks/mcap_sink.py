"""``run.mcap``: transforms, point clouds and 3D boxes as Foxglove protobuf schemas.

Topics: ``/tf`` (FrameTransforms: map -> ego -> each sensor), ``/lidar`` (PointCloud in
the lidar frame; fields x, y, z, intensity, ring, class, instance), ``/gt/boxes``
(SceneUpdate: one cube per labelled object in the ego frame, replacing the last frame's).
Log and publish times are the simulation time in nanoseconds.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from foxglove_schemas_protobuf.Color_pb2 import Color
from foxglove_schemas_protobuf.CubePrimitive_pb2 import CubePrimitive
from foxglove_schemas_protobuf.FrameTransform_pb2 import FrameTransform
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from foxglove_schemas_protobuf.KeyValuePair_pb2 import KeyValuePair
from foxglove_schemas_protobuf.PackedElementField_pb2 import PackedElementField
from foxglove_schemas_protobuf.PointCloud_pb2 import PointCloud
from foxglove_schemas_protobuf.Pose_pb2 import Pose
from foxglove_schemas_protobuf.Quaternion_pb2 import Quaternion
from foxglove_schemas_protobuf.SceneEntity_pb2 import SceneEntity
from foxglove_schemas_protobuf.SceneEntityDeletion_pb2 import SceneEntityDeletion
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from foxglove_schemas_protobuf.Vector3_pb2 import Vector3
from google.protobuf.timestamp_pb2 import Timestamp
from mcap.writer import CompressionType
from mcap_protobuf.writer import Writer

from gtgen.frame import FrameRecord, LidarOutput
from gtgen.labels import FrameLabels
from networks.classes import SemanticClass
from networks.geometry import SE3

LIDAR_POINT_DTYPE = np.dtype(
    [("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("intensity", "<f4"), ("ring", "<u2"), ("class", "u1"),
     ("_pad", "u1"), ("instance", "<u4")]
)  # fmt: skip
_F = PackedElementField
LIDAR_FIELDS = (
    ("x", 0, _F.FLOAT32), ("y", 4, _F.FLOAT32), ("z", 8, _F.FLOAT32), ("intensity", 12, _F.FLOAT32),
    ("ring", 16, _F.UINT16), ("class", 18, _F.UINT8), ("instance", 20, _F.UINT32),
)  # fmt: skip

CLASS_COLORS: dict[int, tuple[float, float, float]] = {
    SemanticClass.CAR: (0.2, 0.6, 1.0),
    SemanticClass.TRUCK: (1.0, 0.6, 0.1),
    SemanticClass.BUS: (1.0, 0.85, 0.1),
    SemanticClass.MOTORCYCLE: (0.9, 0.2, 0.9),
    SemanticClass.BICYCLE: (0.2, 0.9, 0.9),
    SemanticClass.PEDESTRIAN: (1.0, 0.25, 0.25),
}


def _timestamp(ns: int) -> Timestamp:
    return Timestamp(seconds=ns // 1_000_000_000, nanos=ns % 1_000_000_000)


def _pose(t: SE3) -> Pose:
    x, y, z, w = t.quaternion_xyzw()
    return Pose(
        position=Vector3(x=float(t.translation[0]), y=float(t.translation[1]), z=float(t.translation[2])),
        orientation=Quaternion(x=x, y=y, z=z, w=w),
    )


def _transform(ns: int, parent: str, child: str, parent_SE3_child: SE3) -> FrameTransform:
    pose = _pose(parent_SE3_child)
    return FrameTransform(
        timestamp=_timestamp(ns), parent_frame_id=parent, child_frame_id=child,
        translation=pose.position, rotation=pose.orientation,
    )  # fmt: skip


def point_cloud(ns: int, lidar: LidarOutput) -> PointCloud:
    scan = lidar.scan
    packed = np.zeros(len(scan), LIDAR_POINT_DTYPE)
    packed["x"], packed["y"], packed["z"] = scan.xyz_lidar_m.T
    packed["intensity"] = scan.intensity
    packed["ring"] = scan.ring
    packed["class"] = scan.semantic_class
    packed["instance"] = scan.instance_id
    return PointCloud(
        timestamp=_timestamp(ns),
        frame_id=lidar.spec.name,
        pose=_pose(SE3.identity()),
        point_stride=LIDAR_POINT_DTYPE.itemsize,
        fields=[PackedElementField(name=n, offset=o, type=t) for n, o, t in LIDAR_FIELDS],
        data=packed.tobytes(),
    )


def box_update(ns: int, labels: FrameLabels) -> SceneUpdate:
    o = labels.objects
    entities = []
    for i in range(len(o)):
        cls = SemanticClass(int(o.semantic_class[i]))
        r, g, b = CLASS_COLORS.get(cls, (0.8, 0.8, 0.8))
        pose = _pose(SE3.from_xyz_rpy(o.center_ego_m[i], yaw=float(o.yaw_ego_rad[i])))
        size = Vector3(x=float(o.lwh_m[i, 0]), y=float(o.lwh_m[i, 1]), z=float(o.lwh_m[i, 2]))
        entities.append(
            SceneEntity(
                timestamp=_timestamp(ns),
                frame_id="ego",
                id=str(int(o.track_id[i])),
                cubes=[
                    CubePrimitive(pose=pose, size=size, color=Color(r=r, g=g, b=b, a=0.35 if labels.seen[i] else 0.1))
                ],
                metadata=[
                    KeyValuePair(key="class", value=cls.label),
                    KeyValuePair(key="lidar_points", value=str(int(labels.lidar_points[i]))),
                    KeyValuePair(key="parked", value=str(bool(o.parked[i])).lower()),
                ],
            )
        )
    deletion = SceneEntityDeletion(timestamp=_timestamp(ns), type=SceneEntityDeletion.ALL)
    return SceneUpdate(deletions=[deletion], entities=entities)


class McapSink:
    def __init__(self, path: Path) -> None:
        self._path = path
        self._partial = path.with_name(path.name + ".partial")
        self._stream = self._partial.open("wb")
        self._writer = Writer(self._stream, compression=CompressionType.LZ4)

    def write(self, record: FrameRecord) -> None:
        ns = record.timestamp_ns
        transforms = [_transform(ns, "map", "ego", record.map_SE3_ego)]
        transforms += [_transform(ns, "ego", li.spec.name, li.spec.ego_SE3_sensor) for li in record.lidars]
        self._writer.write_message("/tf", FrameTransforms(transforms=transforms), log_time=ns, publish_time=ns)
        for lidar in record.lidars:
            topic = "/lidar" if lidar.spec.name == "lidar" else f"/lidar/{lidar.spec.name}"
            self._writer.write_message(topic, point_cloud(ns, lidar), log_time=ns, publish_time=ns)
        self._writer.write_message("/gt/boxes", box_update(ns, record.labels), log_time=ns, publish_time=ns)

    def close(self) -> None:
        self._writer.finish()
        self._stream.close()
        self._partial.replace(self._path)

    def abort(self) -> None:
        self._stream.close()

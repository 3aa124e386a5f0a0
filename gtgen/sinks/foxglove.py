"""Foxglove protobuf messages for one frame (pure: no file access)."""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt
from foxglove_schemas_protobuf.CameraCalibration_pb2 import CameraCalibration
from foxglove_schemas_protobuf.Color_pb2 import Color
from foxglove_schemas_protobuf.CompressedImage_pb2 import CompressedImage
from foxglove_schemas_protobuf.CubePrimitive_pb2 import CubePrimitive
from foxglove_schemas_protobuf.FrameTransform_pb2 import FrameTransform
from foxglove_schemas_protobuf.ImageAnnotations_pb2 import ImageAnnotations
from foxglove_schemas_protobuf.KeyValuePair_pb2 import KeyValuePair
from foxglove_schemas_protobuf.LinePrimitive_pb2 import LinePrimitive
from foxglove_schemas_protobuf.PackedElementField_pb2 import PackedElementField
from foxglove_schemas_protobuf.Point2_pb2 import Point2
from foxglove_schemas_protobuf.Point3_pb2 import Point3
from foxglove_schemas_protobuf.PointCloud_pb2 import PointCloud
from foxglove_schemas_protobuf.PointsAnnotation_pb2 import PointsAnnotation
from foxglove_schemas_protobuf.Pose_pb2 import Pose
from foxglove_schemas_protobuf.Quaternion_pb2 import Quaternion
from foxglove_schemas_protobuf.SceneEntity_pb2 import SceneEntity
from foxglove_schemas_protobuf.SceneEntityDeletion_pb2 import SceneEntityDeletion
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from foxglove_schemas_protobuf.TextAnnotation_pb2 import TextAnnotation
from foxglove_schemas_protobuf.Vector3_pb2 import Vector3
from google.protobuf.timestamp_pb2 import Timestamp

from gtgen.colours import CLASS_RGB
from gtgen.labels import CameraLabels, FrameLabels
from gtgen.signals import STATE_RGB
from gtgen.sinks.images import JPEG_QUALITY, FrameImages
from networks.classes import SemanticClass
from networks.geometry import SE3
from networks.vocabulary import Lamp
from sensors.camera import CameraOutput
from sensors.lidar import LidarOutput
from sensors.radar import RadarOutput

_F = PackedElementField
LIDAR_POINT_DTYPE = np.dtype(
    [("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("intensity", "<f4"), ("ring", "<u2"), ("class", "u1"),
     ("_pad", "u1"), ("instance", "<u4"), ("t", "<f4")]
)  # fmt: skip
LIDAR_FIELDS = (
    ("x", 0, _F.FLOAT32), ("y", 4, _F.FLOAT32), ("z", 8, _F.FLOAT32), ("intensity", 12, _F.FLOAT32),
    ("ring", 16, _F.UINT16), ("class", 18, _F.UINT8), ("instance", 20, _F.UINT32), ("t", 24, _F.FLOAT32),
)  # fmt: skip
"""A LiDAR point: ``t`` is seconds from the sweep's start (0 for an instant sweep)."""
LIDAR_POINT_DTYPE_NO_TIME = np.dtype(
    [("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("intensity", "<f4"), ("ring", "<u2"), ("class", "u1"),
     ("_pad", "u1"), ("instance", "<u4")]
)  # fmt: skip
"""The layout of files written before points had times."""
RADAR_POINT_DTYPE = np.dtype(
    [("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("range", "<f4"), ("radial_velocity", "<f4"), ("azimuth", "<f4"),
     ("elevation", "<f4"), ("strength", "<f4"), ("instance", "<u4"), ("class", "u1"), ("_pad", "V3")]
)  # fmt: skip
RADAR_FIELDS = (
    ("x", 0, _F.FLOAT32), ("y", 4, _F.FLOAT32), ("z", 8, _F.FLOAT32), ("range", 12, _F.FLOAT32),
    ("radial_velocity", 16, _F.FLOAT32), ("azimuth", 20, _F.FLOAT32), ("elevation", 24, _F.FLOAT32),
    ("strength", 28, _F.FLOAT32), ("instance", 32, _F.UINT32), ("class", 36, _F.UINT8),
)  # fmt: skip

DEPTH_UNITS_PER_M = 256.0  # 16-bit depth PNG: 1/256 m steps up to 255.99 m (as KITTI's depth maps)


def timestamp(ns: int) -> Timestamp:
    return Timestamp(seconds=ns // 1_000_000_000, nanos=ns % 1_000_000_000)


def pose(t: SE3) -> Pose:
    x, y, z, w = t.quaternion_xyzw()
    p = t.translation
    return Pose(
        position=Vector3(x=float(p[0]), y=float(p[1]), z=float(p[2])), orientation=Quaternion(x=x, y=y, z=z, w=w)
    )


def frame_transform(ns: int, parent: str, child: str, parent_SE3_child: SE3) -> FrameTransform:
    p = pose(parent_SE3_child)
    return FrameTransform(timestamp=timestamp(ns), parent_frame_id=parent, child_frame_id=child,
                          translation=p.position, rotation=p.orientation)  # fmt: skip


def _cloud(
    ns: int, frame_id: str, packed: npt.NDArray[np.void], fields: tuple[tuple[str, int, Any], ...]
) -> PointCloud:
    return PointCloud(
        timestamp=timestamp(ns), frame_id=frame_id, pose=pose(SE3.identity()), point_stride=packed.dtype.itemsize,
        fields=[PackedElementField(name=n, offset=o, type=t) for n, o, t in fields], data=packed.tobytes(),
    )  # fmt: skip


def lidar_cloud(ns: int, lidar: LidarOutput, deskewed: bool = False) -> PointCloud:
    """The sweep's points in the LiDAR frame at each point's time (``deskewed``: the copy moved to
    the sweep's reference time, the frame's time)."""
    scan = lidar.scan
    packed = np.zeros(len(scan), LIDAR_POINT_DTYPE)
    packed["x"], packed["y"], packed["z"] = (scan.xyz_deskewed_lidar_m if deskewed else scan.xyz_lidar_m).T
    packed["intensity"], packed["ring"] = scan.intensity, scan.ring
    packed["class"], packed["instance"], packed["t"] = scan.semantic_class, scan.instance_id, scan.t_s
    return _cloud(ns, lidar.spec.name, packed, LIDAR_FIELDS)


def radar_cloud(ns: int, radar: RadarOutput) -> PointCloud:
    scan = radar.scan
    packed = np.zeros(len(scan), RADAR_POINT_DTYPE)
    packed["x"], packed["y"], packed["z"] = scan.xyz_radar_m.T
    packed["range"], packed["radial_velocity"] = scan.range_m, scan.radial_velocity_mps
    packed["azimuth"], packed["elevation"] = scan.azimuth_rad, scan.elevation_rad
    packed["strength"], packed["instance"], packed["class"] = scan.strength_db, scan.instance_id, scan.semantic_class
    return _cloud(ns, radar.spec.name, packed, RADAR_FIELDS)


HAZARD_RGB = (1.0, 0.0, 1.0)


def box_update(ns: int, labels: FrameLabels, signal_states: dict[int, str] | None = None) -> SceneUpdate:
    """A cube per labelled object, coloured by class (traffic lights by the state they show,
    the actors of a hazard event magenta)."""
    o = labels.objects
    states = signal_states or {}
    entities = []
    ego_R_box = o.rotations()
    for i in range(len(o)):
        cls = SemanticClass(int(o.semantic_class[i]))
        state = states.get(int(o.track_id[i]))
        r, g, b = STATE_RGB[Lamp(state)] if state is not None else CLASS_RGB.get(cls, (0.8, 0.8, 0.8))
        event = labels.hazard_event[i] if labels.hazard_event else ""
        if event:
            r, g, b = HAZARD_RGB
        box_pose = pose(SE3(ego_R_box[i], o.center_ego_m[i]))
        size = Vector3(x=float(o.lwh_m[i, 0]), y=float(o.lwh_m[i, 1]), z=float(o.lwh_m[i, 2]))
        cube = CubePrimitive(pose=box_pose, size=size, color=Color(r=r, g=g, b=b, a=0.35 if labels.seen[i] else 0.08))
        metadata = {"class": cls.label, "lidar_points": str(int(labels.lidar_points[i])),
                    "parked": str(bool(o.parked[i])).lower(), "seen": str(bool(labels.seen[i])).lower()}  # fmt: skip
        if state is not None:
            metadata["state"] = state
        if event:
            metadata["hazard_event"] = event
        entities.append(SceneEntity(
            timestamp=timestamp(ns), frame_id="ego", id=str(int(o.track_id[i])), cubes=[cube],
            metadata=[KeyValuePair(key=k, value=v) for k, v in metadata.items()],
        ))  # fmt: skip
    deletion = SceneEntityDeletion(timestamp=timestamp(ns), type=SceneEntityDeletion.ALL)
    return SceneUpdate(deletions=[deletion], entities=entities)


# Map elements' colours (RGBA): dividers white or yellow, edge lines and boundaries red, crossings
# light grey, stop lines white, lane centres faint blue.
_ELEMENT_RGBA = {"edge_line": (1.0, 0.3, 0.3, 1.0), "road_boundary": (1.0, 0.1, 0.1, 1.0),
                 "stop_line": (1.0, 1.0, 1.0, 1.0), "crossing": (0.8, 0.8, 0.8, 1.0),
                 "lane_centre": (0.3, 0.5, 1.0, 0.5)}  # fmt: skip
_IDENTITY = Pose(position=Vector3(x=0.0, y=0.0, z=0.0), orientation=Quaternion(x=0.0, y=0.0, z=0.0, w=1.0))


def map_lines(ns: int, elements: list[dict[str, Any]]) -> SceneUpdate:
    """The frame's map elements as line strips in the ego frame (one entity, replaced each frame)."""
    lines = []
    for e in elements:
        if e["type"] == "lane_divider":
            rgba = (1.0, 0.85, 0.1, 1.0) if e.get("colour") == "yellow" else (1.0, 1.0, 1.0, 1.0)
        else:
            rgba = _ELEMENT_RGBA[e["type"]]
        points = [Point3(x=float(x), y=float(y), z=0.05) for x, y in e["points"]]
        colour = Color(r=rgba[0], g=rgba[1], b=rgba[2], a=rgba[3])
        thickness = 1.0 if e["type"] == "lane_centre" else 2.0
        lines.append(LinePrimitive(type=LinePrimitive.LINE_STRIP, pose=_IDENTITY, thickness=thickness,
                                   scale_invariant=True, points=points, color=colour))  # fmt: skip
    entity = SceneEntity(timestamp=timestamp(ns), frame_id="ego", id="map_vectors", lines=lines)
    deletion = SceneEntityDeletion(timestamp=timestamp(ns), type=SceneEntityDeletion.ALL)
    return SceneUpdate(deletions=[deletion], entities=[entity])


def _compressed(ns: int, frame_id: str, fmt: str, data: bytes) -> CompressedImage:
    return CompressedImage(timestamp=timestamp(ns), frame_id=frame_id, format=fmt, data=data)


def camera_messages(ns: int, camera: CameraOutput, images: FrameImages, index: int) -> dict[str, object]:
    """Shaded image (JPEG), depth (16-bit PNG, 1/256 m), instance ids (16-bit PNG), classes (8-bit PNG)
    of camera ``index`` of the frame."""
    name = camera.spec.name
    return {
        "image": _compressed(ns, name, "jpeg", images.jpeg(index, JPEG_QUALITY)),
        "depth": _compressed(ns, name, "png", images.depth_png(index, DEPTH_UNITS_PER_M)),
        "instance": _compressed(ns, name, "png", images.instance_png(index)),
        "class": _compressed(ns, name, "png", images.class_png(index)),
    }


def calibration(ns: int, camera: CameraOutput) -> CameraCalibration:
    spec, pinhole = camera.spec, camera.spec.pinhole
    return CameraCalibration(
        timestamp=timestamp(ns), frame_id=spec.name, width=spec.width_px, height=spec.height_px,
        distortion_model="plumb_bob", D=list(pinhole.distortion), K=pinhole.K.ravel().tolist(),
        R=np.eye(3).ravel().tolist(), P=pinhole.P.ravel().tolist(),
    )  # fmt: skip


def image_annotations(ns: int, labels: FrameLabels, cam: CameraLabels) -> ImageAnnotations:
    """Tight (modal) boxes of the objects visible in this camera, with their class and id."""
    points, texts = [], []
    o = labels.objects
    for i in np.flatnonzero(cam.visibility.visible_px > 0):
        r, g, b = CLASS_RGB.get(int(o.semantic_class[i]), (1.0, 1.0, 1.0))
        left, top, right, bottom = (float(v) for v in cam.visibility.modal_px[i])
        corners = [Point2(x=left, y=top), Point2(x=right, y=top), Point2(x=right, y=bottom), Point2(x=left, y=bottom)]
        points.append(PointsAnnotation(timestamp=timestamp(ns), type=PointsAnnotation.LINE_LOOP, points=corners,
                                       outline_color=Color(r=r, g=g, b=b, a=1.0), thickness=2.0))  # fmt: skip
        label = f"{SemanticClass(int(o.semantic_class[i])).label} {int(o.track_id[i])}"
        texts.append(TextAnnotation(timestamp=timestamp(ns), position=Point2(x=left, y=max(top - 2.0, 0.0)), text=label,
                                    font_size=12.0, text_color=Color(r=r, g=g, b=b, a=1.0),
                                    background_color=Color(r=0, g=0, b=0, a=0.5)))  # fmt: skip
    return ImageAnnotations(points=points, texts=texts)

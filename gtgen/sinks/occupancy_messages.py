"""Occupancy in the MCAP: ``/occupancy`` (a ``foxglove.SceneUpdate``: one cube per occupied voxel
that a sensor observed, coloured by class, in the ego frame) and each LiDAR point's scene flow
as the cloud's fields ``flow_x``, ``flow_y``, ``flow_z`` (metres to the next sweep, LiDAR axes)."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
from foxglove_schemas_protobuf.Color_pb2 import Color
from foxglove_schemas_protobuf.CubePrimitive_pb2 import CubePrimitive
from foxglove_schemas_protobuf.PackedElementField_pb2 import PackedElementField
from foxglove_schemas_protobuf.PointCloud_pb2 import PointCloud
from foxglove_schemas_protobuf.Pose_pb2 import Pose
from foxglove_schemas_protobuf.Quaternion_pb2 import Quaternion
from foxglove_schemas_protobuf.SceneEntity_pb2 import SceneEntity
from foxglove_schemas_protobuf.SceneEntityDeletion_pb2 import SceneEntityDeletion
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from foxglove_schemas_protobuf.Vector3_pb2 import Vector3

from gtgen.colours import CLASS_RGB
from gtgen.occupancy import FREE_NATIVE, OccupancyFrame
from gtgen.sinks.foxglove import LIDAR_POINT_DTYPE, timestamp
from networks.classes import SemanticClass

OCCUPANCY_TOPIC = "/occupancy"
FLOW_FIELDS = ("flow_x", "flow_y", "flow_z")
LIDAR_FLOW_DTYPE = np.dtype(LIDAR_POINT_DTYPE.descr + [(name, "<f4") for name in FLOW_FIELDS])
_FLOW_OFFSET = LIDAR_POINT_DTYPE.itemsize  # the flow fields follow the LiDAR point's fields


def with_flow(cloud: PointCloud, flow_m: npt.NDArray[np.float32]) -> PointCloud:
    """The LiDAR cloud with each point's scene flow ``(N, 3)`` as three more float32 fields."""
    points = np.frombuffer(cloud.data, LIDAR_POINT_DTYPE)
    packed = np.zeros(points.shape[0], LIDAR_FLOW_DTYPE)
    for name in LIDAR_POINT_DTYPE.names or ():
        packed[name] = points[name]
    for axis, name in enumerate(FLOW_FIELDS):
        packed[name] = flow_m[:, axis]
    fields = list(cloud.fields) + [
        PackedElementField(name=name, offset=_FLOW_OFFSET + 4 * axis, type=PackedElementField.FLOAT32)
        for axis, name in enumerate(FLOW_FIELDS)
    ]  # fmt: skip
    return PointCloud(timestamp=cloud.timestamp, frame_id=cloud.frame_id, pose=cloud.pose,
                      point_stride=LIDAR_FLOW_DTYPE.itemsize, fields=fields, data=packed.tobytes())  # fmt: skip


def occupancy_update(ns: int, occupancy: OccupancyFrame) -> SceneUpdate:
    """One entity of cubes: every occupied voxel in either mask, coloured by class."""
    grid = occupancy.grid
    shown = (occupancy.semantics_native != FREE_NATIVE) & (occupancy.mask_lidar | occupancy.mask_camera)
    flat = np.flatnonzero(shown)
    centers = grid.centers_m(flat)
    classes = occupancy.semantics_native.ravel()[flat]
    size = Vector3(x=grid.voxel_m, y=grid.voxel_m, z=grid.voxel_m)
    colours = {int(c): Color(r=r, g=g, b=b, a=1.0) for c, (r, g, b) in _rgb(np.unique(classes)).items()}
    identity = Quaternion(x=0.0, y=0.0, z=0.0, w=1.0)
    cubes = [
        CubePrimitive(pose=Pose(position=Vector3(x=x, y=y, z=z), orientation=identity), size=size, color=colours[c])
        for (x, y, z), c in zip(centers.tolist(), classes.tolist(), strict=True)
    ]  # fmt: skip
    entity = SceneEntity(timestamp=timestamp(ns), frame_id="ego", id="occupancy", cubes=cubes)
    deletion = SceneEntityDeletion(timestamp=timestamp(ns), type=SceneEntityDeletion.ALL)
    return SceneUpdate(deletions=[deletion], entities=[entity])


def _rgb(classes: npt.NDArray[np.uint8]) -> dict[int, tuple[float, float, float]]:
    out = {}
    for c in classes.tolist():
        known = c in SemanticClass._value2member_map_
        out[c] = CLASS_RGB.get(SemanticClass(c), (0.8, 0.8, 0.8)) if known else (0.8, 0.8, 0.8)
    return out

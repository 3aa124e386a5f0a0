"""Occupancy in the MCAP: ``/occupancy`` (a ``foxglove.SceneUpdate``: cubes of the occupied voxels
that a sensor observed, coloured by class, in the ego frame, a run of one class along x as one
cube) and each LiDAR point's scene flow as the cloud's fields ``flow_x``, ``flow_y``, ``flow_z``
(metres to the next sweep, LiDAR axes)."""

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
    ]
    return PointCloud(timestamp=cloud.timestamp, frame_id=cloud.frame_id, pose=cloud.pose,
                      point_stride=LIDAR_FLOW_DTYPE.itemsize, fields=fields, data=packed.tobytes())  # fmt: skip


def occupancy_update(ns: int, occupancy: OccupancyFrame) -> SceneUpdate:
    """One entity of cubes: the occupied voxels that either mask observed, coloured by class; each
    run of neighbouring voxels of one class along x is one long cube."""
    grid = occupancy.grid
    shown = (occupancy.semantics_native != FREE_NATIVE) & (occupancy.mask_lidar | occupancy.mask_camera)
    classes = np.where(shown, occupancy.semantics_native, FREE_NATIVE)
    x0, length, j, k, cls = runs_along_x(classes)
    keep = cls != FREE_NATIVE
    x0, length, j, k, cls = x0[keep], length[keep], j[keep], k[keep], cls[keep]
    lower, v = grid.lower_m, grid.voxel_m
    x = lower[0] + (x0 + length / 2.0) * v
    y, z = lower[1] + (j + 0.5) * v, lower[2] + (k + 0.5) * v
    colours = {c: Color(r=r, g=g, b=b, a=1.0) for c, (r, g, b) in _rgb(np.unique(cls)).items()}
    identity = Quaternion(x=0.0, y=0.0, z=0.0, w=1.0)
    cubes = [
        CubePrimitive(pose=Pose(position=Vector3(x=px, y=py, z=pz), orientation=identity),
                      size=Vector3(x=n * v, y=v, z=v), color=colours[c])
        for px, py, pz, n, c in zip(x.tolist(), y.tolist(), z.tolist(), length.tolist(), cls.tolist(), strict=True)
    ]  # fmt: skip
    entity = SceneEntity(timestamp=timestamp(ns), frame_id="ego", id="occupancy", cubes=cubes)
    deletion = SceneEntityDeletion(timestamp=timestamp(ns), type=SceneEntityDeletion.ALL)
    return SceneUpdate(deletions=[deletion], entities=[entity])


def runs_along_x(
    classes: npt.NDArray[np.uint8],
) -> tuple[
    npt.NDArray[np.int64], npt.NDArray[np.int64], npt.NDArray[np.int64], npt.NDArray[np.int64], npt.NDArray[np.uint8]
]:
    """Runs of equal values along x of ``(X, Y, Z)`` classes: first x index, length, y, z, value."""
    nx = classes.shape[0]
    rows = np.moveaxis(classes, 0, -1).reshape(-1, nx)  # one row per (y, z), x along it
    start = np.ones(rows.shape, np.bool_)
    start[:, 1:] = rows[:, 1:] != rows[:, :-1]
    row, x0 = np.nonzero(start)
    flat = row * nx + x0
    length = np.diff(np.append(flat, rows.size))
    length = np.minimum(length, nx - x0)  # a run ends with its row
    j, k = np.divmod(row, classes.shape[2])
    return x0, length, j, k, rows[row, x0]


def _rgb(classes: npt.NDArray[np.uint8]) -> dict[int, tuple[float, float, float]]:
    out = {}
    for c in classes.tolist():
        known = c in SemanticClass._value2member_map_
        out[c] = CLASS_RGB.get(SemanticClass(c), (0.8, 0.8, 0.8)) if known else (0.8, 0.8, 0.8)
    return out

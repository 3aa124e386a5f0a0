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
    values = np.zeros((len(cls), len(_CUBE_FIELDS)), np.float64)
    values[:, 0] = lower[0] + (x0 + length / 2.0) * v  # pose.position
    values[:, 1] = lower[1] + (j + 0.5) * v
    values[:, 2] = lower[2] + (k + 0.5) * v
    values[:, 6] = 1.0  # pose.orientation: the identity (x, y, z 0, w 1)
    values[:, 7], values[:, 8], values[:, 9] = length * v, v, v  # size
    palette = _rgb(np.unique(cls))
    rgba = np.ones((256, 4), np.float64)
    for c, rgb in palette.items():
        rgba[c, :3] = rgb
    values[:, 10:14] = rgba[cls]  # color
    header = SceneEntity(timestamp=timestamp(ns), frame_id="ego", id="occupancy").SerializeToString()
    entity = SceneEntity.FromString(header + cubes_bytes(values))
    deletion = SceneEntityDeletion(timestamp=timestamp(ns), type=SceneEntityDeletion.ALL)
    return SceneUpdate(deletions=[deletion], entities=[entity])


_CUBE_FIELDS = (
    "pose.position.x", "pose.position.y", "pose.position.z", "pose.orientation.x", "pose.orientation.y",
    "pose.orientation.z", "pose.orientation.w", "size.x", "size.y", "size.z", "color.r", "color.g", "color.b",
    "color.a",
)  # fmt: skip


def _cube_layout() -> tuple[npt.NDArray[np.uint8], npt.NDArray[np.intp]]:
    """One ``SceneEntity.cubes`` entry as protobuf encodes it with every field of the cube set
    (then each double is in the bytes at a fixed offset), and the offsets of the doubles in
    :data:`_CUBE_FIELDS` order. Found by encoding a cube of distinct marker values."""
    marks = [1.0e300 + 1.0e285 * n for n in range(len(_CUBE_FIELDS))]
    cube = CubePrimitive(
        pose=Pose(position=Vector3(x=marks[0], y=marks[1], z=marks[2]),
                  orientation=Quaternion(x=marks[3], y=marks[4], z=marks[5], w=marks[6])),
        size=Vector3(x=marks[7], y=marks[8], z=marks[9]),
        color=Color(r=marks[10], g=marks[11], b=marks[12], a=marks[13]),
    )  # fmt: skip
    entry = SceneEntity(cubes=[cube]).SerializeToString()
    offsets = [entry.find(np.float64(m).tobytes()) for m in marks]
    if min(offsets) < 0 or len(set(offsets)) != len(marks):
        raise RuntimeError("the protobuf encoding of CubePrimitive has no fixed place for each field")
    return np.frombuffer(entry, np.uint8), np.asarray(offsets, np.intp)


_CUBE_ENTRY, _CUBE_OFFSETS = _cube_layout()


def cubes_bytes(values: npt.NDArray[np.float64]) -> bytes:
    """``SceneEntity.cubes`` entries, encoded, for ``(N, 14)`` values in :data:`_CUBE_FIELDS`
    order: what protobuf writes for the same cubes (zeros written out, which it would leave out;
    both read back the same), made by array operations instead of one message per cube."""
    rows = np.tile(_CUBE_ENTRY, (len(values), 1))
    cells = np.ascontiguousarray(values, "<f8").view(np.uint8).reshape(len(values), len(_CUBE_FIELDS), 8)
    for field, at in enumerate(_CUBE_OFFSETS.tolist()):
        rows[:, at : at + 8] = cells[:, field]
    return rows.tobytes()


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

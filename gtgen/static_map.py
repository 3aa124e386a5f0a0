"""The static world as one Foxglove scene update (written once, in the map frame)."""

from __future__ import annotations

import numpy as np
from foxglove_schemas_protobuf.Color_pb2 import Color
from foxglove_schemas_protobuf.Point3_pb2 import Point3
from foxglove_schemas_protobuf.Pose_pb2 import Pose
from foxglove_schemas_protobuf.Quaternion_pb2 import Quaternion
from foxglove_schemas_protobuf.SceneEntity_pb2 import SceneEntity
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from foxglove_schemas_protobuf.TriangleListPrimitive_pb2 import TriangleListPrimitive
from foxglove_schemas_protobuf.Vector3_pb2 import Vector3
from google.protobuf.timestamp_pb2 import Timestamp

from networks.classes import SemanticClass
from networks.mesh import ClassedMesh

MAP_RGBA: dict[SemanticClass, tuple[float, float, float, float]] = {
    SemanticClass.ROAD: (0.35, 0.35, 0.38, 1.0),
    SemanticClass.CROSSING: (0.4, 0.4, 0.43, 1.0),
    SemanticClass.SIDEWALK: (0.62, 0.6, 0.58, 1.0),
    SemanticClass.CURB: (0.75, 0.75, 0.75, 1.0),
    SemanticClass.BUILDING: (0.72, 0.6, 0.5, 0.9),
    SemanticClass.VEGETATION: (0.25, 0.55, 0.25, 1.0),
    SemanticClass.POLE: (0.6, 0.6, 0.65, 1.0),
    SemanticClass.TERRAIN: (0.3, 0.4, 0.28, 1.0),
    SemanticClass.LANE_MARKING: (0.95, 0.95, 0.95, 1.0),
    SemanticClass.LANE_MARKING_YELLOW: (0.95, 0.8, 0.1, 1.0),
    SemanticClass.TRAFFIC_LIGHT: (0.15, 0.15, 0.15, 1.0),
    SemanticClass.TRAFFIC_SIGN: (0.85, 0.85, 0.85, 1.0),
    SemanticClass.FENCE: (0.7, 0.7, 0.72, 1.0),
    SemanticClass.OTHER_OBJECT: (0.5, 0.35, 0.25, 1.0),
    SemanticClass.TRUNK: (0.45, 0.33, 0.22, 1.0),
    SemanticClass.PARKING: (0.4, 0.38, 0.43, 1.0),
}


def static_map_update(mesh: ClassedMesh, timestamp_ns: int) -> SceneUpdate:
    """One entity ``static_map`` with a triangle list per class (shared, indexed vertices)."""
    stamp = Timestamp(seconds=timestamp_ns // 1_000_000_000, nanos=timestamp_ns % 1_000_000_000)
    identity = Pose(position=Vector3(x=0.0, y=0.0, z=0.0), orientation=Quaternion(x=0.0, y=0.0, z=0.0, w=1.0))
    primitives = []
    for cls, (r, g, b, a) in MAP_RGBA.items():
        tris = mesh.triangles[mesh.triangle_class == cls]
        if tris.shape[0] == 0:
            continue
        used, local = np.unique(tris.ravel(), return_inverse=True)
        points = [Point3(x=float(x), y=float(y), z=float(z)) for x, y, z in mesh.vertices_m[used].tolist()]
        primitives.append(TriangleListPrimitive(pose=identity, points=points, color=Color(r=r, g=g, b=b, a=a),
                                                indices=local.astype(np.uint32).tolist()))  # fmt: skip
    entity = SceneEntity(timestamp=stamp, frame_id="map", id="static_map", frame_locked=True, triangles=primitives)
    return SceneUpdate(entities=[entity])

import numpy as np
from foxglove_schemas_protobuf.Color_pb2 import Color
from foxglove_schemas_protobuf.CubePrimitive_pb2 import CubePrimitive
from foxglove_schemas_protobuf.Pose_pb2 import Pose
from foxglove_schemas_protobuf.Quaternion_pb2 import Quaternion
from foxglove_schemas_protobuf.SceneEntity_pb2 import SceneEntity
from foxglove_schemas_protobuf.Vector3_pb2 import Vector3

from gtgen.sinks.occupancy_messages import cubes_bytes


def test_cubes_encoded_by_arrays_read_back_as_the_cubes_protobuf_makes() -> None:
    rng = np.random.default_rng(5)
    values = rng.normal(scale=30.0, size=(200, 14))
    values[rng.random(values.shape) < 0.2] = 0.0  # zeros, which protobuf itself leaves out
    values[0, 0] = -0.0
    expected = SceneEntity(
        cubes=[
            CubePrimitive(
                pose=Pose(
                    position=Vector3(x=v[0], y=v[1], z=v[2]), orientation=Quaternion(x=v[3], y=v[4], z=v[5], w=v[6])
                ),
                size=Vector3(x=v[7], y=v[8], z=v[9]),
                color=Color(r=v[10], g=v[11], b=v[12], a=v[13]),
            )
            for v in values.tolist()
        ]
    )
    got = SceneEntity.FromString(cubes_bytes(values))
    assert got == expected
    assert got.SerializeToString() == expected.SerializeToString()
    assert cubes_bytes(np.zeros((0, 14))) == b""

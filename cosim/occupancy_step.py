"""The frame loop's occupancy step: the frame's occupancy from the static world near the ego, every
agent of the frame, the LiDAR sweeps and the cameras' rays (each camera's own
depth image read at the grid's resolution)."""

from __future__ import annotations

from cosim.state import WorldState
from gtgen.occupancy import OccupancyFrame, camera_distances_m, occupancy_frame, prepare_camera
from gtgen.voxels import OccupancyGrid
from networks.mesh import ClassedMesh
from sensors.camera import CameraOutput, CameraSpec
from sensors.engine import Scene
from sensors.lidar import LidarOutput
from sensors.sensor import SensorOutput
from sensors.solids import Solids


class OccupancyStep:
    """Makes each frame's :class:`~gtgen.occupancy.OccupancyFrame` on ``grid`` (keeps the solids
    of the whole static world ``world``; prepares the rig's ``cameras``' voxel walks, which are
    the same every frame, before the first frame)."""

    def __init__(self, grid: OccupancyGrid, world: ClassedMesh, cameras: tuple[CameraSpec, ...] = ()) -> None:
        self.grid = grid
        self._solids = Solids(world)
        for camera in cameras:
            prepare_camera(grid, camera)

    def frame(
        self, static: ClassedMesh, scene: Scene, state: WorldState, outputs: tuple[SensorOutput, ...]
    ) -> OccupancyFrame:
        map_SE3_ego = state.ego.map_SE3_ego()
        cameras = tuple(
            (o.spec, camera_distances_m(self.grid, o.spec, o.frame.depth_m))
            for o in outputs
            if isinstance(o, CameraOutput)
        )  # each camera's reach read from its own depth image at the grid's resolution
        lidars = tuple(o for o in outputs if isinstance(o, LidarOutput))
        return occupancy_frame(self.grid, static, self._solids, state.agents, map_SE3_ego, state.ego.velocity_map_mps,
                               lidars, cameras, scene.agent_meshes,
                               state.ego.turn_rates()[1], state.ego)  # fmt: skip

"""The objects gtgen labels: the frame's agents seen from the ego, boxes in the ego frame,
one row per object (struct of arrays)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from networks.geometry import rotations_from_rpy, rpy_from_rotations
from networks.records import check_arrays
from sensors.agents import NO_LAMPS, Agents, EgoState

EXPORT_MARGIN_M = 0.015
"""The KITTI and nuScenes exports write each box this much longer at the front and back and
wider on each side, and lifted by it off the road (its height kept: agents' meshes stand
:data:`sensors.agents.AGENT_LIFT_M` above their box's bottom). A body's surface may touch its
box, and once the points are stored as float32 a strict point-in-box test (the nuScenes
devkit's ``points_in_box``, OpenPCDet's ``points_in_boxes_cpu``) puts about half of the points
on a face outside; with the margin it finds exactly the object's LiDAR points, and none of the
road's."""


@dataclass(frozen=True, slots=True)
class ObjectBoxes:
    """Objects around the ego, in the ego frame.

    ``track_id: (N,) uint32`` stable over a scene and equal to the sensors' instance id;
    ``semantic_class: (N,) uint8`` (:class:`networks.classes.SemanticClass`, from the simulator);
    ``center_ego_m: (N, 3) float64`` box centres; ``lwh_m: (N, 3) float64``;
    ``yaw_ego_rad``, ``pitch_ego_rad``, ``roll_ego_rad: (N,) float64`` the box's orientation in
    the ego frame, ``ego_R_box = Rz(yaw) @ Ry(pitch) @ Rx(roll)`` (a vehicle on a slope the ego
    is not on is pitched; seen from a pitched ego, a vehicle heading across it is rolled);
    ``velocity_ego_mps: (N, 3) float64`` the object's velocity minus the ego's, expressed in the
    ego frame; ``parked: (N,) bool``; ``lamps: (N,) uint8`` the lamps lit
    (:class:`sensors.agents.Lamp` bits; all off where not given).
    """

    track_id: npt.NDArray[np.uint32]
    semantic_class: npt.NDArray[np.uint8]
    center_ego_m: npt.NDArray[np.float64]
    lwh_m: npt.NDArray[np.float64]
    yaw_ego_rad: npt.NDArray[np.float64]
    pitch_ego_rad: npt.NDArray[np.float64]
    roll_ego_rad: npt.NDArray[np.float64]
    velocity_ego_mps: npt.NDArray[np.float64]
    parked: npt.NDArray[np.bool_]
    lamps: npt.NDArray[np.uint8] = field(default_factory=lambda: NO_LAMPS)

    def __post_init__(self) -> None:
        if self.lamps is NO_LAMPS:
            object.__setattr__(self, "lamps", np.zeros(np.shape(self.track_id)[0], np.uint8))
        check_arrays(
            self, track_id=(np.uint32, ("N",)), semantic_class=(np.uint8, ("N",)), center_ego_m=(np.float64, ("N", 3)),
            lwh_m=(np.float64, ("N", 3)), yaw_ego_rad=(np.float64, ("N",)), pitch_ego_rad=(np.float64, ("N",)),
            roll_ego_rad=(np.float64, ("N",)), velocity_ego_mps=(np.float64, ("N", 3)), parked=(np.bool_, ("N",)),
            lamps=(np.uint8, ("N",)),
        )  # fmt: skip

    def footprints_xy(self) -> npt.NDArray[np.float64]:
        """``(N, 4, 2)`` each box's footprint corners in the ego frame: front-left, front-right,
        rear-right, rear-left."""
        c, s = np.cos(self.yaw_ego_rad), np.sin(self.yaw_ego_rad)
        hl, hw = self.lwh_m[:, 0] / 2, self.lwh_m[:, 1] / 2
        local = np.stack(
            [np.stack([hl, hw], 1), np.stack([hl, -hw], 1), np.stack([-hl, -hw], 1), np.stack([-hl, hw], 1)], 1
        )
        x = local[..., 0] * c[:, None] - local[..., 1] * s[:, None]
        y = local[..., 0] * s[:, None] + local[..., 1] * c[:, None]
        return np.stack([x, y], -1) + self.center_ego_m[:, None, :2]

    @classmethod
    def seen_from(cls, ego: EgoState, agents: Agents) -> ObjectBoxes:
        """The agents as the ego sees them: boxes in its frame (their whole orientation relative
        to the ego's), velocities relative to it."""
        ego_SE3_map = ego.map_SE3_ego().inverse()
        roll, pitch, yaw = rpy_from_rotations(ego_SE3_map.rotation @ agents.rotations())
        return cls(
            agents.instance_id, agents.semantic_class, ego_SE3_map.transform_from(agents.center_map_m), agents.lwh_m,
            yaw, pitch, roll, ego_SE3_map.rotate(agents.velocity_map_mps - ego.velocity_map_mps), agents.parked,
            agents.lamps,
        )  # fmt: skip

    def rotations(self) -> npt.NDArray[np.float64]:
        """``(N, 3, 3)`` ego_R_box."""
        return rotations_from_rpy(self.roll_ego_rad, self.pitch_ego_rad, self.yaw_ego_rad)

    def upright_lwh_m(self) -> npt.NDArray[np.float64]:
        """``(N, 3)`` length, width, height of the smallest box turned by yaw only (about the
        ego's z, at the same centre) that holds the box: the box of formats without pitch and
        roll (KITTI). Equal to ``lwh_m`` for a box level with the ego."""
        within_yaw = rotations_from_rpy(self.roll_ego_rad, self.pitch_ego_rad, np.zeros(len(self)))
        return np.asarray(np.einsum("nij,nj->ni", np.abs(within_yaw), self.lwh_m))

    def __len__(self) -> int:
        return int(self.track_id.shape[0])

    def select(self, mask: npt.NDArray[np.bool_] | npt.NDArray[np.intp]) -> ObjectBoxes:
        return ObjectBoxes(
            self.track_id[mask],
            self.semantic_class[mask],
            self.center_ego_m[mask],
            self.lwh_m[mask],
            self.yaw_ego_rad[mask],
            self.pitch_ego_rad[mask],
            self.roll_ego_rad[mask],
            self.velocity_ego_mps[mask],
            self.parked[mask],
            self.lamps[mask],
        )


def points_in_boxes(
    xyz_ego_m: npt.NDArray[np.floating], boxes: ObjectBoxes, index: npt.NDArray[np.intp], tolerance_m: float = 0.0
) -> npt.NDArray[np.bool_]:
    """Whether each point lies inside box ``index[i]`` (its whole orientation, ``tolerance_m`` slack)."""
    d = np.asarray(xyz_ego_m, dtype=np.float64) - boxes.center_ego_m[index]
    local = np.einsum("nji,nj->ni", boxes.rotations()[index], d)  # box_R_ego @ d
    return np.asarray(np.all(np.abs(local) <= boxes.lwh_m[index] / 2.0 + tolerance_m, axis=1))

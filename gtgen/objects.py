"""The objects gtgen labels: boxes in the ego frame, one row per object (struct of arrays)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt


@dataclass(frozen=True, slots=True)
class ObjectBoxes:
    """Objects around the ego, in the ego frame.

    ``track_id: (N,) uint32`` stable over a scene and equal to the sensors' instance id;
    ``semantic_class: (N,) uint8`` (:class:`networks.classes.SemanticClass`, from the simulator);
    ``center_ego_m: (N, 3) float64`` box centres; ``lwh_m: (N, 3) float64``;
    ``yaw_ego_rad: (N,) float64`` about the ego's +z; ``velocity_ego_mps: (N, 3) float64``
    the object's velocity minus the ego's, expressed in the ego frame; ``parked: (N,) bool``.
    """

    track_id: npt.NDArray[np.uint32]
    semantic_class: npt.NDArray[np.uint8]
    center_ego_m: npt.NDArray[np.float64]
    lwh_m: npt.NDArray[np.float64]
    yaw_ego_rad: npt.NDArray[np.float64]
    velocity_ego_mps: npt.NDArray[np.float64]
    parked: npt.NDArray[np.bool_]

    def __post_init__(self) -> None:
        n = np.asarray(self.track_id).shape[0]
        spec = {
            "track_id": (np.uint32, (n,)),
            "semantic_class": (np.uint8, (n,)),
            "center_ego_m": (np.float64, (n, 3)),
            "lwh_m": (np.float64, (n, 3)),
            "yaw_ego_rad": (np.float64, (n,)),
            "velocity_ego_mps": (np.float64, (n, 3)),
            "parked": (np.bool_, (n,)),
        }
        for name, (dtype, shape) in spec.items():
            object.__setattr__(self, name, np.asarray(getattr(self, name), dtype=dtype).reshape(shape))

    def __len__(self) -> int:
        return int(self.track_id.shape[0])

    def select(self, mask: npt.NDArray[np.bool_] | npt.NDArray[np.intp]) -> ObjectBoxes:
        return ObjectBoxes(
            self.track_id[mask],
            self.semantic_class[mask],
            self.center_ego_m[mask],
            self.lwh_m[mask],
            self.yaw_ego_rad[mask],
            self.velocity_ego_mps[mask],
            self.parked[mask],
        )


def points_in_boxes(
    xyz_ego_m: npt.NDArray[np.floating], boxes: ObjectBoxes, index: npt.NDArray[np.intp], tolerance_m: float = 0.0
) -> npt.NDArray[np.bool_]:
    """Whether each point lies inside box ``index[i]`` (yaw-only boxes, ``tolerance_m`` slack)."""
    d = np.asarray(xyz_ego_m, dtype=np.float64) - boxes.center_ego_m[index]
    c, s = np.cos(boxes.yaw_ego_rad[index]), np.sin(boxes.yaw_ego_rad[index])
    local = np.stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1], d[:, 2]], axis=1)
    return np.all(np.abs(local) <= boxes.lwh_m[index] / 2.0 + tolerance_m, axis=1)

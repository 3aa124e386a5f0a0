"""Agents as posed boxes (struct of arrays) and their meshes, one instance id each."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from networks.classes import SemanticClass
from networks.geometry import yaw_to_rotation
from networks.mesh import BOX_TRIANGLES, ClassedMesh


@dataclass(frozen=True, slots=True)
class AgentBoxes:
    """Posed agents in the map frame.

    ``instance_id: (N,) uint32`` (> 0), ``semantic_class: (N,) uint8``,
    ``center_map_m: (N, 3) float64`` box centres, ``lwh_m: (N, 3) float64``,
    ``yaw_map_rad: (N,) float64`` about +z, ``pitch_rad: (N,) float64`` nose-up positive.
    """

    instance_id: npt.NDArray[np.uint32]
    semantic_class: npt.NDArray[np.uint8]
    center_map_m: npt.NDArray[np.float64]
    lwh_m: npt.NDArray[np.float64]
    yaw_map_rad: npt.NDArray[np.float64]
    pitch_rad: npt.NDArray[np.float64]

    def __post_init__(self) -> None:
        n = np.asarray(self.instance_id).shape[0]
        fields = {
            "instance_id": (np.uint32, (n,)),
            "semantic_class": (np.uint8, (n,)),
            "center_map_m": (np.float64, (n, 3)),
            "lwh_m": (np.float64, (n, 3)),
            "yaw_map_rad": (np.float64, (n,)),
            "pitch_rad": (np.float64, (n,)),
        }
        for name, (dtype, shape) in fields.items():
            value = np.asarray(getattr(self, name), dtype=dtype).reshape(shape)
            object.__setattr__(self, name, value)
        if n and int(self.instance_id.min()) == 0:
            raise ValueError("AgentBoxes: instance id 0 is reserved for the static world")

    def __len__(self) -> int:
        return int(self.instance_id.shape[0])

    @classmethod
    def empty(cls) -> AgentBoxes:
        z = np.zeros(0)
        return cls(np.zeros(0, np.uint32), np.zeros(0, np.uint8), np.zeros((0, 3)), np.zeros((0, 3)), z, z)

    def select(self, mask: npt.NDArray[np.bool_]) -> AgentBoxes:
        return AgentBoxes(
            self.instance_id[mask],
            self.semantic_class[mask],
            self.center_map_m[mask],
            self.lwh_m[mask],
            self.yaw_map_rad[mask],
            self.pitch_rad[mask],
        )

    def rotations(self) -> npt.NDArray[np.float64]:
        """``(N, 3, 3)`` map_R_box: yaw about +z after pitch about the box's y axis."""
        rz = yaw_to_rotation(self.yaw_map_rad)
        cp, sp = np.cos(self.pitch_rad), np.sin(self.pitch_rad)
        ry = np.zeros_like(rz)
        ry[:, 0, 0], ry[:, 0, 2], ry[:, 1, 1], ry[:, 2, 0], ry[:, 2, 2] = cp, -sp, 1.0, sp, cp
        return rz @ ry


@dataclass(frozen=True, slots=True)
class AgentMeshes:
    """All agents merged into one mesh; ``triangle_instance: (M,) uint32`` and
    ``triangle_class: (M,) uint8`` tell which agent each triangle belongs to."""

    vertices_m: npt.NDArray[np.float32]
    triangles: npt.NDArray[np.int32]
    triangle_instance: npt.NDArray[np.uint32]
    triangle_class: npt.NDArray[np.uint8]


_UNIT_CORNERS = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=np.float64) / 2.0
_BOX_TRIS = np.asarray(BOX_TRIANGLES, dtype=np.int32)


def box_corners_map(agents: AgentBoxes) -> npt.NDArray[np.float64]:
    """``(N, 8, 3)`` corners of each agent's box in the map frame."""
    local = _UNIT_CORNERS[None, :, :] * agents.lwh_m[:, None, :]
    return np.einsum("nij,nkj->nki", agents.rotations(), local) + agents.center_map_m[:, None, :]


def agent_meshes(agents: AgentBoxes) -> AgentMeshes:
    """One closed box mesh per agent, scaled to its l/w/h and posed."""
    n = len(agents)
    verts = box_corners_map(agents).reshape(-1, 3)
    tris = (_BOX_TRIS[None, :, :] + 8 * np.arange(n, dtype=np.int32)[:, None, None]).reshape(-1, 3)
    return AgentMeshes(
        verts.astype(np.float32),
        tris,
        np.repeat(agents.instance_id, 12),
        np.repeat(agents.semantic_class, 12),
    )


def as_classed_mesh(meshes: AgentMeshes) -> ClassedMesh:
    return ClassedMesh(meshes.vertices_m, meshes.triangles, meshes.triangle_class)


AGENT_CLASS_NAMES = {c.value: c.label for c in SemanticClass if c.is_agent}

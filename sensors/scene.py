"""The one Open3D raycasting scene of a frame: static world plus posed agents.

Open3D scenes have no transforms or instancing, so a frame's scene is rebuilt from
the static mesh near the ego (cropped once per few metres of travel) and one merged
mesh of all agents. Every hit carries the class and instance id of its triangle.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from networks.mesh import ClassedMesh
from sensors.agents import AgentMeshes
from sensors.o3d import INVALID_ID, RaycastingScene, o3c


@dataclass(frozen=True, slots=True)
class RayHits:
    """Per ray: ``range_m: (N,) float32`` (inf where nothing was hit),
    ``semantic_class: (N,) uint8``, ``instance_id: (N,) uint32`` (0: static world),
    ``normal: (N, 3) float32`` unit surface normals in the rays' frame."""

    range_m: npt.NDArray[np.float32]
    semantic_class: npt.NDArray[np.uint8]
    instance_id: npt.NDArray[np.uint32]
    normal: npt.NDArray[np.float32]

    @property
    def hit(self) -> npt.NDArray[np.bool_]:
        return np.isfinite(self.range_m)


class StaticCrop:
    """Keeps the part of the static mesh within ``radius_m`` of a moving centre;
    recrops when the centre has moved more than ``slack_m``."""

    def __init__(self, mesh: ClassedMesh, radius_m: float, slack_m: float = 20.0) -> None:
        self._mesh = mesh
        tri = mesh.vertices_m[mesh.triangles]
        self._centroid_xy = tri[:, :, :2].mean(axis=1)
        self._tri_radius = np.linalg.norm(tri[:, :, :2] - self._centroid_xy[:, None, :], axis=2).max(axis=1)
        self._radius = radius_m
        self._slack = slack_m
        self._center: npt.NDArray[np.float64] | None = None
        self._crop = mesh

    def around(self, center_xy_m: npt.ArrayLike) -> ClassedMesh:
        c = np.asarray(center_xy_m, dtype=np.float64)[:2]
        if self._center is not None and np.linalg.norm(c - self._center) <= self._slack:
            return self._crop
        reach = self._radius + self._slack + self._tri_radius
        keep = np.linalg.norm(self._centroid_xy - c, axis=1) <= reach
        self._center = c
        self._crop = ClassedMesh(self._mesh.vertices_m, self._mesh.triangles[keep], self._mesh.triangle_class[keep])
        return self._crop


class FrameScene:
    """One frame's raycasting scene. Rays are ``(N, 6) float32``: origin, unit direction."""

    def __init__(self, static: ClassedMesh, agents: AgentMeshes, nthreads: int = 0) -> None:
        self._scene = RaycastingScene()
        self._nthreads = nthreads
        self._static_class = static.triangle_class
        self._agent_class = agents.triangle_class
        self._agent_instance = agents.triangle_instance
        self._static_id = self._add(static.vertices_m, static.triangles)
        self._agent_id = self._add(agents.vertices_m, agents.triangles)

    def _add(self, vertices: npt.NDArray[np.floating[Any]], triangles: npt.NDArray[np.integer[Any]]) -> int:
        if triangles.shape[0] == 0:
            return -1
        v = o3c.Tensor.from_numpy(np.ascontiguousarray(vertices, dtype=np.float32))
        t = o3c.Tensor.from_numpy(np.ascontiguousarray(triangles, dtype=np.uint32))
        return int(self._scene.add_triangles(v, t))

    def agent_hits(self, rays: npt.NDArray[np.float32]) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.uint32]]:
        """Every intersection of the rays with agents, not only the nearest: ``(ray index,
        instance id)`` pairs. Used to render an object's silhouette as if it were alone."""
        if self._agent_id < 0 or rays.shape[0] == 0:
            return np.zeros(0, np.int64), np.zeros(0, np.uint32)
        result = self._scene.list_intersections(o3c.Tensor.from_numpy(np.ascontiguousarray(rays, dtype=np.float32)),
                                                nthreads=self._nthreads)  # fmt: skip
        ray_ids = result["ray_ids"].numpy().astype(np.int64)
        geometry = result["geometry_ids"].numpy().astype(np.int64)
        primitive = result["primitive_ids"].numpy().astype(np.int64)
        on_agent = geometry == self._agent_id
        return ray_ids[on_agent], self._agent_instance[primitive[on_agent]]

    def cast(self, rays: npt.NDArray[np.float32]) -> RayHits:
        result = self._scene.cast_rays(o3c.Tensor.from_numpy(np.ascontiguousarray(rays, dtype=np.float32)),
                                       nthreads=self._nthreads)  # fmt: skip
        t_hit = result["t_hit"].numpy()
        geometry = result["geometry_ids"].numpy().astype(np.int64)
        primitive = result["primitive_ids"].numpy().astype(np.int64)
        normal = result["primitive_normals"].numpy()
        n = t_hit.shape[0]
        cls = np.zeros(n, np.uint8)
        inst = np.zeros(n, np.uint32)
        on_static = geometry == self._static_id
        on_agent = geometry == self._agent_id
        cls[on_static] = self._static_class[primitive[on_static]]
        cls[on_agent] = self._agent_class[primitive[on_agent]]
        inst[on_agent] = self._agent_instance[primitive[on_agent]]
        missed = geometry == INVALID_ID
        t_hit = np.where(missed, np.inf, t_hit).astype(np.float32)
        return RayHits(t_hit, cls, inst, normal.astype(np.float32))

"""The fast ray engine: Mitsuba 3's scenes traced with Dr.Jit's LLVM backend (Embree's packet
kernels, coherent rays), the only module that imports them.

The static world near the ego is one Mitsuba scene, made again only when the crop changes; the
agents are a second scene whose one merged mesh is replaced every frame. A ray is cast in both and the
nearer hit wins. Per hit the scenes give the triangle: its class, instance and face normal come
from tables, as in the Open3D engine. A sensor's ray directions are handed to Dr.Jit once and
turned into the map frame on its side. Importing this module raises ImportError, or
RuntimeError/OSError from Dr.Jit, when the engine cannot start (no libLLVM 15 or newer).
"""

from __future__ import annotations

import os
from typing import Any

import cv2
import numpy as np
import numpy.typing as npt
from numba import njit

from networks.cache import cache_root

# Dr.Jit keeps compiled kernels on disk: in this project's cache, not in ~/.drjit.
os.environ.setdefault("DRJIT_CACHE_DIR", str(cache_root() / "drjit"))
try:
    import drjit as dr
    import mitsuba as mi
except ImportError as err:  # pragma: no cover - depends on the machine
    raise ImportError(f"mitsuba and drjit are not installed ({err})") from err

mi.set_variant("llvm_ad_rgb")  # raises when Dr.Jit's LLVM backend finds no libLLVM

from networks.mesh import ClassedMesh  # noqa: E402
from sensors.agents import AgentMeshes, Agents, agent_meshes  # noqa: E402
from sensors.hits import PairHits, RayHits  # noqa: E402
from sensors.scene import _hits_alone, cast_agents_moving  # noqa: E402

_NORMAL = np.dtype((np.void, 12))  # one row of a float32 (N, 3) table, taken whole


def _face_normals(
    vertices: npt.NDArray[np.floating[Any]], triangles: npt.NDArray[np.integer[Any]]
) -> npt.NDArray[np.float32]:
    """``(T, 3)`` unit normals of the triangles (0 for degenerate ones), in float32."""
    return _unit_cross(np.ascontiguousarray(vertices, np.float32), np.ascontiguousarray(triangles, np.int64))


@njit(cache=True, nogil=True)
def _unit_cross(
    v: npt.NDArray[np.float32], triangles: npt.NDArray[np.int64]
) -> npt.NDArray[np.float32]:  # pragma: no cover - compiled
    """Per triangle the cross product of its edges from the first vertex, made unit, in numpy's
    float32 order (``np.cross``, then ``np.linalg.norm``'s squares summed left to right)."""
    out = np.empty((triangles.shape[0], 3), np.float32)
    for t in range(triangles.shape[0]):
        i, j, k = triangles[t, 0], triangles[t, 1], triangles[t, 2]
        a0, a1, a2 = v[j, 0] - v[i, 0], v[j, 1] - v[i, 1], v[j, 2] - v[i, 2]
        b0, b1, b2 = v[k, 0] - v[i, 0], v[k, 1] - v[i, 1], v[k, 2] - v[i, 2]
        n0, n1, n2 = a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0
        length = np.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
        if not length > 0:
            length = np.float32(1.0)
        out[t, 0], out[t, 1], out[t, 2] = n0 / length, n1 / length, n2 / length
    return out


class _Part:
    """One Mitsuba scene of a triangle mesh, or none for an empty one."""

    def __init__(
        self, name: str, vertices: npt.NDArray[np.floating[Any]], triangles: npt.NDArray[np.integer[Any]]
    ) -> None:
        self.triangles = int(triangles.shape[0])
        self.scene: Any = None
        if self.triangles:
            used, local = np.unique(triangles.ravel(), return_inverse=True)
            mesh = mi.Mesh(
                name, int(used.shape[0]), self.triangles, has_vertex_normals=False, has_vertex_texcoords=False
            )
            params = mi.traverse(mesh)
            params["vertex_positions"] = mi.Float(np.ascontiguousarray(vertices[used], dtype=np.float32).ravel())
            params["faces"] = mi.UInt32(local.astype(np.uint32))
            params.update()
            self.scene = mi.load_dict({"type": "scene", name: mesh})

    def cast(self, ray: Any) -> tuple[Any, Any]:
        """Distance (inf: no hit) and triangle of each ray."""
        hit = self.scene.ray_intersect_preliminary(ray, coherent=True)
        return hit.t, hit.prim_index

    def test(self, ray: Any) -> Any:
        """Whether each ray meets anything (Embree's occlusion query: no nearest hit sought)."""
        return self.scene.ray_test(ray, coherent=True)


class _AgentPart:
    """The agents' scene: one mesh whose positions and faces are replaced every frame, at
    this frame's size. The scene object stays the same, so Dr.Jit compiles the kernels that
    trace it once, and Embree builds the agents' BVH over their own triangles only."""

    def __init__(self) -> None:
        self.triangles = 0
        mesh = mi.Mesh("agents", 3, 1, has_vertex_normals=False, has_vertex_texcoords=False)
        self.scene: Any = mi.load_dict({"type": "scene", "agents": mesh})
        self._params: Any = mi.traverse(self.scene)

    def update(self, vertices: npt.NDArray[np.float32], triangles: npt.NDArray[np.int32]) -> None:
        self.triangles = int(triangles.shape[0])
        if self.triangles == 0:
            return  # the last frame's agents stay in the scene, never cast (see MitsubaScene)
        self._params["agents.vertex_positions"] = mi.Float(np.ascontiguousarray(vertices, np.float32).ravel())
        self._params["agents.faces"] = mi.UInt32(np.ascontiguousarray(triangles, np.uint32).ravel())
        self._params.update()

    def cast(self, ray: Any) -> tuple[Any, Any]:
        hit = self.scene.ray_intersect_preliminary(ray, coherent=True)
        return hit.t, hit.prim_index

    def test(self, ray: Any) -> Any:
        return self.scene.ray_test(ray, coherent=True)


class MitsubaEngine:
    name = "mitsuba"

    def __init__(self) -> None:
        self._static_mesh: ClassedMesh | None = None
        self._static: _Part | None = None
        self._static_normals = np.zeros((0, 3), np.float32)
        self.agent_part = _AgentPart()

    def scene(self, static: ClassedMesh, agents: Agents) -> MitsubaScene:
        if static is not self._static_mesh:
            self._static_mesh, self._static = static, _Part("static", static.vertices_m, static.triangles)
            self._static_normals = _face_normals(static.vertices_m, static.triangles)
        if self._static is None:
            raise RuntimeError("MitsubaEngine: no static scene")
        return MitsubaScene(self, static, self._static, agents)


class MitsubaScene:
    """One frame: the static part (kept by the engine) and this frame's agents."""

    def __init__(self, engine: MitsubaEngine, static: ClassedMesh, part: _Part, agents: Agents) -> None:
        self._engine, self._static = engine, part
        self.agents = agents
        self.agent_meshes: AgentMeshes = agent_meshes(agents)
        meshes = self.agent_meshes
        self._agents = engine.agent_part
        self._agents.update(meshes.vertices_m, meshes.triangles)
        n_static, n_agent = static.triangle_class.shape[0], meshes.triangle_class.shape[0]
        self._agent_row0, self._nothing_row = n_static, n_static + n_agent
        self._class_of_row = np.concatenate([static.triangle_class, meshes.triangle_class, [0]]).astype(np.uint8)
        self._instance_of_row = np.concatenate([np.zeros(n_static, np.uint32), meshes.triangle_instance, [0]])
        self._instance_of_row = self._instance_of_row.astype(np.uint32)
        self._part_of_row = np.concatenate([np.zeros(n_static, np.uint8), meshes.triangle_part, [0]]).astype(np.uint8)
        agent_normals = _face_normals(meshes.vertices_m, meshes.triangles)
        self._normal_of_row = np.concatenate([engine._static_normals, agent_normals, np.zeros((1, 3), np.float32)])
        self._normal_of_row = np.ascontiguousarray(self._normal_of_row).view(_NORMAL).ravel()

    def cast(self, rays: npt.NDArray[np.float32]) -> RayHits:
        columns = [mi.Float(np.ascontiguousarray(rays[:, i])) for i in range(6)]
        ray = mi.Ray3f(mi.Point3f(*columns[:3]), mi.Vector3f(*columns[3:]))
        return self._hits(ray)

    def cast_from(
        self,
        origin_map_m: npt.NDArray[np.float64],
        map_R_sensor: npt.NDArray[np.float64],
        dirs_sensor: npt.NDArray[np.float32],
    ) -> RayHits:
        """The same ray directions as the reference engine's (turned by OpenCV in float32), one origin."""
        dirs = np.asarray(cv2.transform(dirs_sensor.reshape(-1, 1, 3), np.asarray(map_R_sensor, np.float32)))
        dirs = dirs.reshape(-1, 3)
        origin = mi.Point3f(*(dr.opaque(mi.Float, float(v)) for v in np.asarray(origin_map_m, np.float32)))
        direction = mi.Vector3f(*(mi.Float(np.ascontiguousarray(dirs[:, i])) for i in range(3)))
        return self._hits(mi.Ray3f(origin, direction))

    def occluded(self, rays: npt.NDArray[np.float32]) -> npt.NDArray[np.bool_]:
        columns = [mi.Float(np.ascontiguousarray(rays[:, i])) for i in range(6)]
        ray = mi.Ray3f(mi.Point3f(*columns[:3]), mi.Vector3f(*columns[3:]))
        hit = self._static.test(ray) if self._static.triangles else dr.zeros(mi.Bool, rays.shape[0])
        if self._agents.triangles:
            hit = hit | self._agents.test(ray)
        return np.asarray(hit.numpy(), np.bool_)

    def cast_raw(self, rays: npt.NDArray[np.float32]) -> Any:
        columns = [mi.Float(np.ascontiguousarray(rays[:, i])) for i in range(6)]
        ray = mi.Ray3f(mi.Point3f(*columns[:3]), mi.Vector3f(*columns[3:]))
        t, _ = self._static.cast(ray)
        if self._agents.triangles:
            t_agent = self._agents.cast(ray)[0]
            t = dr.select(t_agent < t, t_agent, t)
        return t.numpy()  # waits for the kernel: Dr.Jit launches it in the background

    def _hits(self, ray: Any) -> RayHits:
        t, prim = self._static.cast(ray)
        row = mi.UInt32(prim)
        if self._agents.triangles:
            t_agent, prim_agent = self._agents.cast(ray)
            nearer = t_agent < t
            t = dr.select(nearer, t_agent, t)
            # opaque: the numbers change from frame to frame, the compiled kernel must not
            row = dr.select(nearer, prim_agent + dr.opaque(mi.UInt32, self._agent_row0), row)
        row = dr.select(dr.isinf(t), dr.opaque(mi.UInt32, self._nothing_row), row)
        dr.eval(t, row)
        range_m = t.numpy().astype(np.float32, copy=False)
        rows = row.numpy()
        normals = np.take(self._normal_of_row, rows).view(np.float32).reshape(-1, 3)  # 12-byte rows, taken whole
        return RayHits(range_m, np.take(self._class_of_row, rows), np.take(self._instance_of_row, rows), normals,
                       np.take(self._part_of_row, rows))  # fmt: skip

    def cast_static(self, rays: npt.NDArray[np.float32]) -> RayHits:
        """The rays cast into the static world alone (no agents)."""
        columns = [mi.Float(np.ascontiguousarray(rays[:, i])) for i in range(6)]
        t, prim = self._static.cast(mi.Ray3f(mi.Point3f(*columns[:3]), mi.Vector3f(*columns[3:])))
        row = dr.select(dr.isinf(t), dr.opaque(mi.UInt32, self._nothing_row), mi.UInt32(prim))
        dr.eval(t, row)
        rows = row.numpy()
        normals = np.take(self._normal_of_row, rows).view(np.float32).reshape(-1, 3)
        return RayHits(t.numpy().astype(np.float32, copy=False), np.take(self._class_of_row, rows),
                       np.zeros(rows.shape[0], np.uint32), normals, np.zeros(rows.shape[0], np.uint8))  # fmt: skip

    def cast_agents_moving(
        self, rays: npt.NDArray[np.float32], dt_s: npt.NDArray[np.float64], ray_index: npt.NDArray[np.intp],
        agent_index: npt.NDArray[np.intp],
    ) -> PairHits:  # fmt: skip
        return cast_agents_moving(self.agents, rays, dt_s, ray_index, agent_index)

    def hits_alone(self, rays: npt.NDArray[np.float32], instance_id: npt.NDArray[np.uint32]) -> npt.NDArray[np.bool_]:
        return _hits_alone(self.agent_meshes, rays, instance_id)

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

import hashlib
import os
from typing import Any

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
# One worker thread for Dr.Jit's kernels and Embree's builds: the loop's process shares two cores
# with the writer and the traffic, and a second worker costs more CPU than it saves (the camera's
# casts took 100 ms of CPU a frame on two threads, 74 on one, the same hits; wall time under load
# fell too, as the kernels no longer wait for a thread that another process holds off its core).
CAST_THREADS = 1
dr.set_thread_count(CAST_THREADS)

from networks.mesh import ClassedMesh  # noqa: E402
from sensors.agents import AgentMeshes, Agents, agent_meshes  # noqa: E402
from sensors.hits import PairHits, RayHits  # noqa: E402
from sensors.rays import map_directions  # noqa: E402
from sensors.scene import AloneScenes, _hits_alone, _triangle_runs, cast_agents_moving, own_mesh  # noqa: E402


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


U8 = npt.NDArray[np.uint8]


@njit(cache=True, nogil=True)
def _rows_of(
    rows: npt.NDArray[np.uint32], class_of: U8, instance_of: npt.NDArray[np.uint32], part_of: U8,
    normal_bits_of: npt.NDArray[np.uint32],
) -> tuple[U8, npt.NDArray[np.uint32], U8, npt.NDArray[np.uint32]]:  # fmt: skip  # pragma: no cover - compiled
    """Per ray its row's class, instance, part and normal (the normal's float32 bits, copied as
    they are), in one pass over the rays."""
    n = rows.shape[0]
    cls = np.empty(n, np.uint8)
    instance = np.empty(n, np.uint32)
    part = np.empty(n, np.uint8)
    normal = np.empty((n, 3), np.uint32)
    for i in range(n):
        r = rows[i]
        cls[i] = class_of[r]
        instance[i] = instance_of[r]
        part[i] = part_of[r]
        normal[i, 0] = normal_bits_of[r, 0]
        normal[i, 1] = normal_bits_of[r, 1]
        normal[i, 2] = normal_bits_of[r, 2]
    return cls, instance, part, normal


def _rays(rays: npt.NDArray[np.float32]) -> Any:
    """Dr.Jit's rays of ``(N, 6) float32`` rays (origin, direction); columns that are already
    contiguous (a transposed ``(6, N)`` array) are handed over as they are, rows are handed
    over whole and gathered column by column in the kernel that casts them."""
    if rays.dtype == np.float32 and rays.flags.f_contiguous:
        columns = rays.T
        floats = [mi.Float(columns[i]) for i in range(6)]
    else:
        flat = mi.Float(np.ascontiguousarray(rays, np.float32).ravel())
        row = dr.arange(mi.UInt32, rays.shape[0]) * 6
        floats = [dr.gather(mi.Float, flat, row + k) for k in range(6)]
    return mi.Ray3f(mi.Point3f(*floats[:3]), mi.Vector3f(*floats[3:]))


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
    """An agents' scene: one mesh whose positions and faces are replaced when asked, at the new
    size. The scene object stays the same, so Dr.Jit compiles the kernels that trace it once,
    and Embree builds the BVH over these triangles only."""

    def __init__(self, name: str = "agents") -> None:
        self.triangles = 0
        self._name = name
        mesh = mi.Mesh(name, 3, 1, has_vertex_normals=False, has_vertex_texcoords=False)
        self.scene: Any = mi.load_dict({"type": "scene", name: mesh})
        self._params: Any = mi.traverse(self.scene)

    def update(self, vertices: npt.NDArray[np.float32], triangles: npt.NDArray[np.int32]) -> None:
        self.triangles = int(triangles.shape[0])
        if self.triangles == 0:
            return  # the last agents stay in the scene, never cast (see MitsubaScene)
        self._params[f"{self._name}.vertex_positions"] = mi.Float(np.ascontiguousarray(vertices, np.float32).ravel())
        self._params[f"{self._name}.faces"] = mi.UInt32(np.ascontiguousarray(triangles, np.uint32).ravel())
        self._params.update()

    def cast(self, ray: Any) -> tuple[Any, Any]:
        hit = self.scene.ray_intersect_preliminary(ray, coherent=True)
        return hit.t, hit.prim_index

    def test(self, ray: Any) -> Any:
        return self.scene.ray_test(ray, coherent=True)


STILL_GROWTH = 0.25
"""The kept scene of standing agents is made again when agents that stood since the last frame
outside it hold this share of its triangles (or when one of its agents moved or left)."""


class _AgentDigests:
    """Per agent of a frame's meshes a digest of its posed triangles (SHA-256 of its vertices, its
    faces from its first vertex, each face's class and part; 16 bytes) and its run of triangles.
    An agent whose bytes are the same as at the last frame keeps its digest without hashing them
    again (a standing agent's; the same bytes give the same digest)."""

    def __init__(self) -> None:
        self._last: dict[int, tuple[bytes, bytes]] = {}  # per agent of the last frame: its bytes, its digest

    def __call__(self, meshes: AgentMeshes) -> tuple[dict[int, bytes], dict[int, tuple[int, int]]]:
        runs = _triangle_runs(meshes.triangle_instance)
        keys, last = {}, {}
        for instance, (a, b) in runs.items():
            vertices, faces = own_mesh(meshes.vertices_m, meshes.triangles[a:b])
            data = b"".join(p.data for p in (vertices, faces, meshes.triangle_class[a:b], meshes.triangle_part[a:b]))
            kept = self._last.get(instance)
            digest = kept[1] if kept is not None and kept[0] == data else hashlib.sha256(data).digest()[:16]
            keys[instance], last[instance] = digest, (data, digest)
        self._last = last
        return keys, runs


class _Tables:
    """Per triangle of an agents' scene: class, instance, part and face normal."""

    def __init__(self, meshes: AgentMeshes, triangles: npt.NDArray[np.int32], rows: npt.NDArray[np.intp]) -> None:
        self.triangles = triangles
        self.cls = meshes.triangle_class[rows]
        self.instance = meshes.triangle_instance[rows]
        self.part = meshes.triangle_part[rows]
        self.normal = _face_normals(meshes.vertices_m, triangles)


class MitsubaEngine:
    """Keeps the static scene (made again when the static mesh changes) and two agents' scenes:
    one of the agents standing exactly as they stood (the same posed triangles, bit for bit),
    kept from frame to frame, and one of the others, made every frame; and each agent's own Open3D
    scene for the labels' silhouettes, kept while its triangles stay the same (which answers as a
    fresh one: not part of the checkpoint).

    Which agents share a scene changes what Embree answers for a few rays (a ray through an edge,
    between surfaces microns apart), so the split is part of what a frame's outputs depend on:
    :meth:`checkpoint` and :meth:`restore` carry it to a run that continues."""

    name = "mitsuba"

    def __init__(self) -> None:
        self._static_mesh: ClassedMesh | None = None
        self._static: _Part | None = None
        self._static_normals = np.zeros((0, 3), np.float32)
        self.agent_part = _AgentPart()
        self.still_part = _AgentPart("still")
        self._last_keys: dict[int, bytes] = {}
        self._kept: dict[int, bytes] = {}  # the still part's agents and their triangles' bytes
        self._kept_tables: _Tables | None = None
        self._digests = _AgentDigests()
        self._alone = AloneScenes()  # each agent's own scene, for the labels' silhouettes

    def scene(self, static: ClassedMesh, agents: Agents) -> MitsubaScene:
        if static is not self._static_mesh:
            self._static_mesh, self._static = static, _Part("static", static.vertices_m, static.triangles)
            self._static_normals = _face_normals(static.vertices_m, static.triangles)
        if self._static is None:
            raise RuntimeError("MitsubaEngine: no static scene")
        meshes = agent_meshes(agents)
        moving, kept = self._split(meshes)
        self._alone.keep_only(agents.instance_id)
        return MitsubaScene(self, static, self._static, agents, meshes, moving, kept)

    def _split(self, meshes: AgentMeshes) -> tuple[_Tables, _Tables]:
        """This frame's moving agents' tables (their part made here) and the kept still ones'
        (their part made again when an agent in it changed or left, or many more stand)."""
        keys, runs = self._digests(meshes)
        intact = all(keys.get(i) == k for i, k in self._kept.items())
        standing = [i for i, k in keys.items() if self._last_keys.get(i) == k]
        kept_triangles = sum(runs[i][1] - runs[i][0] for i in self._kept) if intact else 0
        joining = sum(runs[i][1] - runs[i][0] for i in standing if i not in self._kept)
        self._last_keys = keys
        if not intact or joining > STILL_GROWTH * kept_triangles:
            self._kept, self._kept_tables = {i: keys[i] for i in standing}, None
        kept_tables = self._kept_tables
        if kept_tables is None:  # made again, or first made (a fresh or restored engine)
            rows = _rows_of_agents(runs, sorted(self._kept))
            kept_tables = self._kept_tables = _Tables(meshes, meshes.triangles[rows], rows)
            self.still_part.update(meshes.vertices_m, kept_tables.triangles)
        rows = _rows_of_agents(runs, sorted(i for i in runs if i not in self._kept))
        moving = _Tables(meshes, meshes.triangles[rows], rows)
        self.agent_part.update(meshes.vertices_m, moving.triangles)
        return moving, kept_tables

    def checkpoint(self) -> dict[str, Any]:
        """What a run that continues after this frame needs to split the agents as this engine
        will: the digests of this frame's agents and which of them the kept scene holds (their
        triangles are this frame's: an agent that changed has left it)."""
        return {"agents": {str(i): k.hex() for i, k in self._last_keys.items()}, "kept": sorted(self._kept)}

    def restore(self, state: dict[str, Any]) -> None:
        """Continue from :meth:`checkpoint`'s ``state`` (an empty one: as a fresh engine); the kept
        scene is made at the next frame, of the same triangles as the engine that ran on had."""
        self._last_keys = {int(i): bytes.fromhex(k) for i, k in state.get("agents", {}).items()}
        self._kept = {int(i): self._last_keys[int(i)] for i in state.get("kept", [])}
        self._kept_tables = None


def _rows_of_agents(runs: dict[int, tuple[int, int]], instances: list[int]) -> npt.NDArray[np.intp]:
    """The triangles (rows of the merged mesh) of ``instances``, in the mesh's order."""
    spans = [np.arange(*runs[i]) for i in instances]
    return np.concatenate(spans) if spans else np.zeros(0, np.intp)


class MitsubaScene:
    """One frame: the static part and the still agents' (kept by the engine) and this frame's
    moving agents. Rows of the tables: static triangles, moving agents', still agents', and
    one for rays that hit nothing."""

    def __init__(
        self, engine: MitsubaEngine, static: ClassedMesh, part: _Part, agents: Agents, meshes: AgentMeshes,
        moving: _Tables, still: _Tables,
    ) -> None:  # fmt: skip
        self._engine, self._static = engine, part
        self.agents = agents
        self.agent_meshes: AgentMeshes = meshes
        self._agents, self._still = engine.agent_part, engine.still_part
        n_static, n_moving, n_still = static.triangle_class.shape[0], moving.cls.shape[0], still.cls.shape[0]
        self._agent_row0, self._still_row0 = n_static, n_static + n_moving
        self._nothing_row = n_static + n_moving + n_still
        self._class_of_row = np.concatenate([static.triangle_class, moving.cls, still.cls, [0]]).astype(np.uint8)
        self._instance_of_row = np.concatenate([np.zeros(n_static, np.uint32), moving.instance, still.instance, [0]])
        self._instance_of_row = self._instance_of_row.astype(np.uint32)
        self._part_of_row = np.concatenate([np.zeros(n_static, np.uint8), moving.part, still.part, [0]])
        self._part_of_row = self._part_of_row.astype(np.uint8)
        normals = [engine._static_normals, moving.normal, still.normal, np.zeros((1, 3), np.float32)]
        self._normal_of_row = np.ascontiguousarray(np.concatenate(normals)).view(np.uint32)  # bits, copied whole

    def cast(self, rays: npt.NDArray[np.float32]) -> RayHits:
        ray = _rays(rays)
        return self._hits(ray)

    def cast_from(
        self,
        origin_map_m: npt.NDArray[np.float64],
        map_R_sensor: npt.NDArray[np.float64],
        dirs_sensor: npt.NDArray[np.float32],
    ) -> RayHits:
        """The same ray directions as the reference engine's (turned by OpenCV in float32), one origin."""
        dirs = map_directions(map_R_sensor, dirs_sensor)
        origin = mi.Point3f(*(dr.opaque(mi.Float, float(v)) for v in np.asarray(origin_map_m, np.float32)))
        direction = dr.unravel(mi.Vector3f, mi.Float(np.ravel(dirs)))  # gathered in the kernel itself
        return self._hits(mi.Ray3f(origin, direction))

    def occluded(self, rays: npt.NDArray[np.float32]) -> npt.NDArray[np.bool_]:
        ray = _rays(rays)
        hit = self._static.test(ray) if self._static.triangles else dr.zeros(mi.Bool, rays.shape[0])
        for agents in (self._agents, self._still):
            if agents.triangles:
                hit = hit | agents.test(ray)
        return np.asarray(hit.numpy(), np.bool_)

    def cast_raw(self, rays: npt.NDArray[np.float32]) -> Any:
        ray = _rays(rays)
        t, _ = self._static.cast(ray)
        for agents in (self._agents, self._still):
            if agents.triangles:
                t_agent = agents.cast(ray)[0]
                t = dr.select(t_agent < t, t_agent, t)
        return t.numpy()  # waits for the kernel: Dr.Jit launches it in the background

    def _hits(self, ray: Any) -> RayHits:
        t, prim = self._static.cast(ray)
        row = mi.UInt32(prim)
        for agents, row0 in ((self._agents, self._agent_row0), (self._still, self._still_row0)):
            if agents.triangles:
                t_agent, prim_agent = agents.cast(ray)
                nearer = t_agent < t
                t = dr.select(nearer, t_agent, t)
                # opaque: the numbers change from frame to frame, the compiled kernel must not
                row = dr.select(nearer, prim_agent + dr.opaque(mi.UInt32, row0), row)
        row = dr.select(dr.isinf(t), dr.opaque(mi.UInt32, self._nothing_row), row)
        dr.eval(t, row)
        range_m = t.numpy().astype(np.float32, copy=False)
        return self._with_rows(range_m, row.numpy())

    def _with_rows(self, range_m: npt.NDArray[np.float32], rows: npt.NDArray[np.uint32]) -> RayHits:
        cls, instance, part, normal = _rows_of(
            np.ascontiguousarray(rows, np.uint32), self._class_of_row, self._instance_of_row, self._part_of_row,
            self._normal_of_row,
        )  # fmt: skip
        return RayHits(range_m, cls, instance, normal.view(np.float32), part)

    def cast_static(self, rays: npt.NDArray[np.float32]) -> RayHits:
        """The rays cast into the static world alone (no agents)."""
        t, prim = self._static.cast(_rays(rays))
        row = dr.select(dr.isinf(t), dr.opaque(mi.UInt32, self._nothing_row), mi.UInt32(prim))
        dr.eval(t, row)
        # the static rows' instance and part are 0
        return self._with_rows(t.numpy().astype(np.float32, copy=False), row.numpy())

    def cast_agents_moving(
        self, rays: npt.NDArray[np.float32], dt_s: npt.NDArray[np.float64], ray_index: npt.NDArray[np.intp],
        agent_index: npt.NDArray[np.intp],
    ) -> PairHits:  # fmt: skip
        return cast_agents_moving(self.agents, rays, dt_s, ray_index, agent_index)

    def hits_alone(self, rays: npt.NDArray[np.float32], instance_id: npt.NDArray[np.uint32]) -> npt.NDArray[np.bool_]:
        return _hits_alone(self.agent_meshes, rays, instance_id, self._engine._alone)

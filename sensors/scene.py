"""The one Open3D raycasting scene of a frame: static world plus posed agents.

Open3D scenes have no transforms or instancing, so a frame's scene is rebuilt from
the static mesh near the ego (cropped once per few metres of travel) and one merged
mesh of the agents. Every hit carries the class and instance id of its triangle. The
scene keeps its agents and their meshes: the radar reads their velocities, the labels cast
an object's unoccluded silhouette against its own mesh (:meth:`FrameScene.hits_alone`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt
from numba import njit

from networks.geometry import SE3
from networks.mesh import ClassedMesh
from sensors.agents import (
    AgentMeshes,
    Agents,
    agent_meshes,
    body_keys,
    mesh_frames,
    motion_over,
    rows_of_ids,
    template_of,
    turn_rate_at,
    turned_about_z,
)
from sensors.hits import PairHits, RayHits
from sensors.o3d import INVALID_ID, RaycastingScene, o3c
from sensors.parts import Part
from sensors.rays import sensor_rays


class Open3DEngine:
    """The reference engine: Open3D's raycasting scene, rebuilt for every frame."""

    name = "open3d"

    def __init__(self) -> None:
        self._static = StaticScene()
        self._alone = AloneScenes()

    def scene(self, static: ClassedMesh, agents: Agents) -> FrameScene:
        self._alone.keep_only(agents.instance_id)
        return FrameScene(static, agents, static_scene=self._static, alone=self._alone)

    def checkpoint(self) -> dict[str, Any]:
        return {}  # every frame's scene is made afresh

    def restore(self, state: dict[str, Any]) -> None:
        pass


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
        self._surfaces: Any = None  # the crop's own scene, for surface_below, made when first asked

    def around(self, center_xy_m: npt.ArrayLike) -> ClassedMesh:
        c = np.asarray(center_xy_m, dtype=np.float64)[:2]
        if self._center is not None and np.linalg.norm(c - self._center) <= self._slack:
            return self._crop
        self.restore(c)
        return self._crop

    @property
    def center_xy_m(self) -> tuple[float, float] | None:
        """The centre of the current crop (None before the first)."""
        return None if self._center is None else (float(self._center[0]), float(self._center[1]))

    def surface_below(self, xyz_m: npt.NDArray[np.float64], reach_m: float) -> npt.NDArray[np.float64]:
        """``(N,)`` height of the first static surface straight below each point, looking at
        most ``reach_m`` down (NaN: nothing there); the points lie within the current crop."""
        if self._surfaces is None:
            self._surfaces = RaycastingScene()
            crop = self._crop
            if crop.triangles.shape[0]:
                self._surfaces.add_triangles(
                    o3c.Tensor.from_numpy(np.ascontiguousarray(crop.vertices_m, np.float32)),
                    o3c.Tensor.from_numpy(crop.triangles.astype(np.uint32)),
                )
        rays = np.zeros((xyz_m.shape[0], 6), np.float32)
        rays[:, :3], rays[:, 5] = xyz_m, -1.0
        t_hit = self._surfaces.cast_rays(o3c.Tensor.from_numpy(rays))["t_hit"].numpy().astype(np.float64)
        return np.where(t_hit <= reach_m, xyz_m[:, 2] - t_hit, np.nan)

    def restore(self, center_xy_m: npt.ArrayLike | None) -> None:
        """Crop around ``center_xy_m`` (a crop's centre kept from an earlier run; None: no crop yet)."""
        self._surfaces = None  # the crop's own scene, for surface_below, made when first asked
        if center_xy_m is None:
            self._center, self._crop = None, self._mesh
            return
        c = np.asarray(center_xy_m, dtype=np.float64)[:2]
        reach = self._radius + self._slack + self._tri_radius
        keep = np.linalg.norm(self._centroid_xy - c, axis=1) <= reach
        self._center = c
        self._crop = ClassedMesh(self._mesh.vertices_m, self._mesh.triangles[keep], self._mesh.triangle_class[keep])


class StaticScene:
    """The static world alone as a raycasting scene, made when first cast into and again only
    when the static mesh changes (the crop moves every few tens of metres): what the rays of a
    timed LiDAR sweep meet besides the agents."""

    def __init__(self) -> None:
        self._mesh: ClassedMesh | None = None
        self._scene: Any = None

    def cast(self, static: ClassedMesh, rays: npt.NDArray[np.float32]) -> RayHits:
        if self._mesh is not static:
            self._mesh, self._scene = static, RaycastingScene()
            if static.triangles.shape[0]:
                self._scene.add_triangles(
                    o3c.Tensor.from_numpy(np.ascontiguousarray(static.vertices_m, np.float32)),
                    o3c.Tensor.from_numpy(np.ascontiguousarray(static.triangles, np.uint32)),
                )
        result = self._scene.cast_rays(o3c.Tensor.from_numpy(np.ascontiguousarray(rays, np.float32)))
        geometry = result["geometry_ids"].numpy()
        miss = geometry == np.uint32(INVALID_ID)
        t_hit = result["t_hit"].numpy()
        t_hit[miss] = np.inf
        n = rays.shape[0]
        cls = np.zeros(n, np.uint8)
        cls[~miss] = static.triangle_class[result["primitive_ids"].numpy()[~miss]]
        return RayHits(t_hit, cls, np.zeros(n, np.uint32), result["primitive_normals"].numpy(), np.zeros(n, np.uint8))


class FrameScene:
    """One frame's raycasting scene of the ``static`` world and the ``agents`` (their meshes
    are built here). Rays are ``(N, 6) float32``: origin, unit direction. The scene's BVH is
    built here, not by the first cast."""

    def __init__(
        self, static: ClassedMesh, agents: Agents, nthreads: int = 0, static_scene: StaticScene | None = None,
        alone: AloneScenes | None = None,
    ) -> None:  # fmt: skip
        self.agents = agents
        self._alone = AloneScenes() if alone is None else alone
        self._static = static
        self._static_scene = StaticScene() if static_scene is None else static_scene
        self.agent_meshes = meshes = agent_meshes(agents)
        self._scene = RaycastingScene()
        self._nthreads = nthreads
        self._static_id = self._add(static.vertices_m, static.triangles)
        self._agent_id = self._add(meshes.vertices_m, meshes.triangles)
        # One row per triangle, static ones first, and a last row for rays that hit nothing.
        self._agent_row0 = np.uint32(static.triangle_class.shape[0])
        self._nothing_row = np.uint32(static.triangle_class.shape[0] + meshes.triangle_class.shape[0])
        self._class_of_row = np.concatenate([static.triangle_class, meshes.triangle_class, [0]]).astype(np.uint8)
        self._instance_of_row = np.concatenate(
            [np.zeros(static.triangle_class.shape[0], np.uint32), meshes.triangle_instance, [0]]
        ).astype(np.uint32)
        self._part_of_row = np.concatenate(
            [np.zeros(static.triangle_class.shape[0], np.uint8), meshes.triangle_part, [0]]
        ).astype(np.uint8)
        self.cast_raw(np.zeros((1, 6), np.float32))  # builds the BVH

    def _add(self, vertices: npt.NDArray[np.floating[Any]], triangles: npt.NDArray[np.integer[Any]]) -> int:
        if triangles.shape[0] == 0:
            return -1
        v = o3c.Tensor.from_numpy(np.ascontiguousarray(vertices, dtype=np.float32))
        t = o3c.Tensor.from_numpy(np.ascontiguousarray(triangles, dtype=np.uint32))
        return int(self._scene.add_triangles(v, t))

    def occluded(self, rays: npt.NDArray[np.float32]) -> npt.NDArray[np.bool_]:
        tensor = o3c.Tensor.from_numpy(np.ascontiguousarray(rays, dtype=np.float32))
        return np.asarray(self._scene.test_occlusions(tensor, nthreads=self._nthreads).numpy(), np.bool_)

    def cast_raw(self, rays: npt.NDArray[np.float32]) -> dict[str, Any]:
        """Open3D's own cast (its tensors by name), nothing added: what the benchmark compares to."""
        tensor = o3c.Tensor.from_numpy(np.ascontiguousarray(rays, dtype=np.float32))
        return dict(self._scene.cast_rays(tensor, nthreads=self._nthreads))

    def cast_from(
        self,
        origin_map_m: npt.NDArray[np.float64],
        map_R_sensor: npt.NDArray[np.float64],
        dirs_sensor: npt.NDArray[np.float32],
    ) -> RayHits:
        return self.cast(sensor_rays(SE3(map_R_sensor, origin_map_m), dirs_sensor))

    def cast(self, rays: npt.NDArray[np.float32]) -> RayHits:
        result = self.cast_raw(rays)
        t_hit = result["t_hit"].numpy()
        geometry = result["geometry_ids"].numpy()
        row = result["primitive_ids"].numpy()  # becomes the row in the class and instance tables
        if self._agent_id >= 0 and self._agent_row0 > 0:
            row[geometry == np.uint32(self._agent_id)] += self._agent_row0
        np.minimum(row, self._nothing_row, out=row)  # misses (INVALID_ID) -> the last row
        t_hit[geometry == np.uint32(INVALID_ID)] = np.inf
        normal = result["primitive_normals"].numpy()
        return RayHits(t_hit, self._class_of_row[row], self._instance_of_row[row], normal, self._part_of_row[row])

    def cast_static(self, rays: npt.NDArray[np.float32]) -> RayHits:
        """The rays cast into the static world alone (no agents)."""
        return self._static_scene.cast(self._static, rays)

    def cast_agents_moving(
        self, rays: npt.NDArray[np.float32], dt_s: npt.NDArray[np.float64], ray_index: npt.NDArray[np.intp],
        agent_index: npt.NDArray[np.intp],
    ) -> PairHits:  # fmt: skip
        return cast_agents_moving(self.agents, rays, dt_s, ray_index, agent_index)

    def hits_alone(self, rays: npt.NDArray[np.float32], instance_id: npt.NDArray[np.uint32]) -> npt.NDArray[np.bool_]:
        """Whether ray ``i`` hits agent ``instance_id[i]`` with every other agent (and the
        static world) taken away: the object's silhouette as if it were alone. One small scene
        per agent, of its own triangles in this scene; ``False`` for agents not in the scene."""
        return _hits_alone(self.agent_meshes, rays, instance_id, self._alone)


class AloneScenes:
    """Each agent's own Open3D scene (its triangles alone, for :func:`_hits_alone`), kept from
    frame to frame while the agent's posed triangles stay the same bit for bit (a parked or a
    stopped agent's): the same triangles give the same hits. An engine keeps one and, per frame,
    drops the agents that left (:meth:`keep_only`)."""

    def __init__(self) -> None:
        self._scenes: dict[int, tuple[tuple[int, bytes], Any]] = {}

    def keep_only(self, instance_id: npt.NDArray[np.uint32]) -> None:
        present = set(instance_id.tolist())
        self._scenes = {i: kept for i, kept in self._scenes.items() if i in present}

    def scene(self, instance: int, vertices: npt.NDArray[np.float32], triangles: npt.NDArray[np.int32]) -> Any:
        """The scene of one agent's ``triangles`` (rows of ``vertices``)."""
        own_vertices, own_triangles = own_mesh(vertices, triangles)
        key = (own_vertices.shape[0], own_vertices.tobytes() + own_triangles.tobytes())  # one way to split them
        kept = self._scenes.get(instance)
        if kept is not None and kept[0] == key:
            return kept[1]
        scene = RaycastingScene()
        scene.add_triangles(o3c.Tensor.from_numpy(own_vertices), o3c.Tensor.from_numpy(own_triangles))
        self._scenes[instance] = (key, scene)
        return scene


def _hits_alone(
    agents: AgentMeshes, rays: npt.NDArray[np.float32], instance_id: npt.NDArray[np.uint32],
    scenes: AloneScenes | None = None,
) -> npt.NDArray[np.bool_]:  # fmt: skip
    hit = np.zeros(rays.shape[0], np.bool_)
    if rays.shape[0] == 0 or agents.triangles.shape[0] == 0:
        return hit
    scenes = AloneScenes() if scenes is None else scenes
    triangles_of = _triangle_runs(agents.triangle_instance)
    order = np.argsort(instance_id, kind="stable")
    ids = instance_id[order]
    bounds = np.flatnonzero(np.r_[True, ids[1:] != ids[:-1], True])
    for a, b in zip(bounds[:-1].tolist(), bounds[1:].tolist(), strict=True):
        instance = int(ids[a])
        run = triangles_of.get(instance)
        if run is not None:
            mine = order[a:b]
            scene = scenes.scene(instance, agents.vertices_m, agents.triangles[run[0] : run[1]])
            hit[mine] = _cast_one(scene, rays[mine])
    return hit


def own_mesh(
    vertices: npt.NDArray[np.float32], triangles: npt.NDArray[np.int32]
) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.uint32]]:
    """One agent's ``triangles`` (rows of the merged ``vertices``) as a mesh of its own: the
    vertices they use (one agent's are consecutive) and the faces counted from the first."""
    first, last = int(triangles.min()), int(triangles.max())
    return np.ascontiguousarray(vertices[first : last + 1], np.float32), (triangles - first).astype(np.uint32)


def _triangle_runs(triangle_instance: npt.NDArray[np.uint32]) -> dict[int, tuple[int, int]]:
    """Instance id -> its ``[start, end)`` triangles (an agent's triangles are contiguous)."""
    starts = np.flatnonzero(np.r_[True, triangle_instance[1:] != triangle_instance[:-1]])
    ends = np.r_[starts[1:], triangle_instance.shape[0]]
    return {int(i): (int(a), int(b)) for i, a, b in zip(triangle_instance[starts], starts, ends, strict=True)}


def _cast_one(scene: Any, rays: npt.NDArray[np.float32]) -> npt.NDArray[np.bool_]:
    """Whether each ray meets the scene (Embree's occlusion query: the same answer as whether a
    cast finds a nearest hit, without seeking it)."""
    tensor = o3c.Tensor.from_numpy(np.ascontiguousarray(rays, dtype=np.float32))
    return np.asarray(scene.test_occlusions(tensor, nthreads=1).numpy(), np.bool_)


_UNIT_SCENES: dict[tuple[int, int, int], tuple[Any, npt.NDArray[np.uint8]]] = {}
_GLASS_LAYERS = 4  # panes a ray may pass through on one agent (a car's windscreen and rear window, and back)
_PAST_M = 1e-4  # a ray continues this far past the glass it passed through


def _unit_scene(key: tuple[int, int, int]) -> tuple[Any, npt.NDArray[np.uint8]]:
    """The Open3D scene of a body type's unit mesh in one pose (made once a process) and each
    triangle's part."""
    if key not in _UNIT_SCENES:
        template = template_of(*key)
        scene = RaycastingScene()
        scene.add_triangles(
            o3c.Tensor.from_numpy(template.unit_vertices.astype(np.float32)),
            o3c.Tensor.from_numpy(template.triangles.astype(np.uint32)),
        )
        _UNIT_SCENES[key] = (scene, np.append(template.triangle_part, np.uint8(0)).astype(np.uint8))
    return _UNIT_SCENES[key]


def hits_alone_in_templates(
    agents: Agents, keys: list[tuple[int, int, int]], rays: npt.NDArray[np.float32],
    instance_id: npt.NDArray[np.uint32],
) -> npt.NDArray[np.bool_]:  # fmt: skip
    """Whether ray ``i`` hits agent ``instance_id[i]`` with everything else taken away (as
    :meth:`FrameScene.hits_alone`; ``False`` for agents not among ``agents``), each agent cast in
    its body template's unit mesh (``keys``: each agent's class, body and pose), the ray taken
    into that mesh's frame as the fast engine's instances take it (:func:`_into_units`): no mesh
    is posed and no scene is built per frame (a template's scene is made once a process)."""
    hit = np.zeros(rays.shape[0], np.bool_)
    if rays.shape[0] == 0 or len(agents) == 0:
        return hit
    agent = rows_of_ids(agents.instance_id, instance_id).astype(np.int64)  # each ray's agent (-1: none)
    rotations, centre, lwh = mesh_frames(agents)
    unit = _into_units(np.ascontiguousarray(rays, np.float32), agent, rotations, centre, lwh)
    agents_of: dict[tuple[int, int, int], list[int]] = {}  # per template, its agents
    for k, key in enumerate(keys):
        agents_of.setdefault(key, []).append(k)
    templates = list(agents_of)
    group = np.full(len(agents) + 1, -1, np.int64)  # each agent's template's number (the last, -1: none)
    for g, key in enumerate(templates):
        group[agents_of[key]] = g
    ray_group = group[agent]
    order = np.argsort(ray_group, kind="stable")
    ordered = ray_group[order]
    bounds = np.flatnonzero(np.r_[True, ordered[1:] != ordered[:-1], True])
    for a, b in zip(bounds[:-1].tolist(), bounds[1:].tolist(), strict=True):
        if ordered[a] >= 0:
            mine = order[a:b]  # one cast per template
            hit[mine] = _cast_one(_unit_scene(templates[int(ordered[a])])[0], unit[mine])
    return hit


@njit(cache=True, nogil=True)
def _into_units(
    rays: npt.NDArray[np.float32], agent: npt.NDArray[np.int64], rotations: npt.NDArray[np.float64],
    centre: npt.NDArray[np.float64], lwh: npt.NDArray[np.float64],
) -> npt.NDArray[np.float32]:  # fmt: skip  # pragma: no cover - compiled
    """``(N, 6)`` each ray (origin, direction) in the unit frame of its ``agent``'s mesh (-1: none,
    the ray left as it is): ``R^T (o - c) / lwh`` and ``R^T d / lwh`` in float64, each product's
    terms summed in order, then rounded to float32."""
    out = np.empty((rays.shape[0], 6), np.float32)
    for i in range(rays.shape[0]):
        k = agent[i]
        if k < 0:
            out[i] = rays[i]
            continue
        x0 = np.float64(rays[i, 0]) - centre[k, 0]
        x1 = np.float64(rays[i, 1]) - centre[k, 1]
        x2 = np.float64(rays[i, 2]) - centre[k, 2]
        d0, d1, d2 = np.float64(rays[i, 3]), np.float64(rays[i, 4]), np.float64(rays[i, 5])
        for j in range(3):
            r0, r1, r2 = rotations[k, 0, j], rotations[k, 1, j], rotations[k, 2, j]
            out[i, j] = np.float32((x0 * r0 + x1 * r1 + x2 * r2) / lwh[k, j])
            out[i, 3 + j] = np.float32((d0 * r0 + d1 * r1 + d2 * r2) / lwh[k, j])
    return out


def cast_agents_moving(
    agents: Agents, rays: npt.NDArray[np.float32], dt_s: npt.NDArray[np.float64],
    ray_index: npt.NDArray[np.intp], agent_index: npt.NDArray[np.intp],
) -> PairHits:  # fmt: skip
    """Ray ``ray_index[k]`` cast at ``dt_s`` from the frame's time against agent ``agent_index[k]``
    alone (pairs grouped by agent, ``agent_index`` ascending), the agent moved by its velocity
    and rate of turn over ``dt_s`` (:func:`sensors.agents.motion_over`). Each agent's body is cast
    in its type's unit mesh (scaled and posed as :func:`sensors.agents.agent_meshes` does), the
    ray taken into that mesh's frame: no mesh is built per frame. A ray passes through glass
    (:attr:`Part.GLASS`): its hit is the next surface of the agent behind the glass, or none."""
    m = ray_index.shape[0]
    out = PairHits(np.full(m, np.inf, np.float32), np.zeros((m, 3), np.float32), np.zeros(m, np.uint8))
    if m == 0:
        return out
    rotations, centre, lwh = mesh_frames(agents)
    starts = np.searchsorted(agent_index, np.arange(len(agents) + 1))
    present = np.flatnonzero(np.diff(starts))
    unit = np.empty((m, 6), np.float32)  # each pair's ray in its agent's unit mesh frame
    turns: dict[int, npt.NDArray[np.float64]] = {}  # each turning agent's turn at each of its pairs' times
    for k in present.tolist():
        a, b = int(starts[k]), int(starts[k + 1])
        mine = ray_index[a:b]
        rates = (agents.yaw_rate_rad_s[k], agents.yaw_rate_after_rad_s[k])
        if rates == (0.0, 0.0):
            moved = rays[mine, :3] - (centre[k] + dt_s[mine, None] * agents.velocity_map_mps[k])
            direction = rays[mine, 3:6].astype(np.float64)
        else:  # the ray taken back by the agent's turn about its centre, into its frame at the reference time
            rate = turn_rate_at(*rates, dt_s[mine])
            shift, turn = motion_over(agents.velocity_map_mps[k], rate, dt_s[mine])
            box_centre = agents.center_map_m[k] + shift
            moved = turned_about_z(rays[mine, :3] - box_centre, -turn) - (centre[k] - agents.center_map_m[k])
            direction = turned_about_z(rays[mine, 3:6].astype(np.float64), -turn)
            turns[k] = turn
        unit[a:b, :3] = (moved @ rotations[k]) / lwh[k]  # x @ R is R^T x
        unit[a:b, 3:] = (direction @ rotations[k]) / lwh[k]
    keys = body_keys(agents.select(present))
    groups, group_of = np.unique(keys, axis=0, return_inverse=True)
    normal_unit = np.zeros((m, 3), np.float32)
    for g, key in enumerate(groups.tolist()):
        blocks = [np.arange(starts[k], starts[k + 1]) for k in present[group_of.ravel() == g].tolist()]
        pairs = np.concatenate(blocks)
        scene, part_of = _unit_scene((key[0], key[1], key[2]))
        out.range_m[pairs], normal_unit[pairs], out.part[pairs] = _cast_through_glass(scene, part_of, unit[pairs])
    for k in present.tolist():
        a, b = int(starts[k]), int(starts[k + 1])
        world = (normal_unit[a:b] / lwh[k]) @ rotations[k].T
        if k in turns:
            world = turned_about_z(world, turns[k])
        length = np.linalg.norm(world, axis=1, keepdims=True)
        out.normal[a:b] = world / np.where(length > 0, length, 1.0)
    return out


def _cast_through_glass(
    scene: Any, part_of: npt.NDArray[np.uint8], rays: npt.NDArray[np.float32]
) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.float32], npt.NDArray[np.uint8]]:
    """Distance along each ray's direction (metres when its length is the map-frame metre's in
    this frame), unit-frame normal and part of the first surface that is not glass (inf: none)."""
    result = scene.cast_rays(o3c.Tensor.from_numpy(np.ascontiguousarray(rays)), nthreads=1)
    t = result["t_hit"].numpy()
    normal = result["primitive_normals"].numpy()
    hit = result["geometry_ids"].numpy() != np.uint32(INVALID_ID)
    part = part_of[np.where(hit, result["primitive_ids"].numpy(), part_of.shape[0] - 1)]
    t[~hit] = np.inf
    glass = np.flatnonzero(part == Part.GLASS)
    for _ in range(_GLASS_LAYERS):
        if glass.size == 0:
            break
        step = t[glass] + np.float32(_PAST_M)
        again = rays[glass].copy()
        again[:, :3] += again[:, 3:] * step[:, None]
        more = scene.cast_rays(o3c.Tensor.from_numpy(again), nthreads=1)
        hit2 = more["geometry_ids"].numpy() != np.uint32(INVALID_ID)
        t[glass] = np.where(hit2, step + more["t_hit"].numpy(), np.inf)
        part[glass] = part_of[np.where(hit2, more["primitive_ids"].numpy(), part_of.shape[0] - 1)]
        normal[glass] = more["primitive_normals"].numpy()
        glass = glass[part[glass] == Part.GLASS]
    t[part == Part.GLASS] = np.inf  # more panes than followed: nothing returns
    return t, normal, part

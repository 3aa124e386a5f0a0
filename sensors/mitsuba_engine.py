"""The fast ray engine: Mitsuba 3's scenes traced with Dr.Jit's LLVM backend (Embree's packet
kernels, coherent rays), the only module that imports them.

The static world near the ego is one Mitsuba scene, made again only when the crop changes; the
agents are a second scene of instances of their bodies' unit meshes (one shape group per body
template, made once), of which a frame changes the transforms. A ray is cast in both and the
nearer hit wins. Per hit the static scene gives the triangle, whose class and face normal come
from tables as in the Open3D engine; the agents' scene gives the instance (the agent) and the
template's triangle (its part, and its normal turned into the map frame). A sensor's ray
directions are handed to Dr.Jit once and turned into the map frame on its side. Importing this
module raises ImportError, or RuntimeError/OSError from Dr.Jit, when the engine cannot start (no
libLLVM 15 or newer).
"""

from __future__ import annotations

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
from sensors.agents import (  # noqa: E402
    AgentMeshes,
    Agents,
    agent_meshes,
    body_keys,
    mesh_frames,
    template_of,
    template_poses,
)
from sensors.hits import PairHits, RayHits  # noqa: E402
from sensors.rays import map_directions  # noqa: E402
from sensors.scene import cast_agents_moving, hits_alone_in_templates  # noqa: E402


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
F64 = npt.NDArray[np.float64]
NO_SLOT = np.uint32(0xFFFFFFFF)
"""The slot of a ray that hit no agent."""


@njit(cache=True, nogil=True)
def _rows_of(
    rows: npt.NDArray[np.uint32], slots: npt.NDArray[np.uint32], class_of: U8, normal_bits_of: npt.NDArray[np.uint32],
    slot_class: U8, slot_instance: npt.NDArray[np.uint32], slot_first: npt.NDArray[np.int64], slot_turn: F64,
    template_part: U8, template_normal: F64,
) -> tuple[U8, npt.NDArray[np.uint32], U8, npt.NDArray[np.uint32]]:  # fmt: skip  # pragma: no cover - compiled
    """Per ray its class, instance, part and normal (the normal's float32 bits), in one pass over
    the rays: a ray that hit no agent (slot :data:`NO_SLOT`) from its row of the static tables
    (class, normal bits copied as they are; instance and part 0), one that hit an agent from its
    slot (class, instance) and its template's triangle ``rows[i]`` (part; unit normal turned by
    the slot's rotation over its scale and made unit, in float64)."""
    n = rows.shape[0]
    cls = np.empty(n, np.uint8)
    instance = np.zeros(n, np.uint32)
    part = np.zeros(n, np.uint8)
    normal = np.empty((n, 3), np.uint32)
    turned = normal.view(np.float32)  # an agent's normal written as float32
    for i in range(n):
        r, s = rows[i], slots[i]
        if s == NO_SLOT:
            cls[i] = class_of[r]
            normal[i, 0] = normal_bits_of[r, 0]
            normal[i, 1] = normal_bits_of[r, 1]
            normal[i, 2] = normal_bits_of[r, 2]
            continue
        t = slot_first[s] + r
        cls[i], instance[i], part[i] = slot_class[s], slot_instance[s], template_part[t]
        m = slot_turn[s]
        u0, u1, u2 = template_normal[t, 0], template_normal[t, 1], template_normal[t, 2]
        x = m[0, 0] * u0 + m[0, 1] * u1 + m[0, 2] * u2
        y = m[1, 0] * u0 + m[1, 1] * u1 + m[1, 2] * u2
        z = m[2, 0] * u0 + m[2, 1] * u1 + m[2, 2] * u2
        length = np.sqrt(x * x + y * y + z * z)
        if not length > 0:
            length = 1.0
        turned[i, 0], turned[i, 1], turned[i, 2] = x / length, y / length, z / length
    return cls, instance, part, normal


def _rays(rays: npt.NDArray[np.float32]) -> Any:
    """Dr.Jit's rays of ``(N, 6) float32`` rays (origin, direction); columns that are already
    contiguous (a transposed ``(6, N)`` array, or the first ``N`` columns of a longer one) are
    handed over as they are, rows are handed over whole and gathered column by column in the
    kernel that casts them."""
    if rays.dtype == np.float32 and (rays.flags.f_contiguous or rays.strides[0] == rays.itemsize):
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


def _template_key(key: tuple[int, int, int]) -> tuple[int, int, int]:
    """A body key (class, body, pose) with its pose taken modulo its body's poses (as
    :func:`sensors.agents.template_of` takes it): keys of one template are one key."""
    c, body, pose = key
    return c, body, pose % template_poses(c, body)


PARKED = np.diag([0.0, 0.0, 0.0, 1.0])
PARKED[2, 3] = -1.0e6
"""The transform of an instance no agent holds: every template shrunk to one point far below the
map. No ray meets it (Embree's ray in a zero-scale instance's frame is not a number)."""
SPARE_SLOTS = 1
"""Instances a template's share of the agents' scene holds beyond the agents that last
outgrew it (so a walker stepping from pose to pose seldom makes it grow again)."""


class _Template:
    """A body template's Mitsuba shape group (its unit mesh, made once an engine) and, per
    triangle, its part and unit normal in the template's frame."""

    def __init__(self, key: tuple[int, int, int], name: str) -> None:
        template = template_of(*key)
        vertices, triangles = template.unit_vertices, template.triangles
        mesh = mi.Mesh(name, int(vertices.shape[0]), int(triangles.shape[0]), has_vertex_normals=False,
                       has_vertex_texcoords=False)  # fmt: skip
        params = mi.traverse(mesh)
        params["vertex_positions"] = mi.Float(np.ascontiguousarray(vertices, np.float32).ravel())
        params["faces"] = mi.UInt32(np.ascontiguousarray(triangles, np.uint32).ravel())
        params.update()
        self.group: Any = mi.load_dict({"type": "shapegroup", name: mesh})
        self.part = template.triangle_part
        v = vertices.astype(np.float64)
        n = np.cross(v[triangles[:, 1]] - v[triangles[:, 0]], v[triangles[:, 2]] - v[triangles[:, 0]])
        length = np.linalg.norm(n, axis=1, keepdims=True)
        self.normal = n / np.where(length > 0, length, 1.0)


class _Instances:
    """The agents' scene: per body template (:func:`sensors.agents.template_of`) a shape group,
    made once, and a number of instances of it (slots), each holding one agent by its transform
    (unit box to map: rotation, scale to the agent's size less :data:`AGENT_LIFT_M`, centre) or
    none (:data:`PARKED`). A frame changes only the transforms that differ from the last frame's
    (Embree then builds its instances' tree again over the templates' trees, which it also
    rebuilds: Mitsuba 3.9 rebuilds every shape group whenever its scene changes). The scene is
    made again, with more slots, when a template has more agents than slots; its layout (the
    templates in order and their slots) is what :meth:`MitsubaEngine.checkpoint` keeps."""

    def __init__(self) -> None:
        self.layout: list[tuple[tuple[int, int, int], int]] = []
        self._templates: dict[tuple[int, int, int], _Template] = {}
        self.scene: Any = None
        self.count = 0  # agents of the frame (0: the scene is not cast)
        self._slot_props: list[tuple[Any, Any, Any]] = []
        self._last = np.zeros((0, 4, 4), np.float32)
        self.keys: list[tuple[int, int, int]] = []

    def set_layout(self, layout: list[tuple[tuple[int, int, int], int]]) -> None:
        self.layout, self.scene = layout, None

    def _template(self, key: tuple[int, int, int]) -> _Template:
        if key not in self._templates:
            self._templates[key] = _Template(key, f"template{len(self._templates)}")
        return self._templates[key]

    def update(self, agents: Agents) -> None:
        """Hold this frame's agents: per slot its agent (-1: none), template rows, class, instance
        id and normal turn (rotation times the inverse scale), for the hits' tables."""
        n = len(agents)
        keys = [_template_key(k) for k in map(tuple, body_keys(agents).tolist())] if n else []
        need: dict[tuple[int, int, int], int] = {}
        for k in keys:
            need[k] = need.get(k, 0) + 1
        have = dict(self.layout)
        if any(count > have.get(k, 0) for k, count in need.items()):
            grown = {k: need[k] + SPARE_SLOTS if need.get(k, 0) > c else c for k, c in have.items()}
            grown.update({k: c + SPARE_SLOTS for k, c in sorted(need.items()) if k not in have})
            self.set_layout(list(grown.items()))
        self.count = n
        self.keys = keys  # each agent's template
        if not self.layout:
            return
        first: dict[tuple[int, int, int], int] = {}
        slot = 0
        for k, c in self.layout:
            first[k] = slot
            slot += c
        agent_of_slot = np.full(slot, -1, np.int64)
        taken = dict.fromkeys(first, 0)
        for a, k in enumerate(keys):
            agent_of_slot[first[k] + taken[k]] = a
            taken[k] += 1
        rotations, centre, lwh = mesh_frames(agents)
        to_world = np.repeat(PARKED[None], slot, axis=0)
        held = agent_of_slot >= 0
        mine = agent_of_slot[held]
        to_world[held, :3, :3] = rotations[mine] * lwh[mine, None, :]
        to_world[held, :3, 3] = centre[mine]
        if self.scene is None:
            self._make(to_world)
        else:
            self._move(to_world)
        self.agent_of_slot = agent_of_slot
        self.slot_instance = np.zeros(slot, np.uint32)
        self.slot_instance[held] = agents.instance_id[mine]
        self.slot_class = np.zeros(slot, np.uint8)
        self.slot_class[held] = agents.semantic_class[mine]
        self.slot_turn = np.zeros((slot, 3, 3))
        self.slot_turn[held] = rotations[mine] / lwh[mine, None, :]  # R diag(1 / lwh): normals' map

    def _make(self, to_world: npt.NDArray[np.float64]) -> None:
        """The scene of the layout, its instances placed at ``to_world``."""
        scene: dict[str, Any] = {"type": "scene"}
        names: list[str] = []
        placed = to_world.astype(np.float32)  # the same transforms (kept in float32), made faster from float32
        for g, (k, c) in enumerate(self.layout):
            scene[f"group{g}"] = self._template(k).group
            for _ in range(c):
                names.append(f"slot{len(names)}")
                scene[names[-1]] = {"type": "instance", "shapegroup": self._template(k).group,
                                    "to_world": mi.ScalarTransform4f(placed[len(names) - 1])}  # fmt: skip
        self.scene = mi.load_dict(scene)
        params = mi.traverse(self.scene)
        self._slot_props = [params.properties[f"{name}.to_world"][:3] for name in names]
        shapes = {shape.id(): shape for shape in self.scene.shapes()}
        registry: Any = [dr.reinterpret_array(mi.UInt32, mi.ShapePtr(shapes[name])) for name in names]
        ids = np.array([int(r[0]) for r in registry])
        slot_of_id = np.full(int(ids.max()) + 1, NO_SLOT, np.uint32)
        slot_of_id[ids] = np.arange(len(names), dtype=np.uint32)
        self._slot_of_id = mi.UInt32(slot_of_id)  # a hit's instance (its registry id) -> its slot
        self._last = placed
        templates = [self._templates[k] for k, _ in self.layout]  # each template's tables once
        first = np.cumsum([0] + [t.part.shape[0] for t in templates])[:-1]
        self.slot_first = np.repeat(first, [c for _, c in self.layout]).astype(np.int64)
        self.part = np.concatenate([t.part for t in templates]).astype(np.uint8)
        self.normal = np.concatenate([t.normal for t in templates])

    def _move(self, to_world: npt.NDArray[np.float64]) -> None:
        """Give the instances whose transform changed their new one; Embree's trees are built again."""
        new = to_world.astype(np.float32)
        changed = np.flatnonzero(np.any(new != self._last, axis=(1, 2)))
        for s in changed.tolist():
            value, value_type, node = self._slot_props[s]
            # from float32: the same transform (Mitsuba keeps it in float32) in a quarter of the time
            mi.set_property(value, value_type, mi.AffineTransform4f(new[s]))
            node.parameters_changed(["to_world"])
        if changed.size:
            self.scene.parameters_changed([f"slot{s}" for s in changed.tolist()])
        self._last = new

    def cast(self, ray: Any) -> tuple[Any, Any, Any]:
        """Distance (inf: no hit), triangle of its template and slot of each ray."""
        hit: Any = self.scene.ray_intersect_preliminary(ray, coherent=True)
        registry: Any = dr.reinterpret_array(mi.UInt32, hit.instance)  # the instance's registry id
        slot = dr.gather(mi.UInt32, self._slot_of_id, registry, hit.is_valid())
        return hit.t, hit.prim_index, slot

    def test(self, ray: Any, active: Any = True) -> Any:
        """Whether each ``active`` ray meets an agent (False for the others: not cast)."""
        return self.scene.ray_test(ray, coherent=True, active=active)


class MitsubaEngine:
    """Keeps the static scene (made again when the static mesh changes) and the agents' scene of
    instanced body templates (:class:`_Instances`). The labels' silhouettes are cast in the
    templates' unit meshes, each agent's rays taken into its template's frame
    (:func:`sensors.scene.hits_alone_in_templates`).

    A hit on an agent depends on its template and transform alone, but which of two agents'
    surfaces at the very same distance a ray reports follows the order of the instances in the
    scene: :meth:`checkpoint` and :meth:`restore` carry the scene's layout to a run that
    continues."""

    name = "mitsuba"

    def __init__(self) -> None:
        self._static_mesh: ClassedMesh | None = None
        self._static: _Part | None = None
        self._static_normals = np.zeros((0, 3), np.float32)
        self.instances = _Instances()

    def scene(self, static: ClassedMesh, agents: Agents) -> MitsubaScene:
        if static is not self._static_mesh:
            self._static_mesh, self._static = static, _Part("static", static.vertices_m, static.triangles)
            self._static_normals = _face_normals(static.vertices_m, static.triangles)
        if self._static is None:
            raise RuntimeError("MitsubaEngine: no static scene")
        self.instances.update(agents)
        return MitsubaScene(self, static, self._static, agents)

    def checkpoint(self) -> dict[str, Any]:
        """The agents' scene's layout: its templates (class, body, pose) in order, each with its
        number of instances."""
        return {"slots": [[*k, c] for k, c in self.instances.layout]}

    def restore(self, state: dict[str, Any]) -> None:
        """Continue from :meth:`checkpoint`'s ``state`` (an empty one: as a fresh engine); the
        agents' scene is made at the next frame, of the same layout as the engine that ran on had."""
        self.instances.set_layout([((int(c), int(b), int(p)), int(n)) for c, b, p, n in state.get("slots", [])])


class MitsubaScene:
    """One frame: the static part and the agents' instances (kept by the engine). Per hit, the
    static world's triangles give its class and normal from tables (their rows, then one for
    rays that hit nothing), an agent's its slot and template triangle (:func:`_rows_of`)."""

    def __init__(self, engine: MitsubaEngine, static: ClassedMesh, part: _Part, agents: Agents) -> None:
        self._engine, self._static = engine, part
        self.agents = agents
        self._instances = engine.instances
        self._keys = engine.instances.keys  # each agent's template, for its silhouette
        self._nothing_row = static.triangle_class.shape[0]
        self._class_of_row = np.concatenate([static.triangle_class, [0]]).astype(np.uint8)
        normals = [engine._static_normals, np.zeros((1, 3), np.float32)]
        self._normal_of_row = np.ascontiguousarray(np.concatenate(normals)).view(np.uint32)  # bits, copied whole
        self._agent_meshes: AgentMeshes | None = None

    @property
    def agent_meshes(self) -> AgentMeshes:
        """The agents' posed meshes (made when first asked: the occupancy)."""
        if self._agent_meshes is None:
            self._agent_meshes = agent_meshes(self.agents)
        return self._agent_meshes

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
        if self._instances.count:  # only the rays the static world lets through
            hit = hit | self._instances.test(ray, ~hit)
        return np.asarray(hit.numpy(), np.bool_)

    def cast_raw(self, rays: npt.NDArray[np.float32]) -> Any:
        ray = _rays(rays)
        t, _ = self._static.cast(ray)
        if self._instances.count:
            t_agent = self._instances.cast(ray)[0]
            t = dr.select(t_agent < t, t_agent, t)
        return t.numpy()  # waits for the kernel: Dr.Jit launches it in the background

    def _hits(self, ray: Any) -> RayHits:
        t, prim = self._static.cast(ray)
        row = mi.UInt32(prim)
        agents = self._instances.count > 0
        if agents:
            t_agent, prim_agent, slot_agent = self._instances.cast(ray)
            nearer = t_agent < t
            t = dr.select(nearer, t_agent, t)
            row = dr.select(nearer, prim_agent, row)
            slot = dr.select(nearer, slot_agent, dr.opaque(mi.UInt32, int(NO_SLOT)))
        # opaque: the number changes from frame to frame, the compiled kernel must not
        row = dr.select(dr.isinf(t), dr.opaque(mi.UInt32, self._nothing_row), row)
        dr.eval(t, row, slot) if agents else dr.eval(t, row)
        range_m = t.numpy().astype(np.float32, copy=False)
        slots = slot.numpy() if agents else np.full(range_m.shape[0], NO_SLOT, np.uint32)
        return self._with_rows(range_m, row.numpy(), slots)

    def _with_rows(
        self, range_m: npt.NDArray[np.float32], rows: npt.NDArray[np.uint32], slots: npt.NDArray[np.uint32]
    ) -> RayHits:
        inst = self._instances
        if inst.count:
            tables = (inst.slot_class, inst.slot_instance, inst.slot_first, inst.slot_turn, inst.part, inst.normal)
        else:
            tables = _NO_AGENTS
        cls, instance, part, normal = _rows_of(
            np.ascontiguousarray(rows, np.uint32), np.ascontiguousarray(slots, np.uint32), self._class_of_row,
            self._normal_of_row, *tables,
        )  # fmt: skip
        return RayHits(range_m, cls, instance, normal.view(np.float32), part)

    def cast_static(self, rays: npt.NDArray[np.float32]) -> RayHits:
        """The rays cast into the static world alone (no agents)."""
        t, prim = self._static.cast(_rays(rays))
        row = dr.select(dr.isinf(t), dr.opaque(mi.UInt32, self._nothing_row), mi.UInt32(prim))
        dr.eval(t, row)
        # the static rows' instance and part are 0
        return self._with_rows(
            t.numpy().astype(np.float32, copy=False), row.numpy(), np.full(rays.shape[0], NO_SLOT, np.uint32)
        )

    def cast_agents_moving(
        self, rays: npt.NDArray[np.float32], dt_s: npt.NDArray[np.float64], ray_index: npt.NDArray[np.intp],
        agent_index: npt.NDArray[np.intp],
    ) -> PairHits:  # fmt: skip
        return cast_agents_moving(self.agents, rays, dt_s, ray_index, agent_index)

    def hits_alone(self, rays: npt.NDArray[np.float32], instance_id: npt.NDArray[np.uint32]) -> npt.NDArray[np.bool_]:
        """Each agent's silhouette cast in its template's unit mesh, as this engine casts its
        instances (:func:`sensors.scene.hits_alone_in_templates`)."""
        return hits_alone_in_templates(self.agents, self._keys, rays, instance_id)


_NO_AGENTS = (np.zeros(0, np.uint8), np.zeros(0, np.uint32), np.zeros(0, np.int64), np.zeros((0, 3, 3)),
              np.zeros(0, np.uint8), np.zeros((0, 3)))  # fmt: skip

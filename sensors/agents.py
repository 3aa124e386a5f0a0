"""The agents of a frame (struct of arrays), the ego, and their low-poly meshes, one instance
id each.

Each agent class has a template mesh (car: body, cabin and wheels; truck: cab, cargo box,
chassis and wheels; bus; motorcycle and bicycle with a rider; pedestrian with legs, torso,
arms and head). Templates are drawn in metres at a nominal size, then normalised into the
unit box ``[-0.5, 0.5]^3`` (x forward, y left, z up), so that scaling by an agent's l/w/h
keeps the whole mesh inside its box. Classes without a template get the plain box.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from networks.classes import SemanticClass
from networks.geometry import SE3, box_rotations, place_in_boxes
from networks.mesh import BOX_TRIANGLES, ClassedMesh
from networks.records import check_arrays
from sensors.pinhole import UNIT_CORNERS


@dataclass(frozen=True, slots=True)
class Agents:
    """Every agent of a frame but the ego, in the map frame: one row per agent.

    ``instance_id: (N,) uint32`` (> 0; the track id, stable over a scene, 0 is the static
    world), ``semantic_class: (N,) uint8`` (from the simulator), ``center_map_m: (N, 3)
    float64`` box centres, ``lwh_m: (N, 3) float64``, ``yaw_map_rad: (N,) float64`` about +z,
    ``pitch_rad: (N,) float64`` nose-up positive, ``velocity_map_mps: (N, 3) float64``,
    ``parked: (N,) bool`` (standing in a parking space for the whole scene).
    """

    instance_id: npt.NDArray[np.uint32]
    semantic_class: npt.NDArray[np.uint8]
    center_map_m: npt.NDArray[np.float64]
    lwh_m: npt.NDArray[np.float64]
    yaw_map_rad: npt.NDArray[np.float64]
    pitch_rad: npt.NDArray[np.float64]
    velocity_map_mps: npt.NDArray[np.float64]
    parked: npt.NDArray[np.bool_]

    def __post_init__(self) -> None:
        check_arrays(
            self, instance_id=(np.uint32, ("N",)), semantic_class=(np.uint8, ("N",)),
            center_map_m=(np.float64, ("N", 3)), lwh_m=(np.float64, ("N", 3)), yaw_map_rad=(np.float64, ("N",)),
            pitch_rad=(np.float64, ("N",)), velocity_map_mps=(np.float64, ("N", 3)), parked=(np.bool_, ("N",)),
        )  # fmt: skip
        if len(self) and int(self.instance_id.min()) == 0:
            raise ValueError("Agents.instance_id: 0 is reserved for the static world")

    def __len__(self) -> int:
        return int(self.instance_id.shape[0])

    @classmethod
    def empty(cls) -> Agents:
        z, z3 = np.zeros(0), np.zeros((0, 3))
        return cls(np.zeros(0, np.uint32), np.zeros(0, np.uint8), z3, z3, z, z, z3, np.zeros(0, np.bool_))

    @classmethod
    def standing(
        cls, instance_id: npt.ArrayLike, semantic_class: npt.ArrayLike, center_map_m: npt.ArrayLike,
        lwh_m: npt.ArrayLike, yaw_map_rad: npt.ArrayLike,
    ) -> Agents:  # fmt: skip
        """Agents that stand still, level, not parked (hand-built scenes)."""
        n = np.asarray(instance_id).shape[0]
        z = np.zeros(n)
        return cls(np.asarray(instance_id), np.asarray(semantic_class), np.asarray(center_map_m, np.float64),
                   np.asarray(lwh_m, np.float64), np.asarray(yaw_map_rad, np.float64), z, np.zeros((n, 3)),
                   np.zeros(n, np.bool_))  # fmt: skip

    def select(self, mask: npt.NDArray[np.bool_] | npt.NDArray[np.intp]) -> Agents:
        return Agents(
            self.instance_id[mask], self.semantic_class[mask], self.center_map_m[mask], self.lwh_m[mask],
            self.yaw_map_rad[mask], self.pitch_rad[mask], self.velocity_map_mps[mask], self.parked[mask],
        )  # fmt: skip

    def rotations(self) -> npt.NDArray[np.float64]:
        """``(N, 3, 3)`` map_R_box: yaw about +z after pitch about the box's y axis."""
        return box_rotations(self.yaw_map_rad, self.pitch_rad)

    def velocities_of(self, instance_id: npt.NDArray[np.uint32]) -> npt.NDArray[np.float64]:
        """``(K, 3)`` map-frame velocity of each given id; zero for ids not here (the static world)."""
        out = np.zeros((instance_id.shape[0], 3))
        if len(self) == 0:
            return out
        order = np.argsort(self.instance_id, kind="stable")
        ids = self.instance_id[order]
        pos = np.minimum(np.searchsorted(ids, instance_id), ids.shape[0] - 1)
        found = ids[pos] == instance_id
        out[found] = self.velocity_map_mps[order[pos[found]]]
        return out


@dataclass(frozen=True, slots=True)
class EgoState:
    """The ego in the map frame: ``center_map_m: (3,) float64`` box centre, ``lwh_m: (3,)
    float64``, ``yaw_map_rad`` and ``pitch_rad`` (nose-up positive), ``velocity_map_mps: (3,)
    float64``."""

    center_map_m: npt.NDArray[np.float64]
    lwh_m: npt.NDArray[np.float64]
    yaw_map_rad: float
    pitch_rad: float
    velocity_map_mps: npt.NDArray[np.float64]

    def __post_init__(self) -> None:
        check_arrays(self, center_map_m=(np.float64, (3,)), lwh_m=(np.float64, (3,)),
                     velocity_map_mps=(np.float64, (3,)))  # fmt: skip

    @classmethod
    def at(cls, map_SE3_ego: SE3, lwh_m: tuple[float, float, float] = (4.5, 1.8, 1.5)) -> EgoState:
        """An ego standing still, level, with its footprint centre at ``map_SE3_ego``'s origin
        and its heading along that frame's x axis (hand-built scenes)."""
        center = map_SE3_ego.translation + map_SE3_ego.rotation[:, 2] * lwh_m[2] / 2.0
        return cls(center, np.asarray(lwh_m, np.float64), map_SE3_ego.yaw_rad(), 0.0, np.zeros(3))

    def map_SE3_ego(self) -> SE3:
        """Ego frame: origin at the footprint centre on the ground, x forward, z up."""
        rotation = box_rotations(self.yaw_map_rad, self.pitch_rad)[0]
        footprint = self.center_map_m - rotation[:, 2] * self.lwh_m[2] / 2.0
        return SE3(rotation, footprint)


@dataclass(frozen=True, slots=True)
class AgentMeshes:
    """All agents merged into one mesh: ``vertices_m: (V, 3) float32`` in the map frame,
    ``triangles: (M, 3) int32``; ``triangle_instance: (M,) uint32`` and
    ``triangle_class: (M,) uint8`` tell which agent each triangle belongs to."""

    vertices_m: npt.NDArray[np.float32]
    triangles: npt.NDArray[np.int32]
    triangle_instance: npt.NDArray[np.uint32]
    triangle_class: npt.NDArray[np.uint8]

    def __post_init__(self) -> None:
        check_arrays(self, vertices_m=(np.float32, ("V", 3)), triangles=(np.int32, ("M", 3)),
                     triangle_instance=(np.uint32, ("M",)), triangle_class=(np.uint8, ("M",)))  # fmt: skip


@dataclass(frozen=True, slots=True)
class MeshTemplate:
    """A class's mesh in the unit box: ``unit_vertices: (V, 3) float64`` within
    ``[-0.5, 0.5]^3`` (x forward, y left, z up), ``triangles: (T, 3) int32``."""

    unit_vertices: npt.NDArray[np.float64]
    triangles: npt.NDArray[np.int32]

    def __post_init__(self) -> None:
        if np.abs(self.unit_vertices).max() > 0.5 + 1e-12:
            raise ValueError("MeshTemplate: vertices must lie in the unit box")
        if self.triangles.min() < 0 or self.triangles.max() >= self.unit_vertices.shape[0]:
            raise ValueError("MeshTemplate: triangle index out of range")


BOX_TEMPLATE = MeshTemplate(UNIT_CORNERS, np.asarray(BOX_TRIANGLES, dtype=np.int32))

Part = tuple[npt.NDArray[np.float64], npt.NDArray[np.int32]]


def _extrude(profile_xz: list[tuple[float, float]], y0: float, y1: float) -> Part:
    """Closed prism of a convex, counter-clockwise x-z profile between y0 and y1 (metres)."""
    p = np.asarray(profile_xz, dtype=np.float64)
    k = p.shape[0]
    near = np.column_stack([p[:, 0], np.full(k, y0), p[:, 1]])
    far = np.column_stack([p[:, 0], np.full(k, y1), p[:, 1]])
    i = np.arange(1, k - 1)
    caps = [np.stack([np.zeros_like(i), i, i + 1], 1), np.stack([np.full_like(i, k), k + i + 1, k + i], 1)]
    j = np.arange(k)
    jn = (j + 1) % k
    sides = [np.stack([j, k + j, jn], 1), np.stack([jn, k + j, k + jn], 1)]
    return np.concatenate([near, far]), np.concatenate(caps + sides).astype(np.int32)


def _cuboid(x0: float, x1: float, y0: float, y1: float, z0: float, z1: float) -> Part:
    return _extrude([(x0, z0), (x1, z0), (x1, z1), (x0, z1)], y0, y1)


def _wheel(x: float, radius: float, y0: float, y1: float, sides: int = 6) -> Part:
    """A wheel as a prism of ``sides`` sides, one corner on the ground."""
    step = 2.0 * np.pi / sides
    a = np.arange(sides) * step + (1.5 * np.pi) % step
    return _extrude([(x + radius * np.cos(t), radius + radius * np.sin(t)) for t in a], y0, y1)


def _template(lwh_m: tuple[float, float, float], parts: list[Part]) -> MeshTemplate:
    """Merge parts drawn in metres (x, y centred, z up from the ground) into a unit template."""
    offsets = np.cumsum([0] + [v.shape[0] for v, _ in parts[:-1]])
    verts = np.concatenate([v for v, _ in parts])
    tris = np.concatenate([t + off for (_, t), off in zip(parts, offsets, strict=True)])
    unit = verts / np.asarray(lwh_m) - np.array([0.0, 0.0, 0.5])
    return MeshTemplate(unit, tris.astype(np.int32))


def _axles(xs: tuple[float, ...], radius: float, y_in: float, y_out: float) -> list[Part]:
    return [_wheel(x, radius, s * y_in, s * y_out) for x in xs for s in (-1.0, 1.0)]


def _car() -> MeshTemplate:
    body = _extrude([(-2.25, 0.3), (2.15, 0.3), (2.25, 0.55), (2.2, 0.85), (-2.2, 0.92), (-2.25, 0.6)], -0.9, 0.9)
    cabin = _extrude([(-1.75, 0.9), (1.0, 0.9), (0.15, 1.5), (-1.35, 1.5)], -0.78, 0.78)
    return _template((4.5, 1.8, 1.5), [body, cabin, *_axles((1.4, -1.4), 0.32, 0.66, 0.88)])


def _truck() -> MeshTemplate:
    cab = _extrude([(2.3, 0.55), (3.75, 0.55), (3.75, 2.0), (3.45, 2.8), (2.3, 2.8)], -1.2, 1.2)
    cargo = _cuboid(-3.75, 2.15, -1.25, 1.25, 0.95, 3.2)
    chassis = _cuboid(-3.6, 3.6, -0.9, 0.9, 0.55, 0.95)
    return _template((7.5, 2.5, 3.2), [cab, cargo, chassis, *_axles((2.9, -1.9, -2.95), 0.5, 0.7, 1.2)])


def _bus() -> MeshTemplate:
    body = _extrude([(-6.0, 0.35), (6.0, 0.35), (6.0, 3.0), (5.75, 3.4), (-5.9, 3.4), (-6.0, 3.1)], -1.25, 1.25)
    return _template((12.0, 2.5, 3.4), [body, *_axles((4.3, -3.6), 0.5, 0.8, 1.22)])


def _rider(x_hip: float, z_seat: float, lean_m: float) -> list[Part]:
    """Legs, leaning torso and head of a seated rider (metres)."""
    legs = _cuboid(x_hip - 0.05, x_hip + 0.35, -0.18, 0.18, z_seat - 0.45, z_seat)
    torso = _extrude([(x_hip - 0.15, z_seat), (x_hip + 0.15, z_seat), (x_hip + 0.15 + lean_m, z_seat + 0.6),
                      (x_hip - 0.12 + lean_m, z_seat + 0.6)], -0.2, 0.2)  # fmt: skip
    head = _cuboid(x_hip + lean_m - 0.1, x_hip + lean_m + 0.12, -0.1, 0.1, z_seat + 0.62, z_seat + 0.85)
    return [legs, torso, head]


def _motorcycle() -> MeshTemplate:
    frame = _extrude([(-0.75, 0.4), (0.55, 0.35), (0.8, 0.85), (0.55, 0.95), (-0.7, 0.8)], -0.18, 0.18)
    bars = _cuboid(0.45, 0.6, -0.38, 0.38, 0.95, 1.05)
    wheels = [_wheel(x, 0.3, -0.07, 0.07) for x in (-0.75, 0.75)]
    return _template((2.2, 0.8, 1.7), [frame, bars, *wheels, *_rider(-0.3, 0.85, 0.2)])


def _bicycle() -> MeshTemplate:
    frame = _extrude([(-0.45, 0.35), (0.5, 0.35), (0.35, 0.75), (-0.3, 0.8)], -0.03, 0.03)
    bars = _cuboid(0.35, 0.45, -0.28, 0.28, 0.95, 1.0)
    wheels = [_wheel(x, 0.34, -0.03, 0.03) for x in (-0.55, 0.55)]
    return _template((1.8, 0.6, 1.75), [frame, bars, *wheels, *_rider(-0.3, 0.9, 0.25)])


def _pedestrian() -> MeshTemplate:
    legs = [_cuboid(-0.08, 0.08, s * 0.03, s * 0.15, 0.0, 0.85) for s in (-1.0, 1.0)]
    torso = _cuboid(-0.12, 0.12, -0.19, 0.19, 0.85, 1.45)
    arms = [_cuboid(-0.06, 0.06, s * 0.19, s * 0.25, 0.8, 1.42) for s in (-1.0, 1.0)]
    head = _cuboid(-0.1, 0.1, -0.09, 0.09, 1.5, 1.75)
    return _template((0.3, 0.5, 1.75), [*legs, torso, *arms, head])


TEMPLATES: dict[int, MeshTemplate] = {
    int(SemanticClass.CAR): _car(),
    int(SemanticClass.TRUCK): _truck(),
    int(SemanticClass.BUS): _bus(),
    int(SemanticClass.MOTORCYCLE): _motorcycle(),
    int(SemanticClass.BICYCLE): _bicycle(),
    int(SemanticClass.PEDESTRIAN): _pedestrian(),
}
"""Template mesh per agent class; other classes are drawn as their box."""


AGENT_LIFT_M = 0.03
"""Agents' meshes stand this far above the bottom of their box (the road): a clearance no
sensor resolves, which keeps every return off the road out of every box and every return of
an agent inside its box, under strict point-in-box tests of the exported labels."""


def agent_meshes(agents: Agents, templates: dict[int, MeshTemplate] | None = None) -> AgentMeshes:
    """All agents' template meshes, scaled to their l/w/h (less :data:`AGENT_LIFT_M` at the
    bottom) and posed; one pass per class."""
    table = TEMPLATES if templates is None else templates
    rotations = agents.rotations()
    mesh_center = agents.center_map_m + rotations[:, :, 2] * (AGENT_LIFT_M / 2.0)
    mesh_lwh = agents.lwh_m - np.array([0.0, 0.0, AGENT_LIFT_M])
    verts, tris, inst, cls = [], [], [], []
    offset = 0
    for c in np.unique(agents.semantic_class):
        mask = agents.semantic_class == c
        group, template = agents.select(mask), table.get(int(c), BOX_TEMPLATE)
        n, v, t = len(group), template.unit_vertices.shape[0], template.triangles.shape[0]
        posed = place_in_boxes(template.unit_vertices, mesh_center[mask], mesh_lwh[mask], rotations[mask])
        verts.append(posed.reshape(-1, 3))
        tris.append(
            (template.triangles[None] + offset + v * np.arange(n, dtype=np.int32)[:, None, None]).reshape(-1, 3)
        )
        inst.append(np.repeat(group.instance_id, t))
        cls.append(np.full(n * t, c, np.uint8))
        offset += n * v
    if not verts:
        return AgentMeshes(np.zeros((0, 3), np.float32), np.zeros((0, 3), np.int32), np.zeros(0, np.uint32),
                           np.zeros(0, np.uint8))  # fmt: skip
    return AgentMeshes(np.concatenate(verts).astype(np.float32), np.concatenate(tris).astype(np.int32),
                       np.concatenate(inst), np.concatenate(cls))  # fmt: skip


def as_classed_mesh(meshes: AgentMeshes) -> ClassedMesh:
    return ClassedMesh(meshes.vertices_m, meshes.triangles, meshes.triangle_class)


AGENT_CLASS_NAMES = {c.value: c.label for c in SemanticClass if c.is_agent}

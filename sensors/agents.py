"""The agents of a frame (struct of arrays), the ego, and their meshes, one instance id each.

Each agent is drawn with its class's body type that fits its size (:mod:`sensors.bodies`:
sedans to pickups, box trucks and semi-trailers, city buses and coaches, riders, walkers in
their gait), normalised into the unit box ``[-0.5, 0.5]^3`` (x forward, y left, z up), so
that scaling by an agent's l/w/h keeps the whole mesh inside its box. Classes without a body
get the plain box.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import IntFlag

import numpy as np
import numpy.typing as npt
from numba import njit

from networks.classes import SemanticClass
from networks.geometry import SE3, box_rotations
from networks.mesh import BOX_TRIANGLES, ClassedMesh
from networks.records import check_arrays
from sensors.bodies import BODIES, Body, body_of, pose_of
from sensors.parts import Part
from sensors.pinhole import UNIT_CORNERS


class Lamp(IntFlag):
    """A vehicle's lamps, as bits of :attr:`Agents.lamps` (set by the traffic)."""

    LIGHTS = 1  # head and tail lamps on: traffic on the move or waiting (parked vehicles are dark)
    BRAKE = 2  # brake lamps
    LEFT = 4  # left indicators flashing (a turn, a lane change, hazard lights)
    RIGHT = 8
    FLASH = 16  # flashing indicators are lit at this instant


NO_LAMPS = np.zeros(0, np.uint8)
"""The default of :attr:`Agents.lamps`: every lamp off."""
NOT_TURNING = np.zeros(0, np.float64)
"""The default of :attr:`Agents.yaw_rate_rad_s`: every heading kept."""
NO_GAIT = np.zeros(0, np.float64)
"""The default of :attr:`Agents.gait_cycles`: not counted (NaN)."""


@dataclass(frozen=True, slots=True)
class Agents:
    """Every agent of a frame but the ego, in the map frame: one row per agent.

    ``instance_id: (N,) uint32`` (> 0; the track id, stable over a scene, 0 is the static
    world), ``semantic_class: (N,) uint8`` (from the simulator), ``center_map_m: (N, 3)
    float64`` box centres, ``lwh_m: (N, 3) float64``, ``yaw_map_rad: (N,) float64`` about +z,
    ``pitch_rad: (N,) float64`` nose-up positive, ``velocity_map_mps: (N, 3) float64``,
    ``parked: (N,) bool`` (standing in a parking space for the whole scene), ``lamps: (N,)
    uint8`` :class:`Lamp` bits (all off where not given), ``yaw_rate_rad_s: (N,) float64`` the
    heading's rate of turn up to the frame's time, counter-clockwise positive (0 where not given),
    and ``yaw_rate_after_rad_s: (N,) float64`` its rate from then on (the same where not given):
    the traffic's headings change step by step, a body turns between two steps at the rate of
    that step (:func:`turn_rate_at`). ``gait_cycles: (N,) float64``: the gait cycles a walker
    has walked (its distance walked over its stride, summed step by step; NaN where not counted:
    its pose then follows its position along its heading, see :func:`sensors.bodies.pose_of`).
    """

    instance_id: npt.NDArray[np.uint32]
    semantic_class: npt.NDArray[np.uint8]
    center_map_m: npt.NDArray[np.float64]
    lwh_m: npt.NDArray[np.float64]
    yaw_map_rad: npt.NDArray[np.float64]
    pitch_rad: npt.NDArray[np.float64]
    velocity_map_mps: npt.NDArray[np.float64]
    parked: npt.NDArray[np.bool_]
    lamps: npt.NDArray[np.uint8] = field(default_factory=lambda: NO_LAMPS)
    yaw_rate_rad_s: npt.NDArray[np.float64] = field(default_factory=lambda: NOT_TURNING)
    yaw_rate_after_rad_s: npt.NDArray[np.float64] = field(default_factory=lambda: NOT_TURNING)
    gait_cycles: npt.NDArray[np.float64] = field(default_factory=lambda: NO_GAIT)

    def __post_init__(self) -> None:
        if self.lamps is NO_LAMPS:
            object.__setattr__(self, "lamps", np.zeros(self.instance_id.shape[0], np.uint8))
        if self.yaw_rate_rad_s is NOT_TURNING:
            object.__setattr__(self, "yaw_rate_rad_s", np.zeros(self.instance_id.shape[0]))
        if self.yaw_rate_after_rad_s is NOT_TURNING:
            object.__setattr__(self, "yaw_rate_after_rad_s", self.yaw_rate_rad_s)
        if self.gait_cycles is NO_GAIT:
            object.__setattr__(self, "gait_cycles", np.full(self.instance_id.shape[0], np.nan))
        check_arrays(
            self, instance_id=(np.uint32, ("N",)), semantic_class=(np.uint8, ("N",)),
            center_map_m=(np.float64, ("N", 3)), lwh_m=(np.float64, ("N", 3)), yaw_map_rad=(np.float64, ("N",)),
            pitch_rad=(np.float64, ("N",)), velocity_map_mps=(np.float64, ("N", 3)), parked=(np.bool_, ("N",)),
            lamps=(np.uint8, ("N",)), yaw_rate_rad_s=(np.float64, ("N",)), yaw_rate_after_rad_s=(np.float64, ("N",)),
            gait_cycles=(np.float64, ("N",)),
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
            self.lamps[mask], self.yaw_rate_rad_s[mask], self.yaw_rate_after_rad_s[mask], self.gait_cycles[mask],
        )  # fmt: skip

    def joined(self, other: Agents) -> Agents:
        """These agents followed by ``other``'s."""
        return Agents(*(np.concatenate([getattr(self, f), getattr(other, f)]) for f in AGENT_FIELDS))

    def turning(self) -> bool:
        """Whether any heading turns, before the frame's time or after."""
        return bool(self.yaw_rate_rad_s.any() or self.yaw_rate_after_rad_s.any())

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


def turn_rate_at(before: npt.ArrayLike, after: npt.ArrayLike, dt_s: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """The rate of turn ``dt_s`` from the frame's time (arguments broadcast): ``before`` it (the
    rate over the traffic's step that ended then), ``after`` from it on (over the next step), so
    a body's heading follows its headings interpolated between the steps."""
    return np.where(np.asarray(dt_s) < 0.0, np.asarray(before, np.float64), np.asarray(after, np.float64))


def motion_over(
    velocity_map_mps: npt.ArrayLike, yaw_rate_rad_s: npt.ArrayLike, dt_s: npt.ArrayLike
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """``(..., 3)`` shift of a box's centre and ``(...)`` turn of its heading (radians) over ``dt_s``
    for a body moving at ``velocity_map_mps`` (at ``dt_s`` 0) whose heading turns at
    ``yaw_rate_rad_s``: speed and rate of turn kept, so the centre runs along a circular arc
    (``velocity * dt`` exactly where the rate is 0). Arguments broadcast against each other
    (velocity with a last axis of 3)."""
    velocity = np.asarray(velocity_map_mps, np.float64)
    dt = np.asarray(dt_s, np.float64)
    turn = np.asarray(yaw_rate_rad_s, np.float64) * dt
    along = dt * np.sinc(turn / np.pi)  # sin(turn) / rate
    across = dt * (0.5 * turn) * np.sinc(turn / (2.0 * np.pi)) ** 2  # (1 - cos(turn)) / rate
    vx, vy, vz = velocity[..., 0], velocity[..., 1], velocity[..., 2]
    shift = np.stack(np.broadcast_arrays(along * vx - across * vy, along * vy + across * vx, dt * vz), axis=-1)
    return shift, turn


def turned_about_z(vectors: npt.NDArray[np.float64], turn_rad: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """``(..., 3)`` vectors turned by ``turn_rad`` about the map's +z (counter-clockwise)."""
    c, s = np.cos(turn_rad), np.sin(turn_rad)
    x, y = vectors[..., 0], vectors[..., 1]
    return np.stack(np.broadcast_arrays(c * x - s * y, s * x + c * y, vectors[..., 2]), axis=-1)


AGENT_FIELDS = ("instance_id", "semantic_class", "center_map_m", "lwh_m", "yaw_map_rad", "pitch_rad",
                "velocity_map_mps", "parked", "lamps", "yaw_rate_rad_s", "yaw_rate_after_rad_s",
                "gait_cycles")  # fmt: skip


@dataclass(frozen=True, slots=True)
class EgoState:
    """The ego in the map frame: ``center_map_m: (3,) float64`` box centre, ``lwh_m: (3,)
    float64``, ``yaw_map_rad`` and ``pitch_rad`` (nose-up positive), ``velocity_map_mps: (3,)
    float64``, ``yaw_rate_rad_s`` up to the frame's time and ``yaw_rate_after_rad_s`` from then on
    (counter-clockwise positive; None: the same, see :class:`Agents`)."""

    center_map_m: npt.NDArray[np.float64]
    lwh_m: npt.NDArray[np.float64]
    yaw_map_rad: float
    pitch_rad: float
    velocity_map_mps: npt.NDArray[np.float64]
    yaw_rate_rad_s: float = 0.0
    yaw_rate_after_rad_s: float | None = None

    def __post_init__(self) -> None:
        check_arrays(
            self, center_map_m=(np.float64, (3,)), lwh_m=(np.float64, (3,)), velocity_map_mps=(np.float64, (3,))
        )

    def turn_rates(self) -> tuple[float, float]:
        """The rate of turn before the frame's time and after it."""
        after = self.yaw_rate_rad_s if self.yaw_rate_after_rad_s is None else self.yaw_rate_after_rad_s
        return self.yaw_rate_rad_s, after

    def turning(self) -> bool:
        return any(rate != 0.0 for rate in self.turn_rates())

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
    ``triangle_class: (M,) uint8`` tell which agent each triangle belongs to,
    ``triangle_part: (M,) uint8`` what it is made of (:class:`~sensors.parts.Part`)."""

    vertices_m: npt.NDArray[np.float32]
    triangles: npt.NDArray[np.int32]
    triangle_instance: npt.NDArray[np.uint32]
    triangle_class: npt.NDArray[np.uint8]
    triangle_part: npt.NDArray[np.uint8]

    def __post_init__(self) -> None:
        check_arrays(self, vertices_m=(np.float32, ("V", 3)), triangles=(np.int32, ("M", 3)),
                     triangle_instance=(np.uint32, ("M",)), triangle_class=(np.uint8, ("M",)),
                     triangle_part=(np.uint8, ("M",)))  # fmt: skip


@dataclass(frozen=True, slots=True)
class MeshTemplate:
    """A body's mesh in the unit box: ``unit_vertices: (V, 3) float64`` within
    ``[-0.5, 0.5]^3`` (x forward, y left, z up), ``triangles: (T, 3) int32`` and the
    ``triangle_part: (T,) uint8`` each is made of (:class:`~sensors.parts.Part`)."""

    unit_vertices: npt.NDArray[np.float64]
    triangles: npt.NDArray[np.int32]
    triangle_part: npt.NDArray[np.uint8]

    def __post_init__(self) -> None:
        if np.abs(self.unit_vertices).max() > 0.5 + 1e-12:
            raise ValueError("MeshTemplate: vertices must lie in the unit box")
        if self.triangles.min() < 0 or self.triangles.max() >= self.unit_vertices.shape[0]:
            raise ValueError("MeshTemplate: triangle index out of range")
        if self.triangle_part.shape != (self.triangles.shape[0],):
            raise ValueError("MeshTemplate: one part per triangle")


BOX_TEMPLATE = MeshTemplate(
    UNIT_CORNERS, np.asarray(BOX_TRIANGLES, dtype=np.int32), np.full(len(BOX_TRIANGLES), int(Part.SURFACE), np.uint8)
)


def _unit_templates(body: Body) -> tuple[MeshTemplate, ...]:
    """Every pose of a body, normalised together into the unit box (one scale for all poses,
    so a walker's limbs swing inside its box without the body changing size); poses that are
    proportions (a truck's) each on its own."""
    pieces = [body.build(p) for p in range(body.poses)]
    groups = [[p] for p in pieces] if body.proportions else [pieces]
    out = []
    for group in groups:
        lo = np.min([p.vertices.min(axis=0) for p in group], axis=0)
        hi = np.max([p.vertices.max(axis=0) for p in group], axis=0)
        centre, extent = (lo + hi) / 2.0, np.maximum(hi - lo, 1e-6)
        for p in group:
            unit = np.clip((p.vertices - centre) / extent, -0.5, 0.5)
            out.append(MeshTemplate(unit, p.triangles, p.parts))
    return tuple(out)


_TEMPLATE_CACHE: dict[tuple[int, int], tuple[MeshTemplate, ...]] = {}


def template_of(semantic_class: int, body: int, pose: int) -> MeshTemplate:
    """The unit mesh of a class's body type in a pose (:mod:`sensors.bodies`); the box for
    classes without bodies."""
    bodies = BODIES.get(int(semantic_class))
    if not bodies:
        return BOX_TEMPLATE
    key = (int(semantic_class), int(body))
    if key not in _TEMPLATE_CACHE:
        _TEMPLATE_CACHE[key] = _unit_templates(bodies[body])
    poses = _TEMPLATE_CACHE[key]
    return poses[pose % len(poses)]


def template_poses(semantic_class: int, body: int) -> int:
    """How many templates a class's body type has (:func:`template_of` takes a pose modulo it)."""
    bodies = BODIES.get(int(semantic_class))
    if not bodies:
        return 1
    template_of(semantic_class, body, 0)
    return len(_TEMPLATE_CACHE[(int(semantic_class), int(body))])


AGENT_LIFT_M = 0.03
"""Agents' meshes stand this far above the bottom of their box (the road): a clearance no
sensor resolves, which keeps every return off the road out of every box and every return of
an agent inside its box, under strict point-in-box tests of the exported labels."""


def body_keys(agents: Agents) -> npt.NDArray[np.int64]:
    """``(N, 3)`` class, body type and pose of each agent (:func:`sensors.bodies.body_of`,
    :func:`sensors.bodies.pose_of`): a walker's pose from the gait cycles it has walked (else
    from its distance along its heading), so its legs move with the ground it covers and stand
    still when it does; a truck's from its length over its height."""
    keys = np.zeros((len(agents), 3), np.int64)
    speed = np.linalg.norm(agents.velocity_map_mps[:, :2], axis=1)
    along = agents.center_map_m[:, 0] * np.cos(agents.yaw_map_rad) + agents.center_map_m[:, 1] * np.sin(
        agents.yaw_map_rad
    )
    for i in range(len(agents)):
        c = int(agents.semantic_class[i])
        length, height = float(agents.lwh_m[i, 0]), float(agents.lwh_m[i, 2])
        pose = pose_of(c, float(speed[i]), float(along[i]), height, float(agents.gait_cycles[i]), length)
        keys[i] = (c, body_of(c, agents.lwh_m[i], int(agents.instance_id[i])), pose)
    return keys


def rows_of_ids(ids: npt.NDArray[np.uint32], wanted: npt.NDArray[np.uint32]) -> npt.NDArray[np.intp]:
    """Each ``wanted`` instance id's row in ``ids`` (ids unique; -1 where it has none)."""
    if len(ids) == 0:
        return np.full(len(wanted), -1, np.intp)
    order = np.argsort(ids, kind="stable")
    pos = np.minimum(np.searchsorted(ids[order], wanted), len(order) - 1)
    return np.where(ids[order[pos]] == wanted, order[pos], -1)


def mesh_frames(
    agents: Agents,
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64]]:  # fmt: skip
    """Where each agent's body template is drawn: its rotation ``(K, 3, 3)``, the centre
    ``(K, 3)`` and size ``(K, 3)`` of its box less :data:`AGENT_LIFT_M` at the bottom (the unit
    mesh is scaled by the size, turned and moved to the centre)."""
    rotations = agents.rotations()
    centre = agents.center_map_m + rotations[:, :, 2] * (AGENT_LIFT_M / 2.0)
    lwh = agents.lwh_m - np.array([0.0, 0.0, AGENT_LIFT_M])
    return rotations, centre, lwh


def agent_meshes(agents: Agents) -> AgentMeshes:
    """All agents' body meshes, scaled to their l/w/h (less :data:`AGENT_LIFT_M` at the
    bottom) and posed. The vertices come grouped by body type and pose (the groups in order of
    class, body, pose; an agent's own in order of the agents), the triangles by instance id."""
    if len(agents) == 0:
        return AgentMeshes(np.zeros((0, 3), np.float32), np.zeros((0, 3), np.int32), np.zeros(0, np.uint32),
                           np.zeros(0, np.uint8), np.zeros(0, np.uint8))  # fmt: skip
    rotations, mesh_center, mesh_lwh = mesh_frames(agents)
    groups, group_of = np.unique(body_keys(agents), axis=0, return_inverse=True)
    group_of = group_of.ravel()
    templates = [template_of(c, body, pose) for c, body, pose in groups.tolist()]
    by_group = np.argsort(group_of, kind="stable")  # the agents in the order of their vertices
    by_instance = np.argsort(agents.instance_id[by_group], kind="stable")  # ... and of their triangles
    vertices, triangles, instance, cls, part = _posed_meshes(
        np.concatenate([t.unit_vertices for t in templates]).astype(np.float64),
        np.concatenate([t.triangles for t in templates]).astype(np.int32),
        np.concatenate([t.triangle_part for t in templates]).astype(np.uint8),
        _starts([t.unit_vertices.shape[0] for t in templates]), _starts([t.triangles.shape[0] for t in templates]),
        groups[:, 0].astype(np.uint8), group_of[by_group], mesh_center[by_group], mesh_lwh[by_group],
        rotations[by_group], agents.instance_id[by_group], by_instance,
    )  # fmt: skip
    return AgentMeshes(vertices, triangles, instance, cls, part)


def _starts(counts: list[int]) -> npt.NDArray[np.int64]:
    """``(K + 1,)`` where each of ``K`` consecutive runs of ``counts`` starts, and their end."""
    return np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)


@njit(cache=True, nogil=True)
def _placed(r0: float, r1: float, r2: float, x: float, y: float, z: float, c: float) -> float:  # pragma: no cover
    """One coordinate of a point ``(x, y, z)`` (in its box, scaled) turned by the rotation's row
    ``(r0, r1, r2)`` and moved by ``c``: as :func:`networks.geometry.place_in_boxes` computes it,
    the float64 bits included (numpy's einsum there sums ``(x r0 + z r2) + y r1``, from 0)."""
    return (0.0 + (((0.0 + r0 * x) + r2 * z) + (0.0 + r1 * y))) + c


@njit(cache=True, nogil=True)
def _posed_meshes(
    unit_vertices: npt.NDArray[np.float64], triangles: npt.NDArray[np.int32], parts: npt.NDArray[np.uint8],
    vertex_starts: npt.NDArray[np.int64], triangle_starts: npt.NDArray[np.int64], group_class: npt.NDArray[np.uint8],
    group: npt.NDArray[np.intp], center: npt.NDArray[np.float64], lwh: npt.NDArray[np.float64],
    rotations: npt.NDArray[np.float64], instance_id: npt.NDArray[np.uint32], triangle_order: npt.NDArray[np.intp],
) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.int32], npt.NDArray[np.uint32], npt.NDArray[np.uint8],
           npt.NDArray[np.uint8]]:  # fmt: skip  # pragma: no cover - compiled
    """The merged mesh of agents, each posed from its group's template (rows ``vertex_starts[g]``
    to ``vertex_starts[g + 1]`` of ``unit_vertices``, likewise the triangles): the vertices agent
    after agent, the triangles in ``triangle_order`` of the agents, each vertex posed by
    :func:`_placed`."""
    n = group.shape[0]
    first_vertex = np.zeros(n + 1, np.int64)
    first_triangle = np.zeros(n + 1, np.int64)
    for a in range(n):
        g = group[a]
        first_vertex[a + 1] = first_vertex[a] + vertex_starts[g + 1] - vertex_starts[g]
    for rank in range(n):
        g = group[triangle_order[rank]]
        first_triangle[rank + 1] = first_triangle[rank] + triangle_starts[g + 1] - triangle_starts[g]
    vertices = np.empty((first_vertex[n], 3), np.float32)
    for a in range(n):
        g = group[a]
        row = first_vertex[a]
        for k in range(vertex_starts[g], vertex_starts[g + 1]):
            x, y, z = unit_vertices[k, 0] * lwh[a, 0], unit_vertices[k, 1] * lwh[a, 1], unit_vertices[k, 2] * lwh[a, 2]
            for i in range(3):
                r = rotations[a, i]
                vertices[row, i] = np.float32(_placed(r[0], r[1], r[2], x, y, z, center[a, i]))
            row += 1
    m = first_triangle[n]
    out_triangles = np.empty((m, 3), np.int32)
    out_instance = np.empty(m, np.uint32)
    out_class = np.empty(m, np.uint8)
    out_part = np.empty(m, np.uint8)
    for rank in range(n):
        a = triangle_order[rank]
        g = group[a]
        row = first_triangle[rank]
        offset = np.int32(first_vertex[a])
        for t in range(triangle_starts[g], triangle_starts[g + 1]):
            for j in range(3):
                out_triangles[row, j] = triangles[t, j] + offset
            out_instance[row], out_class[row], out_part[row] = instance_id[a], group_class[g], parts[t]
            row += 1
    return vertices, out_triangles, out_instance, out_class, out_part


def as_classed_mesh(meshes: AgentMeshes) -> ClassedMesh:
    return ClassedMesh(meshes.vertices_m, meshes.triangles, meshes.triangle_class)


AGENT_CLASS_NAMES = {c.value: c.label for c in SemanticClass if c.is_agent}

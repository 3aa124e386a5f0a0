"""Semantic occupancy of a frame, what the sensors observed of it, and the motion of what fills it.

The grid lies in the ego frame (Occ3D-nuScenes by default: 0.4 m voxels, x and y -40..40 m,
z -1..5.4 m, 200 x 200 x 16). A voxel is occupied by every volume or surface that meets it:

- agents (and traffic-light heads and sign plates): the voxels of the agent's 3D box
  (:func:`gtgen.voxels.box_voxels`, exact overlap) that its body's surface meets, or that its
  surface encloses (no path of face-neighbouring voxels free of its surface leads out of the
  box). Bodies are built of overlapping closed parts, not one watertight mesh, so ray parity
  (Open3D's ``compute_occupancy``) would count the overlaps as outside; the enclosure test
  does not. An agent whose mesh is not in the frame's scene fills its whole box;
- the static world's solids (buildings, trees, poles, bridge piers: prisms; tree crowns): their
  surfaces and every voxel whose centre lies inside them (:mod:`sensors.solids`: ray parity
  along a horizontal ray from a voxel centre under a solid's top, whatever the ego's pitch). Inside
  and outside change only across a solid's wall, top or floor (each prism closed by its top moved
  down to its walls' foot), so the centres of face-neighbouring voxels none of these meets lie
  alike: a few centres are cast per part of such voxels (runs along rows joined across
  neighbouring rows); a voxel only a floor meets joins the part of the voxel above or below it
  where no floor lies between their centres, else is cast on its own; a voxel meets a solid iff it
  meets its surface or its centre is inside, so this is exact;
- the static world's surfaces (roads, sidewalks, curbs, crossings, markings, terrain): the
  voxels their triangles meet (:func:`gtgen.voxels.triangle_voxels`, exact).

Where several classes meet one voxel, the one earliest in :data:`PRIORITY` names it: the static
world's objects (fences, trees, buildings, poles, lights, signs), then the ground (curbs,
sidewalks, paint, crossings, road, terrain), then agents (small before large). Where the static
world's surfaces of several Occ3D classes meet one voxel (a road at a curb, terrain at a
building's foot), the voxel goes to the class that needs it (:func:`_shared_surfaces`): a point
of a surface lies within half a voxel of its own voxel and of the 7 neighbours on its side of
the voxel's middle, so a class needs the voxel for the area of its surface in the voxel's
eighths whose 7 neighbours hold none of its voxels; the most such area wins, the priority names
the voxel where no class needs it (the terrain, laid under the whole world, counts as hidden
under paving). A voxel the ground
runs through is ground, as in Occ3D, where a voxel takes the class of the points it reflects and
the ground reflects most of them in its layer: an agent's voxels start above the ground's layer
(a tyre's lowest 20 cm lie in the road's voxels, within half a voxel of the car's). ``semantics``
holds Occ3D-nuScenes's 18 classes (:data:`OCC3D_CLASSES`, 17 = free), mapped from ours through
nuScenes-lidarseg's categories (:data:`OCC3D_OF_CLASS`); ``semantics_native`` our own classes,
255 = free.

``mask_lidar``: the voxels each LiDAR ray crossed from the sensor to its return, the return's
voxel included (rays without a return are not counted; a timed sweep's rays from where the
sensor was when each fired, moved with the ego's velocity to the frame's time). ``mask_camera``: the same for camera
rays cast at the grid's resolution (one ray per voxel width at the grid's far corner) up to
what they hit, or out of the grid. A voxel in neither mask was not observed. The voxels of a
ray are those a voxel walk visits (Amanatides and Woo's, :class:`~gtgen.voxels.SegmentWalk`);
a ray passes through occupied voxels only where it passes by a surface in them (Occ3D: a voxel
that reflects points is occupied, one a beam passes through in the air is free) or through an
agent's glass into its body (an agent's volume is solid, glass returns nothing).

Flow: every agent voxel carries the velocity of its agent's body at the voxel's centre, in the
ego frame's axes (``flow_mps``: over the ground, the agent's velocity and its turning about its
box's centre; ``flow_relative_mps``: as the ego sees it move, the velocity relative to the ego
frame, which moves with the ego's velocity and turns with its rate of turn). Every LiDAR point
carries its scene flow to the next sweep: where that point of its object is one sweep period
later (the object's box moving along its arc, :func:`sensors.agents.motion_over`), in the LiDAR
frame's axes (0 on the static world).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from gtgen import voxel_kernels
from gtgen.nuscenes_lidarseg import LIDARSEG_CATEGORIES, LIDARSEG_LUT
from gtgen.voxels import OccupancyGrid, VoxelGrid, box_voxels, triangle_voxels, walk_from, walk_voxels
from networks.classes import SemanticClass
from networks.geometry import SE3, box_rotations
from networks.mesh import ClassedMesh
from networks.records import check_arrays
from sensors.agents import AgentMeshes, Agents, EgoState, motion_over, turn_rate_at, turned_about_z
from sensors.camera import CameraSpec
from sensors.lidar import LidarOutput
from sensors.rays import sensor_rays
from sensors.sweep import reference_s, sensor_origins

if TYPE_CHECKING:  # Open3D loads only where rays are cast, not in the writer process
    from sensors.solids import Solids

FREE_NATIVE = 255
OCC3D_CLASSES = (
    "others", "barrier", "bicycle", "bus", "car", "construction_vehicle", "motorcycle", "pedestrian",
    "traffic_cone", "trailer", "truck", "driveable_surface", "other_flat", "sidewalk", "terrain", "manmade",
    "vegetation", "free",
)  # fmt: skip
OCC3D_FREE = OCC3D_CLASSES.index("free")
OCC3D_TERRAIN = OCC3D_CLASSES.index("terrain")
_PAVED_BITS = np.uint32(sum(1 << OCC3D_CLASSES.index(c) for c in ("driveable_surface", "other_flat", "sidewalk")))
# nuScenes-lidarseg category -> Occ3D-nuScenes class (the lidarseg challenge's 16 classes).
_OCC3D_OF_CATEGORY = {
    "human.pedestrian.adult": "pedestrian", "vehicle.bicycle": "bicycle", "vehicle.bus.rigid": "bus",
    "vehicle.car": "car", "vehicle.motorcycle": "motorcycle", "vehicle.truck": "truck", "vehicle.trailer": "trailer",
    "vehicle.construction": "construction_vehicle", "movable_object.trafficcone": "traffic_cone",
    "movable_object.barrier": "barrier",
    "flat.driveable_surface": "driveable_surface", "flat.sidewalk": "sidewalk", "flat.terrain": "terrain",
    "static.manmade": "manmade", "static.vegetation": "vegetation",
}  # fmt: skip
OCC3D_OF_CLASS: dict[SemanticClass, str] = {
    c: _OCC3D_OF_CATEGORY.get(LIDARSEG_CATEGORIES[LIDARSEG_LUT[int(c)]], "others") for c in SemanticClass
}
OCC3D_LUT = np.full(256, OCC3D_CLASSES.index("others"), np.uint8)
for _cls, _name in OCC3D_OF_CLASS.items():
    OCC3D_LUT[int(_cls)] = OCC3D_CLASSES.index(_name)
OCC3D_LUT[FREE_NATIVE] = OCC3D_FREE

PRIORITY = (
    SemanticClass.OTHER_OBJECT, SemanticClass.FENCE, SemanticClass.TRUNK, SemanticClass.VEGETATION,
    SemanticClass.BUILDING, SemanticClass.POLE, SemanticClass.TRAFFIC_LIGHT, SemanticClass.TRAFFIC_SIGN,
    SemanticClass.CURB, SemanticClass.SIDEWALK, SemanticClass.LANE_MARKING, SemanticClass.LANE_MARKING_YELLOW,
    SemanticClass.CROSSING, SemanticClass.ROAD, SemanticClass.PARKING, SemanticClass.TERRAIN,
    SemanticClass.PEDESTRIAN, SemanticClass.BICYCLE, SemanticClass.MOTORCYCLE, SemanticClass.CAR, SemanticClass.TRUCK,
    SemanticClass.BUS, SemanticClass.TRAILER, SemanticClass.CONSTRUCTION_VEHICLE, SemanticClass.TRAFFIC_CONE,
    SemanticClass.BARRIER, SemanticClass.NONE,
)  # fmt: skip
# A camera's walks are kept (12 bytes a step) where its rays times the grid's longest side are at
# most this: the Occ3D grid's default camera (38,000 rays, 2.7 M steps, 33 MB), not the
# OpenOccupancy grid's (250,000 rays, 42 M steps).
KEPT_WALK_STEPS = 16_000_000
_RANK = np.full(256, len(PRIORITY), np.uint8)
for _rank, _cls in enumerate(PRIORITY):
    _RANK[int(_cls)] = _rank


@dataclass(frozen=True, slots=True)
class OccupancyFrame:
    """One frame's occupancy on ``grid``: ``semantics_native: (X, Y, Z) uint8`` (our classes, 255
    free), ``instance: (X, Y, Z) uint32`` (the agent's track id, 0: none), ``mask_lidar`` and
    ``mask_camera: (X, Y, Z) bool``, each agent's motion in the ego frame's axes
    (``agent_id: (A,) uint32``, ``agent_velocity_mps`` over the ground and
    ``agent_velocity_relative_mps`` minus the ego's: ``(A, 3) float32``, its box's centre
    ``agent_center_m: (A, 3) float32`` and its turning ``agent_spin_rad_s: (A, 3) float32``,
    the angular velocity), the ego's turning ``ego_spin_rad_s: (3,) float32``
    (the voxels' flow is made from them, :attr:`flow_mps`), ``point_flow_m``: one ``(N, 3)
    float32`` per LiDAR output."""

    grid: VoxelGrid
    semantics_native: npt.NDArray[np.uint8]
    instance: npt.NDArray[np.uint32]
    mask_lidar: npt.NDArray[np.bool_]
    mask_camera: npt.NDArray[np.bool_]
    agent_id: npt.NDArray[np.uint32]
    agent_velocity_mps: npt.NDArray[np.float32]
    agent_velocity_relative_mps: npt.NDArray[np.float32]
    agent_center_m: npt.NDArray[np.float32]
    agent_spin_rad_s: npt.NDArray[np.float32]
    ego_spin_rad_s: npt.NDArray[np.float32]
    point_flow_m: tuple[npt.NDArray[np.float32], ...] = ()

    def __post_init__(self) -> None:
        s = self.grid.shape
        check_arrays(
            self, semantics_native=(np.uint8, s), instance=(np.uint32, s), mask_lidar=(np.bool_, s),
            mask_camera=(np.bool_, s), agent_id=(np.uint32, ("A",)), agent_velocity_mps=(np.float32, ("A", 3)),
            agent_velocity_relative_mps=(np.float32, ("A", 3)), agent_center_m=(np.float32, ("A", 3)),
            agent_spin_rad_s=(np.float32, ("A", 3)), ego_spin_rad_s=(np.float32, (3,)),
        )  # fmt: skip

    @property
    def flow_mps(self) -> npt.NDArray[np.float32]:
        """``(X, Y, Z, 3) float32``: each agent voxel's velocity over the ground at its centre
        (m/s, ego axes: the agent's velocity and its turning about its box's centre), 0 elsewhere."""
        return self._flow(relative=False)

    @property
    def flow_relative_mps(self) -> npt.NDArray[np.float32]:
        """``(X, Y, Z, 3) float32``: the same relative to the ego frame (the ego's velocity and its
        turning taken out: how the voxel's centre moves as the ego sees it)."""
        return self._flow(relative=True)

    def _flow(self, relative: bool) -> npt.NDArray[np.float32]:
        flow = np.zeros((*self.grid.shape, 3), np.float32)
        instance = self.instance.ravel()
        filled = np.flatnonzero(instance != 0)
        order = np.argsort(self.agent_id)
        if not len(order) or not len(filled):
            return flow
        at = np.clip(np.searchsorted(self.agent_id[order], instance[filled]), 0, len(order) - 1)
        known = self.agent_id[order][at] == instance[filled]
        filled, row = filled[known], order[at[known]]
        centre = self.grid.centers_m(filled)
        velocity = (self.agent_velocity_relative_mps if relative else self.agent_velocity_mps)[row].astype(np.float64)
        spin = self.agent_spin_rad_s[row].astype(np.float64)
        velocity += np.cross(spin, centre - self.agent_center_m[row])
        if relative:
            velocity -= np.cross(self.ego_spin_rad_s.astype(np.float64), centre)
        flow.reshape(-1, 3)[filled] = velocity
        return flow

    @property
    def semantics(self) -> npt.NDArray[np.uint8]:
        """Occ3D-nuScenes classes (:data:`OCC3D_CLASSES`, 17 = free)."""
        native = np.ascontiguousarray(self.semantics_native).reshape(-1)
        return voxel_kernels.looked_up(OCC3D_LUT, native).reshape(self.semantics_native.shape)


def occupancy_frame(
    spec: OccupancyGrid, static: ClassedMesh, solids: Solids, agents: Agents, map_SE3_ego: SE3,
    ego_velocity_map_mps: npt.NDArray[np.float64], lidars: tuple[LidarOutput, ...],
    cameras: tuple[tuple[CameraSpec, npt.NDArray[np.float64]], ...] = (), agent_meshes: AgentMeshes | None = None,
    ego_yaw_rate_rad_s: float = 0.0, ego: EgoState | None = None,
) -> OccupancyFrame:  # fmt: skip
    """The occupancy of one frame. ``static``: the world mesh near the ego (map frame);
    ``solids``: the world's solids; ``agents`` in the map frame; ``cameras``: each camera's spec and the
    distance (m) its grid-resolution rays (:func:`camera_rays`) travelled, inf where they hit
    nothing; ``agent_meshes``: the posed meshes of (some of) the agents (their volumes; the
    others fill their boxes); ``ego_yaw_rate_rad_s``: the ego's rate of turn from the frame's time
    on (counter-clockwise); ``ego``: the ego's state, which places a timed sweep's points where
    the LiDAR was at each point's time for their flow (without it, at the frame's time)."""
    grid = spec.grid
    ego_SE3_map = map_SE3_ego.inverse()
    native, instance = _classes(grid, static, solids, agents, map_SE3_ego, agent_meshes)
    mask_lidar = np.zeros(grid.size, np.bool_)
    for lidar in lidars:
        if np.any(lidar.scan.t_s != 0):  # a timed sweep: each ray from where the sensor was
            starts, ends = lidar_segments(lidar, ego_SE3_map.rotation @ np.asarray(ego_velocity_map_mps, np.float64))
            walk_voxels(grid, starts, ends, mask_lidar)
        else:  # all from the mount: the returns placed in the ego frame as the walk goes
            ego_SE3_lidar = lidar.spec.ego_SE3_sensor
            walk_from(grid, lidar.scan.xyz_lidar_m, ego_SE3_lidar.rotation, ego_SE3_lidar.translation, mask_lidar)
    mask_camera = np.zeros(grid.size, np.bool_)
    for camera, distance_m in cameras:
        if _walks_kept(spec, camera):  # the walks of the rig's fixed rays, made once, as far as each reached
            voxel_kernels.mark_walked(*_camera_walks(spec, camera), camera_reach_m(camera, distance_m), mask_camera)
        else:  # too many to keep (a fine grid): walked each frame
            walk_voxels(grid, *camera_segments(spec, camera, distance_m), mask_camera)
    velocity = agents.velocity_map_mps @ ego_SE3_map.rotation.T
    relative = velocity - ego_SE3_map.rotation @ np.asarray(ego_velocity_map_mps, np.float64)
    up = ego_SE3_map.rotation[:, 2]  # the map's +z in the ego's axes: turning is about it
    agent_spin = agents.yaw_rate_after_rad_s[:, None] * up  # the rates of turn from the frame's time on
    ego_spin = float(ego_yaw_rate_rad_s) * up
    center = _transform(ego_SE3_map, agents.center_map_m)
    point_flow = tuple(point_flow_m(lidar, agents, map_SE3_ego, ego) for lidar in lidars)
    s = grid.shape
    return OccupancyFrame(grid, native.reshape(s), instance.reshape(s), mask_lidar.reshape(s), mask_camera.reshape(s),
                          agents.instance_id, velocity.astype(np.float32), relative.astype(np.float32),
                          center.astype(np.float32), agent_spin.astype(np.float32), ego_spin.astype(np.float32),
                          point_flow)  # fmt: skip


def _transform(dst_SE3_src: SE3, points: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """``(N, 3)`` points mapped by ``dst_SE3_src`` (as :meth:`SE3.transform_from`, without BLAS's
    matrix product: for a few thousand rows of three it costs tens of milliseconds in its threads)."""
    p = np.asarray(points, np.float64)
    return np.asarray(np.einsum("nj,ij->ni", p, dst_SE3_src.rotation) + dst_SE3_src.translation, np.float64)


def lidar_segments(
    lidar: LidarOutput, ego_velocity_ego_mps: npt.NDArray[np.float64]
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """Each return's ray in the ego frame of the frame's time: from where the sensor was when the
    ray fired to the return (a timed sweep's rays fire ``t - t_ref`` from the frame's time and the
    ego moves on meanwhile; an instant sweep's all start at the mount)."""
    scan, spec = lidar.scan, lidar.spec
    ego_SE3_lidar = spec.ego_SE3_sensor
    ends = _transform(ego_SE3_lidar, scan.xyz_lidar_m)
    starts = np.broadcast_to(ego_SE3_lidar.translation, ends.shape)
    if len(scan) and np.any(scan.t_s != 0):
        dt = scan.t_s.astype(np.float64) - reference_s(spec.reference, spec.period_s)
        shift = dt[:, None] * ego_velocity_ego_mps[None, :]  # the ego's travel, its heading kept
        starts, ends = starts + shift, ends + shift
    return np.asarray(starts, np.float64), ends


def _classes(
    grid: VoxelGrid, static: ClassedMesh, solids: Solids, agents: Agents, map_SE3_ego: SE3,
    agent_meshes: AgentMeshes | None,
) -> tuple[npt.NDArray[np.uint8], npt.NDArray[np.uint32]]:  # fmt: skip
    """Flat ``(native class, instance)`` of every voxel."""
    ego_SE3_map = map_SE3_ego.inverse()
    surface, source, surface_class, tri_ego, inside, inside_class = _static_voxels(grid, static, solids, map_SE3_ego)
    parts = [(surface, surface_class, _NO_INSTANCE), (inside, inside_class, _NO_INSTANCE)]
    if len(agents):
        flat, row = _agent_voxels(grid, agents, agent_meshes, ego_SE3_map)
        parts.append((flat, agents.semantic_class[row], agents.instance_id[row]))
    native, instance, best = _paint(grid, parts)
    keep = _shared_surfaces(grid, surface, surface_class, tri_ego, source, native)
    if not keep.all():  # painted again where surface entries left: those voxels' entries only
        cleared = surface[~keep]
        again = np.zeros(grid.size, np.bool_)
        again[cleared] = True
        native[cleared], instance[cleared], best[cleared] = FREE_NATIVE, 0, len(PRIORITY) + 1
        _paint(grid, parts, keep, (native, instance, best, again))
    return native, instance


_StaticVoxels = tuple[
    npt.NDArray[np.int64], npt.NDArray[np.int64], npt.NDArray[np.uint8], npt.NDArray[np.float64],
    npt.NDArray[np.int64], npt.NDArray[np.uint8],
]  # fmt: skip
_STATIC: list[tuple[ClassedMesh, Solids, tuple[object, ...], _StaticVoxels]] = []


def _static_voxels(grid: VoxelGrid, static: ClassedMesh, solids: Solids, map_SE3_ego: SE3) -> _StaticVoxels:
    """The static world's voxels in the ego frame: its surfaces' ``(flat, triangle, class)``, the
    triangles ``(T, 3, 3)`` in the ego frame, and the solids' insides ``(flat, class)``
    (:func:`_solid_insides`). They depend only on the grid, the static mesh, the solids and the
    ego's pose: kept for the last frame's, and used again while the ego stands exactly where it
    stood (the same pose bit for bit, the same mesh and solids objects), as it does at a red light."""
    key = (grid, map_SE3_ego.rotation.tobytes(), map_SE3_ego.translation.tobytes())
    if _STATIC and _STATIC[0][0] is static and _STATIC[0][1] is solids and _STATIC[0][2] == key:
        return _STATIC[0][3]
    ego_SE3_map = map_SE3_ego.inverse()
    near = _static_near_index(grid, static, map_SE3_ego)
    tri_m = np.asarray(static.vertices_m[static.triangles[near]], np.float64)
    tri_ego = _transform(ego_SE3_map, tri_m.reshape(-1, 3)).reshape(-1, 3, 3)
    surface, source = triangle_voxels(grid, tri_ego)
    tri_class = np.asarray(static.triangle_class[near], np.uint8)
    surface_class = tri_class[source]
    solid = np.isin(tri_class, solids.classes)[source]
    inside, inside_class = _solid_insides(grid, solids, map_SE3_ego, surface[solid])
    out = (surface, source, surface_class, tri_ego, inside, inside_class)  # kept: nothing writes to them
    _STATIC[:] = [(static, solids, key, out)]
    return out


_NO_INSTANCE = np.zeros(0, np.uint32)
_ALL = np.zeros(0, np.bool_)


def _paint(
    grid: VoxelGrid,
    parts: list[tuple[npt.NDArray[np.int64], npt.NDArray[np.uint8], npt.NDArray[np.uint32]]],
    keep_first: npt.NDArray[np.bool_] = _ALL,
    into: tuple[npt.NDArray[np.uint8], npt.NDArray[np.uint32], npt.NDArray[np.uint8], npt.NDArray[np.bool_]]
    | None = None,
) -> tuple[npt.NDArray[np.uint8], npt.NDArray[np.uint32], npt.NDArray[np.uint8]]:
    """Each voxel's class and instance: those of its entry earliest in :data:`PRIORITY` (entries
    ``(flat, class, instance)`` part after part, no instance: 0; of the first part only those
    ``keep_first`` marks, if given), and its entry's rank. ``into``: painted over arrays
    ``(native, instance, rank, only)`` at the voxels ``only`` marks (those cleared: every one of
    their entries painted again), not new ones."""
    if into is None:
        native = np.full(grid.size, FREE_NATIVE, np.uint8)
        instance = np.zeros(grid.size, np.uint32)
        best = np.full(grid.size, len(PRIORITY) + 1, np.uint8)
        only = _ALL
    else:
        native, instance, best, only = into
    for n, (flat, cls, inst) in enumerate(parts):
        keep = keep_first if n == 0 else _ALL
        voxel_kernels.paint(
            np.asarray(flat, np.int64), np.asarray(cls, np.uint8), np.asarray(inst, np.uint32), keep, _RANK, native,
            instance, best, only,
        )  # fmt: skip
    return native, instance, best


def _shared_surfaces(
    grid: VoxelGrid, flat: npt.NDArray[np.int64], cls: npt.NDArray[np.uint8], tri_m: npt.NDArray[np.float64],
    source: npt.NDArray[np.int64], native: npt.NDArray[np.uint8], passes: int = 6,
) -> npt.NDArray[np.bool_]:  # fmt: skip
    """Which static surface entries (voxel ``flat``, class ``cls``, triangle ``tri_m[source]`` in the
    ego frame) keep their voxel where surfaces of several Occ3D classes meet one voxel: the voxel
    goes to the class that needs it, the one with the most surface in the voxel that lies farther
    than half a voxel from every other voxel of its class (a point on a surface is within half a
    voxel of the voxel it lies in and of the 7 neighbours on its side of the voxel's middle, so
    only the surface in the eighths of the voxel whose 7 neighbours hold no voxel of that class
    needs this voxel). Where no class needs it, the priority names it. The voxels are chosen in
    turn, each seeing the choices made before it, in up to ``passes`` sweeps (until none changes).
    The terrain (under the whole world) counts as hidden in voxels with paving (road, sidewalk,
    other flat ground). ``native``: every voxel's class so far."""
    label = voxel_kernels.looked_up(OCC3D_LUT, native)
    return np.asarray(
        voxel_kernels.shared_keep(
            flat.astype(np.int64), OCC3D_LUT[cls].astype(np.int64), tri_m, source.astype(np.int64),
            np.asarray(grid.lower_m, np.float64), grid.voxel_m, label, len(OCC3D_CLASSES), *grid.shape, passes,
            int(_PAVED_BITS), OCC3D_TERRAIN,
        ),
        np.bool_,
    )  # fmt: skip


def _static_near_index(grid: VoxelGrid, static: ClassedMesh, map_SE3_ego: SE3) -> npt.NDArray[np.intp]:
    """The static triangles whose bounding circle reaches the grid's bounding circle (map frame)."""
    centroid, radius = _bounding_circles(static)
    lo, hi = np.asarray(grid.lower_m), np.asarray(grid.upper_m)
    grid_center = map_SE3_ego.transform_from((lo + hi) / 2.0)
    reach = float(np.linalg.norm(hi - lo)) / 2.0
    return voxel_kernels.within(centroid, np.asarray(grid_center, np.float64), reach + radius)


_CIRCLES: list[tuple[ClassedMesh, npt.NDArray[np.float64], npt.NDArray[np.float64]]] = []


def _bounding_circles(static: ClassedMesh) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """Each triangle's centroid and its farthest corner's distance from it (kept for the last
    mesh: the frame loop's crop of the static world stays the same object for many frames)."""
    if _CIRCLES and _CIRCLES[0][0] is static:
        return _CIRCLES[0][1], _CIRCLES[0][2]
    tri = static.vertices_m[static.triangles]
    centroid = tri.mean(axis=1)
    radius = np.linalg.norm(tri - centroid[:, None, :], axis=2).max(axis=1)
    _CIRCLES[:] = [(static, centroid, radius)]
    return centroid, radius


def _agent_voxels(
    grid: VoxelGrid, agents: Agents, meshes: AgentMeshes | None, ego_SE3_map: SE3
) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64]]:
    """``(flat, agent row)``: each agent's voxels. An agent with a mesh fills the voxels of its
    box (:func:`~gtgen.voxels.box_voxels`) that its surface meets or that its surface encloses
    (no path of face-neighbouring voxels free of its surface leads out of its box); one without
    fills its box. Only the boxes whose bounding sphere (a voxel wider) reaches the grid's box are
    voxelised: the others meet none of its voxels."""
    center = ego_SE3_map.transform_from(agents.center_map_m)
    lo, hi = np.asarray(grid.lower_m), np.asarray(grid.upper_m)
    radius = np.linalg.norm(agents.lwh_m, axis=1)[:, None] / 2.0 + grid.voxel_m
    near = np.flatnonzero(np.all((center + radius >= lo) & (center - radius <= hi), axis=1))
    rotations = ego_SE3_map.rotation @ box_rotations(agents.yaw_map_rad[near], agents.pitch_rad[near])
    flat, row = box_voxels(grid, center[near], rotations, agents.lwh_m[near])
    row = near[row]
    if meshes is None or meshes.triangles.shape[0] == 0 or flat.size == 0:
        return flat, row
    triangle_id = meshes.triangle_instance
    if row.size > 1 and np.any(row[1:] < row[:-1]):  # box_voxels lists the boxes in order: never
        order = np.argsort(row, kind="stable")
        flat, row = flat[order], row[order]
    bounds = np.flatnonzero(np.r_[True, row[1:] != row[:-1], True])
    group_id = agents.instance_id[row[bounds[:-1]]].astype(np.uint32)
    if np.all(triangle_id[1:] >= triangle_id[:-1]):  # the agents' triangles one after another, ids rising
        tri_rows = np.arange(triangle_id.shape[0], dtype=np.int64)
        by_id = triangle_id
    else:
        tri_rows = np.argsort(triangle_id, kind="stable").astype(np.int64)
        by_id = triangle_id[tri_rows]
    first = np.searchsorted(by_id, group_id, side="left").astype(np.int64)
    last = np.searchsorted(by_id, group_id, side="right").astype(np.int64)
    rotation = np.ascontiguousarray(ego_SE3_map.rotation, np.float64)
    translation = np.ascontiguousarray(ego_SE3_map.translation, np.float64)
    keep = voxel_kernels.agents_filled(
        flat, bounds.astype(np.int64), first, last, tri_rows, meshes.vertices_m, meshes.triangles,
        np.asarray(grid.lower_m, np.float64), grid.voxel_m, *grid.shape, rotation, translation,
    )  # fmt: skip
    return flat[keep], row[keep]


def _solid_insides(
    grid: VoxelGrid, solids: Solids, map_SE3_ego: SE3, surface: npt.NDArray[np.int64]
) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.uint8]]:
    """The voxels whose centre lies inside a solid, and the solid's class. ``surface``: the
    voxels a solid's surface meets. Inside and outside change only across a solid's surface or
    floor, so face-neighbouring voxels that no wall, top or floor meets are alike: the runs of
    such voxels along each row (ego x), joined where neighbouring rows' runs share an x, form parts
    all inside or all outside (:func:`~gtgen.voxel_kernels.solid_runs`), a few centres of each part
    are cast (:meth:`Solids.inside_parts`: each run takes the class of the top over its first
    centre); a voxel that only a floor meets lies as the free voxel above it (or below it) does
    where no floor triangle in it lies between their centres
    (:func:`~gtgen.voxel_kernels.floor_joins`: it joins that voxel's part, not cast itself), else
    it is cast on its own (:meth:`Solids.inside`). Voxels a solid's surface meets are occupied by
    it anyway."""
    ego_SE3_map = map_SE3_ego.inverse()
    lo, hi = np.asarray(grid.lower_m), np.asarray(grid.upper_m)
    reach = float(np.linalg.norm(hi - lo)) / 2.0
    floors = solids.floors_near(map_SE3_ego.transform_from((lo + hi) / 2.0), reach)
    floor, floor_source = np.zeros(0, np.int64), np.zeros(0, np.int64)
    floor_ego = _transform(ego_SE3_map, floors.reshape(-1, 3)).reshape(-1, 3, 3)
    if floors.shape[0]:
        floor, floor_source = triangle_voxels(grid, floor_ego)
        by_voxel = np.argsort(floor, kind="stable")
        floor, floor_source = floor[by_voxel], floor_source[by_voxel]
    kind, ijk, part = voxel_kernels.solid_runs(surface.astype(np.int64), floor, *grid.shape)
    lower = np.asarray(grid.lower_m, np.float64)
    join = voxel_kernels.floor_joins(kind, ijk, part, floor, floor_source, floor_ego, lower, grid.voxel_m, *grid.shape)
    centers = _transform(map_SE3_ego, lower + (ijk + 0.5) * grid.voxel_m)
    cls = np.zeros(ijk.shape[0], np.uint8)
    alone = (part < 0) & (join < 0)
    cls[alone] = solids.inside(centers[alone])
    cls[~alone] = solids.inside_parts(centers[~alone], np.maximum(part, join)[~alone], part[~alone] >= 0)
    return voxel_kernels.solid_fill(kind, ijk, cls, *grid.shape)


def point_flow_m(
    lidar: LidarOutput, agents: Agents, map_SE3_ego: SE3, ego: EgoState | None = None
) -> npt.NDArray[np.float32]:
    """``(N, 3) float32``: where each point of the sweep moves by the next sweep, in the LiDAR's
    axes at the point's time (the frame its ``xyz`` is in): the point's surface carried by its
    object's box from the point's time ``t`` to ``t`` plus the sweep period, along the box's arc
    (:func:`~sensors.agents.motion_over`, the rate of turn before the frame's time and after it as
    the sweep casts them; velocity times the period where the box does not turn); 0 on the
    static world and on unknown ids. In a timed sweep the point is placed where the LiDAR was
    at its time (by ``ego``'s motion; without ``ego``, and in an instant sweep, at the frame's)."""
    scan = lidar.scan
    flow = np.zeros((len(scan), 3), np.float32)
    if len(agents) == 0 or len(scan) == 0:
        return flow
    order = np.argsort(agents.instance_id)
    ids = agents.instance_id[order]
    some = np.flatnonzero(scan.instance_id != 0)  # the static world's points (id 0) are not looked up
    pos = np.clip(np.searchsorted(ids, scan.instance_id[some]), 0, len(ids) - 1)
    hit = ids[pos] == scan.instance_id[some]
    known = np.zeros(len(scan), np.bool_)
    known[some[hit]] = True
    map_SE3_lidar = map_SE3_ego.compose(lidar.spec.ego_SE3_sensor)
    row = order[pos[hit]]
    period = 1.0 / lidar.spec.rate_hz
    timed = lidar.spec.sweep == "timed" and ego is not None
    dt = scan.t_s[known].astype(np.float64) - reference_s(lidar.spec.reference, lidar.spec.period_s) if timed else None
    before, after = agents.yaw_rate_rad_s[row], agents.yaw_rate_after_rad_s[row]
    if dt is None or not (dt.any() and (before.any() or after.any() or (ego is not None and ego.turning()))):
        # one instant (or no turning anywhere): the box's motion over the period from the frame's time
        flow[known] = agents.velocity_map_mps[row] @ map_SE3_lidar.rotation / lidar.spec.rate_hz
        turning = np.flatnonzero(known)[after != 0.0]
        if turning.size:  # along the arc: the centre's shift and the point turned about the centre
            row = row[after != 0.0]
            shift, turn = motion_over(agents.velocity_map_mps[row], agents.yaw_rate_after_rad_s[row], period)
            arm = _transform(map_SE3_lidar, scan.xyz_lidar_m[turning]) - agents.center_map_m[row]
            flow[turning] = (shift + turned_about_z(arm, turn) - arm) @ map_SE3_lidar.rotation
        return flow
    assert ego is not None
    # the LiDAR where it was at each point's time, and the point there in the map frame
    origins, ego_turn = sensor_origins(ego, map_SE3_lidar.translation, dt)
    at_t = turned_about_z(scan.xyz_lidar_m[known].astype(np.float64) @ map_SE3_lidar.rotation.T, ego_turn) + origins
    velocity, centre = agents.velocity_map_mps[row], agents.center_map_m[row]
    shift_t, turn_t = motion_over(velocity, turn_rate_at(before, after, dt), dt)
    shift_n, turn_n = motion_over(velocity, turn_rate_at(before, after, dt + period), dt + period)
    arm = at_t - (centre + shift_t)
    moved = (shift_n - shift_t) + turned_about_z(arm, turn_n - turn_t) - arm
    # into the LiDAR's axes at the point's time (turned by the ego's turn since the frame's time)
    flow[known] = turned_about_z(moved, -ego_turn) @ map_SE3_lidar.rotation
    return flow


@functools.lru_cache(maxsize=16)
def camera_pixels(spec: OccupancyGrid, camera: CameraSpec) -> npt.NDArray[np.intp]:
    """``(R,)`` row-major indices of the pixels whose rays sample ``camera`` at the grid's
    resolution: a column and a row every ``s`` pixels (``s`` need not be whole: the pixel each step's
    middle falls in), ``s`` such that neighbouring samples lie one voxel apart at the grid's
    farthest corner from the camera (to a pixel)."""
    lo, hi = np.asarray(spec.range_m[:3]), np.asarray(spec.range_m[3:])
    corners = np.stack(np.meshgrid(*zip(lo, hi, strict=True), indexing="ij"), -1).reshape(-1, 3)
    far = float(np.max(np.linalg.norm(corners - np.asarray(camera.mount_xyz_m), axis=1)))
    step_px = max(1.0, spec.voxel_m / far * camera.pinhole.focal_px)
    u = np.unique(np.floor(np.arange(step_px / 2.0, camera.width_px, step_px)).astype(np.intp))
    v = np.unique(np.floor(np.arange(step_px / 2.0, camera.height_px, step_px)).astype(np.intp))
    pixels = np.asarray(v[:, None] * camera.width_px + u[None, :], np.intp).reshape(-1)
    pixels.setflags(write=False)  # kept (lru_cache): the same camera's samples every frame
    return pixels


@functools.lru_cache(maxsize=16)
def camera_directions(spec: OccupancyGrid, camera: CameraSpec) -> npt.NDArray[np.float32]:
    """``(R, 3) float32`` unit rays (optical frame) of :func:`camera_pixels`: the camera's own rays
    of those pixels."""
    directions = np.ascontiguousarray(camera.pinhole.image_directions()[camera_pixels(spec, camera)], np.float32)
    directions.setflags(write=False)
    return directions


def camera_distances_m(
    spec: OccupancyGrid, camera: CameraSpec, depth_m: npt.NDArray[np.float32]
) -> npt.NDArray[np.float64]:
    """How far each ray of :func:`camera_pixels` travelled, read from the camera's depth image
    ``(H, W)`` (z-depth, 0 where nothing lies within its range: inf): its range is its depth over
    its cosine to the optical axis. The same as casting :func:`camera_rays` into the frame's scene,
    without casting them again."""
    depth = np.asarray(depth_m).reshape(-1)[camera_pixels(spec, camera)].astype(np.float64)
    cosine = camera_directions(spec, camera)[:, 2].astype(np.float64)
    with np.errstate(divide="ignore"):
        return np.where(depth > 0.0, depth / cosine, np.inf)


def camera_rays(spec: OccupancyGrid, camera: CameraSpec, map_SE3_ego: SE3) -> npt.NDArray[np.float32]:
    """``(R, 6) float32`` map-frame rays of :func:`camera_directions` (to cast into the frame's scene)."""
    return sensor_rays(map_SE3_ego.compose(camera.ego_SE3_sensor), camera_directions(spec, camera))


def camera_reach_m(camera: CameraSpec, distance_m: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """How far each grid-resolution ray of ``camera`` travelled (inf: out of the grid, at most the
    camera's range)."""
    return np.asarray(np.minimum(np.nan_to_num(distance_m, posinf=camera.range_m), camera.range_m), np.float64)


def camera_segments(
    spec: OccupancyGrid, camera: CameraSpec, distance_m: npt.NDArray[np.float64]
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """Ego-frame segments of the camera's grid-resolution rays, each as far as it travelled
    (:func:`camera_reach_m`)."""
    ego_SE3_cam = camera.ego_SE3_sensor
    dirs = _transform(SE3(ego_SE3_cam.rotation, np.zeros(3)), camera_directions(spec, camera))
    starts = np.broadcast_to(ego_SE3_cam.translation, dirs.shape)
    return starts, starts + dirs * camera_reach_m(camera, distance_m)[:, None]


def _walks_kept(spec: OccupancyGrid, camera: CameraSpec) -> bool:
    return bool(camera_directions(spec, camera).shape[0] * max(spec.grid.shape) <= KEPT_WALK_STEPS)


def prepare_camera(spec: OccupancyGrid, camera: CameraSpec) -> None:
    """Make the camera's voxel walks now (they are kept, :data:`KEPT_WALK_STEPS`), not in the first
    frame."""
    if _walks_kept(spec, camera):
        _camera_walks(spec, camera)


@functools.lru_cache(maxsize=16)
def _camera_walks(
    spec: OccupancyGrid, camera: CameraSpec
) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int32], npt.NDArray[np.float64]]:
    """The voxel walks of the camera's grid-resolution rays over its whole range, with the reach
    (:func:`camera_reach_m`) at which each ray enters each voxel: its ``t`` along the whole range
    (:func:`~gtgen.voxel_kernels.walk_steps`) times the range, as the ray's end is its direction
    times its reach. The camera is fixed on the ego and the grid lies in the ego frame, so they are
    the same every frame."""
    grid = spec.grid
    starts, ends = camera_segments(spec, camera, np.full(camera_directions(spec, camera).shape[0], np.inf))
    lower = np.asarray(grid.lower_m, np.float64)
    first, flat, t = voxel_kernels.walk_steps(np.ascontiguousarray(starts), ends, lower, grid.voxel_m, *grid.shape)
    return first, flat, t * camera.range_m

"""A spinning LiDAR's sweep in time: when each ray fires, and its rays cast at their own times.

The head turns clockwise seen from above (as Velodyne's do: nuScenes's data-collection notes,
"the LIDAR rotates clockwise", and their forum thread "lidar pointcloud details: cut angle and
motion distortion") and a sweep starts and ends behind the ego, so the laser faces forward in
its middle. Each column of the ray grid fires at its azimuth's share of the period
``1 / rate_hz``; within a column the beams fire in their sensor's pattern
(:func:`firing_offsets_s`). A point's ``t`` is seconds from the sweep's start.

The frame's state (the traffic's step) stands at the sweep's reference time ``t_ref`` (start,
middle or end of the sweep, as the imitated dataset stamps it: KITTI's camera fires when the
laser faces forward, its boxes are at the middle; nuScenes stamps a sweep when its rotation
ends). A ray fired at ``t`` is cast with the ego and every agent moved over ``t - t_ref`` by
their velocities and rates of turn (:func:`sensors.agents.motion_over`: along an arc, the
heading turning; the traffic gives each rate from its heading's change since the last step):
the static world from the moved and turned sensor, each agent near
the ray's line of sight alone with its own motion (:meth:`sensors.engine.Scene.cast_agents_moving`),
and the nearest hit wins. Points stay in the sensor's frame at their own time, as a real
sensor reports them (a car passing the other way is squeezed, one overtaking stretched);
:func:`deskewed` moves them to the sensor's frame at ``t_ref`` by the ego's motion.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from networks.geometry import SE3
from sensors.agents import Agents, EgoState, motion_over, turn_rate_at, turned_about_z
from sensors.errors import SensorConfigError
from sensors.hits import PairHits, RayHits

FIRINGS = ("even", "hdl64e", "hdl32e")
REFERENCES = ("start", "middle", "end")

# HDL-32E: the 32 lasers fire one after another, 1.152 us apart, in a firing cycle of 46.08 us
# (32 firings and 8 slots of recharge); laser ids alternate between the lower and the upper bank
# of elevations (id 0 at -30.67 deg, id 1 at -9.33 deg, id 2 at -29.33 deg, ...). Velodyne,
# "HDL-32E User's Manual", vertical angle table, and application note "HDL-32E Packet Structure
# and Timing Definition". The cycle is scaled to the grid's column period (the nuScenes preset's
# 1,084 columns at 20 Hz: 46.13 us).
HDL32E_SLOT_OF_CYCLE = 1.152 / 46.08
# HDL-64E S2: the upper block (the 32 upper beams, +2.0 to -8.33 deg) and the lower block fire at
# the same time, each block one laser after another over the firing cycle (Velodyne, "HDL-64E S2
# and S2.1 User's Manual", firing sequence; about 48 us a cycle at 10 Hz and 1.33 M points/s). The
# order within a block is taken top to bottom here (the laser numbers' own order by elevation is
# not modelled: it moves a point's time by under one cycle).


def firing_offsets_s(firing: str, beams: int, cycle_s: float) -> npt.NDArray[np.float64]:
    """``(beams,)`` time of each ring's shot (ring 0 the lowest beam) after its column's firing
    cycle starts, for a cycle of ``cycle_s`` seconds."""
    ring = np.arange(beams)
    if firing == "hdl32e":
        if beams != 32:
            raise SensorConfigError(f"firing hdl32e needs 32 beams, got {beams}")
        laser = np.where(ring < 16, 2 * ring, 2 * (ring - 16) + 1)
        return laser * HDL32E_SLOT_OF_CYCLE * cycle_s
    if firing == "hdl64e":
        if beams != 64:
            raise SensorConfigError(f"firing hdl64e needs 64 beams, got {beams}")
        from_top = np.where(ring >= 32, 63 - ring, 31 - ring)
        return np.asarray(from_top * (cycle_s / 32.0), np.float64)
    if firing == "even":
        return np.asarray(ring * (cycle_s / beams), np.float64)
    raise SensorConfigError(f"firing: expected one of {', '.join(FIRINGS)}, got {firing!r}")


def ray_times_s(
    dirs_lidar: npt.NDArray[np.float64], ring: npt.NDArray[np.uint16], ego_SE3_lidar: SE3, period_s: float,
    azimuth_steps: int, firing: str, beams: int,
) -> npt.NDArray[np.float64]:  # fmt: skip
    """``(N,)`` seconds from the sweep's start at which each ray fires: its azimuth in the ego
    frame, clockwise from straight behind, as a share of the period, plus its beam's offset."""
    dirs_ego = dirs_lidar @ ego_SE3_lidar.rotation.T
    azimuth = np.arctan2(dirs_ego[:, 1], dirs_ego[:, 0])
    turned = np.mod(np.pi - azimuth, 2.0 * np.pi) / (2.0 * np.pi)
    cycle_s = period_s / azimuth_steps
    column = np.floor(turned * azimuth_steps + 1e-6) % azimuth_steps
    return np.asarray(column * cycle_s + firing_offsets_s(firing, beams, cycle_s)[ring])


def reference_s(reference: str, period_s: float) -> float:
    """The sweep's reference time (the frame's state and its boxes) in seconds from its start."""
    return {"start": 0.0, "middle": 0.5 * period_s, "end": period_s}[reference]


SWEPT_SAMPLES = 5  # times over the sweep at which an agent's box is placed to bound the rays near it


def near_pairs(
    agents: Agents, ego: EgoState, map_SE3_lidar: SE3, dt_range_s: tuple[float, float], azimuth_steps: int,
    elevation_rad: npt.NDArray[np.float64],
) -> tuple[npt.NDArray[np.intp], npt.NDArray[np.intp]]:  # fmt: skip
    """``(ray, agent)`` pairs, grouped by agent in ascending order, whose ray may meet the agent's
    box as both it and the ego move (:func:`sensors.agents.motion_over`) over ``dt_range_s``, on
    the grid of a LiDAR (at ``map_SE3_lidar`` at the reference time) whose ray ``ring *
    azimuth_steps + column`` points at azimuth ``column * 2 pi / steps`` and elevation
    ``elevation_rad[ring]`` in the LiDAR frame: the columns between the corners' azimuths of the
    box placed at :data:`SWEPT_SAMPLES` times, seen from the LiDAR at those times, and the rings
    between its lowest and highest elevation (taken at its nearest horizontal distance), each
    widened by half a column. (A box moving straight relative to a sensor that does not turn is
    covered exactly by its two ends; turns bend the path by well under half a column between
    samples.)"""
    if len(agents) == 0:
        return np.zeros(0, np.intp), np.zeros(0, np.intp)
    corners_box = np.stack(np.meshgrid([-0.5, 0.5], [-0.5, 0.5], [-0.5, 0.5], indexing="ij"), -1).reshape(-1, 3)
    arms = np.einsum("kij,kcj->kci", agents.rotations(), corners_box[None] * agents.lwh_m[:, None, :])
    still = not agents.turning() and not ego.turning()
    times = dt_range_s if still else tuple(np.linspace(dt_range_s[0], dt_range_s[1], SWEPT_SAMPLES).tolist())
    seen = []
    for dt in times:
        rate = turn_rate_at(agents.yaw_rate_rad_s, agents.yaw_rate_after_rad_s, dt)
        shift, turn = motion_over(agents.velocity_map_mps, rate, np.full(len(agents), dt))
        corners = agents.center_map_m[:, None, :] + shift[:, None, :] + turned_about_z(arms, turn[:, None])
        lidar_SE3_map = sensor_pose_at(ego, map_SE3_lidar, dt).inverse()
        seen.append(lidar_SE3_map.transform_from(corners.reshape(-1, 3)).reshape(corners.shape))
    local = np.concatenate(seen, axis=1)
    step = 2.0 * np.pi / azimuth_steps
    pad = 0.5 * step + 1e-3
    rays, owners = [], []
    for k in range(len(agents)):
        mine = _pairs_of(local[k], step, pad, azimuth_steps, elevation_rad)
        if mine.size:
            rays.append(mine)
            owners.append(np.full(mine.shape[0], k, np.intp))
    if not rays:
        return np.zeros(0, np.intp), np.zeros(0, np.intp)
    return np.concatenate(rays).astype(np.intp), np.concatenate(owners)


def sensor_pose_at(ego: EgoState, map_SE3_sensor: SE3, dt_s: float) -> SE3:
    """Where a sensor fixed to the ego (at ``map_SE3_sensor`` at the reference time) is ``dt_s``
    seconds later, the ego moving by :func:`sensors.agents.motion_over`."""
    origins, turn = sensor_origins(ego, map_SE3_sensor.translation, np.array([dt_s]))
    c, s = np.cos(turn[0]), np.sin(turn[0])
    turn_R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return SE3(turn_R @ map_SE3_sensor.rotation, origins[0])


def sensor_origins(
    ego: EgoState, origin_map_m: npt.NDArray[np.float64], dt_s: npt.NDArray[np.float64]
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """``(N, 3)`` where a point fixed to the ego (at ``origin_map_m`` at the reference time) is at
    each of ``dt_s`` and ``(N,)`` how far the ego has turned then (radians, counter-clockwise)."""
    rate = turn_rate_at(*ego.turn_rates(), dt_s[:, None])
    shift, turn = motion_over(ego.velocity_map_mps, rate, dt_s[:, None])
    arm = np.asarray(origin_map_m, np.float64) - ego.center_map_m
    turned = turned_about_z(np.broadcast_to(arm, shift[:, 0].shape), turn[:, 0])
    return ego.center_map_m + shift[:, 0] + turned, turn[:, 0]


def _pairs_of(
    corners: npt.NDArray[np.float64], step: float, pad: float, azimuth_steps: int,
    elevation_rad: npt.NDArray[np.float64],
) -> npt.NDArray[np.intp]:  # fmt: skip
    """The rays of a grid that may meet the convex hull of ``corners`` (LiDAR frame)."""
    xy = corners[:, :2]
    centre = xy.mean(axis=0)
    spread = float(np.linalg.norm(xy - centre, axis=1).max())
    nearest = float(np.linalg.norm(centre)) - spread  # a lower bound of the hull's horizontal distance
    z_lo, z_hi = float(corners[:, 2].min()), float(corners[:, 2].max())
    if nearest <= 0.05:
        el_lo, el_hi, columns = -np.pi / 2, np.pi / 2, np.arange(azimuth_steps)
    else:
        farthest = float(np.linalg.norm(xy, axis=1).max())
        el_hi = np.arctan2(z_hi, nearest if z_hi > 0 else farthest)
        el_lo = np.arctan2(z_lo, nearest if z_lo < 0 else farthest)
        mid = np.arctan2(centre[1], centre[0])
        off = np.angle(np.exp(1j * (np.arctan2(xy[:, 1], xy[:, 0]) - mid)))  # each corner's azimuth from mid
        first = int(np.floor((mid + off.min() - pad) / step))
        last = int(np.ceil((mid + off.max() + pad) / step))
        columns = np.arange(first, last + 1) % azimuth_steps
    rings = np.flatnonzero((elevation_rad >= el_lo - pad) & (elevation_rad <= el_hi + pad))
    return (rings[:, None] * azimuth_steps + columns[None, :]).ravel()


def nearest(
    static: RayHits, agents: Agents, ray_index: npt.NDArray[np.intp], agent_index: npt.NDArray[np.intp], pairs: PairHits
) -> RayHits:
    """Per ray, the nearer of its static hit and its agents' hits."""
    range_m = static.range_m.copy()
    hit = np.isfinite(pairs.range_m)
    ray_index, agent_index = ray_index[hit], agent_index[hit]
    pair_range = pairs.range_m[hit]
    if ray_index.size == 0:
        return static
    np.minimum.at(range_m, ray_index, pair_range)
    wins = pair_range <= range_m[ray_index]
    # ties between agents (touching bodies): the last pair in the order wins, deterministically
    at, who = ray_index[wins], agent_index[wins]
    cls, inst = static.semantic_class.copy(), static.instance_id.copy()
    normal, part = static.normal.copy(), static.part.copy()
    cls[at], inst[at] = agents.semantic_class[who], agents.instance_id[who]
    normal[at], part[at] = pairs.normal[hit][wins], pairs.part[hit][wins]
    return RayHits(range_m, cls, inst, normal, part)


def deskewed(
    xyz_lidar_m: npt.NDArray[np.float32], t_s: npt.NDArray[np.float32], t_ref_s: float, ego: EgoState,
    map_SE3_lidar: SE3,
) -> npt.NDArray[np.float32]:  # fmt: skip
    """Points taken from the sensor's frame at their own time to its frame at ``t_ref_s`` (where
    it is at ``map_SE3_lidar``), by the ego's motion (its velocity and rate of turn), as motion
    compensation does."""
    dt = t_s.astype(np.float64) - t_ref_s
    if not ego.turning():  # heading kept: a shift along the velocity
        velocity_lidar = map_SE3_lidar.rotation.T @ ego.velocity_map_mps
        return (xyz_lidar_m + dt[:, None] * velocity_lidar[None, :]).astype(np.float32)
    origins, turn = sensor_origins(ego, map_SE3_lidar.translation, dt)
    in_map = turned_about_z(xyz_lidar_m.astype(np.float64) @ map_SE3_lidar.rotation.T, turn) + origins
    return map_SE3_lidar.inverse().transform_from(in_map).astype(np.float32)

"""Occupancy on town05_crowded against the frame's own geometry and rays: every LiDAR point lies in
an occupied voxel (of its class, or one within half a voxel), and every voxel a LiDAR ray crossed
before the voxel of its return is free or holds a surface the ray passed by: never the inside of
a static solid, the inside of a car's body only where a ray went through its windows (glass
returns nothing; the cabin is part of the body's volume).
``python tests/cosim/test_occupancy_town.py FRAMES`` prints the numbers of a longer run."""

from __future__ import annotations

import sys
from collections import Counter
from typing import Any

import numpy as np
import pytest

from cosim.loop import AGENT_MARGIN_M, NO_PROBE, sense_and_label
from cosim.occupancy_step import OccupancyStep
from cosim.rig import build_rig
from cosim.scenario import load_scenario
from cosim.sumo.traffic import Traffic
from cosim.world_setup import prepare_network
from gtgen.occupancy import FREE_NATIVE, OCC3D_LUT
from gtgen.voxels import segment_voxel_pairs, triangle_voxels
from networks.classes import SemanticClass
from sensors.o3d import RaycastingScene, o3c
from sensors.parts import Part
from sensors.scene import StaticCrop

pytestmark = pytest.mark.slow


class _Scenes(type(NO_PROBE)):  # type: ignore[misc]
    """Keeps the last frame's scene."""

    last: Any = None

    def scene(self, frame_index: int, scene: Any, map_SE3_ego: Any) -> None:
        self.last = scene


def check(frames: int, steps_between: int = 1, ray_step: int = 7) -> Counter[str]:
    scenario = load_scenario("town05_crowded", ["outputs.occupancy.enabled=true", "sensors.radars=[]"])
    prepared = prepare_network(scenario)
    rig = build_rig(scenario)
    crop = StaticCrop(prepared.world.mesh, rig.reach_m)
    step = OccupancyStep(scenario.outputs.occupancy.grid, prepared.world.mesh)
    grid = step.grid.grid
    traffic = Traffic(prepared.net_path, prepared.net, scenario)
    rng = np.random.default_rng(0)
    probe = _Scenes()
    counts: Counter[str] = Counter()
    try:
        traffic.warm_up()
        for frame in range(frames):
            for _ in range(steps_between):
                traffic.step()
            state = traffic.world_state().near(rig.reach_m + AGENT_MARGIN_M)
            record = sense_and_label(frame, state, crop, rig, rng, probe, occupancy=step)
            _check_frame(record, probe.last, crop, grid, counts, ray_step)
    finally:
        traffic.close()
    return counts


def _check_frame(record: Any, scene: Any, crop: StaticCrop, grid: Any, counts: Counter[str], ray_step: int) -> None:
    occupancy = record.occupancy
    ego_SE3_map = record.map_SE3_ego.inverse()
    static = crop.around(record.map_SE3_ego.translation)
    meshes = scene.agent_meshes
    tris = np.concatenate([static.vertices_m[static.triangles], meshes.vertices_m[meshes.triangles]]).astype(float)
    surface = np.zeros(grid.size, np.bool_)
    surface[triangle_voxels(grid, ego_SE3_map.transform_from(tris.reshape(-1, 3)).reshape(-1, 3, 3))[0]] = True
    semantics = occupancy.semantics_native
    occupied = semantics.ravel() != FREE_NATIVE
    for lidar in record.lidars:
        ego_SE3_lidar = lidar.spec.ego_SE3_sensor
        xyz = ego_SE3_lidar.transform_from(lidar.scan.xyz_lidar_m.astype(np.float64))
        ijk = grid.ijk_of(xyz)
        inside = grid.inside(ijk)
        xyz, ijk, cls = xyz[inside], ijk[inside], lidar.scan.semantic_class[inside]
        own = semantics[tuple(ijk.T)]
        near, near_occ3d = own == cls, OCC3D_LUT[own] == OCC3D_LUT[cls]
        g = grid.to_grid(xyz)
        for offset in np.ndindex(3, 3, 3):  # the voxels a cube of half a voxel around the point touches
            q = np.clip(np.floor(g + (np.asarray(offset) - 1) * 0.5).astype(int), 0, np.asarray(grid.shape) - 1)
            near |= semantics[tuple(q.T)] == cls
            near_occ3d |= OCC3D_LUT[semantics[tuple(q.T)]] == OCC3D_LUT[cls]
        counts.update(points=len(cls), occupied=int((own != FREE_NATIVE).sum()), own_class=int((own == cls).sum()),
                      near=int(near.sum()), near_occ3d=int(near_occ3d.sum()))  # fmt: skip
        for point_class, voxel_class in zip(cls[~near_occ3d].tolist(), own[~near_occ3d].tolist(), strict=True):
            counts[f"missed {_name(point_class)} in {_name(voxel_class)}"] += 1
        sample = np.arange(0, len(xyz), ray_step)
        origin = np.broadcast_to(ego_SE3_lidar.translation, (len(sample), 3))
        ray, crossed = segment_voxel_pairs(grid, origin, xyz[sample])
        before = crossed != grid.flat(ijk[sample])[ray]  # crossed before the voxel of the return
        ray_of, pairs = np.unique(np.stack([ray[before], crossed[before]]), axis=1)
        inner = occupied[pairs] & ~surface[pairs]
        agent = occupancy.instance.ravel()[pairs] != 0
        through = np.unique(ray_of[inner & agent])  # rays that crossed the inside of an agent's body
        counts.update(crossed=len(pairs), crossed_occupied=int(occupied[pairs].sum()),
                      crossed_inside_solid=int((inner & ~agent).sum()),
                      crossed_inside_agent=int((inner & agent).sum()), rays_into_agents=len(through),
                      rays_into_agents_not_through_glass=_not_through_glass(
                          meshes, record.map_SE3_ego, origin[through], xyz[sample][through]))  # fmt: skip
    counts["frames"] += 1


def _name(cls: int) -> str:
    return "free" if cls == FREE_NATIVE else SemanticClass(cls).label


def _not_through_glass(meshes: Any, map_SE3_ego: Any, start_ego: Any, end_ego: Any) -> int:
    """How many of the rays ``start -> end`` (ego frame) meet no agent's glass before their end."""
    if len(start_ego) == 0:
        return 0
    scene = RaycastingScene()
    scene.add_triangles(
        o3c.Tensor.from_numpy(np.ascontiguousarray(meshes.vertices_m, np.float32)),
        o3c.Tensor.from_numpy(meshes.triangles.astype(np.uint32)),
    )
    start, end = map_SE3_ego.transform_from(start_ego), map_SE3_ego.transform_from(end_ego)
    length = np.linalg.norm(end - start, axis=1)
    rays = np.concatenate([start, (end - start) / length[:, None]], axis=1).astype(np.float32)
    hit = scene.cast_rays(o3c.Tensor.from_numpy(rays))
    t, prim = hit["t_hit"].numpy(), hit["primitive_ids"].numpy()
    glass = (t < length) & (meshes.triangle_part[np.minimum(prim, len(meshes.triangle_part) - 1)] == Part.GLASS)
    return int((~glass).sum())


def test_lidar_points_lie_in_occupied_voxels_and_rays_cross_only_free_or_surface_voxels():
    counts = check(frames=3, steps_between=10, ray_step=3)
    assert counts["points"] > 50_000
    assert counts["occupied"] == counts["points"]
    assert counts["near_occ3d"] >= 0.999 * counts["points"]
    assert counts["crossed"] > 100_000
    assert counts["crossed_inside_solid"] == 0
    assert counts["crossed_inside_agent"] <= 1e-3 * counts["crossed"]  # through a car's windows into its cabin
    assert counts["rays_into_agents_not_through_glass"] == 0


if __name__ == "__main__":
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 20
    c = check(frames=n)
    p = c["points"]
    print({k: v for k, v in c.items() if not k.startswith("missed")})
    print(
        "points not within half a voxel of a voxel of their Occ3D class, by class and their voxel's:",
        dict(sorted(((k, v) for k, v in c.items() if k.startswith("missed")), key=lambda kv: -kv[1])),
    )
    print(
        f"{c['frames']} frames, {p} LiDAR points in the grid: in an occupied voxel {c['occupied'] / p:.5f}, "
        f"own class in its voxel {c['own_class'] / p:.4f}, within half a voxel {c['near'] / p:.4f} "
        f"(Occ3D classes {c['near_occ3d'] / p:.4f}); {c['crossed']} voxels crossed before a return: free "
        f"{1 - c['crossed_occupied'] / c['crossed']:.4f}, the rest hold a surface the ray passed by, but "
        f"{c['crossed_inside_solid']} inside a static solid and {c['crossed_inside_agent']} inside an agent's body "
        f"({c['rays_into_agents']} rays, {c['rays_into_agents_not_through_glass']} of them not through the "
        "agent's glass: glass returns nothing)"
    )

"""Which points lie inside the static world's solids (buildings, trees, poles, bridge piers).

The world builds these as prisms: vertical walls around a footprint and a flat top (no floor),
or a gable roof on the walls (its slopes count as tops at their highest point).
A point lies inside one iff a horizontal ray from it crosses the walls an odd number of times
(ray parity, as Open3D's ``compute_occupancy`` counts it, along rays that never meet a floor or
a top: walls are vertical, so a horizontal ray below a prism's walls or above them crosses none
of them). Two rays (along map +x and +y) must agree: a ray that grazes a wall's vertical edge
and miscounts leaves the point outside rather than filling a voxel in front of a wall. Only
points under some solid's top (a raster of the tops' heights, map frame) are cast. The rest of
the world (roads, sidewalks, terrain) is surface, not volume.
"""

from __future__ import annotations

import cv2
import numpy as np
import numpy.typing as npt

from networks.classes import SemanticClass
from networks.mesh import ClassedMesh
from sensors.o3d import RaycastingScene, o3c

SOLID_CLASSES = (SemanticClass.BUILDING, SemanticClass.VEGETATION, SemanticClass.POLE)
RASTER_M = 0.2  # the tops' raster (points within two of its cells of a top are cast)


class Solids:
    """The solids of the whole static world (whole prisms: rays run to infinity)."""

    def __init__(self, world: ClassedMesh) -> None:
        keep = np.isin(world.triangle_class, np.asarray(SOLID_CLASSES, np.uint8))
        tri = world.vertices_m[world.triangles[keep]].astype(np.float64)
        self._scene = RaycastingScene()
        if keep.any():
            vertices = np.ascontiguousarray(tri.reshape(-1, 3), np.float32)
            indices = np.arange(tri.shape[0] * 3, dtype=np.uint32).reshape(-1, 3)
            self._scene.add_triangles(o3c.Tensor.from_numpy(vertices), o3c.Tensor.from_numpy(indices))
        normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        flat = np.abs(normal[:, 2]) > 0.999 * np.linalg.norm(normal, axis=1)
        roof = (world.triangle_class[keep] == SemanticClass.BUILDING) & (
            np.abs(normal[:, 2]) > 0.05 * np.linalg.norm(normal, axis=1)
        )  # a gable roof's slopes: tops at their highest point
        self._tops = tri[flat | roof]
        self._top_class = world.triangle_class[keep][flat | roof]

    def inside(self, xyz_map_m: npt.NDArray[np.float64]) -> npt.NDArray[np.uint8]:
        """``(N,) uint8``: the class of the solid each point (map frame) lies inside, 0 if none."""
        out = np.zeros(xyz_map_m.shape[0], np.uint8)
        if self._tops.shape[0] == 0 or xyz_map_m.shape[0] == 0:
            return out
        top_z, top_class, origin = self._raster(xyz_map_m)
        px = np.floor((xyz_map_m[:, :2] - origin) / RASTER_M).astype(np.int64)
        px = np.clip(px, 0, np.asarray(top_z.shape[::-1]) - 1)
        candidate = np.flatnonzero(xyz_map_m[:, 2] <= top_z[px[:, 1], px[:, 0]])
        odd = candidate
        for axis in (0, 1):  # along +x and +y: a ray that grazes a wall's edge miscounts one of them
            rays = np.zeros((odd.shape[0], 6), np.float32)
            rays[:, :3], rays[:, 3 + axis] = xyz_map_m[odd], 1.0
            crossings = self._scene.count_intersections(o3c.Tensor.from_numpy(rays)).numpy()
            odd = odd[crossings % 2 == 1]
        out[odd] = top_class[px[odd, 1], px[odd, 0]]
        return out

    def _raster(
        self, xyz_map_m: npt.NDArray[np.float64]
    ) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.uint8], npt.NDArray[np.float64]]:
        """The highest top's height and class per cell over the points' extent (two cells wider
        all round, each top two cells wider: a point near a footprint's edge is cast)."""
        origin = xyz_map_m[:, :2].min(axis=0) - 4 * RASTER_M
        size = np.ceil((xyz_map_m[:, :2].max(axis=0) + 4 * RASTER_M - origin) / RASTER_M).astype(int)
        top_z = np.full((size[1], size[0]), -np.inf, np.float32)
        top_class = np.zeros((size[1], size[0]), np.uint8)
        xy = (self._tops[:, :, :2] - origin) / RASTER_M
        near = np.all(xy.max(axis=1) >= 0, axis=1) & np.all(xy.min(axis=1) <= size, axis=1)
        tops_px, tops_z, tops_class = xy[near], self._tops[near, :, 2].max(axis=1), self._top_class[near]
        for z in np.unique(tops_z):  # lowest first: a higher top over a lower one wins
            at = tops_z == z
            polygons = list(np.round(tops_px[at] * 16).astype(np.int32))
            cv2.fillPoly(top_z, polygons, float(z), cv2.LINE_8, 4)
            cv2.fillPoly(top_class, polygons, int(tops_class[at][0]), cv2.LINE_8, 4)
        grown = cv2.dilate(top_z, np.ones((5, 5), np.uint8))
        grown_class = cv2.dilate(top_class, np.ones((5, 5), np.uint8))
        classes = np.where(top_class > 0, top_class, grown_class).astype(np.uint8)
        return np.asarray(grown, np.float32), classes, np.asarray(origin, np.float64)

"""Which points lie inside the static world's solids (buildings, trees, poles, bridge piers).

The world builds these as prisms: vertical walls around a footprint and a flat top (no floor),
or a gable roof on the walls (its slopes count as tops at their highest point).
A point lies inside one iff a horizontal ray from it crosses the walls an odd number of times
(ray parity, as Open3D's ``compute_occupancy`` counts it, along rays that never meet a floor or
a top: walls are vertical, so a horizontal ray below a prism's walls or above them crosses none
of them). Two rays (along map +x and +y) must agree: a ray that grazes a wall's vertical edge
and miscounts leaves the point outside rather than filling a voxel in front of a wall. Only
points under some solid's top (a raster of the tops' heights, map frame, made in tiles and
kept) are cast. The rest of the world (roads, sidewalks, terrain) is surface, not volume.

:attr:`Solids.floors` closes the prisms for whoever needs closed surfaces: under each top
triangle, the same triangle at the foot of its prism's walls (inside and outside change
only across a wall, a top or a floor).
"""

from __future__ import annotations

import cv2
import numpy as np
import numpy.typing as npt

from networks.classes import SemanticClass
from networks.mesh import ClassedMesh
from sensors.o3d import RaycastingScene, o3c

SOLID_CLASSES = (SemanticClass.BUILDING, SemanticClass.VEGETATION, SemanticClass.POLE)
ROOFED = np.asarray([SemanticClass.BUILDING, SemanticClass.VEGETATION], np.uint8)  # sloped tops: roofs, crowns
RASTER_M = 0.2  # the tops' raster (points within two of its cells of a top are cast)
TILE = 256  # raster cells along a tile's side (51.2 m)
MARGIN = 4  # cells drawn beyond a tile's sides (the dilation reaches two)
KEPT_TILES = 64


class Solids:
    """The solids of the whole static world (whole prisms: rays run to infinity)."""

    classes = np.asarray(SOLID_CLASSES, np.uint8)

    def __init__(self, world: ClassedMesh) -> None:
        keep = np.isin(world.triangle_class, self.classes)
        tri = world.vertices_m[world.triangles[keep]].astype(np.float64)
        self._scene = RaycastingScene()
        if keep.any():
            vertices = np.ascontiguousarray(tri.reshape(-1, 3), np.float32)
            indices = np.arange(tri.shape[0] * 3, dtype=np.uint32).reshape(-1, 3)
            self._scene.add_triangles(o3c.Tensor.from_numpy(vertices), o3c.Tensor.from_numpy(indices))
        normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        flat = np.abs(normal[:, 2]) > 0.999 * np.linalg.norm(normal, axis=1)
        roof = np.isin(world.triangle_class[keep], ROOFED) & (normal[:, 2] > 0.05 * np.linalg.norm(normal, axis=1))
        self._tops = tri[flat | roof]
        self._top_class = world.triangle_class[keep][flat | roof]
        self._top_z = self._tops[:, :, 2].max(axis=1) if self._tops.shape[0] else np.zeros(0)
        self._top_xy_low = self._tops[:, :, :2].min(axis=1) if self._tops.shape[0] else np.zeros((0, 2))
        self._top_xy_high = self._tops[:, :, :2].max(axis=1) if self._tops.shape[0] else np.zeros((0, 2))
        self.floors = _floors(tri[~(flat | roof)], self._tops)
        self._tiles: dict[tuple[int, int], tuple[npt.NDArray[np.float32], npt.NDArray[np.uint8]]] = {}

    def floors_near(self, center_m: npt.NDArray[np.float64], reach_m: float) -> npt.NDArray[np.float64]:
        """``(F, 3, 3)`` the floors within ``reach_m`` of ``center_m`` (map frame, horizontally)."""
        f = self.floors
        if f.shape[0] == 0:
            return f
        low, high = f[:, :, :2].min(axis=1), f[:, :, :2].max(axis=1)
        gap = np.maximum(np.maximum(low - center_m[:2], center_m[:2] - high), 0.0)
        return np.asarray(f[np.linalg.norm(gap, axis=1) <= reach_m], np.float64)

    def inside(self, xyz_map_m: npt.NDArray[np.float64]) -> npt.NDArray[np.uint8]:
        """``(N,) uint8``: the class of the solid each point (map frame) lies inside, 0 if none."""
        out = np.zeros(xyz_map_m.shape[0], np.uint8)
        if self._tops.shape[0] == 0 or xyz_map_m.shape[0] == 0:
            return out
        top_z, top_class = self._raster_at(xyz_map_m[:, :2])
        candidate = np.flatnonzero(xyz_map_m[:, 2] <= top_z)
        odd = candidate
        for axis in (0, 1):  # along +x and +y: a ray that grazes a wall's edge miscounts one of them
            rays = np.zeros((odd.shape[0], 6), np.float32)
            rays[:, :3], rays[:, 3 + axis] = xyz_map_m[odd], 1.0
            crossings = self._scene.count_intersections(o3c.Tensor.from_numpy(rays)).numpy()
            odd = odd[crossings % 2 == 1]
        out[odd] = top_class[odd]
        return out

    def _raster_at(self, xy_map_m: npt.NDArray[np.float64]) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.uint8]]:
        """The raster's highest top and its class at each point (from the tiles it falls in)."""
        cell = np.floor(xy_map_m / RASTER_M).astype(np.int64)
        tile = np.floor_divide(cell, TILE)
        key = tile[:, 0] * (1 << 32) + tile[:, 1]
        top_z = np.empty(xy_map_m.shape[0], np.float32)
        top_class = np.empty(xy_map_m.shape[0], np.uint8)
        order = np.argsort(key, kind="stable")
        bounds = np.flatnonzero(np.r_[True, key[order][1:] != key[order][:-1], True])
        for a, b in zip(bounds[:-1].tolist(), bounds[1:].tolist(), strict=True):
            rows = order[a:b]
            tx, ty = (int(v) for v in tile[rows[0]])
            z, cls = self._tile(tx, ty)
            local = cell[rows] - np.array([tx * TILE, ty * TILE])
            top_z[rows], top_class[rows] = z[local[:, 1], local[:, 0]], cls[local[:, 1], local[:, 0]]
        return top_z, top_class

    def _tile(self, tx: int, ty: int) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.uint8]]:
        """One tile of the raster: the highest top's height and class per cell (each top two cells
        wider all round: a point near a footprint's edge is cast); the last few are kept."""
        key = (tx, ty)
        if key in self._tiles:
            return self._tiles[key]
        size = TILE + 2 * MARGIN
        origin = (np.array([tx, ty], np.float64) * TILE - MARGIN) * RASTER_M
        top_z = np.full((size, size), -np.inf, np.float32)
        top_class = np.zeros((size, size), np.uint8)
        extent = size * RASTER_M
        near = np.all(self._top_xy_high >= origin, axis=1) & np.all(self._top_xy_low <= origin + extent, axis=1)
        tops_px = (self._tops[near, :, :2] - origin) / RASTER_M
        tops_z, tops_class = self._top_z[near], self._top_class[near]
        for z in np.unique(tops_z):  # lowest first: a higher top over a lower one wins
            at = tops_z == z
            polygons = list(np.round(tops_px[at] * 16).astype(np.int32))
            cv2.fillPoly(top_z, polygons, float(z), cv2.LINE_8, 4)
            cv2.fillPoly(top_class, polygons, int(tops_class[at][0]), cv2.LINE_8, 4)
        grown = cv2.dilate(top_z, np.ones((5, 5), np.uint8))
        grown_class = cv2.dilate(top_class, np.ones((5, 5), np.uint8))
        classes = np.where(top_class > 0, top_class, grown_class).astype(np.uint8)
        inner = slice(MARGIN, MARGIN + TILE)
        tile = (
            np.ascontiguousarray(grown[inner, inner], np.float32),
            np.ascontiguousarray(classes[inner, inner], np.uint8),
        )
        if len(self._tiles) >= KEPT_TILES:
            self._tiles.pop(next(iter(self._tiles)))
        self._tiles[key] = tile
        return tile


def _floors(walls: npt.NDArray[np.float64], tops: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """``(T, 3, 3)``: each top triangle moved down to the lowest foot of the walls that share one
    of its corners (its prism's foot; a top no wall meets gets no floor: it stays where it is)."""
    if tops.shape[0] == 0 or walls.shape[0] == 0:
        return tops.copy()
    wall_keys = np.round(walls.reshape(-1, 3) * 1000.0).astype(np.int64)
    keys, inverse = np.unique(wall_keys, axis=0, return_inverse=True)
    foot = np.full(keys.shape[0], np.inf)
    np.minimum.at(foot, inverse.ravel(), np.repeat(walls[:, :, 2].min(axis=1), 3))
    top_keys = np.round(tops.reshape(-1, 3) * 1000.0).astype(np.int64)
    packed = keys.view([("", np.int64)] * 3).ravel()
    at = np.clip(np.searchsorted(packed, top_keys.view([("", np.int64)] * 3).ravel()), 0, keys.shape[0] - 1)
    found = np.all(keys[at] == top_keys, axis=1)
    z = np.where(found, foot[at], np.inf).reshape(-1, 3).min(axis=1)
    floors = tops.copy()
    floors[:, :, 2] = np.where(np.isfinite(z), z, tops[:, :, 2].min(axis=1))[:, None]
    return floors

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

The rays are cast into a scene of only the solids near the points (whole solids: the parts of
the world's solid surface joined by shared corners, each a closed surface or a ring of walls).
A horizontal ray from a point outside a solid's footprint's bounding box crosses that solid's
surface an even number of times, so leaving out the solids whose boxes hold none of the points
leaves every point's parity as the whole world's; the ray meets far fewer walls.

:attr:`Solids.floors` closes the prisms for whoever needs closed surfaces: under each top
triangle, the same triangle at the foot of its prism's walls (inside and outside change
only across a wall, a top or a floor).
"""

from __future__ import annotations

import math
from typing import Any

import cv2
import numpy as np
import numpy.typing as npt
from numba import njit

from networks.classes import SemanticClass
from networks.mesh import ClassedMesh
from sensors.o3d import RaycastingScene, o3c

SOLID_CLASSES = (SemanticClass.BUILDING, SemanticClass.VEGETATION, SemanticClass.TRUNK, SemanticClass.POLE)
ROOFED = np.asarray([SemanticClass.BUILDING, SemanticClass.VEGETATION], np.uint8)  # sloped tops: roofs, crowns
RASTER_M = 0.2  # the tops' raster (points within two of its cells of a top are cast)
TILE = 256  # raster cells along a tile's side (51.2 m)
MARGIN = 4  # cells drawn beyond a tile's sides (the dilation reaches two)
KEPT_TILES = 64
LOCAL_CELL_M = 51.2  # the local scenes' boxes snap out to this grid (a scene serves while the points stay in its box)
KEPT_SCENES = 4
PART_CASTS = 5  # points cast per part of points no surface parts (inside_parts)


class Solids:
    """The solids of the whole static world (whole prisms: rays run to infinity)."""

    classes = np.asarray(SOLID_CLASSES, np.uint8)

    def __init__(self, world: ClassedMesh) -> None:
        keep = np.isin(world.triangle_class, self.classes)
        tri = world.vertices_m[world.triangles[keep]].astype(np.float64)
        self._vertices = np.ascontiguousarray(tri.reshape(-1, 3), np.float32)
        part = _parts(tri)
        low = np.full((int(part.max(initial=-1)) + 1, 2), np.inf)
        high = np.full((low.shape[0], 2), -np.inf)
        np.minimum.at(low, part, tri[:, :, :2].min(axis=1))
        np.maximum.at(high, part, tri[:, :, :2].max(axis=1))
        self._part, self._part_low, self._part_high = part, low, high
        self._scenes: dict[tuple[int, int, int, int], Any] = {}
        normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        flat = np.abs(normal[:, 2]) > 0.999 * np.linalg.norm(normal, axis=1)
        roof = np.isin(world.triangle_class[keep], ROOFED) & (normal[:, 2] > 0.05 * np.linalg.norm(normal, axis=1))
        self._tops = tri[flat | roof]
        self._top_class = world.triangle_class[keep][flat | roof]
        self._top_z = self._tops[:, :, 2].max(axis=1) if self._tops.shape[0] else np.zeros(0)
        self._top_xy_low = self._tops[:, :, :2].min(axis=1) if self._tops.shape[0] else np.zeros((0, 2))
        self._top_xy_high = self._tops[:, :, :2].max(axis=1) if self._tops.shape[0] else np.zeros((0, 2))
        self.floors = _floors(tri[~(flat | roof)], self._tops)
        self._floor_low, self._floor_high = self.floors[:, :, :2].min(axis=1), self.floors[:, :, :2].max(axis=1)
        self._tiles: dict[tuple[int, int], tuple[npt.NDArray[np.float32], npt.NDArray[np.uint8]]] = {}

    def floors_near(self, center_m: npt.NDArray[np.float64], reach_m: float) -> npt.NDArray[np.float64]:
        """``(F, 3, 3)`` the floors within ``reach_m`` of ``center_m`` (map frame, horizontally)."""
        f = self.floors
        if f.shape[0] == 0:
            return f
        center = np.asarray(center_m[:2], np.float64)
        return np.asarray(f[_boxes_within(self._floor_low, self._floor_high, center, float(reach_m))], np.float64)

    def inside(self, xyz_map_m: npt.NDArray[np.float64]) -> npt.NDArray[np.uint8]:
        """``(N,) uint8``: the class of the solid each point (map frame) lies inside, 0 if none."""
        out = np.zeros(xyz_map_m.shape[0], np.uint8)
        if self._tops.shape[0] == 0 or xyz_map_m.shape[0] == 0:
            return out
        top_z, top_class = self._raster_at(xyz_map_m[:, :2])
        candidate = np.flatnonzero(xyz_map_m[:, 2] <= top_z)
        odd = candidate[self._odd(xyz_map_m[candidate])]
        out[odd] = top_class[odd]
        return out

    def _odd(self, xyz_map_m: npt.NDArray[np.float64]) -> npt.NDArray[np.bool_]:
        """``(N,)``: whether horizontal rays from each point cross the walls an odd number of times."""
        odd = np.arange(xyz_map_m.shape[0])
        if odd.size:
            scene = self._scene_around(xyz_map_m[:, :2].min(axis=0), xyz_map_m[:, :2].max(axis=0))
        for axis in (0, 1):  # along +x and +y: a ray that grazes a wall's edge miscounts one of them
            if odd.size == 0:
                break
            rays = np.zeros((odd.shape[0], 6), np.float32)
            rays[:, :3], rays[:, 3 + axis] = xyz_map_m[odd], 1.0
            crossings = scene.count_intersections(o3c.Tensor.from_numpy(rays), nthreads=1).numpy()
            odd = odd[crossings % 2 == 1]
        out = np.zeros(xyz_map_m.shape[0], np.bool_)
        out[odd] = True
        return out

    def inside_parts(
        self,
        xyz_map_m: npt.NDArray[np.float64],
        part: npt.NDArray[np.int64],
        castable: npt.NDArray[np.bool_] | None = None,
    ) -> npt.NDArray[np.uint8]:
        """:meth:`inside` of points known to lie alike in parts: ``part: (N,)`` (from 0) joins points
        that no solid's surface parts (all of one part lie inside the same solids or outside), so
        only a few points of each part are cast (up to :data:`PART_CASTS`, the part inside where
        most of them are; only those ``castable`` marks, if given); each point under a top (see
        :meth:`inside`) of a part inside takes the class of the highest top over it."""
        out = np.zeros(xyz_map_m.shape[0], np.uint8)
        if self._tops.shape[0] == 0 or xyz_map_m.shape[0] == 0:
            return out
        top_z, top_class = self._raster_at(xyz_map_m[:, :2])
        candidate = np.flatnonzero(xyz_map_m[:, 2] <= top_z)
        if candidate.size == 0:
            return out
        pool = candidate if castable is None else candidate[castable[candidate]]
        order = pool[np.argsort(part[pool], kind="stable")]
        groups = part[order]
        first = np.searchsorted(groups, groups, side="left")
        cast = order[np.arange(order.shape[0]) - first < PART_CASTS]  # the first few of each part
        odd = self._odd(xyz_map_m[cast])
        parts = int(part.max()) + 1
        votes = np.bincount(part[cast], odd, minlength=parts)
        tries = np.bincount(part[cast], minlength=parts)
        inside_part = 2 * votes > tries
        chosen = candidate[inside_part[part[candidate]]]
        out[chosen] = top_class[chosen]
        return out

    def _scene_around(self, low_m: npt.NDArray[np.float64], high_m: npt.NDArray[np.float64]) -> Any:
        """A raycasting scene of the solids whose boxes meet the box ``low_m .. high_m`` (map xy)
        snapped out to :data:`LOCAL_CELL_M`; the last few are kept."""
        lo = np.floor(low_m / LOCAL_CELL_M).astype(np.int64)
        hi = np.ceil(high_m / LOCAL_CELL_M).astype(np.int64)
        key = (int(lo[0]), int(lo[1]), int(hi[0]), int(hi[1]))
        if key in self._scenes:
            return self._scenes[key]
        box_low, box_high = lo * LOCAL_CELL_M, hi * LOCAL_CELL_M
        near = np.all(self._part_high >= box_low, axis=1) & np.all(self._part_low <= box_high, axis=1)
        triangles = np.flatnonzero(near[self._part])
        scene = RaycastingScene()
        if triangles.size:
            vertices = np.ascontiguousarray(self._vertices.reshape(-1, 3, 3)[triangles].reshape(-1, 3))
            indices = np.arange(vertices.shape[0], dtype=np.uint32).reshape(-1, 3)
            scene.add_triangles(o3c.Tensor.from_numpy(vertices), o3c.Tensor.from_numpy(indices))
        if len(self._scenes) >= KEPT_SCENES:
            self._scenes.pop(next(iter(self._scenes)))
        self._scenes[key] = scene
        return scene

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


def _parts(tri: npt.NDArray[np.float64]) -> npt.NDArray[np.int64]:
    """``(T,)``: which part each triangle belongs to, parts joined by shared corners (to the mm)."""
    if tri.shape[0] == 0:
        return np.zeros(0, np.int64)
    keys = np.round(tri.reshape(-1, 3) * 1000.0).astype(np.int64)
    _, corner = np.unique(keys, axis=0, return_inverse=True)
    root = _union(corner.reshape(-1, 3).astype(np.int64), int(corner.max()) + 1)
    _, part = np.unique(root, return_inverse=True)
    return np.asarray(part, np.int64)


@njit(cache=True, nogil=True)
def _union(corner: npt.NDArray[np.int64], count: int) -> npt.NDArray[np.int64]:  # pragma: no cover - compiled
    """Each triangle's part's smallest corner (union-find over the triangles' corners)."""
    parent = np.arange(count)
    for t in range(corner.shape[0]):
        for k in (1, 2):
            a = corner[t, 0]
            while parent[a] != a:
                parent[a] = parent[parent[a]]
                a = parent[a]
            b = corner[t, k]
            while parent[b] != b:
                parent[b] = parent[parent[b]]
                b = parent[b]
            if a != b:
                parent[max(a, b)] = min(a, b)
    out = np.empty(corner.shape[0], np.int64)
    for t in range(corner.shape[0]):
        a = corner[t, 0]
        while parent[a] != a:
            a = parent[a]
        out[t] = a
    return out


@njit(cache=True, nogil=True)
def _boxes_within(
    low: npt.NDArray[np.float64], high: npt.NDArray[np.float64], center: npt.NDArray[np.float64], reach: float
) -> npt.NDArray[np.int64]:  # pragma: no cover - compiled
    """The rows of the boxes ``low .. high: (N, 2)`` at most ``reach`` from ``center: (2,)``: each
    axis's gap (0 where the box spans the centre), the distance as ``np.linalg.norm`` computes it."""
    out = np.empty(low.shape[0], np.int64)
    m = 0
    for n in range(low.shape[0]):
        g0 = max(max(low[n, 0] - center[0], center[0] - high[n, 0]), 0.0)
        g1 = max(max(low[n, 1] - center[1], center[1] - high[n, 1]), 0.0)
        if math.sqrt(g0 * g0 + g1 * g1) <= reach:
            out[m] = n
            m += 1
    return out[:m].copy()

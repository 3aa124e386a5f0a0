"""Triangle meshes with a semantic class per triangle, and the builders of their parts."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
import shapely
from shapely.geometry import Polygon

from networks.classes import SemanticClass


@dataclass(frozen=True, slots=True)
class ClassedMesh:
    """``vertices_m: (N, 3) float32`` in the map frame, ``triangles: (M, 3) int32``,
    ``triangle_class: (M,) uint8`` holding :class:`SemanticClass` values."""

    vertices_m: npt.NDArray[np.floating[Any]]
    triangles: npt.NDArray[np.integer[Any]]
    triangle_class: npt.NDArray[np.integer[Any]]

    def __post_init__(self) -> None:
        v = np.ascontiguousarray(self.vertices_m, dtype=np.float32).reshape(-1, 3)
        t = np.ascontiguousarray(self.triangles, dtype=np.int32).reshape(-1, 3)
        c = np.ascontiguousarray(self.triangle_class, dtype=np.uint8).reshape(-1)
        if c.shape[0] != t.shape[0]:
            raise ValueError(f"ClassedMesh: {t.shape[0]} triangles but {c.shape[0]} classes")
        if t.size and (t.min() < 0 or t.max() >= v.shape[0]):
            raise ValueError("ClassedMesh: triangle index out of range")
        object.__setattr__(self, "vertices_m", v)
        object.__setattr__(self, "triangles", t)
        object.__setattr__(self, "triangle_class", c)

    @classmethod
    def empty(cls) -> ClassedMesh:
        return cls(np.zeros((0, 3), np.float32), np.zeros((0, 3), np.int32), np.zeros(0, np.uint8))

    @property
    def num_triangles(self) -> int:
        return int(self.triangles.shape[0])


def merge(meshes: list[ClassedMesh]) -> ClassedMesh:
    if not meshes:
        return ClassedMesh.empty()
    offsets = np.cumsum([0] + [m.vertices_m.shape[0] for m in meshes[:-1]])
    return ClassedMesh(
        np.concatenate([m.vertices_m for m in meshes]),
        np.concatenate([m.triangles + off for m, off in zip(meshes, offsets, strict=True)]),
        np.concatenate([m.triangle_class for m in meshes]),
    )


def polyline_normals(xy: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """Unit left normals at each vertex of an ``(K, 2)`` polyline (mitred, clamped)."""
    seg = np.diff(xy, axis=0)
    seg_len = np.linalg.norm(seg, axis=1, keepdims=True)
    seg = seg / np.maximum(seg_len, 1e-9)
    seg_normals = np.stack([-seg[:, 1], seg[:, 0]], axis=1)
    normals = np.empty_like(xy)
    normals[0], normals[-1] = seg_normals[0], seg_normals[-1]
    mid = seg_normals[:-1] + seg_normals[1:]
    mid_len = np.linalg.norm(mid, axis=1, keepdims=True)
    mid = mid / np.maximum(mid_len, 1e-9)
    cos_half = np.sum(mid * seg_normals[:-1], axis=1, keepdims=True)
    normals[1:-1] = mid / np.clip(cos_half, 0.5, 1.0)
    return normals


def ribbon(
    shape_m: npt.ArrayLike, width_m: float, cls: SemanticClass, z_offset_m: float = 0.0, wall_height_m: float = 0.0
) -> ClassedMesh:
    """A flat strip of ``width_m`` centred on a ``(K, 3)`` polyline, optionally with
    vertical walls of ``wall_height_m`` below its sides and ends (curbs), classed CURB."""
    p = np.asarray(shape_m, dtype=np.float64)
    keep = np.concatenate([[True], np.linalg.norm(np.diff(p[:, :2], axis=0), axis=1) > 1e-3])
    p = p[keep]
    if p.shape[0] < 2:
        return ClassedMesh.empty()
    n = polyline_normals(p[:, :2]) * (width_m / 2.0)
    z = p[:, 2] + z_offset_m
    left = np.column_stack([p[:, :2] + n, z])
    right = np.column_stack([p[:, :2] - n, z])
    k = p.shape[0]
    verts = np.concatenate([left, right])
    i = np.arange(k - 1)
    tris = np.concatenate([np.stack([i, k + i, i + 1], 1), np.stack([i + 1, k + i, k + i + 1], 1)])
    parts = [ClassedMesh(verts, tris, np.full(tris.shape[0], cls, np.uint8))]
    if wall_height_m > 0:  # both sides and both ends, so that nothing passes under the strip
        for edge in (left, right, np.stack([left[0], right[0]]), np.stack([left[-1], right[-1]])):
            parts.append(_wall(edge, wall_height_m, SemanticClass.CURB))
    return merge(parts)


def _wall(top: npt.NDArray[np.float64], height_m: float, cls: SemanticClass) -> ClassedMesh:
    """Vertical wall hanging ``height_m`` below a ``(K, 3)`` polyline."""
    k = top.shape[0]
    bottom = top - np.array([0.0, 0.0, height_m])
    verts = np.concatenate([top, bottom])
    i = np.arange(k - 1)
    tris = np.concatenate([np.stack([i, i + 1, k + i], 1), np.stack([i + 1, k + i + 1, k + i], 1)])
    return ClassedMesh(verts, tris, np.full(tris.shape[0], cls, np.uint8))


def flat_polygon(polygon: Polygon, z_m: float, cls: SemanticClass) -> ClassedMesh:
    """Triangulate a (possibly non-convex) polygon at height ``z_m``."""
    if polygon.is_empty or polygon.area < 1e-4:
        return ClassedMesh.empty()
    tris = shapely.get_parts(shapely.constrained_delaunay_triangles(polygon))
    if len(tris) == 0:
        return ClassedMesh.empty()
    coords = shapely.get_coordinates(shapely.get_exterior_ring(tris)).reshape(len(tris), 4, 2)[:, :3]
    verts = np.column_stack([coords.reshape(-1, 2), np.full(coords.shape[0] * 3, z_m)])
    return ClassedMesh(verts, np.arange(verts.shape[0]).reshape(-1, 3), np.full(len(tris), cls, np.uint8))


def draped_polygon(polygon: Polygon, outline_m: npt.ArrayLike, cls: SemanticClass) -> ClassedMesh:
    """Triangulate a polygon whose corners lie on a ``(K, 3)`` outline, each vertex at the
    height of the nearest outline point (the triangulation adds no inner vertices)."""
    flat = flat_polygon(polygon, 0.0, cls)
    if flat.num_triangles == 0:
        return flat
    outline = np.asarray(outline_m, dtype=np.float64).reshape(-1, 3)
    xy = flat.vertices_m[:, :2].astype(np.float64)
    nearest = np.argmin(np.linalg.norm(xy[:, None, :] - outline[None, :, :2], axis=2), axis=1)
    return ClassedMesh(np.column_stack([xy, outline[nearest, 2]]), flat.triangles, flat.triangle_class)


def raised_polygon(polygon: Polygon, top_z_m: float, wall_height_m: float, cls: SemanticClass) -> ClassedMesh:
    """A polygon at ``top_z_m`` (classed ``cls``) with CURB walls ``wall_height_m`` deep."""
    if polygon.is_empty or polygon.area < 1e-3:
        return ClassedMesh.empty()
    parts = [flat_polygon(polygon, top_z_m, cls)]
    for ring in (polygon.exterior, *polygon.interiors):
        xy = np.asarray(ring.coords)
        parts.append(_wall(np.column_stack([xy, np.full(len(xy), top_z_m)]), wall_height_m, SemanticClass.CURB))
    return merge(parts)


def prism(footprint: Polygon, z0_m: float, height_m: float, cls: SemanticClass) -> ClassedMesh:
    """Closed extrusion of a polygon footprint from ``z0_m`` up by ``height_m``."""
    ring = np.asarray(footprint.exterior.coords)[:-1]
    top = np.column_stack([ring, np.full(ring.shape[0], z0_m + height_m)])
    closed = np.concatenate([top, top[:1]])
    walls = _wall(closed, height_m, cls)
    return merge([walls, flat_polygon(footprint, z0_m + height_m, cls)])


def box_mesh(lwh_m: tuple[float, float, float], cls: SemanticClass) -> ClassedMesh:
    """Axis-aligned box centred on the origin."""
    half = np.asarray(lwh_m, dtype=np.float64) / 2.0
    corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=np.float64) * half
    tris = np.array(BOX_TRIANGLES, dtype=np.int32)
    return ClassedMesh(corners, tris, np.full(12, cls, np.uint8))


# Corners indexed by (sx, sy, sz) bits as in box_mesh; outward-facing triangles.
BOX_TRIANGLES = (
    (0, 1, 3), (0, 3, 2),  # -x
    (4, 6, 7), (4, 7, 5),  # +x
    (0, 4, 5), (0, 5, 1),  # -y
    (2, 3, 7), (2, 7, 6),  # +y
    (0, 2, 6), (0, 6, 4),  # -z
    (1, 5, 7), (1, 7, 3),  # +z
)  # fmt: skip

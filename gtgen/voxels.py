"""Exact voxel geometry on an axis-aligned grid: which voxels a triangle touches, which a box's
volume overlaps, which a segment crosses. Pure numpy, vectorised over triangles, boxes and rays.

Coordinates are the grid's own frame (the ego frame for occupancy); a voxel ``(i, j, k)`` spans
``lower_m + voxel_m * [i, i + 1] x [j, j + 1] x [k, k + 1]``. Voxels are returned as flat
indices into the ``(nx, ny, nz)`` C-ordered array.

- :func:`triangle_voxels`: every voxel whose closed cube meets a triangle (separating-axis
  test on the 13 axes of a triangle and a cube, after bisecting triangles to at most a voxel).
- :func:`box_voxels`: every voxel whose cube overlaps an oriented box's volume by more than a
  touch (separating-axis test on the 15 axes of two boxes).
- :func:`segment_voxels`: every voxel a segment passes through (each crossing of a voxel
  boundary plane names the voxel entered).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

F64 = npt.NDArray[np.float64]
I64 = npt.NDArray[np.int64]

TOUCH = 1e-9  # in voxels: a box that only touches a voxel's face does not fill it


@dataclass(frozen=True, slots=True)
class VoxelGrid:
    """``lower_m``: the grid's lowest corner (x, y, z); ``shape``: voxels along x, y, z."""

    lower_m: tuple[float, float, float]
    voxel_m: float
    shape: tuple[int, int, int]

    @property
    def size(self) -> int:
        return self.shape[0] * self.shape[1] * self.shape[2]

    @property
    def upper_m(self) -> tuple[float, float, float]:
        lo, n, v = self.lower_m, self.shape, self.voxel_m
        return (lo[0] + n[0] * v, lo[1] + n[1] * v, lo[2] + n[2] * v)

    def to_grid(self, xyz_m: npt.ArrayLike) -> F64:
        """Points in voxel units (voxel ``(i, j, k)`` spans ``[i, i + 1)`` on each axis)."""
        return np.asarray((np.asarray(xyz_m, np.float64) - np.asarray(self.lower_m)) / self.voxel_m, np.float64)

    def flat(self, ijk: I64) -> I64:
        _, ny, nz = self.shape
        return (ijk[..., 0] * ny + ijk[..., 1]) * nz + ijk[..., 2]

    def ijk_of(self, xyz_m: npt.ArrayLike) -> I64:
        """``(N, 3)`` voxel indices of points (may lie outside the grid)."""
        return np.floor(self.to_grid(xyz_m)).astype(np.int64)

    def inside(self, ijk: I64) -> npt.NDArray[np.bool_]:
        return np.asarray(np.all((ijk >= 0) & (ijk < np.asarray(self.shape)), axis=-1), np.bool_)

    def centers_m(self, flat: I64) -> F64:
        """``(N, 3)`` centres of voxels given by flat index."""
        ijk = np.stack(np.unravel_index(flat, self.shape), axis=-1)
        return np.asarray(np.asarray(self.lower_m) + (ijk + 0.5) * self.voxel_m, np.float64)


@dataclass(frozen=True, slots=True)
class OccupancyGrid:
    """The voxel grid in the ego frame: ``range_m`` = (x_min, y_min, z_min, x_max, y_max, z_max)."""

    voxel_m: float = 0.4
    range_m: tuple[float, float, float, float, float, float] = (-40.0, -40.0, -1.0, 40.0, 40.0, 5.4)

    @property
    def grid(self) -> VoxelGrid:
        lo, hi = np.asarray(self.range_m[:3]), np.asarray(self.range_m[3:])
        shape = np.rint((hi - lo) / self.voxel_m).astype(int)
        return VoxelGrid(
            (float(lo[0]), float(lo[1]), float(lo[2])), self.voxel_m, (int(shape[0]), int(shape[1]), int(shape[2]))
        )


PRESETS = {
    "occ3d": OccupancyGrid(0.4, (-40.0, -40.0, -1.0, 40.0, 40.0, 5.4)),  # Occ3D-nuScenes: 200 x 200 x 16
    "openoccupancy": OccupancyGrid(0.2, (-51.2, -51.2, -5.0, 51.2, 51.2, 3.0)),  # 512 x 512 x 40
}


# --- triangles ----------------------------------------------------------------------------------
EPS = 1e-9  # in voxels: a point this close to a voxel's face counts as on it


def triangle_voxels(
    grid: VoxelGrid,
    triangles_m: npt.NDArray[np.floating],
    corners: npt.ArrayLike | None = None,
    rotation: F64 | None = None,
    translation: F64 | None = None,
) -> tuple[I64, I64]:
    """``(flat, source)``: the voxels each triangle ``(T, 3, 3)`` meets (closed cubes: a triangle on
    a voxel face meets the voxels on both sides), and the triangle each pair comes from. With
    ``corners: (T, 3)`` (indices), ``triangles_m`` are the vertices ``(V, 3)`` the triangles index;
    with ``rotation`` and ``translation``, the vertices are in another frame and placed in the
    grid's by them (each triangle's corners only, not every vertex).

    For each row of voxels along x (a ``(y, z)`` cell of the triangle's bounding box), the part of
    the triangle inside that row is a convex polygon; its x extent, from the polygon's corners
    (the triangle's corners in the row, its edges' crossings of the row's four faces, the row's
    four edges' crossings of the triangle), names exactly the voxels of the row it meets."""
    from gtgen import voxel_kernels

    points = np.asarray(triangles_m)  # float32 vertices as they are (each corner made float64 in the walk)
    points = np.ascontiguousarray(points.reshape(-1, 3), np.float32 if points.dtype == np.float32 else np.float64)
    index = np.arange(points.shape[0]).reshape(-1, 3) if corners is None else np.asarray(corners, np.int64)
    lower = np.asarray(grid.lower_m, np.float64)
    r = np.zeros((0, 3)) if rotation is None else np.ascontiguousarray(rotation, np.float64)
    t = np.zeros(3) if translation is None else np.ascontiguousarray(translation, np.float64)
    return voxel_kernels.mesh_voxels(points, np.ascontiguousarray(index), lower, grid.voxel_m, *grid.shape, r, t)


def _ragged(count: I64) -> tuple[I64, I64]:
    """``(owner, index)``: ``count[n]`` entries for each ``n``, numbered from 0 within each."""
    owner = np.repeat(np.arange(count.shape[0], dtype=np.int64), count)
    first = np.cumsum(count) - count
    return owner, np.arange(owner.shape[0], dtype=np.int64) - first[owner]


# --- boxes --------------------------------------------------------------------------------------
def box_voxels(grid: VoxelGrid, center_m: F64, grid_R_box: F64, lwh_m: F64) -> tuple[I64, I64]:
    """``(flat, source)``: the voxels whose cube overlaps the volume of each box (centre
    ``(B, 3)``, orientation ``(B, 3, 3)``, size ``(B, 3)``) by more than a touch, and its box: the
    voxels of each box's bounding box that no separating axis (the 15 of two boxes) parts from it."""
    from gtgen import voxel_kernels

    half = lwh_m / 2.0 / grid.voxel_m
    center = grid.to_grid(center_m)
    reach = np.einsum("bij,bj->bi", np.abs(grid_R_box), half)
    shape = np.asarray(grid.shape)
    low = np.maximum(np.floor(center - reach).astype(np.int64), 0)
    high = np.minimum(np.ceil(center + reach).astype(np.int64), shape) - 1
    size = np.maximum(high - low + 1, 0)
    axes, radius = _separating_axes(grid_R_box, half)
    _, ny, nz = grid.shape
    return voxel_kernels.box_cells(
        low, size, np.ascontiguousarray(center), np.ascontiguousarray(axes), radius - TOUCH, ny, nz
    )


def _separating_axes(R: F64, half: F64) -> tuple[F64, F64]:
    """``(B, 15, 3)`` unit axes that may part each box from a unit cube (the cube's and the box's
    faces, their edges crossed), and ``(B, 15)`` the box's and the cube's reach along each summed
    (``inf`` for the cross of parallel edges: an axis already tested)."""
    eye = np.broadcast_to(np.eye(3), R.shape)
    box_axes = np.swapaxes(R, 1, 2)  # rows: the box's axes
    crossed = np.cross(eye[:, :, None, :], box_axes[:, None, :, :]).reshape(-1, 9, 3)
    axes = np.concatenate([eye, box_axes, crossed], axis=1)
    length = np.linalg.norm(axes, axis=2)
    usable = length > 1e-9
    axes = axes / np.where(usable, length, 1.0)[:, :, None]
    r_box = np.einsum("bj,baj->ba", half, np.abs(np.einsum("bij,bai->baj", R, axes)))
    r_cube = 0.5 * np.abs(axes).sum(axis=2)
    return axes, np.where(usable, r_box + r_cube, np.inf)


# --- segments -----------------------------------------------------------------------------------
def segment_voxels(grid: VoxelGrid, start_m: F64, end_m: F64) -> I64:
    """Flat indices (with repeats) of every voxel that segments ``start -> end`` (``(N, 3)``
    each) pass through within the grid, the voxels of their ends included: the voxels of the
    segment's ends within the grid, and the voxel entered at each crossing of a voxel face."""
    return np.concatenate([flat for _, flat in _segment_chunks(grid, start_m, end_m)])


def segment_voxel_pairs(grid: VoxelGrid, start_m: F64, end_m: F64) -> tuple[I64, I64]:
    """``(segment, flat)``: the voxels of :func:`segment_voxels` with the segment each comes from."""
    pairs = list(_segment_chunks(grid, start_m, end_m))
    return np.concatenate([r for r, _ in pairs]), np.concatenate([f for _, f in pairs])


def mark_segments(grid: VoxelGrid, start_m: F64, end_m: F64, out: npt.NDArray[np.bool_]) -> None:
    """Set ``out`` (flat, ``grid.size``) at every voxel of :func:`segment_voxels`."""
    for _, flat in _segment_chunks(grid, start_m, end_m):
        out[flat] = True


@dataclass(frozen=True, slots=True)
class SegmentWalk:
    """Segments set up for a voxel walk (Amanatides and Woo's): each segment clipped to the grid
    starts in ``voxel: (N, 3) int32``, steps ``step: (N, 3) int32`` (-1, 0, +1) along each axis, meets
    its next face along each axis at ``t_next: (N, 3) float64`` and every face after that
    ``t_delta: (N, 3) float64`` later (parameters of the whole segment, ``inf``: never), and ends at
    ``t_end: (N,) float64``. The walk visits the voxel it is in, then steps across the nearest face
    while that lies before ``t_end`` and within the grid."""

    voxel: npt.NDArray[np.int32]
    step: npt.NDArray[np.int32]
    t_next: F64
    t_delta: F64
    t_end: F64

    @staticmethod
    def of(grid: VoxelGrid, start_m: F64, end_m: F64) -> SegmentWalk:
        s, e = grid.to_grid(start_m), grid.to_grid(end_m)
        shape = np.asarray(grid.shape)
        t0, t1 = _clip_to_box(s, e - s, shape.astype(np.float64))
        keep = t0 < t1
        s, d, t0, t1 = s[keep], (e - s)[keep], t0[keep], t1[keep]
        voxel = np.clip(np.floor(s + d * t0[:, None]).astype(np.int64), 0, shape - 1)
        step = np.sign(d).astype(np.int64)
        with np.errstate(divide="ignore", invalid="ignore"):
            t_next = np.where(step != 0, (np.where(step > 0, voxel + 1, voxel) - s) / d, np.inf)
            t_delta = np.where(step != 0, 1.0 / np.abs(d), np.inf)
        return SegmentWalk(voxel.astype(np.int32), step.astype(np.int32), t_next, t_delta, t1)


def walk_segments(grid: VoxelGrid, walk: SegmentWalk, out: npt.NDArray[np.bool_]) -> None:
    """Set ``out`` (flat, ``grid.size``) at every voxel the walk visits (numpy, all segments a
    step at a time; the same voxels as a compiled walk)."""
    voxel, t_next = walk.voxel.astype(np.int64), walk.t_next.copy()
    step, t_delta, t_end = walk.step.astype(np.int64), walk.t_delta, walk.t_end
    rows = np.arange(voxel.shape[0])
    shape = np.asarray(grid.shape)
    while rows.size:
        out[grid.flat(voxel)] = True
        axis = np.argmin(t_next, axis=1)
        at = np.arange(rows.size)
        t_min = t_next[at, axis]
        voxel[at, axis] += step[rows, axis]
        t_next[at, axis] += t_delta[rows, axis]
        go = (t_min <= t_end[rows]) & np.all((voxel >= 0) & (voxel < shape), axis=1)
        rows, voxel, t_next = rows[go], voxel[go], t_next[go]


def walk_voxels(grid: VoxelGrid, start_m: F64, end_m: F64, out: npt.NDArray[np.bool_]) -> None:
    """Set ``out`` (flat, ``grid.size``) at every voxel the walk of each segment ``start -> end``
    (``(N, 3)`` each) visits: :meth:`SegmentWalk.of` and :func:`walk_segments`, compiled, one
    segment at a time."""
    from gtgen import voxel_kernels

    s, e = np.asarray(start_m, np.float64), np.asarray(end_m, np.float64)
    voxel_kernels.walk(s, e, np.asarray(grid.lower_m, np.float64), grid.voxel_m, *grid.shape, out)


def walk_from(
    grid: VoxelGrid, points: npt.NDArray[np.floating], rotation: F64, translation: F64, out: npt.NDArray[np.bool_]
) -> None:
    """:func:`walk_voxels` of the segments from ``translation`` to each of ``points: (N, 3)``
    mapped into the grid's frame by ``rotation`` and ``translation`` (a sensor's rays from its
    mount to its returns, without an array of ends)."""
    from gtgen import voxel_kernels

    lower = np.asarray(grid.lower_m, np.float64)
    r, t = np.ascontiguousarray(rotation, np.float64), np.ascontiguousarray(translation, np.float64)
    voxel_kernels.walk_from(np.asarray(points), r, t, lower, grid.voxel_m, *grid.shape, out)


def _segment_chunks(grid: VoxelGrid, start_m: F64, end_m: F64) -> Iterator[tuple[I64, I64]]:
    s, e = grid.to_grid(start_m), grid.to_grid(end_m)
    shape = np.asarray(grid.shape)
    t0, t1 = _clip_to_box(s, e - s, shape.astype(np.float64))
    keep = t0 < t1
    kept = np.flatnonzero(keep)
    s, d, t0, t1 = s[keep], (e - s)[keep], t0[keep], t1[keep]
    a, b = s + d * t0[:, None], s + d * t1[:, None]
    step = 1e-6 / np.maximum(np.abs(d).max(axis=1), 1e-12)  # a millionth of a voxel along the segment
    for end in (a, b):  # ends on a face: the voxels on both sides (the crossings give the other)
        yield kept, grid.flat(np.clip(np.floor(end).astype(np.int64), 0, shape - 1))
    for axis in range(3):
        other = [x for x in range(3) if x != axis]
        lo = np.ceil(np.minimum(a[:, axis], b[:, axis]))
        hi = np.floor(np.maximum(a[:, axis], b[:, axis]))
        count = np.where(d[:, axis] != 0, np.maximum(hi - lo + 1, 0), 0).astype(np.int64)
        ray, index = _ragged(count)
        plane = lo[ray] + index
        forward = d[ray, axis] > 0
        t = (plane - s[ray, axis]) / d[ray, axis] + step[ray]  # just past the crossing (edges, corners)
        ijk = np.empty((ray.shape[0], 3), np.int64)
        ijk[:, axis] = np.where(forward, plane, plane - 1)  # the voxel entered at the crossing
        for o in other:
            ijk[:, o] = np.floor(s[ray, o] + d[ray, o] * np.minimum(t, t1[ray]))
        yield kept[ray], grid.flat(np.clip(ijk, 0, shape - 1))


def _clip_to_box(s: F64, d: F64, upper: F64) -> tuple[F64, F64]:
    """Parameters ``[t0, t1]`` within ``[0, 1]`` where ``s + t d`` lies in ``[0, upper]``."""
    with np.errstate(divide="ignore", invalid="ignore"):
        ta = np.where(d != 0, (0.0 - s) / d, -np.inf)
        tb = np.where(d != 0, (upper - s) / d, np.inf)
    inside = (s >= 0) & (s <= upper)
    never = (d == 0) & ~inside  # parallel to a face, outside the slab
    lower = np.where(never, np.inf, np.minimum(ta, tb))
    upper = np.where(never, -np.inf, np.maximum(ta, tb))
    t0 = np.maximum(np.max(lower, axis=1), 0.0)
    t1 = np.minimum(np.min(upper, axis=1), 1.0)
    return t0, t1

"""Compiled loops (Numba) of :mod:`gtgen.voxels` and :mod:`gtgen.occupancy`: the same arithmetic
as their numpy forms, one triangle, row or ray at a time instead of one array pass per step.

Grid coordinates throughout (voxel units, the grid's lowest corner at 0); voxels as flat indices
into the C-ordered ``(nx, ny, nz)`` array. Compiled on first use and cached beside this file."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import numpy.typing as npt
from numba import njit

EPS = 1e-9  # as gtgen.voxels.EPS

I64 = npt.NDArray[np.int64]


@njit(cache=True, nogil=True)
def _grow(a: npt.NDArray[Any], n: int) -> npt.NDArray[Any]:  # pragma: no cover - compiled
    """``a`` copied into a longer array of its type (room for at least ``n`` elements)."""
    b = np.empty(max(2 * a.shape[0], n + 1024), a.dtype)
    b[: a.shape[0]] = a
    return b


@njit(cache=True, nogil=True)
def _in_row(y: float, z: float, j: float, k: float) -> bool:  # pragma: no cover - compiled
    return y >= j - EPS and y <= j + 1 + EPS and z >= k - EPS and z <= k + 1 + EPS


@njit(cache=True, nogil=True)
def _x_extent(
    t: npt.NDArray[np.float64], j: float, k: float, n: npt.NDArray[np.float64]
) -> tuple[float, float]:  # pragma: no cover - compiled
    """As ``gtgen.voxels._x_extent`` for one triangle ``t: (3, 3)`` and the row ``(j, k)``;
    ``n``: the triangle's normal, ``cross(t1 - t0, t2 - t0)``."""
    lo, hi = math.inf, -math.inf
    for v in range(3):
        x = t[v, 0]
        if _in_row(t[v, 1], t[v, 2], j, k) and math.isfinite(x):
            lo, hi = min(lo, x), max(hi, x)
    for axis in (1, 2):
        base = j if axis == 1 else k
        for plane in (base, base + 1.0):
            for e in range(3):
                a0, a1, a2 = t[e, 0], t[e, 1], t[e, 2]
                b = (e + 1) % 3
                d0, d1, d2 = t[b, 0] - a0, t[b, 1] - a1, t[b, 2] - a2
                da = d1 if axis == 1 else d2
                if da == 0.0:
                    continue  # parallel to the plane: numpy's inf or nan, never finite
                s = (plane - (a1 if axis == 1 else a2)) / da
                p0, p1, p2 = a0 + d0 * s, a1 + d1 * s, a2 + d2 * s
                if s >= -EPS and s <= 1 + EPS and _in_row(p1, p2, j, k) and math.isfinite(p0):
                    lo, hi = min(lo, p0), max(hi, p0)
    n0, n1, n2 = n[0], n[1], n[2]
    if abs(n0) > EPS:
        dot = n0 * t[0, 0] + n1 * t[0, 1] + n2 * t[0, 2]
        for cy, cz in ((j, k), (j, k + 1.0), (j + 1.0, k), (j + 1.0, k + 1.0)):
            x = (dot - n1 * cy - n2 * cz) / n0
            if not math.isfinite(x):
                continue
            s0 = (t[1, 1] - t[0, 1]) * (cz - t[0, 2]) - (t[1, 2] - t[0, 2]) * (cy - t[0, 1])
            s1 = (t[2, 1] - t[1, 1]) * (cz - t[1, 2]) - (t[2, 2] - t[1, 2]) * (cy - t[1, 1])
            s2 = (t[0, 1] - t[2, 1]) * (cz - t[2, 2]) - (t[0, 2] - t[2, 2]) * (cy - t[2, 1])
            scale = EPS * max(1.0, max(abs(s0), max(abs(s1), abs(s2))))
            pos = s0 >= -scale and s1 >= -scale and s2 >= -scale
            neg = s0 <= scale and s1 <= scale and s2 <= scale
            if pos or neg:
                lo, hi = min(lo, x), max(hi, x)
    return lo, hi


@njit(cache=True, nogil=True, inline="always")
def _tri_span(
    t: npt.NDArray[np.float64], shape: tuple[int, int, int], lo: I64, hi: I64
) -> bool:  # pragma: no cover - compiled
    """The voxels triangle ``t: (3, 3)`` (grid coordinates) may meet: ``lo[a]..hi[a]`` per axis,
    clamped to the grid ``shape``; False where the triangle lies wholly outside it."""
    meets = True
    for a in range(3):
        mn = min(t[0, a], min(t[1, a], t[2, a]))
        mx = max(t[0, a], max(t[1, a], t[2, a]))
        if not (mx >= -EPS and mn <= shape[a] + EPS):
            meets = False
        lo[a] = min(max(math.floor(mn - EPS), 0), shape[a] - 1)
        hi[a] = min(max(math.floor(mx + EPS), 0), shape[a] - 1)
    return meets


@njit(cache=True, nogil=True, inline="always")
def _tri_normal(t: npt.NDArray[np.float64], n: npt.NDArray[np.float64]) -> None:  # pragma: no cover - compiled
    """``n = cross(t1 - t0, t2 - t0)``, as :func:`_x_extent` takes it."""
    e0 = (t[1, 0] - t[0, 0], t[1, 1] - t[0, 1], t[1, 2] - t[0, 2])
    e2 = (-(t[0, 0] - t[2, 0]), -(t[0, 1] - t[2, 1]), -(t[0, 2] - t[2, 2]))
    n[0] = e0[1] * e2[2] - e0[2] * e2[1]
    n[1] = e0[2] * e2[0] - e0[0] * e2[2]
    n[2] = e0[0] * e2[1] - e0[1] * e2[0]


@njit(cache=True, nogil=True, inline="always")
def _row_span(
    t: npt.NDArray[np.float64], j: int, k: int, n: npt.NDArray[np.float64], nx: int
) -> tuple[int, int]:  # pragma: no cover - compiled
    """The voxels ``i0..i1`` of the row ``(j, k)`` triangle ``t`` meets (``n``: :func:`_tri_normal`),
    clamped to the grid; ``i0 > i1``: none."""
    x_min, x_max = _x_extent(t, float(j), float(k), n)
    if not (x_min <= x_max and x_max >= -EPS and x_min <= nx + EPS):
        return 1, 0
    return min(max(math.floor(x_min - EPS), 0), nx - 1), min(max(math.floor(x_max + EPS), 0), nx - 1)


@njit(cache=True, nogil=True)
def triangle_voxels(
    tri: npt.NDArray[np.float64], nx: int, ny: int, nz: int
) -> tuple[I64, I64]:  # pragma: no cover - compiled
    """``(flat, source)`` of :func:`gtgen.voxels.triangle_voxels` for triangles ``(T, 3, 3)`` in
    grid coordinates, in the same order (triangles within one voxel first, then row by row)."""
    count = tri.shape[0]
    flat = np.empty(max(1024, 4 * count), np.int64)
    source = np.empty(flat.shape[0], np.int64)
    m = 0
    low = np.empty((count, 3), np.int64)
    high = np.empty((count, 3), np.int64)
    state = np.zeros(count, np.int8)  # 0: missed, 1: one voxel, 2: rows
    shape = (nx, ny, nz)
    for t in range(count):
        if _tri_span(tri[t], shape, low[t], high[t]):
            one = low[t, 0] == high[t, 0] and low[t, 1] == high[t, 1] and low[t, 2] == high[t, 2]
            state[t] = 1 if one else 2
    for t in range(count):
        if state[t] == 1:
            if m >= flat.shape[0]:
                flat, source = _grow(flat, m), _grow(source, m)
            flat[m] = (low[t, 0] * ny + low[t, 1]) * nz + low[t, 2]
            source[m] = t
            m += 1
    n = np.empty(3)
    for t in range(count):
        if state[t] != 2:
            continue
        v = tri[t]
        _tri_normal(v, n)
        for j in range(low[t, 1], high[t, 1] + 1):
            for k in range(low[t, 2], high[t, 2] + 1):
                i0, i1 = _row_span(v, j, k, n, nx)
                if i0 > i1:
                    continue
                if m + (i1 - i0 + 1) > flat.shape[0]:
                    flat, source = _grow(flat, m + i1 - i0 + 1), _grow(source, m + i1 - i0 + 1)
                for i in range(i0, i1 + 1):
                    flat[m] = (i * ny + j) * nz + k
                    source[m] = t
                    m += 1
    return flat[:m].copy(), source[:m].copy()


@njit(cache=True, nogil=True)
def _setup(s: float, d: float, t0: float, n: int) -> tuple[int, int, float, float]:  # pragma: no cover
    """One axis of a walk: its first voxel, step, next face and face spacing (in ``t``)."""
    voxel = min(max(math.floor(s + d * t0), 0), n - 1)
    if d > 0:
        return voxel, 1, (voxel + 1 - s) / d, 1.0 / abs(d)
    if d < 0:
        return voxel, -1, (voxel - s) / d, 1.0 / abs(d)
    return voxel, 0, math.inf, math.inf


@njit(cache=True, nogil=True, inline="always")
def _clip_walk(
    s_m: npt.NDArray[np.float64],
    e_m: npt.NDArray[np.float64],
    lower_m: npt.NDArray[np.float64],
    voxel_m: float,
    nx: int,
    ny: int,
    nz: int,
) -> tuple[float, float, float, float, float, float, float, float]:  # pragma: no cover - compiled
    """One segment ``s_m -> e_m`` (metres) in grid coordinates (:meth:`VoxelGrid.to_grid`) and its
    parameters ``t0, t1`` clipped to the grid (``_clip_to_box``; ``not t0 < t1``: it misses)."""
    s0, s1, s2 = (s_m[0] - lower_m[0]) / voxel_m, (s_m[1] - lower_m[1]) / voxel_m, (s_m[2] - lower_m[2]) / voxel_m
    e0, e1, e2 = (e_m[0] - lower_m[0]) / voxel_m, (e_m[1] - lower_m[1]) / voxel_m, (e_m[2] - lower_m[2]) / voxel_m
    lower_t, upper_t = -math.inf, math.inf
    for a in range(3):
        sa = s0 if a == 0 else (s1 if a == 1 else s2)
        da = (e0 if a == 0 else (e1 if a == 1 else e2)) - sa
        upper = float(nx if a == 0 else (ny if a == 1 else nz))
        if da != 0:
            ta, tb = (0.0 - sa) / da, (upper - sa) / da
            lower_t, upper_t = max(lower_t, min(ta, tb)), min(upper_t, max(ta, tb))
        elif not (sa >= 0 and sa <= upper):
            lower_t, upper_t = math.inf, -math.inf
    return s0, s1, s2, e0, e1, e2, max(lower_t, 0.0), min(upper_t, 1.0)


@njit(cache=True, nogil=True, inline="always")
def _placed(
    p: npt.NDArray[np.floating], rotation: npt.NDArray[np.float64], translation: npt.NDArray[np.float64], i: int
) -> float:  # pragma: no cover - compiled
    """Coordinate ``i`` of the point ``p: (3,)`` placed by ``rotation`` and ``translation``, in
    float64: ``p_0 R_i0 + p_1 R_i1 + p_2 R_i2 + t_i``, summed in that order (numpy's einsum,
    which ``gtgen.occupancy._transform`` uses, may sum in another order for some inputs: the two
    can differ in the last bit, about 1e-13 m)."""
    p0, p1, p2 = np.float64(p[0]), np.float64(p[1]), np.float64(p[2])
    return float(p0 * rotation[i, 0] + p1 * rotation[i, 1] + p2 * rotation[i, 2] + translation[i])


@njit(cache=True, nogil=True, inline="always")
def _walk_one(
    s_m: npt.NDArray[np.float64],
    e_m: npt.NDArray[np.float64],
    lower_m: npt.NDArray[np.float64],
    voxel_m: float,
    nx: int,
    ny: int,
    nz: int,
    out: npt.NDArray[np.bool_],
) -> None:  # pragma: no cover - compiled
    """The walk of one segment ``s_m -> e_m`` (:func:`walk`)."""
    s0, s1, s2, e0, e1, e2, t0, t1 = _clip_walk(s_m, e_m, lower_m, voxel_m, nx, ny, nz)
    if not t0 < t1:
        return
    big = nx + ny + nz + 1
    x, sx, tx, dx = _setup(s0, e0 - s0, t0, nx)
    y, sy, ty, dy = _setup(s1, e1 - s1, t0, ny)
    z, sz, tz, dz = _setup(s2, e2 - s2, t0, nz)
    cx = (nx - 1 - x) if sx > 0 else (x if sx < 0 else big)
    cy = (ny - 1 - y) if sy > 0 else (y if sy < 0 else big)
    cz = (nz - 1 - z) if sz > 0 else (z if sz < 0 else big)
    fx, fy = sx * ny * nz, sy * nz
    v = (x * ny + y) * nz + z
    while True:
        out[v] = True
        if tx <= ty and tx <= tz:  # the first of the nearest faces, as numpy's argmin
            if not (tx <= t1 and cx > 0):
                break
            v, tx, cx = v + fx, tx + dx, cx - 1
        elif ty <= tz:
            if not (ty <= t1 and cy > 0):
                break
            v, ty, cy = v + fy, ty + dy, cy - 1
        else:
            if not (tz <= t1 and cz > 0):
                break
            v, tz, cz = v + sz, tz + dz, cz - 1


@njit(cache=True, nogil=True)
def walk(
    s_m: npt.NDArray[np.float64],
    e_m: npt.NDArray[np.float64],
    lower_m: npt.NDArray[np.float64],
    voxel_m: float,
    nx: int,
    ny: int,
    nz: int,
    out: npt.NDArray[np.bool_],
) -> None:  # pragma: no cover - compiled
    """Set ``out`` (flat) at every voxel the segments ``s_m -> e_m`` (``(N, 3)``, the grid's frame,
    metres; its lowest corner ``lower_m``) cross: :meth:`gtgen.voxels.SegmentWalk.of` and
    :func:`gtgen.voxels.walk_segments` in one loop (the flat index stepped by each axis's stride,
    the steps left before the grid's edge counted down along each axis)."""
    for q in range(s_m.shape[0]):
        _walk_one(s_m[q], e_m[q], lower_m, voxel_m, nx, ny, nz, out)


@njit(cache=True, nogil=True)
def walk_from(
    points: npt.NDArray[np.floating],
    rotation: npt.NDArray[np.float64],
    translation: npt.NDArray[np.float64],
    lower_m: npt.NDArray[np.float64],
    voxel_m: float,
    nx: int,
    ny: int,
    nz: int,
    out: npt.NDArray[np.bool_],
) -> None:  # pragma: no cover - compiled
    """:func:`walk` of the segments from ``translation`` to each of ``points: (N, 3)`` (their own
    frame, metres) placed in the grid's frame by ``rotation`` and ``translation`` (:func:`_placed`)."""
    end = np.empty(3)
    for q in range(points.shape[0]):
        for i in range(3):
            end[i] = _placed(points[q], rotation, translation, i)
        _walk_one(translation, end, lower_m, voxel_m, nx, ny, nz, out)


@njit(cache=True, nogil=True)
def walk_steps(
    s_m: npt.NDArray[np.float64],
    e_m: npt.NDArray[np.float64],
    lower_m: npt.NDArray[np.float64],
    voxel_m: float,
    nx: int,
    ny: int,
    nz: int,
) -> tuple[I64, npt.NDArray[np.int32], npt.NDArray[np.float64]]:  # pragma: no cover - compiled
    """The voxels of :func:`walk` one segment at a time, in order: ``(first, flat, entry)``, segment
    ``q``'s voxels ``flat[first[q]:first[q + 1]]`` and where along it the segment enters each (the
    parameter ``t``, 0 at its start, 1 at its end; its first voxel: where it enters the grid)."""
    first = np.zeros(s_m.shape[0] + 1, np.int64)
    flat = np.empty(1024, np.int32)
    entry = np.empty(1024, np.float64)
    m = 0
    for q in range(s_m.shape[0]):
        first[q] = m
        s0, s1, s2, e0, e1, e2, t0, t1 = _clip_walk(s_m[q], e_m[q], lower_m, voxel_m, nx, ny, nz)
        if t0 < t1:
            x, sx, tx, dx = _setup(s0, e0 - s0, t0, nx)
            y, sy, ty, dy = _setup(s1, e1 - s1, t0, ny)
            z, sz, tz, dz = _setup(s2, e2 - s2, t0, nz)
            t = t0
            while True:
                if m >= flat.shape[0]:
                    flat, entry = _grow(flat, m), _grow(entry, m)
                flat[m], entry[m] = (x * ny + y) * nz + z, t
                m += 1
                if tx <= ty and tx <= tz:
                    t, x, tx = tx, x + sx, tx + dx
                    inside = 0 <= x < nx
                elif ty <= tz:
                    t, y, ty = ty, y + sy, ty + dy
                    inside = 0 <= y < ny
                else:
                    t, z, tz = tz, z + sz, tz + dz
                    inside = 0 <= z < nz
                if not (t <= t1 and inside):
                    break
    first[s_m.shape[0]] = m
    return first, flat[:m].copy(), entry[:m].copy()


@njit(cache=True, nogil=True)
def mark_walked(
    first: I64,
    flat: npt.NDArray[np.int32],
    entry: npt.NDArray[np.float64],
    reach: npt.NDArray[np.float64],
    out: npt.NDArray[np.bool_],
) -> None:  # pragma: no cover - compiled
    """Set ``out`` (flat) at the voxels of :func:`walk_steps`' segments as far as each reaches,
    ``reach: (N,)`` in the units of ``entry`` (its ``t`` scaled): a segment's first voxel where it
    starts in it (entry 0) or enters it before ``reach``, each further voxel it enters within
    ``reach`` (``reach >= 0``; 0: a point, in no voxel but the first, as :func:`walk` has it). A
    walk's entries after its first never fall (each is the nearest of three faces that only move
    on), so the last voxel within reach is found by bisection, not by reading every entry."""
    for q in range(first.shape[0] - 1):
        a, b = first[q], first[q + 1]
        if a == b or not (entry[a] == 0.0 or entry[a] < reach[q]):
            continue
        out[flat[a]] = True
        if reach[q] == 0.0:
            continue
        lo, hi = a + 1, b  # the first further voxel entered beyond the reach (entries never fall)
        while lo < hi:
            mid = (lo + hi) >> 1
            if entry[mid] > reach[q]:
                hi = mid
            else:
                lo = mid + 1
        for n in range(a + 1, lo):
            out[flat[n]] = True


@njit(cache=True, nogil=True)
def paint(
    flat: I64,
    cls: npt.NDArray[np.uint8],
    inst: npt.NDArray[np.uint32],
    keep: npt.NDArray[np.bool_],
    rank_of: npt.NDArray[np.uint8],
    native: npt.NDArray[np.uint8],
    instance: npt.NDArray[np.uint32],
    best: npt.NDArray[np.uint8],
    only: npt.NDArray[np.bool_],
) -> None:  # pragma: no cover - compiled
    """Each voxel takes the class and instance of its entry of lowest rank (``rank_of[cls]``), the
    last such one in the entries' order (a stable sort by falling rank, then every entry written in
    turn). ``inst`` empty: instance 0; ``keep`` empty: every entry, else those it marks; ``only``
    empty: every voxel, else the voxels it marks (flat)."""
    for n in range(flat.shape[0]):
        if keep.shape[0] and not keep[n]:
            continue
        v = flat[n]
        if only.shape[0] and not only[v]:
            continue
        rank = rank_of[cls[n]]
        if rank <= best[v]:
            best[v] = rank
            native[v] = cls[n]
            instance[v] = inst[n] if inst.shape[0] else 0


@njit(cache=True, nogil=True)
def box_cells(
    low: I64,
    size: I64,
    center: npt.NDArray[np.float64],
    axes: npt.NDArray[np.float64],
    bound: npt.NDArray[np.float64],
    ny: int,
    nz: int,
) -> tuple[I64, I64]:  # pragma: no cover - compiled
    """``(flat, box)`` of :func:`gtgen.voxels.box_voxels`: the voxels of each box ``b``'s bounding
    voxels (from ``low[b]``, ``size[b]`` along each axis, x slowest) whose centre's offset from
    ``center[b]`` (grid coordinates) projects on every axis ``axes[b, a]`` to less than
    ``bound[b, a]`` (the summed reaches less the touch), the projection summed in numpy's order."""
    count = 0
    for b in range(low.shape[0]):
        count += size[b, 0] * size[b, 1] * size[b, 2]
    flat = np.empty(count, np.int64)
    source = np.empty(count, np.int64)
    m = 0
    for b in range(low.shape[0]):
        for i in range(low[b, 0], low[b, 0] + size[b, 0]):
            d0 = (i + 0.5) - center[b, 0]
            for j in range(low[b, 1], low[b, 1] + size[b, 1]):
                d1 = (j + 0.5) - center[b, 1]
                for k in range(low[b, 2], low[b, 2] + size[b, 2]):
                    d2 = (k + 0.5) - center[b, 2]
                    ok = True
                    for a in range(axes.shape[1]):
                        if not abs(d0 * axes[b, a, 0] + d1 * axes[b, a, 1] + d2 * axes[b, a, 2]) < bound[b, a]:
                            ok = False
                            break
                    if ok:
                        flat[m] = (i * ny + j) * nz + k
                        source[m] = b
                        m += 1
    return flat[:m].copy(), source[:m].copy()


@njit(cache=True, nogil=True)
def within(
    points: npt.NDArray[np.float64], center: npt.NDArray[np.float64], reach: npt.NDArray[np.float64]
) -> I64:  # pragma: no cover - compiled
    """The rows of ``points: (N, 3)`` at most ``reach: (N,)`` from ``center: (3,)`` (the distance
    as ``np.linalg.norm`` computes it: the squares summed in order, then the root)."""
    out = np.empty(points.shape[0], np.int64)
    m = 0
    for n in range(points.shape[0]):
        d0, d1, d2 = points[n, 0] - center[0], points[n, 1] - center[1], points[n, 2] - center[2]
        if math.sqrt(d0 * d0 + d1 * d1 + d2 * d2) <= reach[n]:
            out[m] = n
            m += 1
    return out[:m].copy()


@njit(cache=True, nogil=True)
def enclosed(box: npt.NDArray[np.int64], wall: npt.NDArray[np.int64]) -> npt.NDArray[np.bool_]:  # pragma: no cover
    """Which of a box's voxels ``box: (N, 3)`` (voxel indices) no path of face-neighbouring voxels
    inside the box, free of ``wall: (M, 3)``, joins to the box's outside (a flood from outside)."""
    out = np.zeros(box.shape[0], np.bool_)
    if box.shape[0] == 0:
        return out
    low = np.empty(3, np.int64)
    size = np.empty(3, np.int64)
    for a in range(3):
        low[a] = box[:, a].min() - 1
        size[a] = box[:, a].max() - low[a] + 2
    inside = np.zeros((size[0], size[1], size[2]), np.bool_)
    for n in range(box.shape[0]):
        inside[box[n, 0] - low[0], box[n, 1] - low[1], box[n, 2] - low[2]] = True
    blocked = np.zeros_like(inside)
    for n in range(wall.shape[0]):
        i, j, k = wall[n, 0] - low[0], wall[n, 1] - low[1], wall[n, 2] - low[2]
        if 0 <= i < size[0] and 0 <= j < size[1] and 0 <= k < size[2] and inside[i, j, k]:
            blocked[i, j, k] = True
    reached = _flood_out(inside, blocked)
    for n in range(box.shape[0]):
        out[n] = not reached[box[n, 0] - low[0], box[n, 1] - low[1], box[n, 2] - low[2]]
    return out


@njit(cache=True, nogil=True, inline="always")
def _clip(
    poly: npt.NDArray[np.float64], n: int, a: int, bound: float, side: int, out: npt.NDArray[np.float64]
) -> int:  # pragma: no cover - compiled
    """``poly[:n]`` clipped to ``x_a >= bound`` (side 0) or ``x_a <= bound`` (side 1) into ``out``;
    its corner count."""
    m = 0
    for v in range(n):
        w = v + 1 if v + 1 < n else 0
        dv = poly[v, a] - bound if side == 0 else bound - poly[v, a]
        dw = poly[w, a] - bound if side == 0 else bound - poly[w, a]
        if dv >= 0:  # copied a coordinate at a time (a row's slice assignment costs twice the clip)
            out[m, 0], out[m, 1], out[m, 2] = poly[v, 0], poly[v, 1], poly[v, 2]
            m += 1
        if (dv >= 0) != (dw >= 0):
            t = dv / (dv - dw)
            for c in range(3):
                out[m, c] = poly[v, c] + t * (poly[w, c] - poly[v, c])
            m += 1
    return m


@njit(cache=True, nogil=True, inline="always")
def _half(
    poly: npt.NDArray[np.float64],
    n: int,
    a: int,
    lo: float,
    mid: npt.NDArray[np.float64],
    out: npt.NDArray[np.float64],
) -> int:  # pragma: no cover - compiled
    """``poly[:n]`` clipped to ``lo <= x_a <= lo + 1/2`` into ``out`` (through ``mid``); its corner
    count (below 3: nothing left)."""
    m = _clip(poly, n, a, lo, 0, mid)
    if m < 3:
        return m
    return _clip(mid, m, a, lo + 0.5, 1, out)


@njit(cache=True, nogil=True, inline="always")
def _area(poly: npt.NDArray[np.float64], n: int) -> float:  # pragma: no cover - compiled
    sx, sy, sz = 0.0, 0.0, 0.0
    for v in range(1, n - 1):
        ux, uy, uz = poly[v, 0] - poly[0, 0], poly[v, 1] - poly[0, 1], poly[v, 2] - poly[0, 2]
        wx, wy, wz = poly[v + 1, 0] - poly[0, 0], poly[v + 1, 1] - poly[0, 1], poly[v + 1, 2] - poly[0, 2]
        sx += uy * wz - uz * wy
        sy += uz * wx - ux * wz
        sz += ux * wy - uy * wx
    return 0.5 * math.sqrt(sx * sx + sy * sy + sz * sz)


@njit(cache=True, nogil=True)
def octant_areas(
    tri: npt.NDArray[np.float64], ijk: npt.NDArray[np.int64]
) -> npt.NDArray[np.float64]:  # pragma: no cover
    """``(P, 8)``: the area (voxel units squared) of each triangle ``tri: (P, 3, 3)`` (grid
    coordinates) within each eighth of its voxel ``ijk: (P, 3)``; eighth ``4 hx + 2 hy + hz``
    spans ``[i + hx / 2, i + hx / 2 + 1 / 2]`` along x (and so on). The triangle is clipped to
    each half along x, that to each half along y, that to each half along z."""
    out = np.zeros((tri.shape[0], 8))
    px = np.empty((12, 3))
    py = np.empty((12, 3))
    pz = np.empty((12, 3))
    mid = np.empty((12, 3))
    t = np.empty((3, 3))
    for p in range(tri.shape[0]):
        t[:, :] = tri[p]
        for hx in range(2):
            nx_ = _half(t, 3, 0, ijk[p, 0] + 0.5 * hx, mid, px)
            if nx_ < 3:
                continue
            for hy in range(2):
                ny_ = _half(px, nx_, 1, ijk[p, 1] + 0.5 * hy, mid, py)
                if ny_ < 3:
                    continue
                for hz in range(2):
                    nz_ = _half(py, ny_, 2, ijk[p, 2] + 0.5 * hz, mid, pz)
                    if nz_ < 3:
                        continue
                    out[p, 4 * hx + 2 * hy + hz] = _area(pz, nz_)
    return out


@njit(cache=True, nogil=True)
def choose_shared(
    voxels: I64,
    area: npt.NDArray[np.float64],
    classes: I64,
    label: npt.NDArray[np.integer],
    nx: int,
    ny: int,
    nz: int,
    sweeps: int,
) -> I64:  # pragma: no cover - compiled
    """The class of each shared voxel ``voxels: (M,)`` (flat): the class with the most area
    ``area: (M, C, 8)`` (of the classes ``classes: (C,)``, ascending) in the voxel's eighths whose 7
    neighbours on that eighth's side hold no voxel of that class in ``label`` (flat, every voxel's
    class; updated as each voxel is chosen, in order, sweep after sweep until none changes; of
    equal areas the lowest class); where none needs it, its class in ``label``."""
    chosen = np.empty(voxels.shape[0], np.int64)
    for m in range(voxels.shape[0]):
        chosen[m] = label[voxels[m]]
    need = np.zeros(area.shape[1])
    for _ in range(sweeps):
        changed = 0
        for m in range(voxels.shape[0]):
            v = voxels[m]
            i, j, k = v // (ny * nz), (v // nz) % ny, v % nz
            need[:] = 0.0
            for c in range(area.shape[1]):
                for o in range(8):
                    if area[m, c, o] <= 0.0:
                        continue
                    covered = False
                    for step in range(1, 8):
                        qi = i + ((1 if o & 4 else -1) if step & 4 else 0)
                        qj = j + ((1 if o & 2 else -1) if step & 2 else 0)
                        qk = k + ((1 if o & 1 else -1) if step & 1 else 0)
                        ok = 0 <= qi < nx and 0 <= qj < ny and 0 <= qk < nz
                        if ok and label[(qi * ny + qj) * nz + qk] == classes[c]:
                            covered = True
                            break
                    if not covered:
                        need[c] += area[m, c, o]
            best = chosen[m]
            if need.max() > 0.0:
                best = classes[np.argmax(need)]
            if best != chosen[m]:
                chosen[m] = best
                label[v] = best
                changed += 1
        if changed == 0:
            break
    return chosen


@njit(cache=True, nogil=True)
def looked_up(lut: npt.NDArray[np.uint8], values: npt.NDArray[np.uint8]) -> npt.NDArray[np.uint8]:  # pragma: no cover
    """``lut[values]`` of a flat ``uint8`` array (numpy's fancy index widens every value to an index first)."""
    out = np.empty(values.shape[0], np.uint8)
    for n in range(values.shape[0]):
        out[n] = lut[values[n]]
    return out


@njit(cache=True, nogil=True)
def class_bits(flat: I64, cls: I64, size: int) -> npt.NDArray[np.uint32]:  # pragma: no cover - compiled
    """``(size,)``: each voxel's classes among the entries ``(flat, cls)`` as bits ``1 << cls``."""
    bits = np.zeros(size, np.uint32)
    for n in range(flat.shape[0]):
        bits[flat[n]] |= np.uint32(1) << np.uint32(cls[n])
    return bits


@njit(cache=True, nogil=True)
def _root(parent: I64, a: int) -> int:  # pragma: no cover - compiled
    while parent[a] != a:
        parent[a] = parent[parent[a]]
        a = parent[a]
    return a


@njit(cache=True, nogil=True)
def solid_runs(
    surface: I64, floor: I64, nx: int, ny: int, nz: int
) -> tuple[npt.NDArray[np.int8], I64, I64]:  # pragma: no cover - compiled
    """The voxels to cast for the solids' insides: along each row of voxels (ego x; rows in
    ``(y, z)`` order) the first voxel of each run that no solid's surface ``surface`` nor floor
    ``floor`` (flat) meets, and each voxel only a floor meets. Returns each voxel's kind (0:
    free of both, 1: surface, 2: floor only), the cast voxels ``(T, 3)`` (``i, j, k``, rows in
    order) and each one's part (``-1`` for a floor-only voxel): runs in one part are joined by
    face-neighbouring voxels of kind 0 (runs of neighbouring rows that share an x), so no
    surface or floor parts their centres, numbered from 0 in order of first appearance. Only the
    voxels of kind 1 or 2 are visited (sorted along their rows), not the whole grid."""
    kind = np.zeros(nx * ny * nz, np.int8)
    rows = ny * nz  # row (j, k) is r = j * nz + k; voxel (i, r) at i * rows + r
    taken = np.empty(surface.shape[0] + floor.shape[0], np.int64)  # each voxel of kind 1 or 2 once
    held = 0
    for n in range(surface.shape[0]):
        v = surface[n]
        if kind[v] == 0:
            taken[held] = v
            held += 1
        kind[v] = 1
    for n in range(floor.shape[0]):
        v = floor[n]
        if kind[v] == 0:
            kind[v] = 2
            taken[held] = v
            held += 1
    held_first = np.zeros(rows + 1, np.int64)  # the row's voxels of kind 1 or 2: their x, sorted
    for n in range(held):
        held_first[taken[n] % rows + 1] += 1
    for r in range(rows):
        held_first[r + 1] += held_first[r]
    held_x = np.empty(held, np.int64)
    at = held_first[:rows].copy()
    for n in range(held):
        r = taken[n] % rows
        held_x[at[r]] = taken[n] // rows
        at[r] += 1
    row_first = np.zeros(rows + 1, np.int64)  # the runs of row r: row_first[r]:row_first[r + 1]
    cast_first = np.zeros(rows + 1, np.int64)  # its voxels to cast: cast_first[r]:cast_first[r + 1]
    for r in range(rows):
        a, b = held_first[r], held_first[r + 1]
        for n in range(a + 1, b):  # insertion sort: a row holds few
            x = held_x[n]
            m = n - 1
            while m >= a and held_x[m] > x:
                held_x[m + 1] = held_x[m]
                m -= 1
            held_x[m + 1] = x
        runs_here, casts_here, free_from = 0, 0, 0
        for n in range(a, b):
            i = held_x[n]
            if i > free_from:
                runs_here += 1
            if kind[i * rows + r] == 2:
                casts_here += 1
            free_from = i + 1
        if free_from < nx:
            runs_here += 1
        row_first[r + 1] = row_first[r] + runs_here
        cast_first[r + 1] = cast_first[r] + runs_here + casts_here
    count, runs = cast_first[rows], row_first[rows]
    ijk = np.empty((count, 3), np.int64)
    run_of = np.empty(count, np.int64)
    low = np.empty(runs, np.int64)  # each run's x extent and row
    high = np.empty(runs, np.int64)
    for r in range(rows):
        m, run = cast_first[r], row_first[r]
        j, k = r // nz, r % nz
        free_from = 0
        for n in range(held_first[r], held_first[r + 1] + 1):
            i = held_x[n] if n < held_first[r + 1] else nx
            if i > free_from:  # the free voxels free_from .. i - 1: a run, cast at its first
                ijk[m, 0], ijk[m, 1], ijk[m, 2] = free_from, j, k
                run_of[m] = run
                low[run], high[run] = free_from, i - 1
                m += 1
                run += 1
            if i < nx and kind[i * rows + r] == 2:
                ijk[m, 0], ijk[m, 1], ijk[m, 2] = i, j, k
                run_of[m] = -1
                m += 1
            free_from = i + 1
    parent = np.arange(runs)
    for j in range(ny):
        for k in range(nz):
            row = j * nz + k
            for other in (row + 1 if k + 1 < nz else -1, row + nz if j + 1 < ny else -1):
                if other < 0:
                    continue
                a, b = row_first[row], row_first[other]
                while a < row_first[row + 1] and b < row_first[other + 1]:
                    if max(low[a], low[b]) <= min(high[a], high[b]):
                        ra, rb = _root(parent, a), _root(parent, b)
                        if ra != rb:
                            parent[max(ra, rb)] = min(ra, rb)
                    if high[a] < high[b]:
                        a += 1
                    else:
                        b += 1
    number = np.full(runs, -1, np.int64)
    part = np.empty(count, np.int64)
    parts = 0
    for t in range(count):
        part[t] = -1
        if run_of[t] >= 0:
            root = _root(parent, run_of[t])
            if number[root] < 0:
                number[root] = parts
                parts += 1
            part[t] = number[root]
    return kind, ijk, part


@njit(cache=True, nogil=True)
def solid_fill(
    kind: npt.NDArray[np.int8], ijk: I64, cls: npt.NDArray[np.uint8], nx: int, ny: int, nz: int
) -> tuple[I64, npt.NDArray[np.uint8]]:  # pragma: no cover - compiled
    """``(flat, class)`` of the voxels inside solids (row by row, ``(j, k)`` then ``i``): each run of
    :func:`solid_runs` (its first voxel cast, ``ijk``) takes its cast voxel's class ``cls``, each
    floor-only voxel its own, surface voxels none. Only the runs of a class are visited."""
    count = 0
    for t in range(ijk.shape[0]):
        if cls[t] == 0:
            continue
        v = (ijk[t, 0] * ny + ijk[t, 1]) * nz + ijk[t, 2]
        if kind[v] == 2:
            count += 1
            continue
        for _ in range(ijk[t, 0], nx):
            if kind[v] != 0:
                break
            count += 1
            v += ny * nz
    flat = np.empty(count, np.int64)
    value = np.empty(count, np.uint8)
    m = 0
    for t in range(ijk.shape[0]):
        if cls[t] == 0:
            continue
        v = (ijk[t, 0] * ny + ijk[t, 1]) * nz + ijk[t, 2]
        if kind[v] == 2:
            flat[m], value[m] = v, cls[t]
            m += 1
            continue
        for _ in range(ijk[t, 0], nx):
            if kind[v] != 0:
                break
            flat[m], value[m] = v, cls[t]
            m += 1
            v += ny * nz
    return flat, value


@njit(cache=True, nogil=True)
def mesh_voxels(
    vertices_m: npt.NDArray[np.floating],
    triangles: I64,
    lower_m: npt.NDArray[np.float64],
    voxel_m: float,
    nx: int,
    ny: int,
    nz: int,
    rotation: npt.NDArray[np.float64],
    translation: npt.NDArray[np.float64],
) -> tuple[I64, I64]:  # pragma: no cover - compiled
    """:func:`triangle_voxels` of the triangles ``triangles: (T, 3)`` (corner indices) of
    ``vertices_m: (V, 3)`` (metres; the grid's lowest corner ``lower_m``), in the grid's frame, or
    placed in it by ``rotation: (3, 3)`` and ``translation: (3,)`` (:func:`_placed`) where
    ``rotation`` is given (not empty)."""
    placed = rotation.shape[0] > 0
    tri = np.empty((triangles.shape[0], 3, 3))
    for t in range(triangles.shape[0]):
        for c in range(3):
            v = triangles[t, c]
            for a in range(3):
                x = _placed(vertices_m[v], rotation, translation, a) if placed else np.float64(vertices_m[v, a])
                tri[t, c, a] = (x - lower_m[a]) / voxel_m
    return triangle_voxels(tri, nx, ny, nz)


@njit(cache=True, nogil=True)
def shared_keep(
    flat: I64,
    occ: I64,
    tri_m: npt.NDArray[np.float64],
    source: I64,
    lower_m: npt.NDArray[np.float64],
    voxel_m: float,
    label: npt.NDArray[np.uint8],
    n_occ: int,
    nx: int,
    ny: int,
    nz: int,
    sweeps: int,
    paved_bits: int,
    terrain: int,
) -> npt.NDArray[np.bool_]:  # pragma: no cover - compiled
    """Which surface entries (voxel ``flat``, class ``occ``, triangle ``tri_m[source]`` in the grid's
    frame, metres) keep their voxel where several classes' surfaces meet one (as
    ``gtgen.occupancy._shared_surfaces``): the terrain hidden in voxels with paving (a class among
    ``paved_bits``), the voxels of several classes chosen in ascending order by
    :func:`choose_shared` from the areas of :func:`octant_areas` (summed per class in the entries'
    order), each keeping the entries of its chosen class (all of them where it chose none of its
    own). ``label``: every voxel's class so far (updated with the choices), of ``n_occ`` classes."""
    size = nx * ny * nz
    bits = class_bits(flat, occ, size)
    keep = np.ones(flat.shape[0], np.bool_)
    terrain_bit = np.uint32(1) << np.uint32(terrain)
    for n in range(flat.shape[0]):
        b = bits[flat[n]]
        if b & np.uint32(paved_bits):
            b &= ~terrain_bit
            if occ[n] == terrain:
                continue  # hidden under paving
        count = 0
        while b:
            b &= b - np.uint32(1)
            count += 1
        if count > 1:
            keep[n] = False  # marked shared for now
    entries = np.flatnonzero(~keep)
    if entries.shape[0] == 0:
        keep[:] = True
        return keep
    voxels = np.unique(flat[entries])  # ascending
    voxels_n = voxels.shape[0]
    local = np.searchsorted(voxels, flat[entries])
    ijk = np.empty((entries.shape[0], 3), np.int64)
    tri = np.empty((entries.shape[0], 3, 3))
    for q in range(entries.shape[0]):
        e = entries[q]
        v = flat[e]
        ijk[q, 0], ijk[q, 1], ijk[q, 2] = v // (ny * nz), (v // nz) % ny, v % nz
        for c in range(3):
            for a in range(3):
                tri[q, c, a] = (tri_m[source[e], c, a] - lower_m[a]) / voxel_m
    areas = octant_areas(tri, ijk)
    column = np.full(n_occ, -1, np.int64)  # the shared entries' classes, ascending: their areas' columns
    for q in range(entries.shape[0]):
        column[occ[entries[q]]] = 0
    classes = np.flatnonzero(column >= 0)
    for c in range(classes.shape[0]):
        column[classes[c]] = c
    area = np.zeros((voxels_n, classes.shape[0], 8))
    for o in range(8):
        for q in range(entries.shape[0]):
            area[local[q], column[occ[entries[q]]], o] += areas[q, o]
    chosen = choose_shared(voxels, area, classes, label, nx, ny, nz, sweeps)
    present = np.zeros(voxels_n, np.bool_)
    for q in range(entries.shape[0]):
        if occ[entries[q]] == chosen[local[q]]:
            present[local[q]] = True
    for q in range(entries.shape[0]):
        mine = occ[entries[q]] == chosen[local[q]]
        keep[entries[q]] = mine or not present[local[q]]
    return keep


@njit(cache=True, nogil=True)
def floor_joins(
    kind: npt.NDArray[np.int8],
    ijk: I64,
    part: I64,
    floor_flat: I64,
    floor_source: I64,
    floor_m: npt.NDArray[np.float64],
    lower_m: npt.NDArray[np.float64],
    voxel_m: float,
    nx: int,
    ny: int,
    nz: int,
) -> I64:  # pragma: no cover - compiled
    """For each voxel to cast of :func:`solid_runs` (``kind``, ``ijk``, ``part``) that only a floor
    meets, the part of the voxel above it (else below it) where that voxel is free of every
    surface and floor and no floor triangle that meets this voxel (``floor_flat``, ascending,
    triangle ``floor_m[floor_source]`` in the grid's frame, metres) lies between the two voxels' centres
    (both centres clearly on one side of its plane, farther than a ten-millionth of a voxel from
    it): then nothing parts the two centres and they lie alike. ``-1``: none such (cast it), or
    not a floor-only voxel. A free voxel's part is that of its run's first voxel, the last voxel
    to cast in its row at or before it."""
    count = ijk.shape[0]
    rows = ny * nz
    row_first = np.zeros(rows + 1, np.int64)  # the voxels to cast of row (j, k): row_first[r]:row_first[r + 1]
    for t in range(count):
        row_first[ijk[t, 1] * nz + ijk[t, 2] + 1] += 1
    for r in range(rows):
        row_first[r + 1] += row_first[r]
    out = np.full(count, -1, np.int64)
    first = np.empty(nx * ny * nz, np.int32)  # a floor voxel's first entry (set at floor voxels only)
    for n in range(floor_flat.shape[0] - 1, -1, -1):
        first[floor_flat[n]] = n
    for t in range(count):
        if part[t] >= 0:
            continue
        i, j, k = ijk[t, 0], ijk[t, 1], ijk[t, 2]
        v = (i * ny + j) * nz + k
        lo = first[v]  # the floor entries of v (a floor-only voxel has some): floor_flat[lo:hi]
        hi = lo
        while hi < floor_flat.shape[0] and floor_flat[hi] == v:
            hi += 1
        for dk in (1, -1):
            if not 0 <= k + dk < nz or kind[v + dk] != 0:
                continue
            apart = False
            for n in range(lo, hi):
                f = floor_m[floor_source[n]]
                a0, a1, a2 = (
                    (f[0, 0] - lower_m[0]) / voxel_m,
                    (f[0, 1] - lower_m[1]) / voxel_m,
                    (f[0, 2] - lower_m[2]) / voxel_m,
                )
                u0, u1, u2 = (f[1, 0] - f[0, 0]) / voxel_m, (f[1, 1] - f[0, 1]) / voxel_m, (f[1, 2] - f[0, 2]) / voxel_m
                w0, w1, w2 = (f[2, 0] - f[0, 0]) / voxel_m, (f[2, 1] - f[0, 1]) / voxel_m, (f[2, 2] - f[0, 2]) / voxel_m
                n0, n1, n2 = u1 * w2 - u2 * w1, u2 * w0 - u0 * w2, u0 * w1 - u1 * w0
                size = math.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
                here = n0 * (i + 0.5 - a0) + n1 * (j + 0.5 - a1) + n2 * (k + 0.5 - a2)
                there = here + n2 * dk
                margin = 1e-7 * size
                if not (size > 0.0 and ((here > margin and there > margin) or (here < -margin and there < -margin))):
                    apart = True
                    break
            if apart:
                continue
            r = j * nz + k + dk
            a = row_first[r]  # the last voxel to cast at or before i: its run's first
            out[t] = part[max(a, a + np.searchsorted(ijk[a : row_first[r + 1], 0], i, side="right") - 1)]
            break
    return out


@njit(cache=True, nogil=True)
def agents_filled(
    flat: I64,
    bounds: I64,
    tri_first: I64,
    tri_last: I64,
    tri_rows: I64,
    vertices_m: npt.NDArray[np.floating],
    triangles: npt.NDArray[np.integer],
    lower_m: npt.NDArray[np.float64],
    voxel_m: float,
    nx: int,
    ny: int,
    nz: int,
    rotation: npt.NDArray[np.float64],
    translation: npt.NDArray[np.float64],
) -> npt.NDArray[np.bool_]:  # pragma: no cover - compiled
    """Which box voxels ``flat`` (grouped by agent: group ``g`` is ``bounds[g]:bounds[g + 1]``) the
    agent fills: those its surface meets or encloses (:func:`enclosed`). Group ``g``'s triangles
    are the rows ``tri_rows[tri_first[g]:tri_last[g]]`` of ``triangles`` (corners in
    ``vertices_m``, placed in the grid's frame by ``rotation`` and ``translation`` as
    :func:`mesh_voxels` places them); none: its whole box. Each triangle meets the voxels
    :func:`triangle_voxels` gives it, but only those of the box block the flood from outside, so
    a row of voxels (along x) is searched only where it crosses the box and, within the x a
    triangle can reach there (:func:`_x_bounds`), still holds a box voxel no triangle met: the
    voxels kept are the same as from all of the triangles' voxels."""
    keep = np.ones(flat.shape[0], np.bool_)
    shape = (nx, ny, nz)
    low = np.empty(3, np.int64)
    size = np.empty(3, np.int64)
    tri = np.empty((3, 3))
    n = np.empty(3)
    lo = np.empty(3, np.int64)
    hi = np.empty(3, np.int64)
    corner = np.empty((vertices_m.shape[0], 3))  # the vertices in grid coordinates, as first needed
    placed = np.zeros(vertices_m.shape[0], np.bool_)
    for g in range(bounds.shape[0] - 1):
        if tri_last[g] <= tri_first[g]:
            continue
        a, b = bounds[g], bounds[g + 1]
        if a == b:
            continue
        for ax in range(3):
            low[ax] = 1 << 62
            size[ax] = -(1 << 62)
        for m in range(a, b):
            v = flat[m]
            cell = (v // (ny * nz), (v // nz) % ny, v % nz)
            for ax in range(3):
                low[ax] = min(low[ax], cell[ax])
                size[ax] = max(size[ax], cell[ax])  # the highest for now
        for ax in range(3):
            low[ax] -= 1
            size[ax] = size[ax] - low[ax] + 2
        inside = np.zeros((size[0], size[1], size[2]), np.bool_)
        open_in_row = np.zeros((size[1], size[2]), np.int64)  # box voxels of each row no triangle met yet
        for m in range(a, b):
            v = flat[m]
            i, j, k = v // (ny * nz) - low[0], (v // nz) % ny - low[1], v % nz - low[2]
            if not inside[i, j, k]:
                inside[i, j, k] = True
                open_in_row[j, k] += 1
        blocked = np.zeros_like(inside)
        for q in range(tri_first[g], tri_last[g]):
            t = tri_rows[q]
            for c in range(3):
                vi = triangles[t, c]
                if not placed[vi]:  # each corner placed once (its triangles share it)
                    for ax in range(3):
                        corner[vi, ax] = (_placed(vertices_m[vi], rotation, translation, ax) - lower_m[ax]) / voxel_m
                    placed[vi] = True
                for ax in range(3):
                    tri[c, ax] = corner[vi, ax]
            if not _tri_span(tri, shape, lo, hi):
                continue
            if lo[0] == hi[0] and lo[1] == hi[1] and lo[2] == hi[2]:
                i, j, k = lo[0] - low[0], lo[1] - low[1], lo[2] - low[2]
                in_box = 0 <= i < size[0] and 0 <= j < size[1] and 0 <= k < size[2]
                if in_box and inside[i, j, k] and not blocked[i, j, k]:
                    blocked[i, j, k] = True
                    open_in_row[j, k] -= 1
                continue
            _tri_normal(tri, n)
            x_lo, x_hi = _x_bounds(tri, n, lo, hi)
            if x_lo <= x_hi:  # the row's voxels the triangle may meet, clipped to the box
                x_lo, x_hi = max(x_lo, low[0]) - low[0], min(x_hi, low[0] + size[0] - 1) - low[0]
            for j in range(max(lo[1], low[1]), min(hi[1], low[1] + size[1] - 1) + 1):
                for k in range(max(lo[2], low[2]), min(hi[2], low[2] + size[2] - 1) + 1):
                    if open_in_row[j - low[1], k - low[2]] == 0:
                        continue  # nothing left in this row for the triangle to block
                    if x_lo <= x_hi:
                        found = False
                        for li in range(x_lo, x_hi + 1):
                            if inside[li, j - low[1], k - low[2]] and not blocked[li, j - low[1], k - low[2]]:
                                found = True
                                break
                        if not found:
                            continue  # every box voxel the triangle may meet in this row is met already
                    i0, i1 = _row_span(tri, j, k, n, nx)
                    for i in range(max(i0, low[0]), min(i1, low[0] + size[0] - 1) + 1):
                        li, lj, lk = i - low[0], j - low[1], k - low[2]
                        if inside[li, lj, lk] and not blocked[li, lj, lk]:
                            blocked[li, lj, lk] = True
                            open_in_row[lj, lk] -= 1
        reached = _flood_out(inside, blocked)
        for m in range(a, b):
            v = flat[m]
            keep[m] = not reached[v // (ny * nz) - low[0], (v // nz) % ny - low[1], v % nz - low[2]]
    return keep


@njit(cache=True, nogil=True)
def _flood_out(
    inside: npt.NDArray[np.bool_], blocked: npt.NDArray[np.bool_]
) -> npt.NDArray[np.bool_]:  # pragma: no cover - compiled
    """The voxels of :func:`enclosed`'s flood: from every voxel not ``inside``, through face
    neighbours that are not ``blocked``."""
    s0, s1, s2 = inside.shape
    reached = ~inside
    queue = np.empty((s0 * s1 * s2, 3), np.int64)
    head, tail = 0, 0
    for i in range(s0):
        for j in range(s1):
            for k in range(s2):
                if reached[i, j, k]:
                    queue[tail, 0], queue[tail, 1], queue[tail, 2] = i, j, k
                    tail += 1
    while head < tail:
        i, j, k = queue[head, 0], queue[head, 1], queue[head, 2]
        head += 1
        for di, dj, dk in ((1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)):
            a, b, c = i + di, j + dj, k + dk
            if 0 <= a < s0 and 0 <= b < s1 and 0 <= c < s2 and not reached[a, b, c] and not blocked[a, b, c]:
                reached[a, b, c] = True
                queue[tail, 0], queue[tail, 1], queue[tail, 2] = a, b, c
                tail += 1
    return reached


@njit(cache=True, nogil=True)
def _x_bounds(
    tri: npt.NDArray[np.float64], n: npt.NDArray[np.float64], lo: I64, hi: I64
) -> tuple[int, int]:  # pragma: no cover - compiled
    """Voxels ``x_lo..x_hi`` (not clipped to the grid) holding every voxel :func:`_x_extent` can
    name in any row of the triangle ``tri`` (normal ``n``, rows ``lo..hi`` along y and z), or
    ``x_lo > x_hi`` where no such bound is sure (a triangle nearly parallel to x). Its extent comes
    from its corners (within ``[mn, mx]``, its corners' x), its edges' crossings of row faces (at
    most ``EPS`` of an edge beyond a corner) and the row's corners on its plane inside it within
    a tolerance of ``EPS`` times the largest edge function ``s_i`` (barycentric coordinates above
    ``-2 EPS max(1, |s_i|) / |n_x|``, so at most twice that times ``mx - mn`` beyond ``[mn, mx]``);
    rounding is covered many times over."""
    mn = min(tri[0, 0], min(tri[1, 0], tri[2, 0]))
    mx = max(tri[0, 0], max(tri[1, 0], tri[2, 0]))
    span = mx - mn
    margin = 2.0 * EPS * (span + 1.0) + 1e-12 * (1.0 + abs(mn) + abs(mx))
    n0 = abs(n[0])
    if n0 > EPS:
        reach = 0.0  # the largest |y| or |z| offset between a row corner and a triangle corner
        edge = 0.0  # the largest y or z extent of the triangle
        for ax in (1, 2):
            a_mn = min(tri[0, ax], min(tri[1, ax], tri[2, ax]))
            a_mx = max(tri[0, ax], max(tri[1, ax], tri[2, ax]))
            edge = max(edge, a_mx - a_mn)
            reach = max(reach, max(a_mx - lo[ax], hi[ax] + 1.0 - a_mn))
        s_max = 4.0 * edge * (reach + 1.0) + 1.0
        size = abs(n[1]) * (abs(hi[1]) + 2.0) + abs(n[2]) * (abs(hi[2]) + 2.0)
        size += abs(n[0]) * abs(mx) + abs(n[1]) * abs(tri[0, 1]) + abs(n[2]) * abs(tri[0, 2])
        margin += (4.0 * EPS * s_max * (span + 1.0) + 1e-12 * (1.0 + size + s_max)) / n0
    if not margin < 1e-3:
        return 0, -1
    return math.floor(mn - EPS - margin), math.floor(mx + EPS + margin)

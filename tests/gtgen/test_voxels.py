"""Exact voxel geometry against brute force: triangles, boxes, segments."""

import numpy as np
from hypothesis import assume, example, given, settings
from hypothesis import strategies as st

from gtgen.voxels import (
    SegmentWalk,
    VoxelGrid,
    box_voxels,
    segment_voxels,
    triangle_voxels,
    walk_from,
    walk_segments,
    walk_voxels,
)
from networks.geometry import box_rotations

GRID = VoxelGrid((-4.0, -4.0, -1.0), 0.4, (20, 20, 10))


def _meets_cube(tri, center):
    """Reference separating-axis test of one triangle (3, 3) against the unit cube at ``center``."""
    v = tri - center
    e = v[[1, 2, 0]] - v
    axes = [np.eye(3)[i] for i in range(3)] + [np.cross(e[0], e[1])]
    axes += [np.cross(np.eye(3)[i], e[j]) for i in range(3) for j in range(3)]
    for a in axes:
        if np.linalg.norm(a) < 1e-12:
            continue
        p = v @ a
        r = 0.5 * np.abs(a).sum()
        if p.min() > r + 1e-9 or p.max() < -r - 1e-9:
            return False
    return True


def _brute_triangle(grid, tri_m):
    tri = grid.to_grid(tri_m)
    lo = np.clip(np.floor(tri.min(0) - 1e-6).astype(int), 0, np.array(grid.shape) - 1)
    hi = np.clip(np.floor(tri.max(0) + 1e-6).astype(int), 0, np.array(grid.shape) - 1)
    found = set()
    for ijk in np.ndindex(*(hi - lo + 1)):
        ijk = np.asarray(ijk) + lo
        if _meets_cube(tri, ijk + 0.5):
            found.add(int(grid.flat(ijk)))
    return found


coords = st.floats(-4.5, 4.5, allow_nan=False)


@settings(max_examples=60, deadline=None)
@given(st.lists(coords, min_size=9, max_size=9))
def test_triangle_meets_exactly_the_voxels_a_separating_axis_test_finds(values):
    tri = np.asarray(values).reshape(3, 3) + np.array([0.0137, 0.0291, 0.0173])  # off voxel faces (tolerances differ)
    tri[:, 2] = tri[:, 2] / 2.0 + 0.5  # within the grid's height mostly
    flat, source = triangle_voxels(GRID, tri[None])
    assert set(flat.tolist()) == _brute_triangle(GRID, tri)
    assert np.all(source == 0)


def test_flat_ground_fills_one_layer_and_nothing_above():
    ground = np.array(
        [[[-10, -10, 0.0], [10, -10, 0.0], [10, 10, 0.0]], [[-10, -10, 0.0], [10, 10, 0.0], [-10, 10, 0.0]]]
    )
    flat, _ = triangle_voxels(GRID, ground)
    ijk = np.stack(np.unravel_index(np.unique(flat), GRID.shape), axis=-1)
    assert len(ijk) == 20 * 20  # z = 0 lies inside layer 2 (-0.2 .. 0.2): one layer
    assert set(ijk[:, 2].tolist()) == {2}


def test_axis_aligned_box_fills_exactly_the_voxels_its_volume_covers():
    # a box from x 0.1..2.3, y -0.5..0.7, z 0.0..1.5: voxels x 10..15, y 8..11, z 2..6
    center = np.array([[1.2, 0.1, 0.75]])
    flat, source = box_voxels(GRID, center, box_rotations([0.0], [0.0]), np.array([[2.2, 1.2, 1.5]]))
    ijk = np.stack(np.unravel_index(flat, GRID.shape), axis=-1)
    expected = {(i, j, k) for i in range(10, 16) for j in range(8, 12) for k in range(2, 7)}
    assert {tuple(v) for v in ijk.tolist()} == expected
    assert np.all(source == 0)


def test_box_on_voxel_faces_does_not_fill_the_voxels_it_only_touches():
    center = np.array([[0.4, 0.4, 0.2]])  # x 0..0.8, y 0..0.8, z -0.2..0.6: faces on voxel faces
    flat, _ = box_voxels(GRID, center, box_rotations([0.0], [0.0]), np.array([[0.8, 0.8, 0.8]]))
    assert len(flat) == 2 * 2 * 2


def test_turned_box_fills_every_voxel_a_point_of_it_lies_in_and_no_voxel_away_from_it():
    rng = np.random.default_rng(3)
    center, lwh, yaw, pitch = np.array([[0.3, -0.2, 0.8]]), np.array([[3.1, 1.7, 1.4]]), 0.7, 0.15
    R = box_rotations([yaw], [pitch])
    flat, _ = box_voxels(GRID, center, R, lwh)
    got = set(flat.tolist())
    local = (rng.random((200_000, 3)) - 0.5) * lwh
    points = local @ R[0].T + center
    ijk = GRID.ijk_of(points)
    assert set(GRID.flat(ijk[GRID.inside(ijk)]).tolist()) <= got
    # every voxel found lies within a voxel's diagonal of the box (its centre, in the box's frame)
    centers = (GRID.centers_m(np.asarray(sorted(got))) - center) @ R[0]
    outside = np.maximum(np.abs(centers) - lwh / 2.0, 0.0)
    assert np.linalg.norm(outside, axis=1).max() <= GRID.voxel_m * np.sqrt(3) / 2.0 + 1e-9


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(-6, 6, allow_nan=False), min_size=6, max_size=6))
@example([0.0, 0.0, 0.0, 0.0, 7.190067047107501e-12, -1.0])  # from a voxel's corner, nearly along two faces
def test_segment_crosses_every_voxel_a_dense_walk_along_it_visits(values):
    start, end = np.asarray(values[:3]), np.asarray(values[3:])
    start[2], end[2] = start[2] / 3.0 + 1.0, end[2] / 3.0 + 1.0
    got = set(segment_voxels(GRID, start[None], end[None]).tolist())
    t = np.linspace(0.0, 1.0, 20_001)[:, None]
    g = GRID.to_grid(start + (end - start) * t)
    g = g[np.all(np.abs(g - np.rint(g)) > 1e-6, axis=1)]  # points on a voxel face belong to either side
    ijk = np.floor(g).astype(np.int64)
    walked = set(GRID.flat(ijk[GRID.inside(ijk)]).tolist())
    assert walked <= got
    # nothing beyond: the segment meets every voxel found (slab test, closed cubes grown by 1e-9 m:
    # a corner's coordinate from the voxel's centre is off by ~1e-16 m, which a segment nearly
    # parallel to that face would turn into a large parameter)
    for flat in got:
        lo = GRID.centers_m(np.asarray([flat]))[0] - GRID.voxel_m / 2.0 - 1e-9
        hi = lo + GRID.voxel_m + 2e-9
        t0, t1 = 0.0, 1.0
        for axis in range(3):
            d = end[axis] - start[axis]
            if abs(d) < 1e-12:
                assert lo[axis] <= start[axis] <= hi[axis]
                continue
            ta, tb = sorted(((lo[axis] - start[axis]) / d, (hi[axis] - start[axis]) / d))
            t0, t1 = max(t0, ta), min(t1, tb)
        assert t0 <= t1 + 1e-5


def _walked(walker, starts, ends):
    out = np.zeros(GRID.size, np.bool_)
    walker(SegmentWalk.of(GRID, starts, ends), out)
    return out


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(-6, 6, allow_nan=False), min_size=6, max_size=6))
def test_voxel_walk_visits_the_voxels_the_segment_crosses(values):
    start, end = np.asarray(values[:3]), np.asarray(values[3:])
    start[2], end[2] = start[2] / 3.0 + 1.0, end[2] / 3.0 + 1.0
    assume(np.any(start != end))  # a ray has a length (a point crosses nothing, the walk keeps its voxel)
    got = np.flatnonzero(_walked(lambda w, out: walk_segments(GRID, w, out), start[None], end[None]))
    crossed = set(segment_voxels(GRID, start[None], end[None]).tolist())
    # through a voxel's edge or corner the walk takes one of the voxels beside it; ending on a
    # face, one side
    assert set(got.tolist()) == crossed or _tie(start, end)


def _tie(start, end):
    g0, g1 = GRID.to_grid(start), GRID.to_grid(end)
    t = np.linspace(0.0, 1.0, 200_001)[:, None]
    near = np.abs((g := g0 + (g1 - g0) * t) - np.rint(g)) < 1e-4
    return bool(np.any(near.sum(axis=1) >= 2) or near[0].any() or near[-1].any())


def test_compiled_voxel_walk_visits_the_same_voxels_as_numpy():
    rng = np.random.default_rng(3)
    starts = np.broadcast_to([0.1, 0.2, 0.9], (5000, 3)) + rng.normal(0.0, 0.05, (5000, 3))
    ends = rng.uniform([-7, -7, -1.5], [7, 7, 4], (5000, 3))
    ends[:500] = np.round(ends[:500] / GRID.voxel_m) * GRID.voxel_m  # ends on faces, edges and corners
    starts[500:1000, 2] = ends[500:1000, 2] = 1.2  # in a plane of faces
    numpy_walk = _walked(lambda w, out: walk_segments(GRID, w, out), starts, ends)
    compiled = np.zeros(GRID.size, np.bool_)
    walk_voxels(GRID, starts, ends, compiled)
    assert numpy_walk.sum() > 500
    assert np.array_equal(numpy_walk, compiled)
    for i in range(0, 1000, 7):  # ray by ray
        one = np.zeros(GRID.size, np.bool_)
        walk_voxels(GRID, starts[i : i + 1], ends[i : i + 1], one)
        reference = _walked(lambda w, out: walk_segments(GRID, w, out), starts[i : i + 1], ends[i : i + 1])
        assert np.array_equal(one, reference)


def test_walk_from_a_mount_visits_the_voxels_of_the_segments_it_places():
    rng = np.random.default_rng(5)
    rotation = box_rotations(np.array([0.7]), np.array([0.05]))[0]
    translation = np.array([0.3, -0.2, 0.9])
    points = rng.uniform([-6, -6, -2], [6, 6, 3], (4000, 3)).astype(np.float32)
    points[:400] = np.round(points[:400] / GRID.voxel_m) * GRID.voxel_m  # ends on faces (before the turn)
    ends = np.einsum("nj,ij->ni", points.astype(np.float64), rotation) + translation
    reference = np.zeros(GRID.size, np.bool_)
    walk_voxels(GRID, np.broadcast_to(translation, ends.shape), ends, reference)
    walked = np.zeros(GRID.size, np.bool_)
    walk_from(GRID, points, rotation, translation, walked)
    assert reference.sum() > 500
    assert np.array_equal(walked, reference)
    axis_aligned = np.zeros(GRID.size, np.bool_)  # ends exactly on faces, edges and corners
    snapped = np.round(points[:400].astype(np.float64) / GRID.voxel_m) * GRID.voxel_m
    walk_from(GRID, snapped, np.eye(3), np.zeros(3), axis_aligned)
    reference[:] = False
    walk_voxels(GRID, np.zeros_like(snapped), snapped, reference)
    assert np.array_equal(axis_aligned, reference)


def _components(free):
    """Reference 6-connected components of ``free`` (a flood per unlabelled voxel)."""
    label = np.full(free.shape, -1)
    count = 0
    for start in zip(*np.nonzero(free), strict=True):
        if label[start] >= 0:
            continue
        label[start], stack = count, [start]
        while stack:
            v = stack.pop()
            for axis in range(3):
                for step in (-1, 1):
                    n = list(v)
                    n[axis] += step
                    n = tuple(n)
                    if all(0 <= n[a] < free.shape[a] for a in range(3)) and free[n] and label[n] < 0:
                        label[n] = count
                        stack.append(n)
        count += 1
    return label


@given(st.integers(0, 2**32 - 1), st.floats(0.1, 0.6))
@settings(max_examples=40, deadline=None)
def test_solid_runs_parts_are_the_free_voxels_connected_components(seed, density):
    from gtgen import voxel_kernels

    shape = (9, 7, 5)
    rng = np.random.default_rng(seed)
    kind = rng.choice(3, size=shape, p=[1.0 - density, density * 0.7, density * 0.3])
    flat = np.arange(kind.size).reshape(shape)
    got, ijk, part = voxel_kernels.solid_runs(flat[kind == 1], flat[kind == 2], *shape)
    assert np.array_equal(got.reshape(shape), kind)
    label = _components(kind == 0)
    runs = part >= 0
    assert np.array_equal(kind[tuple(ijk[~runs].T)], np.full((~runs).sum(), 2))  # floor-only voxels cast alone
    starts = ijk[runs]
    assert np.all(kind[tuple(starts.T)] == 0)
    assert np.all((starts[:, 0] == 0) | (kind[starts[:, 0] - 1, starts[:, 1], starts[:, 2]] != 0))
    ref = label[tuple(starts.T)]  # the same partition of the runs as the components'
    assert np.array_equal(ref[:, None] == ref[None, :], part[runs][:, None] == part[runs][None, :])
    assert set(np.unique(label[label >= 0])) == set(ref)  # every component has a run

"""The compiled occupancy kernels against the forms they replaced, bit for bit: the agents' fill
from their own triangles, the solids' runs and fill, the camera walks' marking, the floors near
a point."""

import math

import numpy as np
import numpy.typing as npt
from hypothesis import given, settings
from hypothesis import strategies as st
from numba import njit

from gtgen import occupancy, voxel_kernels
from gtgen.voxel_kernels import I64, _root, class_bits, enclosed, octant_areas
from gtgen.voxels import OccupancyGrid, VoxelGrid, box_voxels, triangle_voxels
from networks.classes import SemanticClass
from networks.geometry import SE3, box_rotations
from sensors.agents import Agents, agent_meshes
from sensors.solids import _boxes_within


@njit(nogil=True)
def solid_runs_before(surface: I64, floor: I64, nx: int, ny: int, nz: int) -> tuple[npt.NDArray[np.int8], I64, I64]:
    """The voxels to cast for the solids' insides: along each row of voxels (ego x; rows in
    ``(y, z)`` order) the first voxel of each run that no solid's surface ``surface`` nor floor
    ``floor`` (flat) meets, and each voxel only a floor meets. Returns each voxel's kind (0:
    free of both, 1: surface, 2: floor only), the cast voxels ``(T, 3)`` (``i, j, k``, rows in
    order) and each one's part (``-1`` for a floor-only voxel): runs in one part are joined by
    face-neighbouring voxels of kind 0 (runs of neighbouring rows that share an x), so no
    surface or floor parts their centres, numbered from 0 in order of first appearance."""
    kind = np.zeros(nx * ny * nz, np.int8)
    for n in range(floor.shape[0]):
        kind[floor[n]] = 2
    for n in range(surface.shape[0]):
        kind[surface[n]] = 1
    rows = ny * nz  # row (j, k) is r = j * nz + k; voxel (i, r) at i * rows + r: read in memory order
    row_first = np.zeros(rows + 1, np.int64)  # the runs of row r: row_first[r]:row_first[r + 1]
    cast_first = np.zeros(rows + 1, np.int64)  # its voxels to cast: cast_first[r]:cast_first[r + 1]
    prev = np.ones(rows, np.int8)
    for i in range(nx):
        base = i * rows
        for r in range(rows):
            c = kind[base + r]
            if c == 2 or (c == 0 and prev[r] != 0):
                cast_first[r + 1] += 1
            if c == 0 and prev[r] != 0:
                row_first[r + 1] += 1
            prev[r] = c
    for r in range(rows):
        cast_first[r + 1] += cast_first[r]
        row_first[r + 1] += row_first[r]
    count, runs = cast_first[rows], row_first[rows]
    ijk = np.empty((count, 3), np.int64)
    run_of = np.empty(count, np.int64)
    low = np.empty(runs, np.int64)  # each run's x extent and row
    high = np.empty(runs, np.int64)
    cast_at = cast_first[:rows].copy()
    run_at = row_first[:rows].copy()
    prev[:] = 1
    for i in range(nx):
        base = i * rows
        for r in range(rows):
            c = kind[base + r]
            if c == 2 or (c == 0 and prev[r] != 0):
                m = cast_at[r]
                ijk[m, 0], ijk[m, 1], ijk[m, 2] = i, r // nz, r % nz
                run_of[m] = -1
                if c == 0:
                    run_of[m] = run_at[r]
                    low[run_at[r]] = i
                    run_at[r] += 1
                cast_at[r] += 1
            if c == 0:
                high[run_at[r] - 1] = i
            prev[r] = c
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


@njit(nogil=True)
def solid_fill_before(
    kind: npt.NDArray[np.int8], cls: npt.NDArray[np.uint8], nx: int, ny: int, nz: int
) -> tuple[I64, npt.NDArray[np.uint8]]:
    """``(flat, class)`` of the voxels inside solids (ascending): each run of :func:`solid_runs`
    takes its cast voxel's class ``cls``, each floor-only voxel its own, surface voxels none."""
    out = np.zeros(nx * ny * nz, np.uint8)
    m = 0
    for j in range(ny):
        for k in range(nz):
            prev = 1
            run = np.uint8(0)
            for i in range(nx):
                v = (i * ny + j) * nz + k
                c = kind[v]
                if c == 2:
                    out[v] = cls[m]
                    m += 1
                elif c == 0:
                    if prev != 0:
                        run = cls[m]
                        m += 1
                    out[v] = run
                prev = c
    count = 0
    for v in range(out.shape[0]):
        if out[v] != 0:
            count += 1
    flat = np.empty(count, np.int64)
    value = np.empty(count, np.uint8)
    m = 0
    for v in range(out.shape[0]):
        if out[v] != 0:
            flat[m], value[m] = v, out[v]
            m += 1
    return flat, value


@njit(nogil=True)
def boxes_filled_before(
    flat: I64,
    bounds: I64,
    agent_id: npt.NDArray[np.uint32],
    meshed: npt.NDArray[np.bool_],
    surface_flat: I64,
    surface_id: npt.NDArray[np.uint32],
    ny: int,
    nz: int,
) -> npt.NDArray[np.bool_]:
    """Which box voxels ``flat`` (flat, grouped by agent: group ``g`` is ``bounds[g]:bounds[g + 1]``,
    its agent ``agent_id[g]``) the agent fills: all of its box where ``meshed[g]`` is false, else
    those its surface meets or encloses (:func:`enclosed`, its surface the voxels ``surface_flat``
    whose ``surface_id`` is the agent's; ``surface_id`` sorted)."""
    keep = np.ones(flat.shape[0], np.bool_)
    for g in range(bounds.shape[0] - 1):
        if not meshed[g]:
            continue
        a, b = bounds[g], bounds[g + 1]
        box = np.empty((b - a, 3), np.int64)
        for n in range(a, b):
            v = flat[n]
            box[n - a, 0], box[n - a, 1], box[n - a, 2] = v // (ny * nz), (v // nz) % ny, v % nz
        lo = np.searchsorted(surface_id, agent_id[g], side="left")
        hi = np.searchsorted(surface_id, agent_id[g], side="right")
        wall = np.empty((hi - lo, 3), np.int64)
        for n in range(lo, hi):
            v = surface_flat[n]
            wall[n - lo, 0], wall[n - lo, 1], wall[n - lo, 2] = v // (ny * nz), (v // nz) % ny, v % nz
        keep[a:b] = enclosed(box, wall)
    return keep


@njit(nogil=True)
def mark_walked_before(first, flat, entry, reach, out):
    for q in range(first.shape[0] - 1):
        a, b = first[q], first[q + 1]
        if a == b or not (entry[a] == 0.0 or entry[a] < reach[q]):
            continue
        out[flat[a]] = True
        if reach[q] == 0.0:
            continue
        for n in range(a + 1, b):
            if entry[n] > reach[q]:
                break
            out[flat[n]] = True


@njit(nogil=True)
def choose_shared_before(
    voxels: I64, area: npt.NDArray[np.float64], label: npt.NDArray[np.integer], nx: int, ny: int, nz: int, sweeps: int
) -> I64:
    """The class of each shared voxel ``voxels: (M,)`` (flat): the class with the most area
    ``area: (M, C, 8)`` in the voxel's eighths whose 7 neighbours on that eighth's side hold no
    voxel of that class in ``label`` (flat, every voxel's class; updated as each voxel is chosen,
    in order, sweep after sweep until none changes); where none needs it, its class in ``label``."""
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
                        if ok and label[(qi * ny + qj) * nz + qk] == c:
                            covered = True
                            break
                    if not covered:
                        need[c] += area[m, c, o]
            best = chosen[m]
            if need.max() > 0.0:
                best = np.argmax(need)
            if best != chosen[m]:
                chosen[m] = best
                label[v] = best
                changed += 1
        if changed == 0:
            break
    return chosen


@njit(nogil=True)
def shared_keep_before(
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
) -> npt.NDArray[np.bool_]:
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
    area = np.zeros((voxels_n, n_occ, 8))
    for o in range(8):
        for q in range(entries.shape[0]):
            area[local[q], occ[entries[q]], o] += areas[q, o]
    chosen = choose_shared_before(voxels, area, label, nx, ny, nz, sweeps)
    present = np.zeros(voxels_n, np.bool_)
    for q in range(entries.shape[0]):
        if occ[entries[q]] == chosen[local[q]]:
            present[local[q]] = True
    for q in range(entries.shape[0]):
        mine = occ[entries[q]] == chosen[local[q]]
        keep[entries[q]] = mine or not present[local[q]]
    return keep


def agent_voxels_before(grid, agents, meshes, ego_SE3_map):
    """The agents' voxels as made before: every in-grid agent's triangles voxelised, then each box
    flooded from outside through the voxels its surface leaves free."""
    center = ego_SE3_map.transform_from(agents.center_map_m)
    rotations = ego_SE3_map.rotation @ box_rotations(agents.yaw_map_rad, agents.pitch_rad)
    flat, row = box_voxels(grid, center, rotations, agents.lwh_m)
    if flat.size == 0:
        return flat, row
    triangle_id = meshes.triangle_instance
    bounds = np.flatnonzero(np.r_[True, row[1:] != row[:-1], True])
    group_id = agents.instance_id[row[bounds[:-1]]].astype(np.uint32)
    in_grid = np.isin(triangle_id, group_id)
    meshed = np.isin(group_id, triangle_id)
    surface, tri = triangle_voxels(
        grid, meshes.vertices_m, meshes.triangles[in_grid], ego_SE3_map.rotation, ego_SE3_map.translation
    )
    surface_id = triangle_id[in_grid][tri]
    by_id = np.argsort(surface_id, kind="stable")
    _, ny, nz = grid.shape
    keep = boxes_filled_before(
        flat, bounds, group_id, meshed, surface[by_id], surface_id[by_id].astype(np.uint32), ny, nz
    )
    return flat[keep], row[keep]


CLASSES = [SemanticClass.CAR, SemanticClass.PEDESTRIAN, SemanticClass.BUS, SemanticClass.BICYCLE, SemanticClass.TRUCK]
SIZES = {
    SemanticClass.CAR: (4.4, 1.8, 1.5), SemanticClass.PEDESTRIAN: (0.6, 0.6, 1.8), SemanticClass.BUS: (12, 2.5, 3.2),
    SemanticClass.BICYCLE: (1.8, 0.6, 1.6), SemanticClass.TRUCK: (8.0, 2.5, 3.5),
}  # fmt: skip


@settings(max_examples=12, deadline=None)
@given(st.integers(0, 2**32 - 1), st.sampled_from(["identity", "turned", "edge"]))
def test_agents_fill_the_same_voxels_as_from_all_their_triangles_voxels(seed, ego):
    rng = np.random.default_rng(seed)
    n = 24
    cls = rng.choice(CLASSES, n)
    lwh = np.array([SIZES[c] for c in cls]) * rng.uniform(0.8, 1.2, (n, 1))
    # across the grid and over its edges; yaws often square to the grid (faces parallel to x)
    xy = rng.uniform(-44.0, 44.0, (n, 2))
    z = lwh[:, 2] / 2 + rng.uniform(-1.5, 3.0, n)
    yaw = np.where(rng.random(n) < 0.5, rng.integers(0, 4, n) * (np.pi / 2), rng.uniform(-np.pi, np.pi, n))
    agents = Agents.standing(np.arange(1, n + 1), cls.astype(np.int64), np.c_[xy, z], lwh, yaw)
    meshes = agent_meshes(agents)
    if ego == "identity":
        map_SE3_ego = SE3.identity()
    else:
        turn = rng.uniform(-np.pi, np.pi) if ego == "turned" else np.pi / 2
        c, s = math.cos(turn), math.sin(turn)
        map_SE3_ego = SE3(np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]), rng.uniform(-3, 3, 3))
    grid = OccupancyGrid().grid
    ego_SE3_map = map_SE3_ego.inverse()
    got = occupancy._agent_voxels(grid, agents, meshes, ego_SE3_map)
    expected = agent_voxels_before(grid, agents, meshes, ego_SE3_map)
    assert expected[0].size > 0
    assert np.array_equal(got[0], expected[0]) and np.array_equal(got[1], expected[1])


def test_agents_fill_the_same_voxels_from_triangles_out_of_order_and_nearly_parallel_to_x():
    """Triangles of one agent not one after another, and triangles whose plane is within a hair of
    x's direction (their rows' x reach far for a tiny turn of the plane: no row is left out)."""
    rng = np.random.default_rng(7)
    grid = VoxelGrid((-4.0, -4.0, -1.0), 0.4, (20, 20, 10))
    agents = Agents.standing([3, 5], [int(SemanticClass.CAR)] * 2, [[0.1, 0.2, 0.8], [-1.3, 1.1, 0.9]],
                             [[4.0, 2.0, 1.6], [2.0, 2.4, 1.8]], [0.0, 0.3])  # fmt: skip
    for tilt in (0.0, 1e-10, 1e-8, 1e-6, 1e-3):
        corners = []
        for center in agents.center_map_m:
            for _ in range(40):
                p = center + rng.uniform(-1.0, 1.0, 3)
                q = p + rng.uniform(-1.5, 1.5, 3)
                q[0] = p[0] + rng.uniform(-2, 2)
                r = p + np.array([rng.uniform(-2, 2), 0.0, 0.0]) + tilt * rng.standard_normal(3)
                r[1:] += (q[1:] - p[1:]) * rng.uniform(-1, 1)  # in the plane through p and q along x
                corners.append([p, q, r])
        vertices = np.asarray(corners, np.float32).reshape(-1, 3)
        triangles = np.arange(vertices.shape[0], dtype=np.int32).reshape(-1, 3)
        ids = np.repeat(np.array([3, 5], np.uint32), 40)
        order = rng.permutation(ids.shape[0])  # the agents' triangles interleaved
        meshes = type(agent_meshes(agents))(
            vertices,
            triangles[order],
            ids[order],
            np.full(80, int(SemanticClass.CAR), np.uint8),
            np.zeros(80, np.uint8),
        )
        for map_SE3_ego in (SE3.identity(), SE3(np.eye(3), np.array([0.013, -0.2, 0.0]))):
            ego_SE3_map = map_SE3_ego.inverse()
            got = occupancy._agent_voxels(grid, agents, meshes, ego_SE3_map)
            expected = agent_voxels_before(grid, agents, meshes, ego_SE3_map)
            assert np.array_equal(got[0], expected[0]) and np.array_equal(got[1], expected[1])


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**32 - 1), st.floats(0.0, 0.7), st.sampled_from([(9, 7, 5), (1, 4, 3), (30, 6, 2), (5, 1, 1)]))
def test_solid_runs_and_fill_as_before(seed, density, shape):
    rng = np.random.default_rng(seed)
    kind = rng.choice(3, size=shape, p=[1.0 - density, density * 0.6, density * 0.4])
    flat = np.arange(kind.size).reshape(shape)
    surface = rng.permutation(np.repeat(flat[kind == 1], rng.integers(1, 4, (kind == 1).sum())))  # repeats too
    floor = np.r_[rng.permutation(np.repeat(flat[kind == 2], 2)), flat[kind == 1][: rng.integers(0, 3)]]
    got = voxel_kernels.solid_runs(surface, floor, *shape)
    expected = solid_runs_before(surface, floor, *shape)
    for a, b in zip(got, expected, strict=True):
        assert a.dtype == b.dtype and np.array_equal(a, b)
    kind_, ijk, _ = got
    cls = rng.choice(np.array([0, 0, 3, 9], np.uint8), ijk.shape[0])
    flat_got, cls_got = voxel_kernels.solid_fill(kind_, ijk, cls, *shape)
    flat_exp, cls_exp = solid_fill_before(kind_, cls, *shape)
    order = np.argsort(flat_got)
    assert np.array_equal(flat_got[order], flat_exp) and np.array_equal(cls_got[order], cls_exp)
    assert np.unique(flat_got).size == flat_got.size


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_camera_walks_marked_as_far_as_each_reached_as_before(seed):
    rng = np.random.default_rng(seed)
    grid = VoxelGrid((-4.0, -4.0, -1.0), 0.4, (20, 20, 10))
    n = 300
    starts = np.broadcast_to(rng.uniform(-1, 1, 3), (n, 3))
    ends = starts + rng.standard_normal((n, 3)) * 8.0
    lower = np.asarray(grid.lower_m, np.float64)
    first, flat, t = voxel_kernels.walk_steps(np.ascontiguousarray(starts), ends, lower, grid.voxel_m, *grid.shape)
    entry = t * 30.0
    reach = rng.uniform(0.0, 35.0, n)
    reach[rng.random(n) < 0.1] = 0.0
    some = rng.random(n) < 0.2  # exactly at an entry: that voxel is reached
    for q in np.flatnonzero(some & (np.diff(first) > 1)):
        reach[q] = entry[rng.integers(first[q], first[q + 1])]
    got, expected = np.zeros(grid.size, np.bool_), np.zeros(grid.size, np.bool_)
    voxel_kernels.mark_walked(first, flat, entry, reach, got)
    mark_walked_before(first, flat, entry, reach, expected)
    assert np.array_equal(got, expected)


def test_floors_near_a_point_as_numpy_finds_them():
    rng = np.random.default_rng(3)
    low = rng.uniform(-100, 100, (5000, 2))
    high = low + rng.uniform(0, 20, (5000, 2))
    for center, reach in ((np.array([3.0, -7.0]), 40.0), (np.array([0.0, 0.0]), 0.0), (low[5], 57.3)):
        gap = np.maximum(np.maximum(low - center, center - high), 0.0)
        expected = np.flatnonzero(np.linalg.norm(gap, axis=1) <= reach)
        assert np.array_equal(_boxes_within(low, high, center, reach), expected)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_shared_surfaces_keep_the_same_entries_as_before(seed):
    """Flat triangles of a few classes on a small grid, many of them in the same voxels (equal
    areas too: squares of ground split alike), as the static world's surfaces meet."""
    rng = np.random.default_rng(seed)
    shape = (8, 7, 4)
    grid = VoxelGrid((0.0, 0.0, 0.0), 1.0, shape)
    triangles = []
    for _ in range(rng.integers(5, 40)):
        x0, y0 = rng.integers(0, 6, 2) + rng.choice([0.0, 0.5, 0.25], 2)
        w, h = rng.choice([0.5, 1.0, 2.0, 1.7], 2)
        z = rng.choice([0.5, 1.0, 1.25, 2.0]) + rng.choice([0.0, 0.0, 0.1]) * rng.random()
        a, b, c, d = [x0, y0, z], [x0 + w, y0, z], [x0 + w, y0 + h, z], [x0, y0 + h, z]
        triangles += [[a, b, c], [a, c, d]]
    tri_m = np.asarray(triangles, np.float64)
    tri_m[rng.random(tri_m.shape[0]) < 0.3, 2, 2] += 0.4  # some tilted
    flat, source = triangle_voxels(grid, tri_m)
    occ_classes = np.array([11, 12, 13, 14, 15, 16])
    cls = rng.choice(occ_classes, tri_m.shape[0])[source].astype(np.int64)
    label = rng.choice(np.r_[occ_classes, 4, 17], grid.size).astype(np.uint8)
    args = (flat, cls, tri_m, source, np.zeros(3), 1.0)
    tail = (18, *shape, 6, (1 << 11) | (1 << 12) | (1 << 13), 14)
    got_label, expected_label = label.copy(), label.copy()
    got = voxel_kernels.shared_keep(*args, got_label, *tail)
    expected = shared_keep_before(*args, expected_label, *tail)
    assert np.array_equal(got, expected) and np.array_equal(got_label, expected_label)

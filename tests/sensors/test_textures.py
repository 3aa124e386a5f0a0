import numpy as np

from sensors import textures


def _hash_in_int64(ix: np.ndarray, iy: np.ndarray, seed: int) -> np.ndarray:
    """The texture hash as written with 64-bit integers masked to 32 bits."""
    h = (ix * 374761393 + iy * 668265263 + seed * 2147483647) & 0xFFFFFFFF
    h = ((h ^ (h >> 13)) * 1274126177) & 0xFFFFFFFF
    h ^= h >> 16
    return (h & 0xFFFFFF).astype(np.float32) / np.float32(16777216.0)


def test_hash_in_32_bit_arithmetic_equals_the_64_bit_formula_for_negative_and_far_lattice_points() -> None:
    rng = np.random.default_rng(5)
    ix = rng.integers(-3_000_000, 3_000_000, 20_000)
    iy = rng.integers(-3_000_000, 3_000_000, 20_000)
    for seed in (0, 7, 91, 1000):
        assert np.array_equal(textures.hash01(ix, iy, seed), _hash_in_int64(ix, iy, seed))


def test_value_noise_takes_each_lattice_points_hash_there_and_blends_between() -> None:
    rng = np.random.default_rng(6)
    ix = rng.integers(-5000, 5000, 2000)
    iy = rng.integers(-5000, 5000, 2000)
    at_points = textures.value_noise(ix.astype(np.float32), iy.astype(np.float32), 3)
    assert np.array_equal(at_points, _hash_in_int64(ix, iy, 3))
    x = ix.astype(np.float32) + np.float32(0.5)
    y = iy.astype(np.float32) + np.float32(0.5)
    mid = textures.value_noise(x, y, 3)  # the four corners' mean at a cell's centre
    corners = [_hash_in_int64(ix + dx, iy + dy, 3) for dx in (0, 1) for dy in (0, 1)]
    assert np.allclose(mid, np.mean(corners, axis=0), atol=1e-6)


def _value_noise_numpy(x: np.ndarray, y: np.ndarray, seed: int) -> np.ndarray:
    """Value noise in whole-array numpy steps (the form the compiled loop replaced)."""
    fx, fy = np.floor(x), np.floor(y)
    corner = textures._lattice(fx.astype(np.int64), fy.astype(np.int64), seed)
    tx, ty = x - fx, y - fy
    tx = tx * tx * (np.float32(3.0) - np.float32(2.0) * tx)
    ty = ty * ty * (np.float32(3.0) - np.float32(2.0) * ty)
    a, b = textures._mixed01(corner), textures._mixed01(corner + textures._STEP_X)
    c = textures._mixed01(corner + textures._STEP_Y)
    d = textures._mixed01(corner + (textures._STEP_X + textures._STEP_Y))
    top = a + (b - a) * tx
    return np.asarray(top + (c + (d - c) * tx - top) * ty, np.float32)


def test_compiled_noise_equals_the_array_form_bit_for_bit_in_float32_and_float64() -> None:
    rng = np.random.default_rng(8)
    for kind in (np.float32, np.float64):
        x = rng.normal(0.0, 500.0, 50_000).astype(kind)
        y = rng.normal(0.0, 500.0, 50_000).astype(kind)
        x[:6] = [0.0, -0.0, 1e-9, -1e-9, -0.5, -(2.0**31) + 0.5]
        for seed in (3, 61):
            assert np.array_equal(textures.value_noise(x, y, seed), _value_noise_numpy(x, y, seed))
        total, amp, f = np.zeros(len(x), np.float32), 1.0, np.float32(1.0 / 7.0)
        for o in range(3):
            total += np.float32(amp) * _value_noise_numpy(x * f, y * f, 5 + o)
            amp, f = amp * 0.5, f * np.float32(2.0)
        assert np.array_equal(textures.fbm(x, y, 5, 3, 7.0), total / np.float32(1.75))


def test_leaves_lie_on_the_plane_a_surface_faces_and_have_dark_gaps_and_lit_clumps() -> None:
    from sensors.textures import foliage

    rng = np.random.default_rng(3)
    y, z = rng.uniform(0.0, 20.0, 4000), rng.uniform(0.0, 20.0, 4000)
    wall = np.stack([np.zeros_like(y), y, z], axis=1).astype(np.float32)
    facing_x = np.tile(np.array([[1.0, 0.0, 0.0]], np.float32), (len(y), 1))
    deeper = wall + np.array([0.7, 0.0, 0.0], np.float32)
    a, b = foliage(wall, facing_x, 71), foliage(deeper, facing_x, 71)
    # A surface facing x: the leaves depend on where on it (y, z), not how deep it lies (no streaks)
    # beyond the crown's big mottling, which varies over metres.
    assert np.corrcoef(a, b)[0, 1] > 0.8
    assert np.quantile(a, 0.1) < 0.5 < 1.0 < np.quantile(a, 0.9)
    assert 0.7 < a.mean() < 1.3


def test_bark_furrows_run_up_the_trunk() -> None:
    from sensors.textures import bark

    rng = np.random.default_rng(4)
    p = np.stack([rng.uniform(0, 50, 5000), np.zeros(5000), rng.uniform(0, 3, 5000)], axis=1).astype(np.float32)
    step = np.float32(0.04)
    around = np.abs(bark(p + np.array([step, 0, 0], np.float32)) - bark(p)).mean()
    up = np.abs(bark(p + np.array([0, 0, step], np.float32)) - bark(p)).mean()
    assert around > 3 * up


def test_grass_is_olive_with_dry_patches_metres_across_and_grain_centimetres_across() -> None:
    from networks.classes import SemanticClass
    from sensors.materials import ALBEDO_BGR_BY_CLASS

    rng = np.random.default_rng(6)
    p = np.stack([rng.uniform(-200, 200, 20000), rng.uniform(-200, 200, 20000), np.zeros(20000)], axis=1)
    p = p.astype(np.float32)
    tint = textures.grass(p, 73)
    assert np.array_equal(tint, textures.grass(p.copy(), 73))  # the same ground, the same grass
    bgr = tint * ALBEDO_BGR_BY_CLASS[SemanticClass.TERRAIN]
    b, g, r = bgr.mean(axis=0)
    assert b < 0.7 * g and 0.75 * g < r < g  # olive: red close under green, blue well below (not lime)
    yellowness = bgr[:, 2] / bgr[:, 1]
    assert np.quantile(yellowness, 0.95) > 1.05 * np.quantile(yellowness, 0.05)  # dry and lush patches
    step = np.float32(0.03)
    near = textures.grass(p + np.array([step, 0, 0], np.float32), 73)
    far = textures.grass(p + np.array([1.5, 0, 0], np.float32), 73)
    hue = lambda t: t[:, 2] / t[:, 1]  # noqa: E731
    assert np.abs(near - tint).mean() > 0.05  # the blades' grain changes within centimetres
    assert np.abs(hue(near) - hue(tint)).mean() < 0.5 * np.abs(hue(far) - hue(tint)).mean()  # patches: metres


def test_leaf_tilt_turns_normals_clump_by_clump_and_they_stay_unit_and_facing_the_camera() -> None:
    from networks.classes import SemanticClass
    from sensors.photo import leafy_normals

    rng = np.random.default_rng(7)
    n = 5000
    dirs = rng.normal(size=(n, 3)).astype(np.float32)
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    normal = -dirs  # facing the camera
    cls = np.where(np.arange(n) % 2 == 0, SemanticClass.VEGETATION, SemanticClass.BUILDING).astype(np.uint8)
    range_m = rng.uniform(2.0, 40.0, n).astype(np.float32)
    out = leafy_normals(normal.copy(), cls, dirs, range_m, np.array([3.0, -2.0, 1.5]))
    leafy = cls == SemanticClass.VEGETATION
    assert np.array_equal(out[~leafy], normal[~leafy])
    assert np.allclose(np.linalg.norm(out, axis=1), 1.0, atol=1e-5)
    assert np.all(np.einsum("ij,ij->i", out[leafy], dirs[leafy]) < 0.0)
    turned = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", out[leafy], normal[leafy]), -1, 1)))
    assert np.median(turned) > 10.0 and np.quantile(turned, 0.9) > 25.0
    p = np.stack([rng.uniform(0, 20, n), rng.uniform(0, 20, n), rng.uniform(0, 10, n)], axis=1).astype(np.float32)
    near = textures.leaf_tilt(p + np.float32(0.02), 67) - textures.leaf_tilt(p, 67)
    far = textures.leaf_tilt(p + np.float32(0.6), 67) - textures.leaf_tilt(p, 67)
    assert np.abs(near).mean() < 0.25 * np.abs(far).mean()  # clumps decimetres across, not per point


def test_facade_of_runs_of_points_equals_each_point_taken_alone() -> None:
    rng = np.random.default_rng(12)
    normals = np.array(
        [[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [-0.0, 1.0, 0.0], [0.0, -1.0, 0.0], [0.6, 0.8, 0.0],
         [0.6, 0.8, 0.0], [0.0, 0.0, 1.0], [0.3, -0.2, 0.93], [-0.7071, 0.7071, 0.0]],
        np.float32,
    )  # fmt: skip
    runs = rng.integers(0, len(normals), 60)  # runs of one normal, some repeated, along walls and across them
    normal = np.repeat(normals[runs], rng.integers(1, 40, len(runs)), axis=0)
    p = rng.uniform(-60.0, 60.0, (len(normal), 3)).astype(np.float32)
    p[:, 2] = rng.uniform(0.0, 20.0, len(normal))
    p[::3, :2] = np.round(p[::3, :2] / 4.0) * 4.0  # points on the same wall, one bay after another
    wall, glass, lit = textures.facade(p, normal)
    assert glass.any() and lit.any() and (~glass).any()
    for i in range(len(p)):
        one = textures.facade(p[i : i + 1], normal[i : i + 1])
        np.testing.assert_array_equal(wall[i : i + 1].view(np.uint32), one[0].view(np.uint32))
        assert glass[i] == one[1][0] and lit[i] == one[2][0]


def test_asphalt_is_its_grain_and_patches_noises_in_float32() -> None:
    rng = np.random.default_rng(31)
    p = rng.uniform(-300.0, 300.0, (20_000, 3)).astype(np.float32)
    x, y = p[:, 0], p[:, 1]
    grain = textures.value_noise(x * 9.0, y * 9.0, 3) - np.float32(0.5)
    patches = textures.fbm(x, y, 5, 3, 7.0) - np.float32(0.5)
    want = np.float32(1.0) + np.float32(0.14) * grain + np.float32(0.25) * patches
    assert want.dtype == np.float32
    np.testing.assert_array_equal(textures.asphalt(p).view(np.uint32), want.view(np.uint32))

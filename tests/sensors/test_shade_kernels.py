"""The realistic camera's compiled loops give their numpy forms' float32 results bit for bit
(the images stay the same bytes)."""

import numpy as np

from sensors import shade_kernels as kernels

from . import reference_forms as ref


def _unit_rows(rng: np.random.Generator, n: int) -> np.ndarray:
    v = rng.standard_normal((n, 3)).astype(np.float32)
    return np.asarray(v / np.linalg.norm(v, axis=1, keepdims=True), np.float32)


def test_normals_are_turned_to_the_camera_as_numpy_turns_them() -> None:
    rng = np.random.default_rng(3)
    normal, dirs = _unit_rows(rng, 50_000), _unit_rows(rng, 50_000)
    dirs[:100] = np.cross(normal[:100], _unit_rows(rng, 100))  # grazing: the sign decided by rounding
    want = normal.copy()
    np.negative(want, out=want, where=(np.einsum("ij,ij->i", normal, dirs) > 0)[:, None])
    instance = np.zeros(len(normal), np.uint32)
    got, ratio = kernels.turned_and_ratios(normal, dirs, instance, np.ones(len(normal), np.float32), np.float32(1.0),
                                           np.float32(0.1), np.ones(3, np.float32))  # fmt: skip
    assert ratio.shape == (0, 3)
    np.testing.assert_array_equal(got.view(np.uint32), want.view(np.uint32))


def test_blurred_normals_are_made_unit_as_numpy_makes_them() -> None:
    rng = np.random.default_rng(4)
    grid = rng.standard_normal((40, 60, 3)).astype(np.float32)
    num = (rng.standard_normal((20, 30, 3)) * rng.uniform(1e-7, 3.0, (20, 30, 1))).astype(np.float32)
    den = rng.uniform(0.0, 1.0, (20, 30)).astype(np.float32)
    den[0, :5] = 0.0  # no neighbours' weight: floored
    pick = rng.random((20, 30)) < 0.6
    want = grid.copy()
    mean = num[pick] / np.maximum(den[pick], np.float32(1e-6))[:, None]
    want[5:25, 7:37][pick] = mean / np.maximum(np.linalg.norm(mean, axis=-1, keepdims=True), np.float32(1e-6))
    level = np.full((40, 60), -1, np.int8)
    level[5:25, 7:37] = np.where(pick, 2, 1)
    kernels.blurred_unit(grid, 5, 7, level, 2, num, den)
    np.testing.assert_array_equal(grid.view(np.uint32), want.view(np.uint32))


def test_level_spans_are_the_rows_and_columns_holding_each_level() -> None:
    rng = np.random.default_rng(24)
    level = np.full((50, 70), -1, np.int8)
    level[rng.random((50, 70)) < 0.01] = 0
    level[10:13, 40] = 2
    spans = kernels.level_spans(level, 3)
    for k in range(3):
        rows, cols = np.flatnonzero((level == k).any(axis=1)), np.flatnonzero((level == k).any(axis=0))
        want = [rows[0], rows[-1], cols[0], cols[-1]] if len(rows) else [-1, -1, -1, -1]
        np.testing.assert_array_equal(spans[k], want)


def test_rows_scaled_tinted_and_least_values_kept_as_numpy_does() -> None:
    rng = np.random.default_rng(5)
    table = rng.uniform(0, 1, (1000, 3)).astype(np.float32)
    rows = np.sort(rng.choice(1000, 300, replace=False)).astype(np.int64)
    factor = rng.uniform(0.3, 1.7, 300).astype(np.float32)
    want = table.copy()
    want[rows] *= factor[:, None]
    kernels.scale_rows(table, rows, factor)
    np.testing.assert_array_equal(table, want)
    tint = rng.uniform(0.3, 1.7, (300, 3)).astype(np.float32)
    want[rows] *= tint
    kernels.tint_rows(table, rows, tint)
    np.testing.assert_array_equal(table, want)
    light = np.ones(500, np.float32)
    at = rng.integers(0, 500, 2000).astype(np.int64)  # a row given many values: the least is kept
    values = rng.uniform(0, 1.2, 2000).astype(np.float32)
    want_light = light.copy()
    np.minimum.at(want_light, at, values)
    kernels.minimum_at(light, at, values)
    np.testing.assert_array_equal(light, want_light)


def test_the_filmic_curve_is_numpys() -> None:
    rng = np.random.default_rng(6)
    linear = np.concatenate([rng.uniform(0, 3, 30_000), rng.uniform(-0.1, 0.0, 100), [0.0, 100.0]]).astype(np.float32)
    linear = linear.reshape(-1, 2)[:, :, None].repeat(3, axis=2).reshape(-1, 3).copy()
    gain = np.float32(1.8) * np.float32(1.3)
    keep = rng.uniform(0.7, 1.0, len(linear)).astype(np.float32)
    vignetted = linear.copy()
    vignetted *= keep[:, None]
    x = vignetted * gain
    f = np.float32
    y = (x * (f(2.51) * x + f(0.03))) / (x * (f(2.43) * x + f(0.59)) + f(0.14))
    np.testing.assert_array_equal(kernels.filmic(linear, keep, gain), np.clip(y, 0.0, 1.0))


def test_sub_rays_are_averaged_into_their_pixels_as_numpy_averages_them() -> None:
    rng = np.random.default_rng(7)
    linear = rng.uniform(0, 2, (5000, 3)).astype(np.float32)
    pixel = np.sort(rng.choice(5000, 700, replace=False)).astype(np.int64)
    sub = (rng.uniform(0, 2, (700 * 4, 3)) * rng.uniform(1e-4, 30, (700 * 4, 1))).astype(np.float32)
    want = linear.copy()
    want[pixel] = (want[pixel] + sub.reshape(-1, 4, 3).sum(axis=1)) / np.float32(5)
    kernels.add_subsamples(linear, pixel, sub, 4)
    np.testing.assert_array_equal(linear.view(np.uint32), want.view(np.uint32))


def test_sub_rays_directions_are_the_pinholes_bit_for_bit() -> None:
    from sensors.photo import SUBPIXEL_OFFSETS
    from sensors.pinhole import Pinhole

    pinhole = Pinhole(1280, 720, 85.0)
    pixel = np.sort(np.random.default_rng(8).choice(1280 * 720, 20_000, replace=False)).astype(np.int64)
    v, u = np.divmod(pixel, 1280)
    su = (u[:, None] + SUBPIXEL_OFFSETS[None, :, 0]).ravel()
    sv = (v[:, None] + SUBPIXEL_OFFSETS[None, :, 1]).ravel()
    want = pinhole.pixel_directions(su, sv).astype(np.float32)
    K = pinhole.K
    got = kernels.subpixel_directions(pixel, 1280, SUBPIXEL_OFFSETS, K[0, 0], K[0, 2], K[1, 1], K[1, 2])
    np.testing.assert_array_equal(got.view(np.uint32), want.view(np.uint32))


def test_street_lamp_offsets_are_numpys() -> None:
    rng = np.random.default_rng(9)
    points = rng.uniform(-500, 500, (40_000, 3)).astype(np.float32)
    points[:50, :2] = np.float32(14.0) + np.float32(28.0) * rng.integers(-5, 5, (50, 2))  # halfway: rounds to even
    s = np.float32(28.0)
    off = points[:, :2] - np.round(points[:, :2] / s) * s
    want = (off**2).sum(axis=1)
    np.testing.assert_array_equal(kernels.lamp_offsets_sq(points, s).view(np.uint32), want.view(np.uint32))


def test_agents_part_colours_are_part_albedo_to_the_gamma_bit_for_bit() -> None:
    from sensors.parts import MATERIALS, part_albedo
    from sensors.photo import _PART_LINEAR, GAMMA

    rng = np.random.default_rng(9)
    parts = np.array([int(p) for p in MATERIALS], np.uint8)
    part = rng.choice(parts, 200_000)
    instance = rng.integers(0, 2**32, 200_000, dtype=np.uint64).astype(np.uint32)
    rows = rng.permutation(300_000)[:200_000].astype(np.int64)
    albedo = np.full((300_000, 3), 7.0, np.float32)
    want = albedo.copy()
    want[rows] = part_albedo(part, instance) ** GAMMA
    kernels.part_rows(albedo, rows, part, instance, *_PART_LINEAR)
    np.testing.assert_array_equal(albedo.view(np.uint32), want.view(np.uint32))


def test_class_order_is_numpys_stable_argsort() -> None:
    rng = np.random.default_rng(10)
    scattered = rng.choice(np.array([0, 1, 4, 7, 200, 255], np.uint8), 100_000)
    runs = np.repeat(scattered[:3000], rng.integers(1, 60, 3000))  # runs of one class, as along rows
    for cls in (scattered, runs, scattered[:1], scattered[:0], np.full(500, 9, np.uint8)):
        order, end = kernels.class_order(cls)
        np.testing.assert_array_equal(order, np.argsort(cls, kind="stable"))
        np.testing.assert_array_equal(end, np.cumsum(np.bincount(cls, minlength=256)))


def test_rows_taken_are_numpys_fancy_index() -> None:
    rng = np.random.default_rng(12)
    table = rng.standard_normal((5000, 3)).astype(np.float32)
    rows = np.concatenate([rng.integers(0, 5000, 3000), np.argsort(rng.random(5000))]).astype(np.int64)
    np.testing.assert_array_equal(kernels.rows_taken(table, rows).view(np.uint32), table[rows].view(np.uint32))
    assert kernels.rows_taken(table, np.zeros(0, np.int64)).shape == (0, 3)
    classes = rng.integers(0, 256, 4000).astype(np.uint8)  # a table's row per class, as np.take
    want = np.take(table[:256], classes, axis=0)
    np.testing.assert_array_equal(kernels.rows_taken(table[:256].copy(), classes).view(np.uint32), want.view(np.uint32))


def test_bright_span_is_numpys() -> None:
    rng = np.random.default_rng(11)
    image = rng.uniform(0.0, 1.0, (60, 80, 3)).astype(np.float32)
    threshold = np.float32(1.6)
    assert kernels.over_span(image, threshold) == (-1, -1, -1, -1)
    image[[7, 40], [55, 12], [2, 0]] = 1.7
    image[20, 70, 1] = np.nan  # never above
    over = (image > threshold).any(axis=-1)
    rows, cols = np.flatnonzero(over.any(axis=1)), np.flatnonzero(over.any(axis=0))
    assert kernels.over_span(image, threshold) == (rows[0], rows[-1], cols[0], cols[-1]) == (7, 40, 12, 55)


def test_emitting_rows_are_the_lamps_and_lit_bus_windows_hit() -> None:
    from networks.classes import SemanticClass
    from sensors.parts import Part
    from sensors.photo import _EMITS_BY_PART, _emits

    rng = np.random.default_rng(13)
    part = rng.integers(0, 30, 50_000).astype(np.uint8)
    cls = rng.choice(np.array([int(SemanticClass.BUS), int(SemanticClass.CAR), 0], np.uint8), 50_000)
    range_m = np.where(rng.random(50_000) < 0.1, np.inf, 10.0).astype(np.float32)
    for night in (0.0, 1.0):
        want = np.flatnonzero(np.isfinite(range_m) & _emits(part, cls, night))
        got = kernels.emitting_rows(
            range_m, part, cls, _EMITS_BY_PART, night > 0, int(Part.GLASS), int(SemanticClass.BUS)
        )
        np.testing.assert_array_equal(got, want)
    assert len(want) > len(np.flatnonzero(np.isfinite(range_m) & _emits(part, cls, 0.0))) > 0


def test_sky_is_its_numpy_form_with_clouds_above_the_horizon_only() -> None:
    from sensors import photo, textures

    rng = np.random.default_rng(12)
    dirs = _unit_rows(rng, 40_000)
    dirs[:200, 2] = 0.0  # on the horizon: no clouds
    dirs[200:400, 2] = -0.0
    horizon, zenith = photo.to_linear((200.0, 180.0, 160.0)), photo.to_linear((190.0, 120.0, 60.0))
    t = np.sqrt(np.clip(dirs[:, 2], 0.0, 1.0))[:, None]
    sky = horizon + t * (zenith - horizon)
    up = np.flatnonzero(dirs[:, 2] > 0)
    cover = np.zeros((len(dirs), 1), np.float32)
    cover[up] = textures.clouds(dirs[up])[:, None] * np.float32(0.85) * np.clip(dirs[up, 2:3] * 6.0, 0.0, 1.0)
    cloud = horizon * np.float32(1.05) + np.float32(0.02)
    want = np.asarray(sky + cover * (cloud - sky), np.float32)
    got = kernels.sky(dirs, horizon, zenith, photo._CLOUD_SEEDS, np.float32(1.875))
    np.testing.assert_array_equal(got.view(np.uint32), want.view(np.uint32))


def test_sky_of_rows_is_the_sky_of_those_rows_written_in_place() -> None:
    from sensors import photo

    rng = np.random.default_rng(14)
    dirs = _unit_rows(rng, 30_000)
    dirs[:100, 2] = 0.0
    rows = np.sort(rng.choice(30_000, 12_000, replace=False)).astype(np.int64)
    horizon, zenith = photo.to_linear((200.0, 180.0, 160.0)), photo.to_linear((190.0, 120.0, 60.0))
    out = np.full((30_000, 3), 7.0, np.float32)
    want = out.copy()
    want[rows] = kernels.sky(dirs[rows], horizon, zenith, photo._CLOUD_SEEDS, np.float32(1.875))
    kernels.sky_rows(dirs, rows, horizon, zenith, photo._CLOUD_SEEDS, np.float32(1.875), out)
    np.testing.assert_array_equal(out.view(np.uint32), want.view(np.uint32))
    env = rng.random((30_000, 3)).astype(np.float32)
    want = env.copy()
    want[dirs[:, 2] < 0] = np.float32(0.3)
    kernels.below_horizon(env, dirs, np.float32(0.3))
    np.testing.assert_array_equal(env, want)


def test_shiny_hits_reflections_and_half_vectors_are_numpys() -> None:
    from sensors.parts import SHININESS_BY_PART, SPECULAR_BY_PART

    rng = np.random.default_rng(15)
    n, k = 20_000, 15_000
    at = np.sort(rng.choice(n, k, replace=False)).astype(np.int64)
    dirs, nrm = _unit_rows(rng, n), _unit_rows(rng, k)
    range_m = rng.uniform(1.0, 80.0, n).astype(np.float32)
    part = rng.integers(0, 12, n).astype(np.uint8)
    instance = rng.integers(0, 3, n).astype(np.uint32)
    sun_lit, sky_open = rng.random(n) < 0.5, rng.random(n).astype(np.float32)
    p = rng.uniform(-5, 5, (k, 3)).astype(np.float32)
    cos_v = rng.random(k).astype(np.float32)
    albedo = rng.random((k, 3)).astype(np.float32)
    mirror = np.where(rng.random(k) < 0.2, np.float32(0.3), np.float32(0.0)).astype(np.float32)
    sun = _unit_rows(rng, 1)[0]
    light_k = np.array([0.5, 2.0, 1.0, 30.0, 1.5, 0.1, 0.5, 1.0, 1.0, 60.0, 0.5, 0.2, 3.0, 6.0], np.float32)
    head, pool = rng.random(k).astype(np.float32), rng.random(k).astype(np.float32)
    street = np.array([0.55, 0.8, 1.0], np.float32)
    colour, shiny_at, refl, half_cos, shininess, away = kernels.lit_colour(
        at, dirs, range_m, part, instance, sun_lit, sky_open, p, nrm, cos_v, albedo, mirror, head, pool, sun,
        light_k, street, SPECULAR_BY_PART, SHININESS_BY_PART,
    )  # fmt: skip
    want_at = np.flatnonzero((SPECULAR_BY_PART[part[at]] > 0) | (mirror > 0))
    assert 0 < len(want_at) < k
    np.testing.assert_array_equal(shiny_at, want_at)
    d, m = dirs[at[want_at]], nrm[want_at]
    h = sun - d
    hn = np.sqrt(h[:, 0] * h[:, 0] + h[:, 1] * h[:, 1] + h[:, 2] * h[:, 2])
    want_cos = np.maximum(m[:, 0] * (h[:, 0] / hn) + m[:, 1] * (h[:, 1] / hn) + m[:, 2] * (h[:, 2] / hn), 0)
    dd = np.float32(2.0) * (d[:, 0] * m[:, 0] + d[:, 1] * m[:, 1] + d[:, 2] * m[:, 2])
    np.testing.assert_array_equal(half_cos.view(np.uint32), want_cos.astype(np.float32).view(np.uint32))
    np.testing.assert_array_equal(refl.view(np.uint32), (d - dd[:, None] * m).view(np.uint32))
    np.testing.assert_array_equal(shininess, SHININESS_BY_PART[part[at[want_at]]])
    np.testing.assert_array_equal(away.view(np.uint32), (np.float32(1.0) - cos_v[want_at]).view(np.uint32))
    assert colour.shape == (k, 3)


def test_levelled_bytes_are_levels_then_to_bytes() -> None:
    rng = np.random.default_rng(13)
    image = rng.uniform(-5.0, 260.0, (20_000, 3)).astype(np.float32)
    grey = ref.grey_of(image)
    noise = rng.standard_normal((20_000, 1), dtype=np.float32)
    for black in (np.float32(0.0), np.float32(37.5)):
        scale = np.float32(247.0) / (np.float32(255.0) - black) if black > 0 else np.float32(1.0)
        levelled = image.copy()
        ref.levels(levelled, grey, black, scale, np.float32(1.3), np.float32(8.0))
        want = ref.to_bytes(levelled, noise, np.float32(2.5))
        sat, toe, sigma = np.float32(1.3), np.float32(8.0), np.float32(2.5)
        got = ref.levelled_bytes(image, grey, black, scale, sat, toe, noise, sigma)
        np.testing.assert_array_equal(got, want)


def test_hits_ranges_and_street_pixels_are_numpys() -> None:
    rng = np.random.default_rng(14)
    n = 50_000
    depth = rng.uniform(0.0, 300.0, n).astype(np.float32)
    depth[rng.random(n) < 0.2] = 0.0
    depth[:10] = np.nan
    dirs = _unit_rows(rng, n)
    dirs[:, 2] = np.abs(dirs[:, 2]) + np.float32(0.1)
    want = np.where(depth > 0, depth / dirs[:, 2], np.float32(np.inf)).astype(np.float32)
    np.testing.assert_array_equal(kernels.ray_range(depth, dirs).view(np.uint32), want.view(np.uint32))
    cls = rng.integers(0, 30, n).astype(np.uint8)
    street = np.flatnonzero(((cls == 7) | (cls == 9)) & (depth > 0))
    np.testing.assert_array_equal(kernels.street_pixels(cls, depth, 7, 9), street)
    range_m = want.copy()
    range_m[:100] = np.float32(250.0)  # beyond the range below
    instance, part = rng.integers(0, 50, n).astype(np.uint32), rng.integers(0, 20, n).astype(np.uint8)
    normal, origin = _unit_rows(rng, n), np.array([3.0, -2.0, 1.5], np.float32)
    at, miss, c, inst, pt, p, nrm, cos_v = kernels.split_hits_geometry(
        range_m, np.float32(200.0), cls, instance, part, dirs, normal, origin
    )
    hit = np.isfinite(range_m) & (range_m <= np.float32(200.0))
    np.testing.assert_array_equal(at, np.flatnonzero(hit))
    np.testing.assert_array_equal(miss, np.flatnonzero(~hit))
    for got, whole in ((c, cls), (inst, instance), (pt, part)):
        assert got.dtype == whole.dtype
        np.testing.assert_array_equal(got, whole[at])
    np.testing.assert_array_equal(p.view(np.uint32), (origin + dirs[at] * range_m[at, None]).view(np.uint32))
    facing = np.einsum("ij,ij->i", normal[at], dirs[at])
    want = np.where((facing > 0)[:, None], -normal[at], normal[at])
    np.testing.assert_array_equal(nrm.view(np.uint32), want.view(np.uint32))
    np.testing.assert_array_equal(cos_v.view(np.uint32), np.abs(facing).view(np.uint32))


def test_rounding_levels_are_numpys() -> None:
    rng = np.random.default_rng(15)
    instance = (rng.random(60_000) < 0.3).astype(np.uint32) * 7
    depth = rng.uniform(0.0, 120.0, 60_000).astype(np.float32)
    depth[:50] = 0.05  # nearer than the nearest counted
    levels = np.asarray((1.5, 4.0, 10.0), np.float32)
    size = np.float32(1000.0 * 0.12)
    on = instance > 0
    want_ratio = (size / np.maximum(depth[on], np.float32(0.1)))[:, None] / levels
    normal, dirs = _unit_rows(rng, 60_000), _unit_rows(rng, 60_000)
    turned, ratio = kernels.turned_and_ratios(normal, dirs, instance, depth, size, np.float32(0.1), levels)
    np.testing.assert_array_equal(np.abs(turned), np.abs(normal))
    np.testing.assert_array_equal(ratio.view(np.uint32), want_ratio.view(np.uint32))
    want = np.full(60_000, -1, np.int8)
    want[on] = np.abs(np.log(want_ratio)).argmin(axis=-1)
    ties = np.log(np.array([[2.0, 0.5, 3.0], [1.0, 1.0, 1.0], [0.5, 2.0, 2.0]], np.float32))
    np.testing.assert_array_equal(kernels.nearest_levels(np.ones(3, np.uint32), ties), [0, 0, 0])
    np.testing.assert_array_equal(kernels.nearest_levels(instance, np.log(ratio)), want)


def test_haze_of_the_hits_is_haze_fraction() -> None:
    from sensors.photo import _haze_at
    from sensors.weather import PRESETS, haze_fraction

    rng = np.random.default_rng(16)
    range_m = rng.uniform(0.0, 260.0, 30_000).astype(np.float32)
    range_m[:20] = 0.0
    at = np.sort(rng.choice(30_000, 20_000, replace=False)).astype(np.int64)
    for weather in PRESETS.values():
        want = haze_fraction(weather, range_m[at], 250.0)
        np.testing.assert_array_equal(_haze_at(weather, at, range_m, 250.0).view(np.uint32), want.view(np.uint32))


def test_edges_are_those_of_the_class_part_and_instance_key() -> None:
    rng = np.random.default_rng(9)
    h, w = 37, 53
    cls = rng.integers(0, 3, h * w).astype(np.uint8)
    part = rng.integers(0, 2, h * w).astype(np.uint8)
    instance = rng.choice(np.array([0, 1, 2**32 - 1], np.uint32), h * w)
    range_m = rng.choice(np.array([1.0, 1.02, 1.05, 2e4, np.inf], np.float32), h * w)
    cls[: w * 10], part[: w * 10], instance[: w * 10] = 1, 0, 7  # flat rows: edges by range alone
    key = (cls.astype(np.int64) << 40) | (part.astype(np.int64) << 32) | instance
    capped = np.minimum(range_m, np.float32(1e4)).reshape(h, w)
    k = key.reshape(h, w)
    want = np.zeros((h, w), np.bool_)
    for a, b, ka, kb in (
        (capped[:, :-1], capped[:, 1:], k[:, :-1], k[:, 1:]),
        (capped[:-1], capped[1:], k[:-1], k[1:]),
    ):
        differ = (ka != kb) | (np.abs(a - b) > np.float32(0.03) * np.minimum(a, b))
        if a.shape[1] < w:
            want[:, :-1] |= differ
            want[:, 1:] |= differ
        else:
            want[:-1] |= differ
            want[1:] |= differ
    np.testing.assert_array_equal(kernels.edges(cls, part, instance, range_m, h, w), want.ravel())


def test_shadow_rays_come_in_columns_of_the_rows() -> None:
    from sensors.camera import ShadowScratch, _shadow_rays

    rng = np.random.default_rng(10)
    n = 5000
    dirs, normal = _unit_rows(rng, n), _unit_rows(rng, n)
    range_m = rng.uniform(0.0, 200.0, n).astype(np.float32)
    range_m[:50] = np.inf
    sun = np.array([0.3, 0.2, 0.93], np.float32)
    origin = np.array([1.0, 2.0, 3.0], np.float32)
    scratch = ShadowScratch()
    rows, kept = scratch.take(n)
    k = _shadow_rays(origin, dirs, range_m, normal, sun, np.float32(120.0), np.float32(0.02), rows, kept)
    at, columns = rows[:k], kept[:, :k]
    facing = np.where((np.einsum("ij,ij->i", normal, dirs) > 0)[:, None], -normal, normal)
    want_at = np.flatnonzero((range_m < 120.0) & (facing @ sun > 0))
    np.testing.assert_array_equal(at, want_at)
    rays = columns.T
    assert rays.shape == (len(at), 6) and all(rays[:, i].flags.c_contiguous for i in range(6))
    assert scratch.take(n)[0] is rows and scratch.take(n + 1)[0] is not rows  # kept, made anew when short
    point = (origin + dirs[at] * range_m[at, None]) + facing[at] * np.float32(0.02)
    np.testing.assert_array_equal(rays[:, :3].view(np.uint32), point.astype(np.float32).view(np.uint32))
    np.testing.assert_array_equal(rays[:, 3:], np.broadcast_to(sun, (len(at), 3)))


def _pcg64_words(bit_generator: np.random.PCG64) -> np.ndarray:
    state = bit_generator.state
    pcg, low = state["state"], (1 << 64) - 1
    words = [pcg["state"] >> 64, pcg["state"] & low, pcg["inc"] >> 64, pcg["inc"] & low]
    return np.array([*words, state["has_uint32"], state["uinteger"]], np.uint64)


def test_standard_normals_are_numpys_draws() -> None:
    for seed in (0, 7, 2**40 + 3):
        want = np.random.default_rng(seed).standard_normal(2_000_000, dtype=np.float32)
        assert (np.abs(want) > 3.6541528).sum() > 100  # the ziggurat's tail drawn, as its wedges are
        np.testing.assert_array_equal(ref.standard_normals(seed, len(want)).view(np.uint32), want.view(np.uint32))
    assert len(ref.standard_normals(5, 0)) == 0
    rng = np.random.default_rng(11)
    rng.random(3, dtype=np.float32)  # a 32-bit half kept for the next draw
    words = _pcg64_words(rng.bit_generator)
    assert words[4] == 1
    got = ref.standard_normals_of_state(words, 1000)
    np.testing.assert_array_equal(got.view(np.uint32), rng.standard_normal(1000, dtype=np.float32).view(np.uint32))
    assert words[4] == 1  # the state given is left as it is


def test_agents_lower_parts_take_their_own_boxes_floor_as_numpy_looks_it_up() -> None:
    rng = np.random.default_rng(13)
    n = 20_000
    instance = np.repeat(rng.choice(np.array([0, 3, 5, 9, 40, 41], np.uint32), 400), rng.integers(1, 100, 400))[:n]
    n = len(instance)
    dirs = _unit_rows(rng, n)
    range_m = rng.uniform(1.0, 80.0, n).astype(np.float32)
    range_m[::17] = np.inf
    ids = np.array([3, 5, 5, 9, 41], np.uint32)  # sorted, one repeated; 40 has no box
    floor_z = rng.uniform(-2.0, 1.0, len(ids)).astype(np.float32)
    origin = np.array([1.0, 2.0, 1.5], np.float32)
    light = rng.uniform(0.5, 1.0, n).astype(np.float32)
    want = light.copy()
    pos = np.minimum(np.searchsorted(ids, instance), len(ids) - 1)
    found = (instance > 0) & np.isfinite(range_m) & (ids[pos] == instance)
    height = (origin[2] + dirs[:, 2] * range_m) - floor_z[pos]
    want[found] = (np.float32(0.45) + np.float32(0.55) * np.clip(height / np.float32(0.5), 0.0, 1.0))[found]
    kernels.agents_low_light(light, dirs, range_m, instance, origin, ids, floor_z)
    np.testing.assert_array_equal(light.view(np.uint32), want.view(np.uint32))


def test_agent_weighted_windows_are_numpys_products() -> None:
    rng = np.random.default_rng(14)
    grid = rng.standard_normal((30, 40, 3)).astype(np.float32)
    grid[0, 0] = np.nan
    instance = np.where(rng.random((30, 40)) < 0.4, rng.integers(1, 9, (30, 40)), 0).astype(np.uint32)
    agent = (instance > 0).astype(np.float32)
    weighted, near = kernels.agent_weighted(grid, instance, 0, 22, 5, 40)
    want = grid[0:22, 5:40] * agent[0:22, 5:40][..., None]  # -0 off agents where the normal is negative
    np.testing.assert_array_equal(weighted.view(np.uint32), want.view(np.uint32))
    np.testing.assert_array_equal(near, agent[0:22, 5:40])
    assert weighted.flags.c_contiguous and near.flags.c_contiguous


def test_scaled_grey_is_the_product_in_place_then_grey_of() -> None:
    rng = np.random.default_rng(21)
    image = rng.uniform(0.0, 1.0, (30_000, 3)).astype(np.float32)
    image[:3] = [[0.0, 1.0, 0.5], [np.nan, 0.2, 0.3], [1e-40, 0.999999, 0.7]]
    want = image * np.float32(255.0)
    grey = ref.scaled_grey(image, np.float32(255.0))
    np.testing.assert_array_equal(image.view(np.uint32), want.view(np.uint32))
    np.testing.assert_array_equal(grey.view(np.uint32), ref.grey_of(want).view(np.uint32))


def test_depth_units_are_numpys_rounding_and_range() -> None:
    rng = np.random.default_rng(22)
    depth = rng.uniform(-1.0, 80.0, 50_000).astype(np.float32)
    special = [np.nan, np.inf, -np.inf, 0.0, -0.0, 65.535, 65.5355, 65.5345, 0.0005, 0.0015, 255.99, 256.0, 3e38]
    depth[: len(special)] = special
    with np.errstate(over="ignore", invalid="ignore"):
        cases = ((depth, 1000.0, False), (depth, 256.0, True), (depth.astype(np.float64), 100.0, False))
        for d, units, in_float32 in cases:
            units_m = np.rint(d * np.float32(units)) if in_float32 else np.rint(d.astype(np.float64) * units)
            want = np.where(np.isfinite(units_m) & (units_m > 0) & (units_m <= 65535), units_m, 0).astype(np.uint16)
            np.testing.assert_array_equal(kernels.depth_units(d, units, in_float32, 65535.0), want)


def test_finished_bytes_are_the_steps_one_after_another() -> None:
    from sensors.photo import finished_bytes

    rng = np.random.default_rng(23)
    curve = rng.uniform(0.0, 1.0, (50_001, 3)).astype(np.float32)
    curve[:40] *= np.float32(0.02)  # a dark corner: a black level above 0
    sample = kernels.grey_sample(curve, np.float32(255.0), 7)
    scaled = curve.copy()
    grey = ref.scaled_grey(scaled, np.float32(255.0))
    np.testing.assert_array_equal(sample.view(np.uint32), grey[::7].view(np.uint32))
    for saturation, seed in ((1.3, 5), (1.0, 2**40 + 3)):
        grey_again, black, scale = ref.black_level(scaled, grey)
        noise = ref.standard_normals(seed, len(curve)).reshape(-1, 1)
        sigma, sat, toe = np.float32(2.7), np.float32(saturation), np.float32(8.0)
        want = ref.levelled_bytes(scaled, grey_again, black, scale, sat, toe, noise, sigma)
        np.testing.assert_array_equal(finished_bytes(curve, saturation, seed, sigma), want)

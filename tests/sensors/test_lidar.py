from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from networks.classes import SemanticClass
from sensors.lidar import Lidar, LidarScan, LidarSpec
from sensors.weather import DAY, weather_preset


def small_lidar(**kw: float) -> Lidar:
    return Lidar(LidarSpec(beams=16, azimuth_steps=256, **kw))  # type: ignore[arg-type]


def same_scan(a: LidarScan, b: LidarScan) -> bool:
    fields = ("xyz_lidar_m", "intensity", "ring", "semantic_class", "instance_id")
    return all(np.array_equal(getattr(a, f), getattr(b, f)) for f in fields)


def test_a_ray_at_a_wall_returns_the_walls_distance(synth: SimpleNamespace, rng: np.random.Generator) -> None:
    lidar = small_lidar()
    scan = lidar.sense(synth.scene([synth.wall_at_x(10.0)]), synth.EGO, DAY, rng).scan
    ahead = scan.xyz_lidar_m[:, 0] > 0
    assert ahead.sum() > 100
    np.testing.assert_allclose(scan.xyz_lidar_m[ahead, 0], 10.0, atol=1e-3)
    dirs = scan.xyz_lidar_m[ahead] / np.linalg.norm(scan.xyz_lidar_m[ahead], axis=1, keepdims=True)
    np.testing.assert_allclose(np.linalg.norm(scan.xyz_lidar_m[ahead], axis=1), 10.0 / dirs[:, 0], rtol=1e-4)


def test_wall_returns_carry_the_walls_class_and_instance_zero(synth: SimpleNamespace, rng: np.random.Generator) -> None:
    scan = small_lidar().sense(synth.scene([synth.wall_at_x(10.0)]), synth.EGO, DAY, rng).scan
    assert np.all(scan.semantic_class == SemanticClass.BUILDING)
    assert np.all(scan.instance_id == 0)


def test_day_and_night_do_not_change_the_lidar(synth: SimpleNamespace) -> None:
    world = synth.scene([synth.ground(), synth.wall_at_x(30.0)])
    lidar = small_lidar(dropout=0.1, range_noise_m=0.02)
    plain = lidar.sense(world, synth.EGO, DAY, np.random.default_rng(1)).scan
    day = lidar.sense(world, synth.EGO, weather_preset("day"), np.random.default_rng(1)).scan
    night = lidar.sense(world, synth.EGO, weather_preset("night"), np.random.default_rng(1)).scan
    assert same_scan(plain, day) and same_scan(plain, night)


def test_fog_hides_a_wall_beyond_its_shortened_range(synth: SimpleNamespace, rng: np.random.Generator) -> None:
    world = synth.scene([synth.wall_at_x(60.0)])
    assert len(small_lidar().sense(world, synth.EGO, DAY, rng).scan) > 100
    fog = small_lidar().sense(world, synth.EGO, weather_preset("fog"), rng).scan
    assert np.all(fog.semantic_class == SemanticClass.NONE)


def test_rain_drops_and_weakens_returns_and_adds_near_spurious_ones(synth: SimpleNamespace) -> None:
    world = synth.scene([synth.wall_at_x(20.0)])
    lidar = Lidar(LidarSpec(beams=32, azimuth_steps=1024))
    day = lidar.sense(world, synth.EGO, DAY, np.random.default_rng(2)).scan
    rain = lidar.sense(world, synth.EGO, weather_preset("rain"), np.random.default_rng(2)).scan
    on_wall = rain.semantic_class == SemanticClass.BUILDING
    assert on_wall.sum() < 0.95 * len(day)
    assert rain.intensity[on_wall].mean() < 0.9 * day.intensity.mean()
    spurious = rain.semantic_class == SemanticClass.NONE
    assert spurious.sum() > 0
    assert np.all(np.linalg.norm(rain.xyz_lidar_m[spurious], axis=1) <= 6.2)
    assert np.all(rain.instance_id[spurious] == 0)


def test_compiled_reflectance_is_the_parts_table_bit_for_bit() -> None:
    from sensors.lidar import reflectance_of

    from .reference_forms import lidar_reflectance

    rng = np.random.default_rng(4)
    n = 200_000
    part = rng.integers(0, 40, n).astype(np.uint8)
    part[rng.random(n) < 0.5] = 0  # the static world, by class
    cls = rng.integers(0, 40, n).astype(np.uint8)
    instance = rng.integers(0, 2**32, n, dtype=np.uint64).astype(np.uint32)
    want, want_retro = lidar_reflectance(cls, part, instance)
    got, got_retro = reflectance_of(cls, part, instance)
    assert got.dtype == want.dtype == np.float32
    np.testing.assert_array_equal(got.view(np.uint32), want.view(np.uint32))
    np.testing.assert_array_equal(got_retro, want_retro)
    assert reflectance_of(cls[:0], part[:0], instance[:0])[0].shape == (0,)

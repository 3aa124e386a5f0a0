from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from networks.classes import SemanticClass
from sensors.camera import Camera, CameraSpec
from sensors.errors import SensorConfigError
from sensors.shading import shade_frame
from sensors.weather import DAY, PRESETS, Weather, haze_fraction, weather_preset

SMALL = CameraSpec(width_px=160, height_px=90)


def street(synth: SimpleNamespace) -> object:
    boxes = synth.agents([(1, SemanticClass.CAR, 12.0, 0.0, 0.75, 4.5, 1.8, 1.5, 0.0)])
    return synth.scene([synth.ground(), synth.wall_at_x(60.0)], boxes)


def test_the_four_presets_exist_and_unknown_names_are_rejected() -> None:
    assert set(PRESETS) == {"day", "night", "rain", "fog"}
    assert weather_preset("fog").lidar_range_scale < weather_preset("rain").lidar_range_scale < 1.0
    with pytest.raises(SensorConfigError, match="snow"):
        weather_preset("snow")


def test_out_of_range_weather_is_rejected() -> None:
    with pytest.raises(SensorConfigError):
        Weather("bad", lidar_dropout=1.0)


def test_night_and_rain_darken_the_image_and_add_noise(synth: SimpleNamespace) -> None:
    camera, world = Camera(SMALL), street(synth)
    day = camera.sense(world, synth.EGO, weather_preset("day"), np.random.default_rng(0)).frame
    night = camera.sense(world, synth.EGO, weather_preset("night"), np.random.default_rng(0)).frame
    rain = camera.sense(world, synth.EGO, weather_preset("rain"), np.random.default_rng(0)).frame
    # the auto contrast takes the day frame's veil out (day's mean 85 with the clear day's thin
    # haze, the far wall no longer pale; night 56)
    assert shade_frame(night).mean() < 0.7 * shade_frame(day).mean()
    assert shade_frame(rain).mean() < shade_frame(day).mean()
    night_again = camera.sense(world, synth.EGO, weather_preset("night"), np.random.default_rng(1)).frame
    day_again = camera.sense(world, synth.EGO, weather_preset("day"), np.random.default_rng(1)).frame
    assert np.abs(shade_frame(night).astype(int) - shade_frame(night_again)).mean() > 2.0
    assert np.abs(shade_frame(day).astype(int) - shade_frame(day_again)).mean() < 2.0  # read noise only
    same_seed = camera.sense(world, synth.EGO, weather_preset("day"), np.random.default_rng(0)).frame
    np.testing.assert_array_equal(shade_frame(day), shade_frame(same_seed))


def test_weather_changes_the_image_but_not_the_masks_or_depth(synth: SimpleNamespace) -> None:
    camera, world = Camera(SMALL), street(synth)
    day = camera.sense(world, synth.EGO, DAY, np.random.default_rng(0)).frame
    for name in ("night", "rain", "fog"):
        other = camera.sense(world, synth.EGO, weather_preset(name), np.random.default_rng(0)).frame
        np.testing.assert_array_equal(other.depth_m, day.depth_m)
        np.testing.assert_array_equal(other.instance_id, day.instance_id)


def test_fog_hazes_far_surfaces_more_than_near_ones() -> None:
    fog = weather_preset("fog")
    f = haze_fraction(fog, np.array([5.0, 50.0, 150.0], np.float32), 200.0)
    assert f[0] < 0.2 < f[1] < f[2] <= 1.0
    assert haze_fraction(fog, np.array([200.0], np.float32), 200.0)[0] == pytest.approx(1.0)


def test_a_clear_day_barely_hazes_road_users_at_their_usual_distances() -> None:
    # clear-day visibility of several km (5 % contrast at 3 x haze_m): a car 40 m away keeps
    # 98 % of its own light, the rain's and fog's haze take far more
    near = np.array([10.0, 40.0, 80.0], np.float32)
    assert haze_fraction(DAY, near, 200.0).max() < 0.04
    assert haze_fraction(DAY, near[1:2], 200.0)[0] < 0.02
    assert haze_fraction(weather_preset("rain"), near[1:2], 200.0)[0] > 0.1
    assert haze_fraction(DAY, np.array([200.0], np.float32), 200.0)[0] == pytest.approx(1.0)  # the far cut-off


def test_a_wet_road_mirrors_the_sky_most_where_it_is_seen_at_a_grazing_angle(synth: SimpleNamespace) -> None:
    from dataclasses import replace

    camera = Camera(CameraSpec(width_px=320, height_px=180))
    world = synth.scene([synth.ground()], synth.agents([(1, SemanticClass.CAR, 12.0, 0.0, 0.75, 4.5, 1.8, 1.5, 0.0)]))
    rain = weather_preset("rain")
    assert rain.wet_ground > 0
    wet = camera.sense(world, synth.EGO, rain, np.random.default_rng(0)).frame
    dry = camera.sense(world, synth.EGO, replace(rain, wet_ground=0.0), np.random.default_rng(0)).frame
    grey_wet, grey_dry = shade_frame(wet).mean(axis=2), shade_frame(dry).mean(axis=2)
    road = (wet.semantic_class == SemanticClass.ROAD) & (wet.instance_id == 0)
    far, near = road & (wet.depth_m > 40.0), road & (wet.depth_m < 6.0)
    assert far.sum() > 100 and near.sum() > 100  # the test means something: road far and near in view
    gain_far = grey_wet[far].mean() - grey_dry[far].mean()
    gain_near = grey_wet[near].mean() - grey_dry[near].mean()
    assert gain_far > 20 and gain_far > 2 * gain_near  # Fresnel: the far road shines, the near one stays dark


def test_a_bridge_decks_side_stays_dry_in_rain(synth: SimpleNamespace) -> None:
    from dataclasses import replace

    camera = Camera(CameraSpec(width_px=320, height_px=180))
    # the side of a deck (classed road) along the street, 5 m to the left, 3-6 m high: seen at a grazing angle
    side = synth.quad([(8.0, 5.0, 3.0), (200.0, 5.0, 3.0), (200.0, 5.0, 6.0), (8.0, 5.0, 6.0)], SemanticClass.ROAD)
    world = synth.scene([synth.ground(), side])
    rain = weather_preset("rain")
    wet = camera.sense(world, synth.EGO, rain, np.random.default_rng(0)).frame
    dry = camera.sense(world, synth.EGO, replace(rain, wet_ground=0.0), np.random.default_rng(0)).frame
    grey_wet, grey_dry = shade_frame(wet).mean(axis=2), shade_frame(dry).mean(axis=2)
    road = wet.semantic_class == SemanticClass.ROAD
    above = np.arange(180)[:, None] < 88  # above the horizon: the side; below it: the street
    street = road & ~above & (wet.depth_m > 30.0)
    assert (road & above).sum() > 200 and street.sum() > 100  # the test means something: both in view
    assert np.abs(grey_wet[road & above] - grey_dry[road & above]).mean() < 3  # no film of water on a wall
    assert grey_wet[street].mean() - grey_dry[street].mean() > 10  # the street: wet

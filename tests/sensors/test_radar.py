from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from networks.classes import SemanticClass
from sensors.errors import SensorConfigError
from sensors.radar import Radar, RadarScan, RadarSpec
from sensors.weather import DAY

CAR_ID = 4


def car_ahead(
    synth: SimpleNamespace, x_m: float = 30.0, velocity_mps: tuple[float, float, float] = (0, 0, 0)
) -> object:
    boxes = synth.agents([(CAR_ID, SemanticClass.CAR, x_m, 0.0, 0.75, 4.5, 1.8, 1.5, 0.0)], [velocity_mps])
    return synth.scene([synth.ground(), synth.wall_at_x(120.0)], boxes)


def scan(radar: Radar, scene: object, synth: SimpleNamespace, rng: np.random.Generator, ego_v=(0.0, 0.0, 0.0)):
    return radar.sense(scene, synth.ego(ego_v), DAY, rng).scan


def expected_radial(scan: RadarScan, relative_velocity_mps: np.ndarray) -> np.ndarray:
    """Radar axes equal map axes here (identity ego pose, no mount rotation)."""
    unit = scan.xyz_radar_m / np.linalg.norm(scan.xyz_radar_m, axis=1, keepdims=True)
    return unit @ relative_velocity_mps


@pytest.mark.parametrize("car_vx_mps", [-10.0, 10.0])
def test_radial_velocity_of_a_car_has_the_right_sign_and_size(
    synth: SimpleNamespace, rng: np.random.Generator, car_vx_mps: float
) -> None:
    returns = scan(Radar(RadarSpec()), car_ahead(synth, velocity_mps=(car_vx_mps, 0.0, 0.0)), synth, rng)
    on_car = returns.instance_id == CAR_ID
    assert on_car.sum() >= 5
    assert np.all(np.sign(returns.radial_velocity_mps[on_car]) == np.sign(car_vx_mps))
    np.testing.assert_allclose(np.abs(returns.radial_velocity_mps[on_car]), abs(car_vx_mps), rtol=0.02)
    expected = expected_radial(returns, np.array([car_vx_mps, 0.0, 0.0]))
    np.testing.assert_allclose(returns.radial_velocity_mps[on_car], expected[on_car], atol=1e-4)


def test_the_static_world_approaches_a_moving_ego(synth: SimpleNamespace, rng: np.random.Generator) -> None:
    ego_v = np.array([8.0, 0.0, 0.0])
    returns = scan(Radar(RadarSpec()), car_ahead(synth), synth, rng, ego_v)
    static = returns.instance_id == 0
    assert static.sum() > 10
    assert np.all(returns.radial_velocity_mps[static] < 0)
    np.testing.assert_allclose(returns.radial_velocity_mps, expected_radial(returns, -ego_v), atol=1e-4)


def test_a_car_driving_along_with_the_ego_has_zero_radial_velocity(
    synth: SimpleNamespace, rng: np.random.Generator
) -> None:
    v = (12.0, 0.0, 0.0)
    returns = scan(Radar(RadarSpec()), car_ahead(synth, velocity_mps=v), synth, rng, v)
    np.testing.assert_allclose(returns.radial_velocity_mps[returns.instance_id == CAR_ID], 0.0, atol=1e-5)


def test_returns_carry_class_and_instance_and_range(synth: SimpleNamespace, rng: np.random.Generator) -> None:
    returns = scan(Radar(RadarSpec()), car_ahead(synth, 20.0), synth, rng)
    on_car = returns.instance_id == CAR_ID
    assert np.all(returns.semantic_class[on_car] == SemanticClass.CAR)
    assert np.all(returns.semantic_class[~on_car] != SemanticClass.CAR)
    xyz_map = RadarSpec().ego_SE3_sensor.transform_from(returns.xyz_radar_m[on_car])
    assert np.all((xyz_map[:, 0] >= 17.75 - 0.02) & (xyz_map[:, 0] <= 22.25 + 0.02))
    np.testing.assert_allclose(np.linalg.norm(returns.xyz_radar_m, axis=1), returns.range_m, rtol=1e-5)
    wall = returns.semantic_class == SemanticClass.BUILDING
    np.testing.assert_allclose(returns.xyz_radar_m[wall, 0], 118.0, atol=1e-2)


def test_scan_is_sparse_in_its_field_of_view_and_repeatable_for_a_seed(synth: SimpleNamespace) -> None:
    spec = RadarSpec(points_per_frame=120)
    world = car_ahead(synth)
    scans = [scan(Radar(spec), world, synth, np.random.default_rng(5)) for _ in range(2)]
    assert len(scans[0]) == 120
    np.testing.assert_array_equal(scans[0].xyz_radar_m, scans[1].xyz_radar_m)
    assert np.all(np.abs(scans[0].azimuth_rad) <= np.radians(45.0))
    assert np.all(np.abs(scans[0].elevation_rad) <= np.radians(9.0))
    assert np.all(scans[0].range_m <= spec.range_m)


def test_strength_falls_with_range(synth: SimpleNamespace, rng: np.random.Generator) -> None:
    near = scan(Radar(RadarSpec()), car_ahead(synth, 15.0), synth, rng)
    far = scan(Radar(RadarSpec()), car_ahead(synth, 60.0), synth, rng)
    assert near.strength_db[near.instance_id == CAR_ID].max() > far.strength_db[far.instance_id == CAR_ID].max() + 15


def test_agent_velocities_look_up_by_id_and_default_to_zero(synth: SimpleNamespace) -> None:
    rows = [(i, SemanticClass.CAR, 0.0, 0.0, 0.75, 4.5, 1.8, 1.5, 0.0) for i in (9, 3)]
    agents = synth.agents(rows, [[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]])
    out = agents.velocities_of(np.array([3, 0, 9, 7], np.uint32))
    np.testing.assert_array_equal(out, [[4, 5, 6], [0, 0, 0], [1, 2, 3], [0, 0, 0]])


def test_out_of_range_radar_specs_are_rejected() -> None:
    with pytest.raises(SensorConfigError):
        RadarSpec(hfov_deg=0.0)
    with pytest.raises(SensorConfigError):
        RadarSpec(points_per_frame=0)


def test_cross_section_comes_from_the_material_table_metal_strong_people_weak(
    synth: SimpleNamespace, rng: np.random.Generator
) -> None:
    from sensors.parts import Part, radar_reflectivity

    metal = [Part.PAINT, Part.RIM, Part.CHROME, Part.CARGO, Part.FRAME, Part.LIVERY, Part.SAFETY_YELLOW]
    people = [Part.SKIN, Part.HAIR, Part.TOP, Part.TROUSERS, Part.SHOES]
    table = radar_reflectivity(
        np.full(len(metal + people), int(SemanticClass.CAR), np.uint8), np.array(metal + people, np.uint8)
    )
    assert table[: len(metal)].min() >= 0.8 and table[len(metal) :].max() <= 0.15
    # a car and a pedestrian side by side, 15 m ahead: the car's returns are about 8 times stronger
    rows = [
        (CAR_ID, SemanticClass.CAR, 15.0, -2.0, 0.75, 4.5, 1.8, 1.5, np.pi / 2),
        (9, SemanticClass.PEDESTRIAN, 15.0, 2.0, 0.9, 0.5, 0.6, 1.8, np.pi),
    ]
    world = synth.scene([synth.ground(), synth.wall_at_x(120.0)], synth.agents(rows))
    returns = scan(Radar(RadarSpec(points_per_frame=2000)), world, synth, rng)  # enough to reach the person
    car, person = (returns.strength_db[returns.instance_id == k] for k in (CAR_ID, 9))
    assert car.size > 5 and person.size > 0
    assert np.median(car) > np.median(person) + 6.0  # paint 1.0 against clothes and skin 0.1-0.15: 8-10 dB

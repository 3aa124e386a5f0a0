from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from networks.classes import SemanticClass
from networks.geometry import SE3
from sensors.errors import SensorConfigError
from sensors.radar import InstanceVelocities, Radar, RadarScan, RadarSpec

CAR_ID = 4


def car_ahead(synth: SimpleNamespace, x_m: float = 30.0) -> object:
    boxes = synth.agents([(CAR_ID, SemanticClass.CAR, x_m, 0.0, 0.75, 4.5, 1.8, 1.5, 0.0)])
    return synth.scene([synth.ground(), synth.wall_at_x(120.0)], boxes)


def expected_radial(scan: RadarScan, relative_velocity_mps: np.ndarray) -> np.ndarray:
    """Radar axes equal map axes here (identity ego pose, no mount rotation)."""
    unit = scan.xyz_radar_m / np.linalg.norm(scan.xyz_radar_m, axis=1, keepdims=True)
    return unit @ relative_velocity_mps


@pytest.mark.parametrize("car_vx_mps", [-10.0, 10.0])
def test_radial_velocity_of_a_car_has_the_right_sign_and_size(
    synth: SimpleNamespace, rng: np.random.Generator, car_vx_mps: float
) -> None:
    velocities = InstanceVelocities.from_unsorted([CAR_ID], [[car_vx_mps, 0.0, 0.0]])
    scan = Radar(RadarSpec()).scan(car_ahead(synth), SE3.identity(), velocities, np.zeros(3), rng)
    on_car = scan.instance_id == CAR_ID
    assert on_car.sum() >= 5
    assert np.all(np.sign(scan.radial_velocity_mps[on_car]) == np.sign(car_vx_mps))
    np.testing.assert_allclose(np.abs(scan.radial_velocity_mps[on_car]), abs(car_vx_mps), rtol=0.02)
    expected = expected_radial(scan, np.array([car_vx_mps, 0.0, 0.0]))
    np.testing.assert_allclose(scan.radial_velocity_mps[on_car], expected[on_car], atol=1e-4)


def test_the_static_world_approaches_a_moving_ego(synth: SimpleNamespace, rng: np.random.Generator) -> None:
    ego_v = np.array([8.0, 0.0, 0.0])
    scan = Radar(RadarSpec()).scan(car_ahead(synth), SE3.identity(), InstanceVelocities.empty(), ego_v, rng)
    static = scan.instance_id == 0
    assert static.sum() > 10
    assert np.all(scan.radial_velocity_mps[static] < 0)
    np.testing.assert_allclose(scan.radial_velocity_mps, expected_radial(scan, -ego_v), atol=1e-4)


def test_a_car_driving_along_with_the_ego_has_zero_radial_velocity(
    synth: SimpleNamespace, rng: np.random.Generator
) -> None:
    v = np.array([12.0, 0.0, 0.0])
    velocities = InstanceVelocities.from_unsorted([CAR_ID], [v])
    scan = Radar(RadarSpec()).scan(car_ahead(synth), SE3.identity(), velocities, v, rng)
    np.testing.assert_allclose(scan.radial_velocity_mps[scan.instance_id == CAR_ID], 0.0, atol=1e-5)


def test_returns_carry_class_and_instance_and_range(synth: SimpleNamespace, rng: np.random.Generator) -> None:
    scan = Radar(RadarSpec()).scan(car_ahead(synth, 20.0), SE3.identity(), InstanceVelocities.empty(), np.zeros(3), rng)
    on_car = scan.instance_id == CAR_ID
    assert np.all(scan.semantic_class[on_car] == SemanticClass.CAR)
    assert np.all(scan.semantic_class[~on_car] != SemanticClass.CAR)
    xyz_map = RadarSpec().ego_SE3_sensor.transform_from(scan.xyz_radar_m[on_car])
    assert np.all((xyz_map[:, 0] >= 17.75 - 0.02) & (xyz_map[:, 0] <= 22.25 + 0.02))
    np.testing.assert_allclose(np.linalg.norm(scan.xyz_radar_m, axis=1), scan.range_m, rtol=1e-5)
    wall = scan.semantic_class == SemanticClass.BUILDING
    np.testing.assert_allclose(scan.xyz_radar_m[wall, 0], 118.0, atol=1e-2)


def test_scan_is_sparse_in_its_field_of_view_and_repeatable_for_a_seed(synth: SimpleNamespace) -> None:
    spec = RadarSpec(points_per_frame=120)
    world = car_ahead(synth)
    scans = [Radar(spec).scan(world, SE3.identity(), InstanceVelocities.empty(), np.zeros(3), np.random.default_rng(5))
             for _ in range(2)]  # fmt: skip
    assert len(scans[0]) == 120
    np.testing.assert_array_equal(scans[0].xyz_radar_m, scans[1].xyz_radar_m)
    assert np.all(np.abs(scans[0].azimuth_rad) <= np.radians(45.0))
    assert np.all(np.abs(scans[0].elevation_rad) <= np.radians(9.0))
    assert np.all(scans[0].range_m <= spec.range_m)


def test_strength_falls_with_range(synth: SimpleNamespace, rng: np.random.Generator) -> None:
    near = Radar(RadarSpec()).scan(car_ahead(synth, 15.0), SE3.identity(), InstanceVelocities.empty(), np.zeros(3), rng)
    far = Radar(RadarSpec()).scan(car_ahead(synth, 60.0), SE3.identity(), InstanceVelocities.empty(), np.zeros(3), rng)
    assert near.strength_db[near.instance_id == CAR_ID].max() > far.strength_db[far.instance_id == CAR_ID].max() + 15


def test_instance_velocities_look_up_by_id_and_default_to_zero() -> None:
    table = InstanceVelocities.from_unsorted([9, 3], [[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]])
    out = table.lookup(np.array([3, 0, 9, 7], np.uint32))
    np.testing.assert_array_equal(out, [[4, 5, 6], [0, 0, 0], [1, 2, 3], [0, 0, 0]])
    with pytest.raises(ValueError):
        InstanceVelocities(np.array([3, 2], np.uint32), np.zeros((2, 3)))


def test_out_of_range_radar_specs_are_rejected() -> None:
    with pytest.raises(SensorConfigError):
        RadarSpec(hfov_deg=0.0)
    with pytest.raises(SensorConfigError):
        RadarSpec(points_per_frame=0)

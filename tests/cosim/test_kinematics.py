import math

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from cosim.kinematics import front_bumper_to_center, heading_vectors, sumo_angle_to_yaw, up_vectors

compass = st.floats(0.0, 360.0, allow_nan=False)
slopes = st.floats(-0.3, 0.3, allow_nan=False)
lengths = st.floats(0.2, 20.0, allow_nan=False)
coords = st.floats(-5e3, 5e3, allow_nan=False)


def test_sumo_compass_angles_become_counter_clockwise_yaw():
    yaw = sumo_angle_to_yaw([0.0, 90.0, 180.0, 270.0])
    assert np.allclose(np.cos(yaw), [0, 1, 0, -1], atol=1e-12)  # north, east, south, west
    assert np.allclose(np.sin(yaw), [1, 0, -1, 0], atol=1e-12)


@given(compass)
def test_heading_points_where_sumo_angle_points(angle_deg):
    heading = heading_vectors(sumo_angle_to_yaw(angle_deg), 0.0)
    # SUMO: 0 deg = north (+y), clockwise: east component sin(angle), north component cos(angle)
    assert np.allclose(heading[:2], [math.sin(math.radians(angle_deg)), math.cos(math.radians(angle_deg))], atol=1e-9)


@given(coords, coords, coords, compass, slopes, lengths, lengths)
def test_front_bumper_lies_half_a_length_ahead_of_the_centre(x, y, z, angle, pitch, length, height):
    yaw = sumo_angle_to_yaw(angle)
    center = front_bumper_to_center([x, y, z], yaw, pitch, length, height)[0]
    front_from_center = center + heading_vectors(yaw, pitch) * length / 2 - up_vectors(yaw, pitch) * height / 2
    assert np.allclose(front_from_center, [x, y, z], atol=1e-6)
    assert math.isclose(np.linalg.norm(center - [x, y, z]), math.hypot(length / 2, height / 2), rel_tol=1e-6)


@given(compass, slopes)
def test_heading_and_up_are_orthonormal(angle, pitch):
    yaw = sumo_angle_to_yaw(angle)
    h, u = heading_vectors(yaw, pitch), up_vectors(yaw, pitch)
    assert math.isclose(float(h @ u), 0.0, abs_tol=1e-9)
    assert math.isclose(float(np.linalg.norm(h)), 1.0) and math.isclose(float(np.linalg.norm(u)), 1.0)


def test_flat_car_facing_east_has_centre_behind_and_above_the_bumper():
    center = front_bumper_to_center([10.0, 5.0, 0.0], sumo_angle_to_yaw(90.0), 0.0, 4.0, 1.5)[0]
    assert np.allclose(center, [8.0, 5.0, 0.75])


def test_lamps_follow_sumo_signals_and_flash_half_the_time():
    from cosim.kinematics import lamps_of
    from sensors.agents import Lamp

    # SUMO bits: 1 right blinker, 2 left, 4 emergency, 8 brake
    signals = np.array([0, 8, 2, 1, 4, 8, 8])
    has_lamps = np.array([True, True, True, True, True, True, False])  # the last one a bicycle
    parked = np.array([False, False, False, False, False, True, False])
    lamps = lamps_of(signals, has_lamps, parked, 0.0, np.arange(7)) & ~np.uint8(Lamp.FLASH)
    assert lamps.tolist() == [
        Lamp.LIGHTS, Lamp.LIGHTS | Lamp.BRAKE, Lamp.LIGHTS | Lamp.LEFT, Lamp.LIGHTS | Lamp.RIGHT,
        Lamp.LIGHTS | Lamp.LEFT | Lamp.RIGHT, 0, 0,
    ]  # fmt: skip
    times = np.arange(0.0, 20.0, 0.01)
    lit = [lamps_of([2], [True], [False], float(t), [11])[0] & Lamp.FLASH > 0 for t in times]
    assert abs(np.mean(lit) - 0.5) < 0.01
    changes = np.count_nonzero(np.diff(np.asarray(lit, int)))
    assert abs(changes - 2 * 1.5 * 20.0) <= 1  # on and off 1.5 times a second
    assert not any(lamps_of([0], [True], [False], float(t), [11])[0] & Lamp.FLASH for t in times[:200])

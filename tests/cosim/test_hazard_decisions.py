"""The hazards' decisions, without SUMO: poses decoded from SUMO's conventions, where a vehicle
is beside or in line with the ego, pacing, when the ego stops for a jaywalker, who runs a red
light and which phase a light is switched to."""

import math
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from cosim.hazards.decisions import (
    JAYWALK_LOOK_M,
    LEADER_PACE_S,
    RED_LIGHT_S,
    RED_RUN_MPS,
    Kerb,
    Pose,
    approach_s,
    beside_gap,
    braking_s,
    closing_s,
    cut_in_gaps,
    cut_in_room,
    ego_stops_for_walker,
    in_ego_frame,
    in_line,
    leader_brakes,
    pace,
    parked_in_time,
    phase_to_green,
    red_run,
    straight,
)
from cosim.scenario import HazardConfig
from networks.vocabulary import Lamp, SignalState

EAST = 90.0  # SUMO's angle of a vehicle heading east (degrees clockwise from north)


def _east(front_x: float, front_y: float, length_m: float = 4.0, angle_deg: float = EAST) -> Pose:
    return Pose.of_sumo((front_x, front_y), angle_deg, length_m)


def test_a_pose_decodes_sumos_angle_and_puts_the_centre_behind_the_front_bumper():
    north = Pose.of_sumo((10.0, 20.0), 0.0, 4.0)
    assert north.yaw_rad == pytest.approx(math.pi / 2)
    np.testing.assert_allclose(north.centre_xy_m, [10.0, 18.0], atol=1e-12)
    np.testing.assert_allclose(_east(10.0, 20.0).centre_xy_m, [8.0, 20.0], atol=1e-12)


def test_a_pose_refuses_a_position_of_the_wrong_shape():
    with pytest.raises(ValueError, match=r"Pose.front_xy_m: expected shape \(2,\)"):
        Pose(np.zeros(3), 0.0, 4.0)


@given(
    st.floats(-1e3, 1e3), st.floats(-1e3, 1e3), st.floats(0.0, 359.9), st.floats(1.0, 18.0),
    st.floats(-100.0, 100.0), st.floats(-100.0, 100.0),
)  # fmt: skip
def test_the_ego_frame_keeps_distances_from_the_egos_centre(x, y, angle, length, dx, dy):
    ego = Pose.of_sumo((x, y), angle, length)
    point = ego.centre_xy_m + np.array([dx, dy])
    local = in_ego_frame(ego, point)
    assert np.hypot(*local) == pytest.approx(math.hypot(dx, dy), abs=1e-6)
    np.testing.assert_allclose(in_ego_frame(ego, ego.centre_xy_m), [0.0, 0.0], atol=1e-9)


def test_the_ego_frame_has_x_forward_and_y_left():
    ego = Pose.of_sumo((0.0, 0.0), 0.0, 4.0)  # heading north, centre at (0, -2)
    np.testing.assert_allclose(in_ego_frame(ego, [0.0, 8.0]), [10.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(in_ego_frame(ego, [-3.0, -2.0]), [0.0, 3.0], atol=1e-9)


def test_a_vehicle_in_the_next_lane_is_beside_the_ego_with_its_gap_from_rear_to_front_bumper():
    ego = _east(0.0, 0.0)
    assert beside_gap(ego, _east(14.0, 3.5)) == pytest.approx(10.0)  # its rear 10 m ahead
    assert beside_gap(ego, _east(-5.0, -3.5)) == pytest.approx(-9.0)  # behind, in the lane to the right
    assert beside_gap(ego, _east(14.0, 0.0)) is None  # in the ego's lane
    assert beside_gap(ego, _east(14.0, 7.0)) is None  # two lanes over
    assert beside_gap(ego, _east(14.0, 3.5, angle_deg=EAST + 30.0)) is None  # turning away


def test_a_leader_is_in_line_on_a_gentle_bend_but_not_off_to_the_side():
    ego = _east(0.0, 0.0)
    assert in_line(ego, _east(24.0, 0.5))
    assert in_line(ego, _east(24.0, 0.0, angle_deg=EAST + 6.0))
    assert not in_line(ego, _east(24.0, 2.0))
    assert not in_line(ego, _east(24.0, 0.0, angle_deg=EAST + 12.0))


def test_a_way_is_straight_only_over_its_whole_reach_without_a_turn():
    line = np.array([[0.0, 0.0], [100.0, 0.0]])
    bend = np.array([[0.0, 0.0], [50.0, 0.0], [50.0 + 50.0 * math.cos(0.5), 50.0 * math.sin(0.5)]])
    gentle = np.array([[0.0, 0.0], [50.0, 0.0], [50.0 + 50.0 * math.cos(0.05), 50.0 * math.sin(0.05)]])
    assert straight(line, 80.0)
    assert not straight(line, 120.0)  # the way ends within reach
    assert not straight(bend, 100.0)
    assert straight(gentle, 100.0)


def test_a_kerb_measures_across_its_driving_lanes():
    kerb = Kerb(np.zeros(2), np.array([1.0, 0.0]), np.array([0.0, 1.0]), (1, 2), (2.0, 3.0, 3.5))
    assert kerb.to_lane_m(1) == pytest.approx(1.5)
    assert kerb.to_lane_m(2) == pytest.approx(3.0 + 1.75)
    assert kerb.across_m() == pytest.approx(6.5)


def test_a_cut_in_gap_keeps_within_its_distance_and_time_gap():
    hazard = HazardConfig("cut_in", 3.0, distance_m=(5.0, 15.0), time_gap_s=(0.3, 1.0))
    assert cut_in_gaps(hazard, 20.0) == pytest.approx((6.0, 15.0))
    near, far = cut_in_gaps(hazard, 4.0)  # slow: the time gap leaves no gap in metres
    assert near >= far


@given(st.floats(0.0, 40.0), st.floats(-200.0, 60.0), st.floats(0.0, 60.0), st.floats(-5.0, 60.0))
def test_a_paced_vehicle_drives_at_least_1_mps_and_at_most_10_mps_faster_than_the_ego(ego, gap, wanted, left):
    speed = pace(ego, gap, wanted, left)
    assert 1.0 <= speed <= ego + 10.0 + 1e-9
    assert speed >= ego - 4.0 - 1e-9


def test_pacing_closes_a_gap_from_behind_and_drops_back_from_ahead():
    assert pace(20.0, 0.0, 10.0, 5.0) == pytest.approx(22.0)
    assert pace(20.0, 30.0, 10.0, 5.0) == pytest.approx(16.0)
    assert pace(20.0, -100.0, 10.0, 5.0) == pytest.approx(30.0)  # far behind: up to 10 m/s faster


def test_a_vehicle_farther_from_its_place_takes_longer_to_get_there():
    assert approach_s(-60.0, 10.0) > approach_s(-20.0, 10.0) > approach_s(5.0, 10.0)
    assert closing_s(300.0, 20.0) > closing_s(40.0, 20.0) == LEADER_PACE_S  # at least 20 s


def test_a_vehicle_cuts_in_at_the_egos_pace_with_room_before_the_egos_leader():
    assert cut_in_room(10.0, 20.0, 20.0, 4.5, None)  # no leader
    assert cut_in_room(10.0, 20.0, 20.0, 4.5, 15.5)  # its length and 1 m before the leader
    assert not cut_in_room(10.0, 20.0, 20.0, 4.5, 15.0)
    assert not cut_in_room(10.0, 13.5, 20.0, 4.5, None)  # rammed: far slower than the ego
    assert not cut_in_room(10.0, 23.5, 20.0, 4.5, None)  # pulling away


def test_a_leader_brakes_within_its_distance_from_a_speed_it_can_lose():
    hazard = HazardConfig("hard_brake", 6.0, distance_m=(5.0, 40.0), decel_mps2=7.0, to_speed_mps=2.0)
    assert leader_brakes(20.0, 20.0, hazard)
    assert not leader_brakes(45.0, 20.0, hazard) and not leader_brakes(4.0, 20.0, hazard)
    assert not leader_brakes(20.0, 5.5, hazard)  # hardly faster than the speed it brakes to
    assert braking_s(23.0, hazard) == pytest.approx(3.0)


def test_a_jaywalker_steps_out_at_the_parked_car_the_ego_reaches_nearest_the_time_due():
    parked = [("near", 30.0), ("mid", 100.0), ("far", 200.0), ("passed", 10.0)]
    # reach 25 m, 10 m/s: the ego comes within reach of near in 0.5 s, mid in 7.5 s, far in 17.5 s
    assert parked_in_time(parked, 25.0, 10.0, 8.0) == "mid"
    assert parked_in_time(parked, 25.0, 10.0, 0.0) == "near"
    assert parked_in_time(parked, 25.0, 10.0, 60.0) == "far"
    assert parked_in_time([("passed", 10.0)], 25.0, 10.0, 8.0) is None  # nearer than the reach


def test_the_ego_stops_for_a_walker_in_or_coming_into_its_path_ahead():
    ego = _east(0.0, 0.0)
    assert ego_stops_for_walker(ego, 20.0, 0.5, 10.0, 1.4)  # in its path
    assert ego_stops_for_walker(ego, 20.0, -4.0, 10.0, 1.4)  # on its right, walking in before it could stop
    assert not ego_stops_for_walker(ego, 20.0, -9.0, 1.0, 1.4)  # far to the right, the ego nearly stands
    assert not ego_stops_for_walker(ego, 20.0, 4.0, 10.0, 1.4)  # on its left: it has crossed the ego's path
    assert not ego_stops_for_walker(ego, JAYWALK_LOOK_M + 1.0, 0.0, 10.0, 1.4)  # too far ahead
    assert not ego_stops_for_walker(ego, -10.0, 0.0, 10.0, 1.4)  # behind


def test_a_red_light_runner_goes_before_the_ego_or_behind_it_or_not_at_all():
    assert red_run(10.0, 8.0, 20.0, 25.0) == (RED_RUN_MPS, RED_LIGHT_S)  # through long before the ego
    speed, lasts = red_run(60.0, 8.0, 3.0, 6.0)  # the ego is near: it crosses behind it
    assert speed == pytest.approx(10.0) and lasts == pytest.approx(6.0 + 25.0 / 10.0 + 1.0)
    assert red_run(5.0, 2.0, 1.0, 4.0) is None  # too near to go behind, too slow to go before


# Two links, north-south (0) and east-west (1): green, yellow, the other's green, its yellow.
PROGRAM = [SignalState.decode(s) for s in ("Gr", "yr", "rG", "ry")]
DURATIONS = [30.0, 3.0, 30.0, 3.0]


def test_a_light_turns_green_for_the_ego_through_the_yellow_that_ends_the_crossing_green():
    assert phase_to_green(PROGRAM, DURATIONS, 2, 0, 10.0) == 3
    assert phase_to_green(PROGRAM, DURATIONS, 2, 0, 3.5) is None  # the ego would be there before the yellow ends
    assert phase_to_green(PROGRAM, DURATIONS, 3, 0, 10.0) is None  # already in that yellow
    assert phase_to_green(PROGRAM, DURATIONS, 2, 1, 10.0) is None  # no phase to come gives green to a link green now


def test_a_light_is_not_switched_where_a_green_link_would_skip_its_yellow():
    program = [SignalState.decode(s) for s in ("rG", "rG", "rr", "Gr")]
    assert phase_to_green(program, [10.0] * 4, 0, 0, 60.0) is None


def test_every_signal_letter_decodes_to_a_state_with_a_lamp():
    states = SignalState.decode("GgsryYuoO")
    assert len(set(states)) == len(SignalState) and all(s.lamp in Lamp for s in states)
    assert SignalState.of("x") is SignalState.OFF
    assert [s.is_green for s in SignalState.decode("Ggsr")] == [True, True, False, False]


def test_the_decisions_need_no_simulation():
    code = "import sys, cosim.hazards.decisions, cosim.hazards.plan; print('libsumo' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"

"""The world states' rates of turn on both sides of each frame's time (cosim.traffic_feed,
without SUMO)."""

import numpy as np

from cosim.state import WorldState
from cosim.traffic_feed import turn_rates_across
from sensors.agents import Agents, EgoState, motion_over, turn_rate_at

STEP_S = 0.1
ACCEL = 0.8  # rad/s^2: bodies entering a bend, their rate of turn rising with time


def heading(t_s: float) -> float:
    return 0.5 * ACCEL * t_s * t_s


def state(t_s: float, ids: list[int], scene_cut: bool = False) -> WorldState:
    """Agents ``ids`` and the ego turning ever faster, with the rate the traffic gives: the
    heading's change since the step before, over the step."""
    n = len(ids)
    backward = (heading(t_s) - heading(t_s - STEP_S)) / STEP_S
    agents = Agents(np.array(ids, np.uint32), np.full(n, 10, np.uint8), np.zeros((n, 3)), np.ones((n, 3)),
                    np.full(n, heading(t_s)), np.zeros(n), np.zeros((n, 3)), np.zeros(n, np.bool_),
                    yaw_rate_rad_s=np.full(n, backward))  # fmt: skip
    ego = EgoState(np.zeros(3), np.ones(3), heading(t_s), 0.0, np.zeros(3), backward)
    return WorldState(t_s, agents, ego, scene_cut)


def test_bodies_turn_to_their_headings_interpolated_between_steps_on_both_sides_of_the_frames_time():
    t = 2.0
    now, ahead = state(t, [1, 2, 3]), state(t + STEP_S, [1, 3, 4])
    out = turn_rates_across(now, ahead, before=np.array([1, 2, 9], np.uint32))
    agents = out.agents
    assert agents.instance_id.tolist() == [1, 2, 3] and out.time_s == t  # only the rates change
    # half a step before and after: the heading halfway to the step before's, and to the next's
    for dt, other in ((-STEP_S / 2, t - STEP_S), (STEP_S / 2, t + STEP_S)):
        halfway = 0.5 * (heading(t) + heading(other))
        rate = turn_rate_at(agents.yaw_rate_rad_s[0], agents.yaw_rate_after_rad_s[0], dt)
        assert abs(heading(t) + motion_over(np.zeros(3), rate, dt)[1] - halfway) < 1e-12
        rate = turn_rate_at(*out.ego.turn_rates(), dt)
        assert abs(heading(t) + rate * dt - halfway) < 1e-12
        one_rate = now.agents.yaw_rate_rad_s[0]  # the step's own rate on both sides
        assert dt < 0 or abs(heading(t) + one_rate * dt - halfway) > 1e-3
    assert agents.yaw_rate_rad_s[1] == agents.yaw_rate_after_rad_s[1] == now.agents.yaw_rate_rad_s[1]  # gone next
    assert agents.yaw_rate_rad_s[2] == agents.yaw_rate_after_rad_s[2] == ahead.agents.yaw_rate_rad_s[1]  # new now


def test_the_ego_keeps_its_own_rate_before_a_scene_cut_and_takes_the_next_after_one():
    t = 1.0
    own, following = state(t, [1]).ego.yaw_rate_rad_s, state(t + STEP_S, [1]).ego.yaw_rate_rad_s
    before = np.array([1], np.uint32)
    cut_next = turn_rates_across(state(t, [1]), state(t + STEP_S, [1], scene_cut=True), before)
    assert cut_next.ego.turn_rates() == (own, own)
    cut_now = turn_rates_across(state(t, [1], scene_cut=True), state(t + STEP_S, [1]), before)
    assert cut_now.ego.turn_rates() == (following, following)
    first = turn_rates_across(state(t, [1]), state(t + STEP_S, [1]), None)  # no step read before
    assert first.ego.turn_rates() == (following, following)
    assert first.agents.yaw_rate_rad_s[0] == first.agents.yaw_rate_after_rad_s[0] == following

"""When hazard events are due and where the rig cannot see (no SUMO)."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from cosim.hazards.plan import BACKLOG, Schedule, Sight
from cosim.scenario import SensorsConfig
from sensors.camera import CameraSpec
from sensors.lidar import LidarSpec


def _dues(schedule: Schedule, until_s: float) -> list[float]:
    """Every due time up to ``until_s``, each event started when due."""
    dues = []
    while schedule.due_s() <= until_s:
        dues.append(schedule.due_s())
        schedule.take(schedule.due_s())
    return dues


def test_one_event_is_due_in_the_middle_half_of_each_period():
    dues = _dues(Schedule(20.0, 100.0, np.random.default_rng(3)), 100.0 + 20.0 * 50)
    assert len(dues) == 50
    for k, due in enumerate(dues):
        assert 100.0 + (k + 0.25) * 20.0 <= due <= 100.0 + (k + 0.75) * 20.0
    assert min(np.diff(dues)) >= 0.5 * 20.0 and max(np.diff(dues)) <= 1.5 * 20.0


@given(st.integers(0, 2**32 - 1), st.floats(0.5, 30.0), st.floats(0.0, 300.0), st.floats(1.0, 300.0))
def test_any_stretch_of_a_run_holds_the_rate_asked_to_within_one_and_a_half_events(seed, per_minute, start_s, length_s):
    period = 60.0 / per_minute
    dues = np.array(_dues(Schedule(period, 0.0, np.random.default_rng(seed)), start_s + length_s + period))
    count = np.count_nonzero((dues >= start_s) & (dues < start_s + length_s))
    assert abs(count - length_s / period) <= 1.5


def test_over_many_runs_the_mean_count_is_the_rate_asked():
    counts = [len(_dues(Schedule(20.0, 0.0, np.random.default_rng(seed)), 30.0)) for seed in range(2000)]
    assert np.mean(counts) == pytest.approx(1.5, abs=0.05)  # 3 a minute over 30 s


def test_a_kind_owes_at_most_two_events():
    schedule = Schedule(10.0, 0.0, np.random.default_rng(0))
    schedule.take(200.0)  # the first started 20 periods late
    assert 200.0 - BACKLOG * 10.0 - 10.0 <= schedule.due_s() < 200.0 - (BACKLOG - 1) * 10.0
    assert schedule.due_s(1) > schedule.due_s()


def test_the_default_rig_sees_its_lidar_range_around_and_its_cameras_range_ahead():
    sight = Sight.of_rig(SensorsConfig())  # LiDAR 120 m around, camera 200 m and radar 150 m ahead
    assert sight.label_m == 120.0
    assert sight.sees(np.array([-110.0, 3.5]), 3.0) and not sight.sees(np.array([-130.0, 3.5]), 3.0)
    assert sight.sees(np.array([190.0, 0.0]), 3.0) and not sight.sees(np.array([210.0, 0.0]), 3.0)
    assert sight.sees(np.array([150.0, 100.0]), 3.0)  # 34 degrees left: in the camera's 42.5
    assert not sight.sees(np.array([100.0, 150.0]), 3.0)  # 56 degrees left, 180 m: no sensor
    assert 125.0 <= sight.clear_behind_m(3.5, 8.0) <= 135.0
    assert 205.0 <= sight.clear_ahead_m(8.0) <= 215.0


def test_a_rig_without_lidar_labels_as_far_as_its_farthest_sensor():
    rig = SensorsConfig(lidars=(), cameras=(CameraSpec(range_m=80.0),), radars=())
    sight = Sight.of_rig(rig)
    assert sight.label_m == 80.0 and not sight.sees(np.array([0.0, 90.0]), 1.0)


def test_a_camera_turned_backwards_sees_behind():
    rig = SensorsConfig(
        lidars=(LidarSpec(range_m=50.0),), cameras=(CameraSpec(mount_rpy_deg=(0.0, 0.0, 180.0)),), radars=()
    )
    sight = Sight.of_rig(rig)
    assert sight.sees(np.array([-150.0, 0.0]), 3.0) and not sight.sees(np.array([150.0, 0.0]), 3.0)

"""The benchmark's probe, table and targets (the runs themselves are `make bench`)."""

import pytest

from cosim.bench import MEMORY_FROM_FRAME, BenchProbe, table, targets


def test_the_probe_keeps_a_few_scenes_spread_over_the_run_and_samples_memory_every_25_frames():
    probe = BenchProbe(frames=200, cast_scenes=4)
    probe.frame_done(-1)
    for i in range(200):
        with probe.stage("camera"):
            probe.scene(i, scene=object(), map_SE3_ego=None)  # type: ignore[arg-type]
        probe.frame_done(i)
    assert len(probe.scenes) == 4
    assert probe.times.calls["camera"] == 200 and len(probe.frame_end_s) == 201
    assert sorted(probe.rss_mb) == [MEMORY_FROM_FRAME, 125, 150, 175, 200] and probe.rss_mb[200] > 10
    assert sorted(probe.rss_mb_by_process) == [MEMORY_FROM_FRAME, 200]
    assert probe.peak_mb["main"] >= probe.rss_mb[200] * 0.5


def test_targets_compare_the_right_numbers_and_the_table_shows_every_case():
    results = {
        "full": {"frames": 10, "fps": 16.0, "frame_ms": 62.0, "frame_over_cast": 2.5, "rss_growth_pct": 1.0,
                 "stages_ms": {"camera": 90.0}, "pure_cast_ms": {"camera": 55.0}},
        "lidar": {"frames": 10, "fps": 30.0, "frame_ms": 33.0, "stages_ms": {"lidar": 9.0}},
        "v500": {"frames": 10, "frame_ms": 140.0, "stages_ms": {}},
        "v5000": {"frames": 10, "error": "TrafficError: boom"},
    }  # fmt: skip
    t = targets(results)
    assert t["full_fps"]["met"] is True and t["lidar_fps"]["met"] is False
    assert t["cast_ratio"]["met"] is False and t["rss_growth_pct"]["met"] is True
    assert t["v5000_over_v500"]["met"] is None  # the 5,000-vehicle case failed: no verdict
    text = table(results)
    assert "camera" in text and "v5000: error: TrafficError: boom" in text


def test_the_occupancy_target_is_on_its_stages_cpu_time_not_its_wall_time():
    probe = BenchProbe(frames=2, cast_scenes=0)
    with probe.stage("occupancy"):
        sum(i * i for i in range(200_000))  # CPU
    with probe.stage("occupancy"):
        import time

        time.sleep(0.05)  # wall only
    assert probe.times.seconds["occupancy"] >= probe.cpu_times.seconds["occupancy"] + 0.04
    results = {"occupancy": {"frames": 2, "frame_ms": 900.0, "stages_ms": {"occupancy": 800.0},
                             "stages_cpu_ms": {"occupancy": 12.0}}}  # fmt: skip
    assert targets(results)["occupancy_ms"] == {"value": 12.0, "target": "<= 15.0", "met": True}
    assert "occupancy (CPU)" in table(results)


def test_the_timed_sweep_target_is_the_frame_rate_it_takes_by_the_main_process_cpu():
    results = {"lidar-kitti": {"frames": 5, "fps": 2.0, "cpu_ms_per_frame": {"main": 100.0, "helpers": 30.0}},
               "lidar-kitti-instant": {"frames": 5, "fps": 4.0, "cpu_ms_per_frame": {"main": 80.0}}}  # fmt: skip
    t = targets(results)["timed_sweep_cost_pct"]
    assert t["value"] == pytest.approx(20.0) and t["met"] is True and t["target"] == "<= 25.0"
    results["lidar-kitti"]["cpu_ms_per_frame"]["main"] = 120.0  # the rate falls by a third
    assert targets(results)["timed_sweep_cost_pct"]["met"] is False
    del results["lidar-kitti-instant"]
    assert targets(results)["timed_sweep_cost_pct"]["met"] is None


def test_memory_growth_compares_the_high_water_marks_of_the_first_and_last_tenth():
    """Samples that swing (the camera's buffers) but do not climb read as flat; a climb reads as
    the climb."""
    from cosim.bench import rss_growth_pct

    swinging = {k: 600.0 + (60.0 if (k // 25) % 3 == 0 else 0.0) for k in range(100, 3001, 25)}
    swinging[3000] = 600.0  # the last sample low, the first high: single samples would say -9 %
    assert rss_growth_pct(swinging, 3000) == pytest.approx(0.0)
    climbing = {k: 600.0 + 0.1 * (k - 100) for k in range(100, 3001, 25)}
    assert rss_growth_pct(climbing, 3000) == pytest.approx(100 * (890.0 / 627.5 - 1))  # frame 3,000's over 375's
    assert rss_growth_pct({100: 600.0}, 100) is None

import numpy as np
import pandas as pd
import pytest

from gtgen.content import CLASSES, main, seen_near, speeds_of, table


def _labels(rows):
    return pd.DataFrame(rows, columns=["frame", "type", "seen", "distance", "parked"])


def test_seen_objects_within_the_radius_are_counted_per_frame_by_class():
    labels = _labels([
        (0, "pedestrian", 1, 10.0, 0), (0, "pedestrian", 1, 49.9, 0), (0, "pedestrian", 0, 5.0, 0),  # unseen
        (0, "pedestrian", 1, 50.1, 0),  # beyond 50 m
        (1, "bicycle", 1, 20.0, 0), (1, "car", 1, 8.0, 1), (1, "car", 1, 8.0, 0), (1, "bicycle", 1, 3.0, 1),
    ])  # fmt: skip
    near = seen_near(labels, frames=4)
    assert near["pedestrian"] == pytest.approx(2 / 4)
    assert near["cyclist"] == pytest.approx(1 / 4)  # the parked bicycle is no cyclist
    assert near["car"] == pytest.approx(1 / 4) and near["parked"] == pytest.approx(2 / 4)
    assert near["truck"] == 0 and set(CLASSES) <= set(near)


def test_speeds_from_positions_start_each_scene_with_the_next_frames_speed():
    t = np.arange(6) * 0.05
    x = np.array([0.0, 0.5, 1.0, 1.0, 500.0, 500.5])  # moving, standing, a cut at frame 4, moving
    xyz = np.stack([x, np.zeros(6), np.zeros(6)], axis=1)
    speed = speeds_of(t, xyz, scene_cuts=[4])
    assert speed == pytest.approx([10.0, 10.0, 10.0, 0.0, 10.0, 10.0])


def test_table_has_a_row_per_run_and_the_references(capsys, tmp_path):
    assert main([str(tmp_path)]) == 2
    assert "no labels.csv" in capsys.readouterr().err
    lines = table([])
    assert lines[0].startswith("| run | frames | pedestrian | cyclist")
    assert any(line.startswith("| nuScenes |") and "6.5" in line for line in lines)
